//! Frame statistics: HDR histograms of compute time and |period error| (ns), deadline and
//! contact counters, and a serialisable summary.

use hdrhistogram::Histogram;

/// Largest value the histograms resolve (ns): 10 s. Larger values are recorded as this.
pub const HISTOGRAM_MAX_NS: u64 = 10_000_000_000;

/// p50 / p99 / p99.9 / max of a histogram (ns). All zero for an empty histogram.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Percentiles {
    /// Median (ns).
    pub p50: u64,
    /// 99th percentile (ns).
    pub p99: u64,
    /// 99.9th percentile (ns).
    pub p999: u64,
    /// Largest value (ns).
    pub max: u64,
}

impl Percentiles {
    fn of(h: &Histogram<u64>) -> Percentiles {
        if h.is_empty() {
            return Percentiles::default();
        }
        Percentiles {
            p50: h.value_at_quantile(0.5),
            p99: h.value_at_quantile(0.99),
            p999: h.value_at_quantile(0.999),
            max: h.max(),
        }
    }
}

/// A session's figures, ready for JSON.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StatsSummary {
    /// Frames run.
    pub frames: u64,
    /// Ticks skipped because the loop fell a period or more behind (docs/architecture.md#timing: no coordinated
    /// omission).
    pub missed_deadlines: u64,
    /// Of those, ticks skipped after a frame that lost more time before it started (late
    /// start: the frame thread, asleep until its tick, did not run in time) than it took to
    /// compute. With SCHED_FIFO granted only the machine (interrupts, higher-priority kernel
    /// threads, a hypervisor descheduling the vCPU) delays that thread; the frame's work had
    /// no part in it.
    pub missed_after_late_start: u64,
    /// The rest: ticks skipped after a frame whose compute time was the larger part of its
    /// overshoot (work over budget, or the thread stalled while computing).
    pub missed_after_long_frame: u64,
    /// Frames whose device output was forced to zero by the watchdog (compute over budget).
    pub watchdog_trips: u64,
    /// Frames whose handle sample was rejected (non-finite or absurd: the core's
    /// `rejected_input`); the device got zero and the part held still.
    pub rejected_input_frames: u64,
    /// Frames whose state or result was non-finite (the core's `non_finite`); the device got zero.
    pub non_finite_frames: u64,
    /// Frames whose device output was forced to zero for any of the three reasons above (each
    /// frame counted once). Zero output in free space is not counted: it is the right output.
    pub zeroed_frames: u64,
    /// Class shares the pool computed on the frame thread because a worker missed its deadline.
    pub fallback_shares: u64,
    /// Per-frame compute time, device read to device write (ns).
    pub compute_ns: Percentiles,
    /// |actual start − scheduled tick| (ns); empty (zeros) in free-running mode.
    pub period_error_ns: Percentiles,
    /// Frames with at least one contact (a Surface point with depth > 0).
    pub contact_frames: u64,
    /// Frames with ≥ 1 point in a Surface or Interior voxel.
    pub touching_frames: u64,
    /// Frames with ≥ 1 point in an Interior voxel.
    pub penetrating_frames: u64,
    /// Frames whose device wrench hit the device maxima.
    pub clamped_frames: u64,
    /// `penetrating_frames / touching_frames` (the paper's Table 2); `None` before any touch.
    pub penetration_ratio: Option<f64>,
}

/// What one frame contributes to the statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FrameRecord {
    /// Device read to device write (ns).
    pub compute_ns: u64,
    /// |start − scheduled| (ns), `None` in free-running mode.
    pub period_error_ns: Option<u64>,
    /// Ticks skipped before this frame.
    pub missed: u64,
    /// The watchdog zeroed the output.
    pub watchdog_tripped: bool,
    /// The core rejected the handle sample (zero output).
    pub rejected_input: bool,
    /// The core's state or result was non-finite (zero output).
    pub non_finite: bool,
    /// Shares the frame thread computed as fallback.
    pub fallback_shares: u32,
    /// Contact count N > 0.
    pub contact: bool,
    /// ≥ 1 point in Surface or Interior.
    pub touching: bool,
    /// ≥ 1 point in Interior.
    pub penetrating: bool,
    /// The device wrench was limited.
    pub clamped: bool,
}

/// Accumulates [`FrameRecord`]s. `record` does not allocate or block (the histograms are sized
/// once in [`FrameStats::new`]).
#[derive(Clone, Debug)]
pub struct FrameStats {
    compute: Histogram<u64>,
    period_error: Histogram<u64>,
    summary: StatsSummary,
    /// The previous frame's start lateness and compute time (ns): ticks skipped before a frame
    /// are the previous frame's overshoot.
    previous: (u64, u64),
}

impl Default for FrameStats {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameStats {
    /// Empty statistics; histograms cover 1 ns .. [`HISTOGRAM_MAX_NS`] at 3 significant digits.
    pub fn new() -> FrameStats {
        let histogram = || {
            Histogram::new_with_bounds(1, HISTOGRAM_MAX_NS, 3)
                .expect("constant histogram bounds are valid")
        };
        FrameStats {
            compute: histogram(),
            period_error: histogram(),
            summary: StatsSummary::default(),
            previous: (0, 0),
        }
    }

    /// Adds one frame. Does not allocate or block.
    pub fn record(&mut self, r: &FrameRecord) {
        self.compute.saturating_record(r.compute_ns.max(1));
        if let Some(e) = r.period_error_ns {
            self.period_error.saturating_record(e.max(1));
        }
        let s = &mut self.summary;
        s.frames += 1;
        s.missed_deadlines += r.missed;
        let (late, compute) = self.previous;
        if late >= compute {
            s.missed_after_late_start += r.missed;
        } else {
            s.missed_after_long_frame += r.missed;
        }
        self.previous = (r.period_error_ns.unwrap_or(0), r.compute_ns);
        s.watchdog_trips += r.watchdog_tripped as u64;
        s.rejected_input_frames += r.rejected_input as u64;
        s.non_finite_frames += r.non_finite as u64;
        s.zeroed_frames += (r.watchdog_tripped || r.rejected_input || r.non_finite) as u64;
        s.fallback_shares += r.fallback_shares as u64;
        s.contact_frames += r.contact as u64;
        s.touching_frames += r.touching as u64;
        s.penetrating_frames += r.penetrating as u64;
        s.clamped_frames += r.clamped as u64;
    }

    /// The counters so far (percentiles not filled in; for the state feed, every frame). Does not
    /// allocate or block.
    pub fn counters(&self) -> &StatsSummary {
        &self.summary
    }

    /// The full summary with percentiles and the penetration ratio.
    pub fn summary(&self) -> StatsSummary {
        let s = &self.summary;
        StatsSummary {
            compute_ns: Percentiles::of(&self.compute),
            period_error_ns: Percentiles::of(&self.period_error),
            penetration_ratio: (s.touching_frames > 0)
                .then(|| s.penetrating_frames as f64 / s.touching_frames as f64),
            ..s.clone()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_percentiles() {
        let mut st = FrameStats::new();
        for i in 1..=1000u64 {
            st.record(&FrameRecord {
                compute_ns: i * 1000,
                period_error_ns: Some(i),
                missed: (i == 10) as u64 * 3,
                touching: i % 2 == 0,
                penetrating: i % 10 == 0,
                contact: i % 4 == 0,
                ..FrameRecord::default()
            });
        }
        let s = st.summary();
        assert_eq!(s.frames, 1000);
        assert_eq!(s.missed_deadlines, 3);
        assert_eq!(
            (s.touching_frames, s.penetrating_frames, s.contact_frames),
            (500, 100, 250)
        );
        assert_eq!(s.penetration_ratio, Some(0.2));
        assert!(
            (s.compute_ns.p50 as i64 - 500_000).abs() <= 500,
            "{:?}",
            s.compute_ns
        );
        assert!((s.compute_ns.max as i64 - 1_000_000).abs() <= 1000);
        assert!(s.period_error_ns.p99 >= 985 && s.period_error_ns.p99 <= 995);
        let json = serde_json::to_string(&s).unwrap();
        let back: StatsSummary = serde_json::from_str(&json).unwrap();
        assert_eq!(back, s);
    }

    #[test]
    fn skipped_ticks_are_blamed_on_the_larger_part_of_the_previous_frames_overshoot() {
        let mut st = FrameStats::new();
        let frame = |late_us: u64, compute_us: u64, missed: u64| FrameRecord {
            compute_ns: compute_us * 1000,
            period_error_ns: Some(late_us * 1000),
            missed,
            ..FrameRecord::default()
        };
        st.record(&frame(5, 400, 0));
        // Started 1.8 ms late, computed 0.4 ms: the 2 ticks skipped next are the late start's.
        st.record(&frame(1_800, 400, 0));
        st.record(&frame(3, 400, 2));
        // Started on time, computed 2.5 ms: the long frame's.
        st.record(&frame(2, 2_500, 0));
        st.record(&frame(40, 400, 1));
        let s = st.summary();
        assert_eq!(s.missed_deadlines, 3);
        assert_eq!(
            (s.missed_after_late_start, s.missed_after_long_frame),
            (2, 1)
        );
        // Free-running frames have no lateness: a skip after one is the frame's.
        let mut free = FrameStats::new();
        free.record(&FrameRecord {
            compute_ns: 10,
            ..FrameRecord::default()
        });
        free.record(&FrameRecord {
            missed: 4,
            ..FrameRecord::default()
        });
        assert_eq!(free.summary().missed_after_long_frame, 4);
    }

    #[test]
    fn empty_and_saturating() {
        let mut st = FrameStats::new();
        assert_eq!(st.summary().penetration_ratio, None);
        assert_eq!(st.summary().compute_ns, Percentiles::default());
        st.record(&FrameRecord {
            compute_ns: u64::MAX,
            ..FrameRecord::default()
        });
        assert!(st.summary().compute_ns.max >= HISTOGRAM_MAX_NS);
        assert_eq!(st.summary().period_error_ns, Percentiles::default());
    }
}
