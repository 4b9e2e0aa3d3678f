//! How a session is stopped from outside its frame thread: SIGINT, SIGTERM and SIGHUP set the
//! session's stop flag (and record which signal came); the frame thread sees the flag once the
//! frame in progress is written, before the next one, writes the exact zero wrench and returns its
//! report (see [`crate::haptic_loop`]). The handlers only store into atomics (async-signal-safe); a
//! second signal while the session stops sets the same flags again and cannot skip the zero write.
//!
//! Exit codes of a session command (listed in docs/sessions.md; set by the `vps` binary,
//! `vps_app::exit`): 0 the session ran to its end, 1 an error (the device failed, a bad argument),
//! 2 a command line refused or a worker refused for good, 101 a panic on the frame path (the
//! device was sent zero first), `128 + N` stopped by signal N after the report was written
//! ([`StopSignal::exit_code`]: 129 SIGHUP, 130 SIGINT, 143 SIGTERM).

use crate::RuntimeError;
use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;

/// A signal that stops a session.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum StopSignal {
    /// SIGINT (Ctrl-C).
    Interrupt,
    /// SIGTERM (`kill`, `systemctl stop`).
    Terminate,
    /// SIGHUP (the terminal went away).
    Hangup,
}

impl StopSignal {
    /// Every signal that stops a session.
    pub const ALL: [StopSignal; 3] = [
        StopSignal::Interrupt,
        StopSignal::Terminate,
        StopSignal::Hangup,
    ];

    /// The signal number.
    pub fn number(self) -> i32 {
        match self {
            StopSignal::Interrupt => SIGINT,
            StopSignal::Terminate => SIGTERM,
            StopSignal::Hangup => SIGHUP,
        }
    }

    /// The conventional name, e.g. `SIGTERM`.
    pub fn name(self) -> &'static str {
        match self {
            StopSignal::Interrupt => "SIGINT",
            StopSignal::Terminate => "SIGTERM",
            StopSignal::Hangup => "SIGHUP",
        }
    }

    /// The exit status of a process stopped by this signal: `128 + number` (130 SIGINT,
    /// 143 SIGTERM, 129 SIGHUP).
    pub fn exit_code(self) -> i32 {
        128 + self.number()
    }

    fn from_number(number: usize) -> Option<StopSignal> {
        StopSignal::ALL
            .into_iter()
            .find(|s| usize::try_from(s.number()).is_ok_and(|n| n == number))
    }
}

/// SIGINT, SIGTERM and SIGHUP handlers that set a stop flag and record the signal.
///
/// The handlers stay installed for the rest of the process (signal-hook cannot restore the default
/// action once it has replaced it): install them once the process holds a device, in a command
/// that ends after its session.
pub struct SignalStop {
    stop: Arc<AtomicBool>,
    last: Arc<AtomicUsize>,
}

impl SignalStop {
    /// Installs the handlers: each of the three signals stores its number and then sets `stop`.
    /// Allocates; not for the frame path.
    pub fn install(stop: &Arc<AtomicBool>) -> Result<SignalStop, RuntimeError> {
        let last = Arc::new(AtomicUsize::new(0));
        for signal in StopSignal::ALL {
            let number = signal.number();
            let value = usize::try_from(number).unwrap_or(0);
            // The signal is recorded before the flag is set, so whoever sees the flag set and
            // then reads `received` finds the signal.
            signal_hook::flag::register_usize(number, last.clone(), value)
                .and_then(|_| signal_hook::flag::register(number, stop.clone()))
                .map_err(|e| RuntimeError::Signal {
                    signal: signal.name(),
                    message: e.to_string(),
                })?;
        }
        Ok(SignalStop {
            stop: stop.clone(),
            last,
        })
    }

    /// The stop flag the handlers set.
    pub fn flag(&self) -> &Arc<AtomicBool> {
        &self.stop
    }

    /// The last stop signal received, if any. Does not block.
    pub fn received(&self) -> Option<StopSignal> {
        StopSignal::from_number(self.last.load(Ordering::SeqCst))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exit_codes_are_128_plus_the_signal_number() {
        assert_eq!(StopSignal::Interrupt.exit_code(), 130);
        assert_eq!(StopSignal::Terminate.exit_code(), 143);
        assert_eq!(StopSignal::Hangup.exit_code(), 129);
        for s in StopSignal::ALL {
            assert_eq!(StopSignal::from_number(s.number() as usize), Some(s));
        }
        assert_eq!(StopSignal::from_number(0), None);
    }

    #[test]
    fn a_raised_signal_sets_the_flag_and_is_recorded() {
        let stop = Arc::new(AtomicBool::new(false));
        let signals = SignalStop::install(&stop).unwrap();
        assert_eq!(signals.received(), None);
        // SIGHUP: the other tests of this process do not use it.
        signal_hook::low_level::raise(SIGHUP).unwrap();
        assert!(stop.load(Ordering::SeqCst));
        assert_eq!(signals.received(), Some(StopSignal::Hangup));
    }
}
