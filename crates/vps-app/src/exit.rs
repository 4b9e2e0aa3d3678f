//! How a session command ends: the outcome of a session as an exit status, after its report.
//!
//! Exit statuses: 0 the session ran to its end; 1 an error (a bad value or file, the device
//! failed); 2 a command line clap refuses, or a worker refused for good; 101 a panic on the frame path (caught; the device was sent zero first); `128 + N` stopped by
//! signal N (130 SIGINT, 143 SIGTERM, 129 SIGHUP), after the device was sent zero and the
//! (partial) report was written.

use vps_runtime::{SessionEnd, SignalStop};

/// Exit status of a session whose frame path panicked.
pub const EXIT_PANIC: i32 = 101;

/// A session that did not run to its end: the process exits with `code` once its report is out.
#[derive(Debug)]
pub struct SessionExit {
    /// The process exit status.
    pub code: i32,
    /// Why it ended (the report's `end`).
    pub reason: String,
}

impl std::fmt::Display for SessionExit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.reason)
    }
}

impl std::error::Error for SessionExit {}

/// Why a session ended, in words, and the exit status that says so (0 for a complete session).
pub fn outcome(end: &SessionEnd, signals: Option<&SignalStop>) -> (String, i32) {
    match end {
        SessionEnd::FramesDone => ("frames done".into(), 0),
        SessionEnd::Stopped => match signals.and_then(SignalStop::received) {
            Some(signal) => (format!("stopped by {}", signal.name()), signal.exit_code()),
            None => ("stopped".into(), 1),
        },
        SessionEnd::DeviceFailed(message) => (format!("device failed: {message}"), 1),
        SessionEnd::Panicked(message) => (format!("panic: {message}"), EXIT_PANIC),
    }
}

/// Fails with a [`SessionExit`] (its exit status) unless the session ran to its end: for commands
/// whose figures mean nothing for a partial session (the benchmarks).
pub fn require_complete(end: &SessionEnd, signals: Option<&SignalStop>) -> anyhow::Result<()> {
    let (reason, code) = outcome(end, signals);
    if code == 0 {
        return Ok(());
    }
    Err(SessionExit {
        code,
        reason: format!("the session ended early ({reason}); the device was sent zero force"),
    }
    .into())
}

/// The exit status for an error that ended the program.
pub fn exit_code(err: &anyhow::Error) -> i32 {
    err.downcast_ref::<SessionExit>().map_or(1, |e| e.code)
}
