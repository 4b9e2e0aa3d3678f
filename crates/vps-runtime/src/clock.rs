//! Frame timing: absolute deadlines `t0 + n·period`, sleep until shortly before the deadline and
//! spin the rest, never drift, never burst.
//!
//! The schedule is anchored at `t0`: tick `n` is due at `t0 + n·period` whatever happened before, so
//! a late frame does not push later ticks back. When the loop wakes more than one period after a
//! tick was due, the ticks it can no longer meet are counted as missed deadlines and the loop waits
//! for the next future tick instead of running the backlog back to back.

use std::time::{Duration, Instant};

/// Which tick to run next, and how many were given up, for a loop that has run up to tick
/// `next - 1` and is now `elapsed` after `t0`. Pure arithmetic; see [`FrameClock`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Schedule {
    /// The tick to run (its deadline is `t0 + tick·period`).
    pub tick: u64,
    /// Ticks skipped as missed deadlines (`tick - next`).
    pub missed: u64,
}

/// Plans the next tick. Rules: if tick `next` is still ahead, or less than one period late, run it
/// (late frames are recorded against their scheduled tick). If it is a whole period or more late,
/// skip to the first tick strictly after `elapsed` and count the skipped ones as missed.
/// `period` must be > 0 (a zero period is treated as 1 ns). Pure; does not allocate or block.
pub fn schedule(elapsed: Duration, next: u64, period: Duration) -> Schedule {
    let period_ns = period.as_nanos().max(1);
    let due = period_ns.saturating_mul(next as u128);
    let now = elapsed.as_nanos();
    if now < due.saturating_add(period_ns) {
        return Schedule {
            tick: next,
            missed: 0,
        };
    }
    let tick = u64::try_from(now / period_ns + 1)
        .unwrap_or(u64::MAX)
        .max(next);
    Schedule {
        tick,
        missed: tick - next,
    }
}

/// `t0 + n·period` as an offset from `t0`, saturating at `Duration::MAX`.
pub fn tick_offset(n: u64, period: Duration) -> Duration {
    let ns = period.as_nanos().saturating_mul(n as u128);
    match u64::try_from(ns / 1_000_000_000) {
        Ok(secs) => Duration::new(secs, (ns % 1_000_000_000) as u32),
        Err(_) => Duration::MAX,
    }
}

/// One tick as the loop started it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Tick {
    /// Tick index since `t0`.
    pub index: u64,
    /// When the tick was due.
    pub scheduled: Instant,
    /// When the wait returned (≥ `scheduled`, except in free-running mode where they are equal).
    pub started: Instant,
    /// Ticks skipped as missed deadlines just before this one.
    pub missed: u64,
}

impl Tick {
    /// `started − scheduled` (the period error), in ns, saturating. Does not allocate or block.
    pub fn lateness_ns(&self) -> u64 {
        u64::try_from(
            self.started
                .saturating_duration_since(self.scheduled)
                .as_nanos(),
        )
        .unwrap_or(u64::MAX)
    }
}

/// The frame clock. Not `Sync`: one frame thread owns it.
#[derive(Clone, Debug)]
pub struct FrameClock {
    t0: Instant,
    period: Duration,
    spin_margin: Duration,
    next: u64,
}

impl FrameClock {
    /// A clock whose tick 0 is due at `t0`.
    pub fn new(t0: Instant, period: Duration, spin_margin: Duration) -> FrameClock {
        FrameClock {
            t0,
            period,
            spin_margin,
            next: 0,
        }
    }

    /// The start of the schedule.
    pub fn t0(&self) -> Instant {
        self.t0
    }

    /// When tick `n` is due (capped at about 136 years after `t0`, which no session reaches).
    pub fn deadline(&self, n: u64) -> Instant {
        let cap = Duration::from_secs(1 << 32);
        self.t0 + tick_offset(n, self.period).min(cap)
    }

    /// Waits for the next tick: [`schedule`] it, `std::thread::sleep` until `deadline −
    /// spin_margin`, then spin (`std::hint::spin_loop`) until the deadline. Blocks the calling
    /// thread for up to one period (plus the OS's sleep overshoot beyond the spin margin); does
    /// not allocate.
    pub fn wait_next(&mut self) -> Tick {
        let plan = schedule(
            Instant::now().saturating_duration_since(self.t0),
            self.next,
            self.period,
        );
        let scheduled = self.deadline(plan.tick);
        let wake = scheduled.checked_sub(self.spin_margin).unwrap_or(scheduled);
        let now = Instant::now();
        if wake > now {
            std::thread::sleep(wake - now);
        }
        let mut started = Instant::now();
        while started < scheduled {
            std::hint::spin_loop();
            started = Instant::now();
        }
        self.next = plan.tick + 1;
        Tick {
            index: plan.tick,
            scheduled,
            started,
            missed: plan.missed,
        }
    }

    /// The next tick without waiting (free-running mode: frames back to back, no missed ticks,
    /// no period error). Does not block or allocate.
    pub fn next_immediate(&mut self) -> Tick {
        let now = Instant::now();
        let tick = Tick {
            index: self.next,
            scheduled: now,
            started: now,
            missed: 0,
        };
        self.next += 1;
        tick
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    /// Each `(elapsed µs, next tick, tick run, ticks missed)` holds for [`schedule`] at 1 ms.
    fn assert_schedules(cases: &[(u64, u64, u64, u64)]) {
        for &(elapsed_us, next, tick, missed) in cases {
            assert_eq!(
                schedule(Duration::from_micros(elapsed_us), next, MS),
                Schedule { tick, missed },
                "{elapsed_us} us with tick {next} next"
            );
        }
    }

    #[test]
    fn early_or_slightly_late_runs_the_due_tick() {
        // 0.9 ms late (5.9 ms, tick 5): still run tick 5, recorded against its schedule.
        assert_schedules(&[(0, 0, 0, 0), (4_200, 5, 5, 0), (5_900, 5, 5, 0)]);
    }

    #[test]
    fn a_period_or_more_late_skips_to_the_next_future_tick() {
        // Exactly one period late (6 ms, tick 5): tick 5 and 6 are due or past; run 7.
        assert_schedules(&[(6_000, 5, 7, 2), (6_500, 5, 7, 2), (105_100, 5, 106, 101)]);
    }

    #[test]
    fn deadlines_are_anchored_at_t0_without_drift() {
        let period = Duration::from_nanos(333_333);
        assert_eq!(tick_offset(3, period), Duration::from_nanos(999_999));
        // A million ticks later the offset is the exact product, not a rounded running sum.
        assert_eq!(
            tick_offset(3_000_000, period),
            Duration::from_nanos(999_999_000_000)
        );
        assert_eq!(
            tick_offset(u64::MAX, Duration::from_secs(u64::MAX)),
            Duration::MAX
        );
        let t0 = Instant::now();
        let clock = FrameClock::new(t0, MS, Duration::ZERO);
        assert_eq!(clock.deadline(1_000) - t0, Duration::from_secs(1));
    }

    #[test]
    fn free_running_ticks_count_up_with_no_error() {
        let mut c = FrameClock::new(Instant::now(), MS, Duration::ZERO);
        let a = c.next_immediate();
        let b = c.next_immediate();
        assert_eq!((a.index, b.index), (0, 1));
        assert_eq!(b.lateness_ns(), 0);
        assert_eq!(b.missed, 0);
    }

    #[test]
    fn wait_next_never_returns_before_its_deadline() {
        let mut c = FrameClock::new(
            Instant::now(),
            Duration::from_micros(200),
            Duration::from_micros(50),
        );
        for _ in 0..5 {
            let t = c.wait_next();
            assert!(t.started >= t.scheduled);
            assert_eq!(t.scheduled, c.deadline(t.index));
        }
    }
}
