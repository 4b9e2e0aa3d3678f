//! The manual holds together: every relative link in README.md and docs/ resolves (the file exists;
//! a `#anchor` names a heading of the target page, by GitHub's rules), and every file kept under
//! docs/results/ is cited by a page (README.md or a page under docs/), so nothing there is orphaned.
//!
//! Std-only; reads files, builds nothing.

use std::collections::BTreeSet;
use std::fs;
use std::path::{Component, Path, PathBuf};

fn workspace() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// README.md, deploy/README.md and every `.md` under docs/ (recursively), sorted.
fn pages(ws: &Path) -> Vec<PathBuf> {
    let mut out = vec![ws.join("README.md")];
    if ws.join("deploy/README.md").is_file() {
        out.push(ws.join("deploy/README.md"));
    }
    let mut dirs = vec![ws.join("docs")];
    while let Some(d) = dirs.pop() {
        let Ok(rd) = fs::read_dir(&d) else { continue };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                dirs.push(p);
            } else if p.extension().is_some_and(|x| x == "md") {
                out.push(p);
            }
        }
    }
    out.sort();
    out
}

/// The page's text outside fenced code blocks and inline code spans, line by line.
fn prose_lines(text: &str) -> Vec<(usize, String)> {
    let mut out = Vec::new();
    let mut fenced = false;
    for (i, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced {
            continue;
        }
        // Drop inline code spans.
        let mut kept = String::new();
        let mut in_code = false;
        for c in line.chars() {
            if c == '`' {
                in_code = !in_code;
            } else if !in_code {
                kept.push(c);
            }
        }
        out.push((i + 1, kept));
    }
    out
}

/// GitHub's anchor for a heading: lower case; letters, digits, `-` and `_` kept; spaces become `-`;
/// everything else dropped. Repeated anchors get `-1`, `-2`, ...
fn anchors(text: &str) -> BTreeSet<String> {
    let mut seen = BTreeSet::new();
    let mut fenced = false;
    for line in text.lines() {
        if line.trim_start().starts_with("```") {
            fenced = !fenced;
            continue;
        }
        if fenced || !line.starts_with('#') {
            continue;
        }
        let title = line.trim_start_matches('#').trim();
        let mut slug = String::new();
        for c in title.to_lowercase().chars() {
            if c.is_alphanumeric() || c == '-' || c == '_' {
                slug.push(c);
            } else if c == ' ' {
                slug.push('-');
            }
        }
        let mut candidate = slug.clone();
        let mut n = 0;
        while seen.contains(&candidate) {
            n += 1;
            candidate = format!("{slug}-{n}");
        }
        seen.insert(candidate);
    }
    seen
}

/// `[text](target)` link targets on one line of prose.
fn link_targets(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut rest = line;
    while let Some(i) = rest.find("](") {
        let after = &rest[i + 2..];
        let Some(end) = after.find(')') else { break };
        let target = after[..end]
            .split_whitespace()
            .next()
            .unwrap_or("")
            .to_string();
        out.push(target);
        rest = &after[end..];
    }
    out
}

/// `a/./b/../c` → `a/c` (no file system access).
fn normalise(p: &Path) -> PathBuf {
    let mut out = PathBuf::new();
    for c in p.components() {
        match c {
            Component::ParentDir => {
                out.pop();
            }
            Component::CurDir => {}
            other => out.push(other.as_os_str()),
        }
    }
    out
}

/// Every broken relative link: "page:line: target (why)".
fn broken_links(ws: &Path) -> Vec<String> {
    let mut bad = Vec::new();
    for page in pages(ws) {
        let text = fs::read_to_string(&page).unwrap();
        let rel = page.strip_prefix(ws).unwrap_or(&page).display().to_string();
        for (line, prose) in prose_lines(&text) {
            for target in link_targets(&prose) {
                if target.is_empty()
                    || target.contains("://")
                    || target.starts_with("mailto:")
                    || target.starts_with('<')
                {
                    continue;
                }
                let (path_part, anchor) = match target.split_once('#') {
                    Some((p, a)) => (p, Some(a)),
                    None => (target.as_str(), None),
                };
                let file = if path_part.is_empty() {
                    page.clone()
                } else {
                    normalise(&page.parent().unwrap().join(path_part))
                };
                if !file.exists() {
                    bad.push(format!("{rel}:{line}: {target} (no such file)"));
                    continue;
                }
                if let Some(a) = anchor {
                    if file.extension().is_some_and(|x| x == "md") {
                        let t = fs::read_to_string(&file).unwrap_or_default();
                        if !anchors(&t).contains(a) {
                            bad.push(format!(
                                "{rel}:{line}: {target} (no heading with anchor #{a})"
                            ));
                        }
                    }
                }
            }
        }
    }
    bad
}

#[test]
fn every_relative_link_resolves() {
    let bad = broken_links(&workspace());
    assert!(bad.is_empty(), "broken links:\n{}", bad.join("\n"));
}

#[test]
fn every_result_file_is_cited_by_a_page() {
    let ws = workspace();
    let all: String = pages(&ws)
        .iter()
        .map(|p| fs::read_to_string(p).unwrap())
        .collect::<Vec<_>>()
        .join("\n");
    let mut orphans = Vec::new();
    let mut files = 0;
    for e in fs::read_dir(ws.join("docs/results")).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        files += 1;
        if !all.contains(&name) {
            orphans.push(name);
        }
    }
    orphans.sort();
    assert!(files > 0, "docs/results is empty");
    assert!(
        orphans.is_empty(),
        "files under docs/results that no page cites (cite them by their full name, or delete them):\n{}",
        orphans.join("\n")
    );
}

/// README.md links every top-level page under docs/ (the manual's table of contents).
#[test]
fn the_readme_links_every_docs_page() {
    let ws = workspace();
    let readme = fs::read_to_string(ws.join("README.md")).unwrap();
    let linked: BTreeSet<String> = prose_lines(&readme)
        .iter()
        .flat_map(|(_, l)| link_targets(l))
        .collect();
    let mut missing = Vec::new();
    for e in fs::read_dir(ws.join("docs")).unwrap().flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if name.ends_with(".md")
            && !linked
                .iter()
                .any(|t| t.split('#').next() == Some(&format!("docs/{name}")))
        {
            missing.push(name);
        }
    }
    missing.sort();
    assert!(
        missing.is_empty(),
        "docs pages the README does not link: {missing:?}"
    );
}

/// Every `results/NAME` a page names (outside links too, e.g. in a command) exists, unless it is a
/// pattern (`<...>`, `*`, `{a,b}`) standing for files the reader makes.
#[test]
fn every_cited_result_file_exists() {
    let ws = workspace();
    let mut missing = Vec::new();
    for page in pages(&ws) {
        let text = fs::read_to_string(&page).unwrap();
        let rel = page
            .strip_prefix(&ws)
            .unwrap_or(&page)
            .display()
            .to_string();
        for (i, line) in text.lines().enumerate() {
            let mut rest = line;
            while let Some(at) = rest.find("results/") {
                let tail = &rest[at + "results/".len()..];
                let name: String = tail
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || "._-<>*{},".contains(*c))
                    .collect();
                rest = &tail[name.len()..];
                let name = name.trim_end_matches(['.', ',']);
                if name.is_empty() || name.contains(['<', '*', '{']) || !name.contains('.') {
                    continue;
                }
                if !ws.join("docs/results").join(name).exists() {
                    missing.push(format!("{rel}:{}: results/{name}", i + 1));
                }
            }
        }
    }
    assert!(
        missing.is_empty(),
        "cited result files that do not exist:\n{}",
        missing.join("\n")
    );
}

#[test]
fn the_checks_can_fail() {
    // Anchors follow GitHub's rules.
    let a = anchors(
        "# Cluster\n## The end: p99.9 (µs)\n## Words\n## Words\n```\n# not a heading\n```\n",
    );
    for expected in ["cluster", "the-end-p999-µs", "words", "words-1"] {
        assert!(a.contains(expected), "{expected} missing from {a:?}");
    }
    assert!(!a.contains("not-a-heading"));
    // Links in prose are found; links in code are not.
    let lines = prose_lines("see [a](a.md#x) and `[b](b.md)`\n```\n[c](c.md)\n```\n");
    let targets: Vec<String> = lines.iter().flat_map(|(_, l)| link_targets(l)).collect();
    assert_eq!(targets, vec!["a.md#x".to_string()]);
    assert_eq!(
        normalise(Path::new("docs/../README.md")),
        PathBuf::from("README.md")
    );
}
