//! No two source files of the workspace import each other, directly or in a circle.
//!
//! The graph has one node per `.rs` file reachable from a crate root (`src/lib.rs`, `src/main.rs`,
//! `src/bin/*.rs` of the root package and of every `crates/*`), found by following `mod x;`
//! declarations. An edge A → B means a path in A that starts with `crate::` or `super::` names an
//! item of B:
//! - the path is resolved module by module to the deepest module that has its own file (`a.rs` or
//!   `a/mod.rs`); an item the path then names is followed through that module's `use` declarations
//!   (re-exports such as `pub use error::Error` in `lib.rs`), so `crate::Error` leads to `error.rs`;
//! - inline modules (`mod tests { use super::*; }`) belong to their file, so a test module importing
//!   its parent is no edge; `self::` paths and bare paths (`child::f`, an extern crate) give no edge;
//! - comments, doc comments and string literals are skipped; `$crate::` in macros gives no edge.
//!
//! The checker is std-only and runs without building the crates it reads. Its own logic is tested
//! below on small synthetic crates; the workspace test lists every circle it finds.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fs;
use std::path::{Path, PathBuf};

/// One import edge: from `from` (file) at `line`, the path `path` names an item of `to` (file).
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Edge {
    from: PathBuf,
    to: PathBuf,
    line: usize,
    path: String,
}

/// A module that has its own file: its path from the crate root and what the file declares.
struct ModFile {
    /// Module path from the crate root (empty for the root).
    module: Vec<String>,
    /// Inline modules' paths (relative to the file's module) → their `use` bindings, for re-exports;
    /// the file's own module is the empty key.
    uses: HashMap<Vec<String>, Vec<UseBinding>>,
    /// Inline modules' paths relative to the file's module.
    inline_mods: BTreeSet<Vec<String>>,
}

/// `use a::b::c as name;` inside some module: `name` is bound to the full path `a::b::c`.
#[derive(Clone, Debug)]
struct UseBinding {
    name: String,
    path: Vec<String>,
}

// ---------------------------------------------------------------------------------------------
// Lexing: blank comments, strings and char literals so only code is scanned.

fn strip_comments_and_strings(src: &str) -> String {
    let b = src.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    let blank = |out: &mut Vec<u8>, c: u8| out.push(if c == b'\n' { b'\n' } else { b' ' });
    while i < b.len() {
        let c = b[i];
        if c == b'/' && b.get(i + 1) == Some(&b'/') {
            while i < b.len() && b[i] != b'\n' {
                out.push(b' ');
                i += 1;
            }
        } else if c == b'/' && b.get(i + 1) == Some(&b'*') {
            let mut depth = 0;
            while i < b.len() {
                if b[i] == b'/' && b.get(i + 1) == Some(&b'*') {
                    depth += 1;
                    out.extend_from_slice(b"  ");
                    i += 2;
                } else if b[i] == b'*' && b.get(i + 1) == Some(&b'/') {
                    depth -= 1;
                    out.extend_from_slice(b"  ");
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    blank(&mut out, b[i]);
                    i += 1;
                }
            }
        } else if (c == b'r' || (c == b'b' && b.get(i + 1) == Some(&b'r')))
            && !prev_is_ident(b, i)
            && raw_string_start(b, if c == b'b' { i + 1 } else { i }).is_some()
        {
            let start = if c == b'b' { i + 1 } else { i };
            let hashes = raw_string_start(b, start).unwrap_or(0);
            // Skip `r`, the hashes and the opening quote.
            let body = start + 1 + hashes + 1;
            while i < body {
                out.push(b' ');
                i += 1;
            }
            loop {
                if i >= b.len() {
                    break;
                }
                if b[i] == b'"'
                    && b[i + 1..]
                        .iter()
                        .take(hashes)
                        .filter(|&&h| h == b'#')
                        .count()
                        == hashes
                {
                    out.resize(out.len() + 1 + hashes, b' ');
                    i += 1 + hashes;
                    break;
                }
                blank(&mut out, b[i]);
                i += 1;
            }
        } else if c == b'"' {
            out.push(b' ');
            i += 1;
            while i < b.len() && b[i] != b'"' {
                if b[i] == b'\\' && i + 1 < b.len() {
                    blank(&mut out, b[i]);
                    i += 1;
                }
                blank(&mut out, b[i]);
                i += 1;
            }
            out.push(b' ');
            i += 1;
        } else if c == b'\'' {
            // A char literal ('x', '\n', '\u{..}', '"') or a lifetime ('a).
            if b.get(i + 1) == Some(&b'\\') {
                let mut j = i + 2;
                while j < b.len() && b[j] != b'\'' {
                    j += 1;
                }
                while i <= j && i < b.len() {
                    out.push(b' ');
                    i += 1;
                }
            } else if b.get(i + 2) == Some(&b'\'') {
                out.extend_from_slice(b"   ");
                i += 3;
            } else {
                // A multi-byte char literal or a lifetime: keep as is (no quotes to confuse).
                let len = src[i + 1..].chars().next().map_or(1, char::len_utf8);
                if b.get(i + 1 + len) == Some(&b'\'') {
                    out.resize(out.len() + len + 2, b' ');
                    i += len + 2;
                } else {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    // Only ASCII bytes were replaced by ASCII spaces, and whole multi-byte sequences inside comments
    // and strings by spaces, so the result is valid UTF-8; be safe anyway.
    String::from_utf8_lossy(&out).into_owned()
}

fn prev_is_ident(b: &[u8], i: usize) -> bool {
    i > 0 && (b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// At `b[i] == b'r'`: the number of `#` of a raw string start (`r"`, `r#"`, ...), if it is one.
fn raw_string_start(b: &[u8], i: usize) -> Option<usize> {
    if b.get(i) != Some(&b'r') {
        return None;
    }
    let mut j = i + 1;
    while b.get(j) == Some(&b'#') {
        j += 1;
    }
    (b.get(j) == Some(&b'"')).then_some(j - i - 1)
}

// ---------------------------------------------------------------------------------------------
// Tokens.

#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    Punct(char),
    PathSep,
}

/// Tokens with their 1-based line numbers. Lifetimes and numbers become idents; that is harmless.
fn tokenize(code: &str) -> Vec<(Tok, usize)> {
    let b = code.as_bytes();
    let mut toks = Vec::new();
    let mut line = 1;
    let mut i = 0;
    while i < b.len() {
        let c = b[i];
        if c == b'\n' {
            line += 1;
            i += 1;
        } else if c.is_ascii_whitespace() {
            i += 1;
        } else if c.is_ascii_alphanumeric() || c == b'_' || c >= 0x80 {
            let s = i;
            while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_' || b[i] >= 0x80) {
                i += 1;
            }
            let word = &code[s..i];
            // Raw identifiers: r#type.
            toks.push((Tok::Ident(word.to_string()), line));
        } else if c == b':' && b.get(i + 1) == Some(&b':') {
            toks.push((Tok::PathSep, line));
            i += 2;
        } else {
            toks.push((Tok::Punct(c as char), line));
            i += 1;
        }
    }
    // Fold raw identifiers `r # ident` into `ident`.
    let mut folded: Vec<(Tok, usize)> = Vec::with_capacity(toks.len());
    let mut k = 0;
    while k < toks.len() {
        if let (Tok::Ident(r), Some((Tok::Punct('#'), _)), Some((Tok::Ident(w), l))) =
            (&toks[k].0, toks.get(k + 1), toks.get(k + 2))
        {
            if r == "r" {
                folded.push((Tok::Ident(w.clone()), *l));
                k += 3;
                continue;
            }
        }
        folded.push(toks[k].clone());
        k += 1;
    }
    folded
}

fn ident(t: Option<&(Tok, usize)>) -> Option<&str> {
    match t {
        Some((Tok::Ident(s), _)) => Some(s),
        _ => None,
    }
}

// ---------------------------------------------------------------------------------------------
// Use trees and module structure of one file.

/// Expands the use tree starting at `toks[*k]` (after `use`) up to and including `;` into bindings;
/// `prefix` is the path so far. Globs bind the name `*`.
fn parse_use_tree(
    toks: &[(Tok, usize)],
    k: &mut usize,
    prefix: Vec<String>,
    out: &mut Vec<(UseBinding, usize)>,
) {
    let mut path = prefix;
    let line = toks.get(*k).map_or(0, |t| t.1);
    loop {
        match toks.get(*k) {
            Some((Tok::PathSep, _)) => *k += 1,
            Some((Tok::Ident(s), _)) if s == "as" => {
                *k += 1;
                if let Some(name) = ident(toks.get(*k)) {
                    out.push((
                        UseBinding {
                            name: name.to_string(),
                            path: path.clone(),
                        },
                        line,
                    ));
                    *k += 1;
                }
                return;
            }
            Some((Tok::Ident(s), _)) => {
                path.push(s.clone());
                *k += 1;
            }
            Some((Tok::Punct('*'), _)) => {
                out.push((
                    UseBinding {
                        name: "*".into(),
                        path: path.clone(),
                    },
                    line,
                ));
                *k += 1;
                return;
            }
            Some((Tok::Punct('{'), _)) => {
                *k += 1;
                loop {
                    match toks.get(*k) {
                        Some((Tok::Punct('}'), _)) => {
                            *k += 1;
                            return;
                        }
                        Some((Tok::Punct(','), _)) => *k += 1,
                        None => return,
                        _ => {
                            let before = *k;
                            parse_use_tree(toks, k, path.clone(), out);
                            if *k == before {
                                *k += 1;
                            }
                        }
                    }
                }
            }
            _ => {
                // `,`, `}` or `;` ends this branch.
                if let Some(last) = path.last() {
                    let name = if last == "self" {
                        path.pop();
                        path.last().cloned().unwrap_or_default()
                    } else {
                        last.clone()
                    };
                    out.push((
                        UseBinding {
                            name,
                            path: path.clone(),
                        },
                        line,
                    ));
                }
                return;
            }
        }
    }
}

/// What one file holds: `mod x;` declarations (with the inline-module path they sit in), `use`
/// bindings per inline module, and every `crate::`/`super::` path with its line and inline module.
struct Scan {
    /// (inline module path, declared module name) for `mod name;`.
    mod_decls: Vec<(Vec<String>, String)>,
    uses: HashMap<Vec<String>, Vec<UseBinding>>,
    /// (inline module path, full path as written, line).
    paths: Vec<PathUse>,
    inline_mods: BTreeSet<Vec<String>>,
}

fn scan(code: &str) -> Scan {
    let toks = tokenize(code);
    let mut scan = Scan {
        mod_decls: Vec::new(),
        uses: HashMap::new(),
        paths: Vec::new(),
        inline_mods: BTreeSet::new(),
    };
    // Stack of (inline module name, brace depth at which it opened).
    let mut inline: Vec<(String, usize)> = Vec::new();
    let mut depth = 0usize;
    let mut pending_mod: Option<String> = None;
    let mut k = 0;
    let cur =
        |inline: &Vec<(String, usize)>| inline.iter().map(|(n, _)| n.clone()).collect::<Vec<_>>();
    while k < toks.len() {
        let (tok, line) = &toks[k];
        match tok {
            Tok::Punct('{') => {
                depth += 1;
                if let Some(name) = pending_mod.take() {
                    inline.push((name, depth));
                    scan.inline_mods.insert(cur(&inline));
                }
                k += 1;
            }
            Tok::Punct('}') => {
                if inline.last().is_some_and(|&(_, d)| d == depth) {
                    inline.pop();
                }
                depth = depth.saturating_sub(1);
                k += 1;
            }
            Tok::Punct(';') => {
                if let Some(name) = pending_mod.take() {
                    scan.mod_decls.push((cur(&inline), name));
                }
                k += 1;
            }
            Tok::Ident(w) if w == "mod" && ident(toks.get(k + 1)).is_some() => {
                let before_is_path = k > 0 && matches!(toks[k - 1].0, Tok::PathSep);
                if !before_is_path {
                    pending_mod = ident(toks.get(k + 1)).map(str::to_string);
                }
                k += 2;
            }
            Tok::Ident(w) if w == "use" && !(k > 0 && matches!(toks[k - 1].0, Tok::PathSep)) => {
                k += 1;
                let mut bindings = Vec::new();
                parse_use_tree(&toks, &mut k, Vec::new(), &mut bindings);
                let here = cur(&inline);
                for (b, l) in bindings {
                    if matches!(b.path.first().map(String::as_str), Some("crate" | "super")) {
                        scan.paths.push((here.clone(), b.path.clone(), l));
                    }
                    scan.uses.entry(here.clone()).or_default().push(b);
                }
            }
            Tok::Ident(w)
                if (w == "crate" || w == "super")
                    && matches!(toks.get(k + 1), Some((Tok::PathSep, _)))
                    && !(k > 0 && matches!(toks[k - 1].0, Tok::PathSep | Tok::Punct('$'))) =>
            {
                // An expression or type path: crate::a::b, super::super::x.
                let mut path = vec![w.clone()];
                let mut j = k + 1;
                while matches!(toks.get(j), Some((Tok::PathSep, _))) {
                    match ident(toks.get(j + 1)) {
                        Some(s) => {
                            path.push(s.to_string());
                            j += 2;
                        }
                        None => break,
                    }
                }
                scan.paths.push((cur(&inline), path, *line));
                k = j;
            }
            _ => k += 1,
        }
    }
    scan
}

// ---------------------------------------------------------------------------------------------
// The crate graph.

/// A `crate::`/`super::` path in a file: (inline module it sits in, the path as written, line).
type PathUse = (Vec<String>, Vec<String>, usize);

/// One crate's files by module path, plus the module paths that exist as inline modules.
struct CrateTree {
    files: BTreeMap<Vec<String>, PathBuf>,
    mods: HashMap<PathBuf, ModFile>,
    paths: HashMap<PathBuf, Vec<PathUse>>,
}

/// Reads a crate from its root file by following `mod x;` declarations; `read` returns a file's
/// source (None: absent).
fn load_crate(root: &Path, read: &dyn Fn(&Path) -> Option<String>) -> CrateTree {
    let mut tree = CrateTree {
        files: BTreeMap::new(),
        mods: HashMap::new(),
        paths: HashMap::new(),
    };
    let mut todo = vec![(root.to_path_buf(), Vec::<String>::new())];
    while let Some((file, module)) = todo.pop() {
        let Some(src) = read(&file) else { continue };
        let code = strip_comments_and_strings(&src);
        let s = scan(&code);
        // A non-root, non-mod.rs file `a.rs` keeps its children in `a/`.
        let name = file.file_name().and_then(|n| n.to_str()).unwrap_or("");
        let dir = file.parent().unwrap_or(Path::new("")).to_path_buf();
        let child_dir = if module.is_empty() || name == "mod.rs" {
            dir
        } else {
            dir.join(file.file_stem().and_then(|n| n.to_str()).unwrap_or(""))
        };
        for (inl, child) in &s.mod_decls {
            let mut d = child_dir.clone();
            for part in inl {
                d.push(part);
            }
            let mut m = module.clone();
            m.extend(inl.iter().cloned());
            m.push(child.clone());
            let flat = d.join(format!("{child}.rs"));
            let nested = d.join(child).join("mod.rs");
            let chosen = if read(&flat).is_some() { flat } else { nested };
            todo.push((chosen, m));
        }
        tree.files.insert(module.clone(), file.clone());
        tree.paths.insert(file.clone(), s.paths);
        tree.mods.insert(
            file,
            ModFile {
                module,
                uses: s.uses,
                inline_mods: s.inline_mods,
            },
        );
    }
    tree
}

impl CrateTree {
    /// The file whose module is the longest prefix of `module`, and the rest of the path.
    fn file_of(&self, module: &[String]) -> (PathBuf, usize) {
        for n in (0..=module.len()).rev() {
            if let Some(f) = self.files.get(&module[..n]) {
                return (f.clone(), n);
            }
        }
        (self.files[&Vec::new()].clone(), 0)
    }

    /// Turns a path written in module `at` into an absolute path from the crate root (`crate::`
    /// and `super::` resolved; `self::` and a leading bare child module resolved against `at`).
    fn absolute(&self, at: &[String], path: &[String]) -> Option<Vec<String>> {
        let mut base: Vec<String> = at.to_vec();
        let mut rest = path;
        match rest.first().map(String::as_str) {
            Some("crate") => {
                base.clear();
                rest = &rest[1..];
            }
            Some("super") | Some("self") => {
                while let Some(first) = rest.first() {
                    match first.as_str() {
                        "super" => {
                            base.pop()?;
                        }
                        "self" => {}
                        _ => break,
                    }
                    rest = &rest[1..];
                }
            }
            _ => {}
        }
        base.extend(rest.iter().cloned());
        Some(base)
    }

    /// Is `module` a module of this crate (a file or an inline module in one)?
    fn is_module(&self, module: &[String]) -> bool {
        let (file, n) = self.file_of(module);
        n == module.len() || self.mods[&file].inline_mods.contains(&module[n..])
    }

    /// The file that defines what absolute path `abs` names, following `use` re-exports (at most
    /// `hops` of them).
    fn target(&self, abs: &[String], hops: usize) -> PathBuf {
        // The module part: the longest prefix that is a module; the next segment is an item.
        let mut n = abs.len();
        while n > 0 && !self.is_module(&abs[..n]) {
            n -= 1;
        }
        let (file, fn_len) = self.file_of(&abs[..n]);
        if n < abs.len() && hops > 0 {
            let item = &abs[n];
            let m = &self.mods[&file];
            let inl: Vec<String> = abs[fn_len..n].to_vec();
            if let Some(b) = m
                .uses
                .get(&inl)
                .and_then(|bs| bs.iter().find(|b| &b.name == item))
            {
                let mut at = m.module.clone();
                at.extend(inl.iter().cloned());
                let first = b.path.first().map(String::as_str).unwrap_or("");
                let local_child = {
                    let mut c = at.clone();
                    c.push(first.to_string());
                    self.is_module(&c)
                };
                if matches!(first, "crate" | "super" | "self") || local_child {
                    if let Some(mut next) = self.absolute(&at, &b.path) {
                        next.extend(abs[n + 1..].iter().cloned());
                        return self.target(&next, hops - 1);
                    }
                }
            }
        }
        file
    }

    fn edges(&self) -> Vec<Edge> {
        let mut out = Vec::new();
        for (file, paths) in &self.paths {
            let m = &self.mods[file];
            for (inl, path, line) in paths {
                let mut at = m.module.clone();
                at.extend(inl.iter().cloned());
                let Some(abs) = self.absolute(&at, path) else {
                    continue;
                };
                let to = self.target(&abs, 8);
                if &to != file {
                    out.push(Edge {
                        from: file.clone(),
                        to,
                        line: *line,
                        path: path.join("::"),
                    });
                }
            }
        }
        out.sort();
        out
    }
}

/// The groups of files that import each other (strongly connected components with more than one
/// file), each with the edges inside it.
fn cycles(edges: &[Edge]) -> Vec<(Vec<PathBuf>, Vec<Edge>)> {
    let nodes: BTreeSet<&PathBuf> = edges.iter().flat_map(|e| [&e.from, &e.to]).collect();
    let nodes: Vec<&PathBuf> = nodes.into_iter().collect();
    let idx: HashMap<&PathBuf, usize> = nodes.iter().enumerate().map(|(i, n)| (*n, i)).collect();
    let mut adj = vec![BTreeSet::new(); nodes.len()];
    for e in edges {
        adj[idx[&e.from]].insert(idx[&e.to]);
    }
    // Tarjan, iterative.
    let n = nodes.len();
    let mut index = vec![usize::MAX; n];
    let mut low = vec![0; n];
    let mut on = vec![false; n];
    let mut stack = Vec::new();
    let mut next = 0;
    let mut comps = Vec::new();
    for s in 0..n {
        if index[s] != usize::MAX {
            continue;
        }
        let mut call: Vec<(usize, Vec<usize>)> = vec![(s, adj[s].iter().copied().collect())];
        index[s] = next;
        low[s] = next;
        next += 1;
        stack.push(s);
        on[s] = true;
        while let Some((v, succ)) = call.last_mut() {
            let v = *v;
            if let Some(w) = succ.pop() {
                if index[w] == usize::MAX {
                    index[w] = next;
                    low[w] = next;
                    next += 1;
                    stack.push(w);
                    on[w] = true;
                    call.push((w, adj[w].iter().copied().collect()));
                } else if on[w] {
                    low[v] = low[v].min(index[w]);
                }
            } else {
                call.pop();
                if let Some((u, _)) = call.last() {
                    low[*u] = low[*u].min(low[v]);
                }
                if low[v] == index[v] {
                    let mut comp = Vec::new();
                    while let Some(w) = stack.pop() {
                        on[w] = false;
                        comp.push(w);
                        if w == v {
                            break;
                        }
                    }
                    if comp.len() > 1 {
                        comps.push(comp);
                    }
                }
            }
        }
    }
    let mut out: Vec<(Vec<PathBuf>, Vec<Edge>)> = comps
        .into_iter()
        .map(|c| {
            let set: BTreeSet<&PathBuf> = c.iter().map(|&i| nodes[i]).collect();
            let inside = edges
                .iter()
                .filter(|e| set.contains(&e.from) && set.contains(&e.to))
                .cloned()
                .collect();
            (set.into_iter().cloned().collect(), inside)
        })
        .collect();
    out.sort();
    out
}

fn report(cycles: &[(Vec<PathBuf>, Vec<Edge>)]) -> String {
    let mut s = String::new();
    for (files, edges) in cycles {
        let names: Vec<String> = files.iter().map(|f| f.display().to_string()).collect();
        s.push_str(&format!(
            "circle of {} files: {}\n",
            files.len(),
            names.join(" <-> ")
        ));
        for e in edges {
            s.push_str(&format!(
                "    {}:{} -> {} (`{}`)\n",
                e.from.display(),
                e.line,
                e.to.display(),
                e.path
            ));
        }
    }
    s
}

/// Crate roots of the workspace: the root package's and every `crates/*` package's.
fn workspace_roots(ws: &Path) -> Vec<PathBuf> {
    let mut pkgs = vec![ws.to_path_buf()];
    if let Ok(rd) = fs::read_dir(ws.join("crates")) {
        let mut v: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
        v.sort();
        pkgs.extend(v);
    }
    let mut roots = Vec::new();
    for p in pkgs {
        for r in ["src/lib.rs", "src/main.rs"] {
            if p.join(r).is_file() {
                roots.push(p.join(r));
            }
        }
        if let Ok(rd) = fs::read_dir(p.join("src/bin")) {
            let mut v: Vec<PathBuf> = rd
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|x| x == "rs"))
                .collect();
            v.sort();
            roots.extend(v);
        }
    }
    roots
}

fn workspace_edges(ws: &Path) -> (Vec<Edge>, usize) {
    let read = |p: &Path| fs::read_to_string(p).ok();
    let mut edges = Vec::new();
    let mut files = 0;
    for root in workspace_roots(ws) {
        let tree = load_crate(&root, &read);
        files += tree.files.len();
        edges.extend(tree.edges().into_iter().map(|mut e| {
            e.from = e
                .from
                .strip_prefix(ws)
                .map(Path::to_path_buf)
                .unwrap_or(e.from);
            e.to = e.to.strip_prefix(ws).map(Path::to_path_buf).unwrap_or(e.to);
            e
        }));
    }
    (edges, files)
}

/// No file of the workspace imports itself through others: the test fails listing each circle.
#[test]
fn no_file_imports_itself_through_others() {
    let ws = Path::new(env!("CARGO_MANIFEST_DIR"));
    let (edges, files) = workspace_edges(ws);
    assert!(
        files > 50,
        "found only {files} files: is the workspace layout as expected?"
    );
    let found = cycles(&edges);
    assert!(
        found.is_empty(),
        "files that import each other:\n{}",
        report(&found)
    );
}

/// The checker reads the real workspace: every crate root is found, and the graph has edges.
#[test]
fn workspace_graph_is_read() {
    let ws = Path::new(env!("CARGO_MANIFEST_DIR"));
    let roots = workspace_roots(ws);
    assert!(roots
        .iter()
        .any(|r| r.ends_with("crates/vps-voxmap/src/lib.rs")));
    assert!(roots.iter().any(|r| r.ends_with("src/main.rs")));
    let (edges, files) = workspace_edges(ws);
    assert!(files > 50, "{files} files");
    // A known import: the voxmap file format imports the tree.
    assert!(
        edges
            .iter()
            .any(|e| e.from.ends_with("vps-voxmap/src/file.rs")
                && e.to.ends_with("vps-voxmap/src/tree/mod.rs")),
        "file.rs -> tree/mod.rs missing"
    );
}

// ---------------------------------------------------------------------------------------------
// The checker on synthetic crates.

fn synthetic(files: &[(&str, &str)]) -> Vec<Edge> {
    let map: HashMap<PathBuf, String> = files
        .iter()
        .map(|(p, s)| (PathBuf::from(p), s.to_string()))
        .collect();
    let read = |p: &Path| map.get(p).cloned();
    load_crate(Path::new("src/lib.rs"), &read).edges()
}

fn pairs(edges: &[Edge]) -> Vec<(String, String)> {
    edges
        .iter()
        .map(|e| (e.from.display().to_string(), e.to.display().to_string()))
        .collect()
}

#[test]
fn finds_a_direct_circle() {
    let edges = synthetic(&[
        ("src/lib.rs", "mod a;\nmod b;\n"),
        ("src/a.rs", "use crate::b::B;\npub struct A;\n"),
        (
            "src/b/mod.rs",
            "pub struct B;\nfn f() { let _ = crate::a::A; }\n",
        ),
    ]);
    let c = cycles(&edges);
    let text = report(&c);
    assert_eq!(c.len(), 1, "{text}");
    assert_eq!(
        c[0].0,
        vec![PathBuf::from("src/a.rs"), PathBuf::from("src/b/mod.rs")]
    );
    assert!(
        text.contains("src/b/mod.rs:2 -> src/a.rs (`crate::a::A`)"),
        "{text}"
    );
}

#[test]
fn finds_a_circle_of_three_through_super_and_reexports() {
    let edges = synthetic(&[
        ("src/lib.rs", "mod a;\nmod b;\nmod c;\npub use c::C;\n"),
        ("src/a.rs", "use super::b::B;\n"),
        ("src/b.rs", "pub struct B;\nuse crate::C;\n"),
        ("src/c.rs", "pub struct C;\nfn g() { crate::a::f(); }\n"),
    ]);
    let c = cycles(&edges);
    assert_eq!(c.len(), 1, "{}", report(&c));
    assert_eq!(c[0].0.len(), 3, "{}", report(&c));
}

#[test]
fn test_modules_comments_strings_and_self_are_no_edges() {
    let edges = synthetic(&[
        ("src/lib.rs", "mod a;\nmod b;\n"),
        (
            "src/a.rs",
            "//! See [`crate::b::B`].\nuse crate::b::B;\npub fn f() {}\n\
             fn s() -> &'static str { \"crate::b::x\" }\nfn t() { self::f(); }\n",
        ),
        (
            "src/b.rs",
            "pub struct B;\n/* crate::a::f */\nconst Q: char = '\"';\n#[cfg(test)]\nmod tests {\n    use super::*;\n    \
             fn s() -> &'static str { r#\"crate::a::f\"# }\n}\n",
        ),
    ]);
    assert_eq!(
        pairs(&edges),
        vec![("src/a.rs".to_string(), "src/b.rs".to_string())]
    );
    assert!(cycles(&edges).is_empty());
}

#[test]
fn a_test_module_importing_another_file_counts_for_its_file() {
    let edges = synthetic(&[
        ("src/lib.rs", "mod a;\nmod b;\n"),
        ("src/a.rs", "use crate::b::B;\npub fn f() {}\n"),
        ("src/b.rs", "pub struct B;\n#[cfg(test)]\nmod tests {\n    use super::*;\n    use crate::a::f;\n}\n"),
    ]);
    assert_eq!(cycles(&edges).len(), 1);
}

#[test]
fn parent_and_child_through_bare_paths_are_no_circle() {
    // mod.rs uses its child by a bare path (no edge); the child imports its parent with super::.
    let edges = synthetic(&[
        ("src/lib.rs", "mod t;\n"),
        (
            "src/t/mod.rs",
            "mod walk;\npub struct T;\nfn f() { walk::g(); }\n",
        ),
        ("src/t/walk.rs", "use super::T;\npub fn g() {}\n"),
    ]);
    assert_eq!(
        pairs(&edges),
        vec![("src/t/walk.rs".to_string(), "src/t/mod.rs".to_string())]
    );
}
