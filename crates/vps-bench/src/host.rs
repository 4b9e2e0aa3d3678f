//! `vps bench host`: how often, and for how long, this machine takes the frame thread's core away
//! (in the manner of `cyclictest`). One thread, given the frame thread's real-time request
//! (SCHED_FIFO, pinned to the last core), runs the loop's rhythm with no haptics in it: every
//! 1 ms tick it sleeps until shortly before the tick, spins to it, then spins `--busy-us` more (the
//! "frame"), reading the monotonic clock all the while. A start later than the tick, or a gap
//! between two consecutive reads, is time the thread did not run (an interrupt, a higher-priority
//! kernel thread, or the hypervisor descheduling the vCPU). Nothing else runs, so a tick that
//! starts a period late, or whose frame is stretched past the period, is one the 1 kHz loop
//! cannot avoid either: run it beside `vps bench loop` to tell the machine's misses from the
//! loop's. (The duty cycle stays below the kernel's real-time throttling limit, 95 % by default.)

use anyhow::Result;
use serde::Serialize;
use std::time::{Duration, Instant};
use vps_app::output::print_report;
use vps_netem::transport_bench::{percentiles, TransportPercentiles};
use vps_runtime::RtGrant;

/// Gap thresholds reported (µs).
const THRESHOLDS_US: [u64; 5] = [20, 100, 500, 1_000, 5_000];

/// The largest gaps kept for the report.
const LARGEST_KEPT: usize = 20;

/// The tick period (the loop's).
const PERIOD: Duration = Duration::from_millis(1);

/// How long before a tick the thread stops sleeping and spins (the loop's margin).
const SPIN_MARGIN: Duration = Duration::from_micros(150);

#[derive(Serialize)]
struct GapCount {
    /// Gaps of at least this long (µs).
    at_least_us: u64,
    count: u64,
    /// Their total length (ms).
    total_ms: f64,
}

#[derive(Serialize)]
struct HostBench {
    method: &'static str,
    seconds: f64,
    busy_us: u64,
    rt: RtGrant,
    host_idle: crate::machine::HostIdle,
    ticks: u64,
    /// Ticks whose start was a whole period late or more, or whose frame (start to the end of
    /// the busy stretch) lasted a period or more: the ticks a loop doing `busy_us` of work per
    /// frame would have missed on this machine.
    disturbed_ticks: u64,
    /// Distinct stalls of 1 ms or more: gaps, and late starts whose previous tick started on
    /// time (the ticks after a stall start late while the thread catches up; they are one
    /// stall).
    stalls_over_1ms: u64,
    /// Start lateness after the tick (ns), nearest-rank percentiles.
    lateness: TransportPercentiles,
    /// Gaps inside the busy stretches, by threshold.
    gaps: Vec<GapCount>,
    max_gap_us: f64,
    /// The largest stalls (µs; gaps, and late starts counted as in `stalls_over_1ms`), largest
    /// first, with when they happened (s from the start).
    largest_stalls: Vec<(f64, f64)>,
}

/// Runs the measurement for `seconds` with `busy_us` of spinning per tick and prints JSON.
pub fn run(seconds: f64, busy_us: u64, json: bool) -> Result<()> {
    anyhow::ensure!(
        seconds.is_finite() && seconds > 0.0 && seconds <= 86_400.0,
        "--seconds must be in (0, 86400], got {seconds}"
    );
    anyhow::ensure!(
        busy_us <= 900,
        "--busy-us must be at most 900 (a 1 ms period), got {busy_us}"
    );
    let report = std::thread::Builder::new()
        .name("vps-host-probe".into())
        .spawn(move || measure(Duration::from_secs_f64(seconds), busy_us))?
        .join()
        .map_err(|_| anyhow::anyhow!("the probe thread panicked"))?;
    print_report(
        "bench host: stalls of the frame thread's core with no haptics in it",
        &report,
        json,
    )
}

/// Keeps the `LARGEST_KEPT` largest stalls.
fn keep_largest(largest: &mut Vec<(Duration, Duration)>, stall: Duration, at: Duration) {
    if largest.len() < LARGEST_KEPT || stall > largest[largest.len() - 1].0 {
        largest.push((stall, at));
        largest.sort_by_key(|s| std::cmp::Reverse(s.0));
        largest.truncate(LARGEST_KEPT);
    }
}

fn measure(length: Duration, busy_us: u64) -> HostBench {
    let rt = vps_runtime::request_realtime(None);
    let busy = Duration::from_micros(busy_us);
    let mut counts = [0u64; THRESHOLDS_US.len()];
    let mut totals = [Duration::ZERO; THRESHOLDS_US.len()];
    let mut largest = Vec::with_capacity(LARGEST_KEPT + 1);
    let mut lateness = Vec::new();
    let (mut ticks, mut disturbed, mut stalls) = (0u64, 0u64, 0u64);
    let mut previous_late = false;
    let start = Instant::now();
    for n in 1u32.. {
        let tick = start + PERIOD * n;
        if tick - start > length {
            break;
        }
        let now = Instant::now();
        if tick > now + SPIN_MARGIN {
            std::thread::sleep(tick - now - SPIN_MARGIN);
        }
        while Instant::now() < tick {
            std::hint::spin_loop();
        }
        let begun = Instant::now();
        let late = begun - tick;
        lateness.push(late);
        let is_late = late >= Duration::from_micros(THRESHOLDS_US[0]);
        if is_late && !previous_late {
            keep_largest(&mut largest, late, tick - start);
            stalls += u64::from(late >= PERIOD);
        }
        previous_late = is_late;
        let mut last = begun;
        while last < begun + busy {
            let now = Instant::now();
            let gap = now - last;
            last = now;
            if gap >= Duration::from_micros(THRESHOLDS_US[0]) {
                for (i, &t) in THRESHOLDS_US.iter().enumerate() {
                    if gap >= Duration::from_micros(t) {
                        counts[i] += 1;
                        totals[i] += gap;
                    }
                }
                keep_largest(&mut largest, gap, now - start);
                stalls += u64::from(gap >= PERIOD);
            }
        }
        ticks += 1;
        if late >= PERIOD || last - tick >= PERIOD {
            disturbed += 1;
        }
    }
    HostBench {
        method: "one thread with the frame thread's real-time request keeps the loop's rhythm \
                 (sleep, spin to the 1 ms tick, spin busy_us) reading the monotonic clock; a late \
                 start or a gap between two reads is time it did not run",
        seconds: (Instant::now() - start).as_secs_f64(),
        busy_us,
        host_idle: crate::machine::HostIdle::read(),
        rt,
        ticks,
        disturbed_ticks: disturbed,
        stalls_over_1ms: stalls,
        lateness: percentiles(&lateness),
        gaps: THRESHOLDS_US
            .iter()
            .zip(counts.iter().zip(&totals))
            .map(|(&at_least_us, (&count, total))| GapCount {
                at_least_us,
                count,
                total_ms: total.as_secs_f64() * 1e3,
            })
            .collect(),
        max_gap_us: largest.first().map_or(0.0, |g| g.0.as_secs_f64() * 1e6),
        largest_stalls: largest
            .iter()
            .map(|&(stall, at)| (stall.as_secs_f64() * 1e6, at.as_secs_f64()))
            .collect(),
    }
}
