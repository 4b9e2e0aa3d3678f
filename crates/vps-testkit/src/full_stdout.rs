//! A command whose stdout is full: `vps` must fail with status 1 and an error naming stdout and
//! the cause, never panic and never lose the error (Linux `/dev/full`).

use std::process::Command;

/// Runs `cmd` with stdout on `/dev/full` and asserts what the binary promises there: exit status
/// 1, an error on stderr naming `stdout` and "No space left", and no panic. Returns the stderr.
pub fn assert_full_stdout_is_an_error(cmd: &mut Command) -> String {
    let full = std::fs::File::create("/dev/full").expect("/dev/full opens for writing");
    let out = cmd.stdout(full).output().expect("the command runs");
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("stdout") && err.contains("No space left"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    err
}
