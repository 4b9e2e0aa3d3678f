//! What a waiting worker's log says about its failed attempts to join its coordinator.
//!
//! A worker started before its coordinator, or left waiting after one, retries every 5 s at most
//! for as long as it runs; one warning per attempt wrote about 17 000 lines a day into the
//! journal of a worker whose coordinator was simply off. [`JoinLog`] logs the first failure at
//! once, a failure that differs from the last one logged (a new reason) at once, and otherwise at
//! most one line per [`JOIN_LOG_PERIOD`] counting the attempts since. A successful join resets it.
//! Pure: the caller passes the failure and the time, and logs the line it gets back.

use std::time::{Duration, Instant};

/// The shortest time between two lines about the same failure to join (60 s).
pub const JOIN_LOG_PERIOD: Duration = Duration::from_secs(60);

/// The log state of a worker's failed attempts since its last join.
#[derive(Clone, Debug, Default)]
pub struct JoinLog {
    /// The longest wait between two attempts, for the summary line.
    retry_at_most: Duration,
    last_reason: Option<String>,
    last_logged: Option<Instant>,
    attempts_since_logged: u64,
}

impl JoinLog {
    /// A log for a worker that waits at most `retry_at_most` between attempts.
    pub fn new(retry_at_most: Duration) -> JoinLog {
        JoinLog {
            retry_at_most,
            ..JoinLog::default()
        }
    }

    /// A failed attempt to join `coordinator` because of `reason`, at `now`: the line to log, if
    /// one is due.
    pub fn failed(&mut self, coordinator: &str, reason: &str, now: Instant) -> Option<String> {
        self.attempts_since_logged += 1;
        let same_reason = self.last_reason.as_deref() == Some(reason);
        let quiet = self
            .last_logged
            .is_some_and(|at| now.duration_since(at) < JOIN_LOG_PERIOD);
        if same_reason && quiet {
            return None;
        }
        let line = if same_reason {
            format!(
                "still cannot join {coordinator}: {reason}; {} attempts since the last line, retrying every {} s at most (logged once per {} s)",
                self.attempts_since_logged,
                self.retry_at_most.as_secs(),
                JOIN_LOG_PERIOD.as_secs()
            )
        } else {
            format!("cannot join {coordinator}: {reason}; retrying (repeats of this are logged once per {} s)", JOIN_LOG_PERIOD.as_secs())
        };
        self.last_reason = Some(reason.to_string());
        self.last_logged = Some(now);
        self.attempts_since_logged = 0;
        Some(line)
    }

    /// The worker joined: the next failure is logged at once.
    pub fn joined(&mut self) {
        *self = JoinLog::new(self.retry_at_most);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_failure_at_once_then_one_line_a_minute_counting_attempts() {
        let t0 = Instant::now();
        let mut log = JoinLog::new(Duration::from_secs(5));
        let first = log.failed("10.0.0.1:7800", "timed out", t0).unwrap();
        assert!(
            first.starts_with("cannot join 10.0.0.1:7800: timed out; retrying"),
            "{first}"
        );
        // Every 5 s for a minute: quiet.
        for k in 1..12 {
            let at = t0 + Duration::from_secs(5 * k);
            assert_eq!(log.failed("10.0.0.1:7800", "timed out", at), None);
        }
        let summary = log
            .failed("10.0.0.1:7800", "timed out", t0 + JOIN_LOG_PERIOD)
            .unwrap();
        assert!(
            summary.starts_with(
                "still cannot join 10.0.0.1:7800: timed out; 12 attempts since the last line"
            ),
            "{summary}"
        );
        assert_eq!(
            log.failed(
                "10.0.0.1:7800",
                "timed out",
                t0 + JOIN_LOG_PERIOD + Duration::from_secs(5)
            ),
            None
        );
    }

    #[test]
    fn a_new_reason_is_logged_at_once_and_a_join_resets() {
        let t0 = Instant::now();
        let mut log = JoinLog::new(Duration::from_secs(5));
        assert!(log.failed("c", "timed out", t0).is_some());
        let other = log
            .failed("c", "connection refused", t0 + Duration::from_secs(1))
            .unwrap();
        assert!(
            other.starts_with("cannot join c: connection refused"),
            "{other}"
        );
        log.joined();
        assert!(log
            .failed("c", "connection refused", t0 + Duration::from_secs(2))
            .is_some());
    }
}
