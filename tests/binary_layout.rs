//! The binary stays a thin front end: `src/` holds the command line, dispatch and printing, and
//! no more than [`MAX_SRC_LINES`] lines; every session is prepared and run by the application
//! layer (`crates/vps-app`), so no command module (`src/cmd/*.rs`) builds or runs a session
//! itself.
//!
//! Std-only; reads files, builds nothing.

use std::fs;
use std::path::{Path, PathBuf};

/// The most lines the binary's own sources (`src/**/*.rs`) may hold.
const MAX_SRC_LINES: usize = 3000;

/// What only the application layer does: build a session's assets and plan, make it live, run
/// the loop or a coordinator. A command module naming one of these (outside comments) builds a
/// session itself.
const SESSION_BUILDING: &[&str] = &[
    "SessionAssets::from_loaded",
    "LoadedScene::load",
    "run_loop(",
    ".plan(",
    "into_setup(",
    "into_live_setup(",
    "into_stopped_setup(",
    "Prepared::from_plan",
    "Prepared {",
    "go_live(",
    "run_scripted(",
    "run_coordinator_session(",
    "Coordinator::start(",
];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            rust_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "rs") {
            out.push(p);
        }
    }
}

/// The lines of `text` that are code: comment lines (`//`, `///`, `//!`) left out.
fn code_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim_start().starts_with("//"))
        .map(|(i, l)| (i + 1, l))
}

/// The session-building names `text`'s code uses, with their line numbers.
fn session_building(text: &str) -> Vec<(usize, &'static str)> {
    code_lines(text)
        .flat_map(|(n, l)| {
            SESSION_BUILDING
                .iter()
                .filter(move |name| l.contains(*name))
                .map(move |name| (n, *name))
        })
        .collect()
}

#[test]
fn the_binary_sources_are_at_most_the_line_budget() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    assert!(
        files.len() > 3,
        "found only {files:?} under {}",
        src.display()
    );
    let mut sizes: Vec<(usize, PathBuf)> = files
        .into_iter()
        .map(|f| (fs::read_to_string(&f).unwrap().lines().count(), f))
        .collect();
    sizes.sort();
    let total: usize = sizes.iter().map(|(n, _)| n).sum();
    assert!(
        total <= MAX_SRC_LINES,
        "src/ holds {total} lines, over {MAX_SRC_LINES}: move what is not the command line, \
         dispatch or printing into a crate (largest: {:?})",
        sizes.iter().rev().take(5).collect::<Vec<_>>()
    );
}

#[test]
fn no_command_module_builds_a_session() {
    let cmd = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/cmd");
    let mut files = Vec::new();
    rust_files(&cmd, &mut files);
    assert!(
        !files.is_empty(),
        "no command modules under {}",
        cmd.display()
    );
    let found: Vec<String> = files
        .iter()
        .flat_map(|f| {
            let text = fs::read_to_string(f).unwrap();
            session_building(&text)
                .into_iter()
                .map(|(n, name)| format!("{}:{n}: {name}", f.display()))
                .collect::<Vec<_>>()
        })
        .collect();
    assert!(
        found.is_empty(),
        "command modules build sessions themselves (use vps_app::prepare and Prepared::run): \
         {found:#?}"
    );
}

#[test]
fn the_check_finds_session_building_in_code_and_not_in_comments() {
    let text = "// run_loop(x) in a comment\nlet r = run_loop(tree, shell, setup)?;\n\
                let p = assets.plan(&device, script, config)?;\n";
    assert_eq!(
        session_building(text),
        vec![(2, "run_loop("), (3, ".plan(")]
    );
    assert!(session_building("vps_app::prepare(&request)?.run(Backend::Local)").is_empty());
}
