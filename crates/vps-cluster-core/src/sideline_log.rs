//! What the coordinator's log says about one worker being sidelined and reinstated.
//!
//! A worker whose replies are late every few frames is sidelined and reinstated again and
//! again; one log line per transition filled a coordinator's journal at up to 59 lines/s with two
//! workers. [`SidelineLog`] logs the first transition at once, then at most one line per worker per
//! [`SIDELINE_LOG_PERIOD`], summing the transitions since the last line. Pure: the caller passes the
//! transition counters and the time, and logs the [`SidelineLine`] it gets back.

use std::time::{Duration, Instant};

/// The shortest time between two sideline lines about one worker (10 s).
pub const SIDELINE_LOG_PERIOD: Duration = Duration::from_secs(10);

/// One line to log about a worker's sideline transitions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SidelineLine {
    /// It was sidelined once since the last line.
    Sidelined,
    /// It was reinstated (was given work again) once since the last line.
    Recovered,
    /// Several transitions since the last line: how many each way, and where it is now.
    Flapping {
        /// Times it was sidelined.
        sidelined: u64,
        /// Times it was reinstated.
        recovered: u64,
        /// Whether it is sidelined now.
        now_sidelined: bool,
    },
}

/// The log state of one worker's sideline transitions: counters already seen, transitions not yet
/// logged, and until when to stay quiet.
#[derive(Clone, Debug, Default)]
pub struct SidelineLog {
    seen_sidelined: u64,
    seen_recovered: u64,
    pending_sidelined: u64,
    pending_recovered: u64,
    quiet_until: Option<Instant>,
}

impl SidelineLog {
    /// Takes the worker's transition counters (`sidelined_total`, `recovered_total`: monotonic
    /// counts since it joined) and whether it is sidelined now, at time `now`. Returns the
    /// line to log, if one is due: at once for a first transition after a quiet period, else
    /// once [`SIDELINE_LOG_PERIOD`] has passed since the last line. `flush` (the session is ending)
    /// logs whatever is pending at once. Never allocates or blocks.
    pub fn observe(
        &mut self,
        sidelined_total: u64,
        recovered_total: u64,
        now_sidelined: bool,
        now: Instant,
        flush: bool,
    ) -> Option<SidelineLine> {
        self.pending_sidelined += sidelined_total.saturating_sub(self.seen_sidelined);
        self.pending_recovered += recovered_total.saturating_sub(self.seen_recovered);
        self.seen_sidelined = self.seen_sidelined.max(sidelined_total);
        self.seen_recovered = self.seen_recovered.max(recovered_total);
        let quiet = self.quiet_until.is_some_and(|until| now < until);
        if self.pending_sidelined + self.pending_recovered == 0 {
            if !quiet {
                self.quiet_until = None;
            }
            return None;
        }
        if quiet && !flush {
            return None;
        }
        let line = match (self.pending_sidelined, self.pending_recovered) {
            (1, 0) => SidelineLine::Sidelined,
            (0, 1) => SidelineLine::Recovered,
            (sidelined, recovered) => SidelineLine::Flapping {
                sidelined,
                recovered,
                now_sidelined,
            },
        };
        self.pending_sidelined = 0;
        self.pending_recovered = 0;
        self.quiet_until = Some(now + SIDELINE_LOG_PERIOD);
        Some(line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A worker flapping every 100 ms for 60 s: the first transition is logged at once, then one
    /// summed line per 10 s, and the sums add up to every transition.
    #[test]
    fn a_flapping_worker_gets_one_line_per_period_and_no_transition_is_lost() {
        let start = Instant::now();
        let mut log = SidelineLog::default();
        let (mut sidelined, mut recovered) = (0u64, 0u64);
        let mut lines = Vec::new();
        for tick in 1..=600u64 {
            // Odd ticks sideline it, even ticks bring it back.
            let now_sidelined = tick % 2 == 1;
            if now_sidelined {
                sidelined += 1;
            } else {
                recovered += 1;
            }
            let now = start + Duration::from_millis(100 * tick);
            if let Some(line) = log.observe(sidelined, recovered, now_sidelined, now, false) {
                lines.push((tick, line));
            }
        }
        assert_eq!(lines[0], (1, SidelineLine::Sidelined));
        assert!(lines.len() <= 7, "{} lines in 60 s: {lines:?}", lines.len());
        for pair in lines.windows(2) {
            let gap = Duration::from_millis(100 * (pair[1].0 - pair[0].0));
            assert!(gap >= SIDELINE_LOG_PERIOD, "{pair:?}");
        }
        let flushed = log.observe(
            sidelined,
            recovered,
            false,
            start + Duration::from_secs(61),
            true,
        );
        let (mut logged_sidelined, mut logged_recovered) = (0, 0);
        for line in lines.iter().map(|(_, l)| l).chain(flushed.iter()) {
            match *line {
                SidelineLine::Sidelined => logged_sidelined += 1,
                SidelineLine::Recovered => logged_recovered += 1,
                SidelineLine::Flapping {
                    sidelined,
                    recovered,
                    ..
                } => {
                    logged_sidelined += sidelined;
                    logged_recovered += recovered;
                }
            }
        }
        assert_eq!((logged_sidelined, logged_recovered), (sidelined, recovered));
    }

    #[test]
    fn a_rare_transition_is_logged_at_once_each_time() {
        let start = Instant::now();
        let mut log = SidelineLog::default();
        let at = |s: u64| start + Duration::from_secs(s);
        assert_eq!(log.observe(0, 0, false, at(0), false), None);
        assert_eq!(
            log.observe(1, 0, true, at(1), false),
            Some(SidelineLine::Sidelined)
        );
        // Recovered 3 s later: within the quiet period, so held back until it ends.
        assert_eq!(log.observe(1, 1, false, at(4), false), None);
        assert_eq!(
            log.observe(1, 1, false, at(11), false),
            Some(SidelineLine::Recovered)
        );
        // Nothing for a while: the quiet period lapses, so the next transition is immediate.
        assert_eq!(log.observe(1, 1, false, at(30), false), None);
        assert_eq!(
            log.observe(2, 1, true, at(31), false),
            Some(SidelineLine::Sidelined)
        );
        assert_eq!(
            log.observe(3, 2, true, at(32), true),
            Some(SidelineLine::Flapping {
                sidelined: 1,
                recovered: 1,
                now_sidelined: true
            }),
            "a flush logs what is pending at once"
        );
    }
}
