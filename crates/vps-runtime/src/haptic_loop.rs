//! The 1 kHz haptic loop: one dedicated frame thread that reads the device, samples the shell with
//! the [`ClassPool`] (or another [`FrameSampler`], [`spawn_loop_with`]), steps the sans-IO core and
//! writes the device, every tick.
//!
//! Per frame: wait for the tick ([`FrameClock`]) → `device.read(tick time)` → [`KernelPose`] of the
//! current state → the [`FrameSampler`] computes all classes, with a reply deadline half the
//! watchdog budget after the frame started (when the frame thread woke for its tick, where the
//! watchdog counts from too) → [`step_with_parts`] (the pairs of several parts, [`crate::parts`]) → saturation to the device's
//! [`DeviceLimits`](vps_device::DeviceLimits) (counted as clamped) → watchdog check →
//! `device.write` → statistics → publish to the state feed (never blocks). With the local
//! [`ClassPool`], pool threads and the frame thread claim classes, and the frame thread computes
//! any class a pool thread still holds at the *hedge* (see [`crate::pool`]); the cluster's
//! gatherer is `vps_cluster::shares`.
//!
//! Watchdog: a frame whose compute time (device read to just before the write) reaches
//! `LoopConfig::watchdog` sends the zero wrench instead (counted in `watchdog_trips`); the part's
//! state still advances. A device read or write error writes the zero wrench and ends the session
//! cleanly with the error in the [`LoopReport`].
//!
//! Stop path: every session ends by writing the exact zero wrench before the frame thread returns
//! its report, whatever ended it: its frame count, the stop flag (set by another thread or by a
//! signal handler, [`crate::stop::SignalStop`]; seen at the next tick), a device error, a panic
//! in the frame's work (caught on the frame thread) or a panic on a pool thread
//! ([`FrameSampler::failure`], checked after every gather, before the frame's write).
//!
//! The device is given the scheduled tick time (`tick · period`, s), never the wall clock, so a
//! simulated device runs identically in real-time and free-running mode.

use crate::clock::FrameClock;
use crate::feed::{FeedFrame, OtherPartFrame, RecentMax, StateFeedSender, MAX_OTHER_PARTS};
use crate::parts::{PartReport, PartsSetup, RunningParts};
use crate::pool::{panic_message, ClassPool, FrameSampler};
use crate::recording::TraceRecording;
use crate::rt::{request_realtime, RtGrant};
use crate::stats::{FrameRecord, FrameStats, StatsSummary};
use crate::RuntimeError;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use vps_device::{DeviceError, HapticDevice, Trace, TraceRecorder};
use vps_haptic::pair::PairCounts;
use vps_haptic::{
    step_with_parts, ClassedShell, HandleSample, HapticParams, KernelPose, OtherParts, PartState,
    Wrench,
};
use vps_voxmap::VoxelLookup;

/// How the loop runs. The number of classes is the [`ClassedShell`]'s own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LoopConfig {
    /// Frame period; must equal `HapticParams::dt` to within 1 ns. Default 1 ms.
    pub period: Duration,
    /// Frames to run; `None` runs until `stop` is set or the device fails.
    pub frames: Option<u64>,
    /// Compute threads, the frame thread included (≥ 1). Default 1.
    pub threads: usize,
    /// How long before each deadline the frame thread stops sleeping and starts spinning.
    /// Default 200 µs.
    pub spin_margin: Duration,
    /// Request SCHED_FIFO and core pinning for the frame thread (best effort). Default false.
    pub realtime: bool,
    /// The core to pin the frame thread to when `realtime` (`None`: the last available core).
    pub core: Option<usize>,
    /// Compute budget per frame; at or over it the device gets the zero wrench. Workers' replies
    /// are awaited until half of it. Default 800 µs.
    pub watchdog: Duration,
    /// Run frames back to back without waiting for ticks (tests, benchmarks). Default false.
    pub free_running: bool,
    /// Record every handle sample into [`LoopReport::trace`] (and every other part's into its
    /// [`PartReport::trace`]). Default false.
    pub record_trace: bool,
}

impl Default for LoopConfig {
    fn default() -> Self {
        LoopConfig {
            period: Duration::from_millis(1),
            frames: None,
            threads: 1,
            spin_margin: Duration::from_micros(200),
            realtime: false,
            core: None,
            watchdog: Duration::from_micros(800),
            free_running: false,
            record_trace: false,
        }
    }
}

impl LoopConfig {
    /// Checks the config against the haptic parameters (period = dt, threads ≥ 1).
    pub fn validate(&self, params: &HapticParams) -> Result<(), RuntimeError> {
        if self.period.is_zero() {
            return Err(RuntimeError::Config {
                field: "period",
                message: "must be > 0".into(),
            });
        }
        if (self.period.as_secs_f64() - params.dt).abs() > 1e-9 {
            return Err(RuntimeError::Config {
                field: "period",
                message: format!(
                    "{} s differs from the haptic time step dt = {} s",
                    self.period.as_secs_f64(),
                    params.dt
                ),
            });
        }
        if self.threads == 0 {
            return Err(RuntimeError::Config {
                field: "threads",
                message: "must be at least 1".into(),
            });
        }
        Ok(())
    }
}

/// Why a session ended.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum SessionEnd {
    /// `LoopConfig::frames` frames ran.
    FramesDone,
    /// The stop flag was set.
    Stopped,
    /// The device failed (message of the [`DeviceError`], also in [`LoopReport::device_error`]).
    DeviceFailed(String),
    /// A panic on the frame thread or one of its pool threads (the message says which and
    /// where). The frame path is written not to panic: this is a bug, caught so that the device
    /// is still written zero.
    Panicked(String),
}

impl SessionEnd {
    /// True when the session ran all its frames (a complete report); false for a partial one.
    pub fn is_complete(&self) -> bool {
        matches!(self, SessionEnd::FramesDone)
    }
}

/// What a session did.
#[derive(Clone, Debug)]
pub struct LoopReport {
    /// Why it ended.
    pub end: SessionEnd,
    /// The device error that ended it, if any.
    pub device_error: Option<DeviceError>,
    /// Frame figures.
    pub stats: StatsSummary,
    /// What real-time scheduling was granted (default, empty, when not requested).
    pub rt: RtGrant,
    /// The part's state after the last frame.
    pub final_state: PartState,
    /// The handle as the device gave it in the last frame (`None` when no frame ran): where the
    /// hand is, which a part held back by an obstacle does not reach.
    pub final_handle: Option<HandleSample>,
    /// The device's name.
    pub device_name: String,
    /// The handle trace, when `record_trace` was set.
    pub trace: Option<Trace>,
    /// Why trace recording stopped early, if it did (e.g. a non-finite handle sample).
    pub trace_error: Option<String>,
    /// The device's own counters ([`HapticDevice::counters`]), read after the last write.
    pub device_counters: Option<serde_json::Value>,
    /// The session's other moving parts (empty in a one-part session), in their order.
    pub other_parts: Vec<PartReport>,
    /// The pairs' counts (all zero in a one-part session).
    pub pairs: PairCounts,
    /// The first part's contact wrench from the other parts in the last frame (N, N·m about its
    /// origin; zero in a one-part session).
    pub last_pair_wrench: Wrench,
    /// Frames where the first part was in contact with another part.
    pub pair_contact_frames: u64,
    /// Largest force magnitude written to the device (N; the final zero included).
    pub max_device_force: f64,
}

/// A running session. Dropping it detaches the frame thread (set the stop flag first).
pub struct LoopHandle {
    thread: JoinHandle<LoopReport>,
}

impl LoopHandle {
    /// Blocks until the session ends.
    pub fn join(self) -> Result<LoopReport, RuntimeError> {
        self.thread.join().map_err(|_| RuntimeError::FramePanicked)
    }

    /// True once the frame thread has finished.
    pub fn is_finished(&self) -> bool {
        self.thread.is_finished()
    }
}

/// Everything a session runs with besides where its sums come from.
pub struct SessionSetup {
    /// Haptic parameters (validated when the session starts).
    pub params: HapticParams,
    /// The device read and written every frame.
    pub device: Box<dyn HapticDevice>,
    /// The part's state at the first frame.
    pub initial: PartState,
    /// Rate, length, threads, watchdog, real-time request (validated against `params`).
    pub config: LoopConfig,
    /// Where the loop publishes its state for viewers (never blocks the loop).
    pub feed: Option<StateFeedSender>,
    /// Set to end the session early (the device then gets zero).
    pub stop: Arc<AtomicBool>,
    /// The other moving parts and every part's body (`None`: the one-part session).
    pub parts: Option<PartsSetup>,
}

/// Starts a session on a new thread named `vps-frame` and returns at once. Validates the
/// parameters and configuration and spawns the pool's workers first (errors are returned,
/// nothing is left running).
pub fn spawn_loop<L: VoxelLookup + Send + Sync + 'static>(
    map: Arc<L>,
    shell: Arc<ClassedShell>,
    setup: SessionSetup,
) -> Result<LoopHandle, RuntimeError> {
    setup.params.validate("haptic parameters")?;
    setup.config.validate(&setup.params)?;
    let pool = ClassPool::new(map, shell, setup.config.threads)?;
    spawn_loop_with(Box::new(pool), setup)
}

/// [`spawn_loop`] with the frame's sums taken from `sampler` instead of a local [`ClassPool`]
/// (the cluster's extension point; `config.threads` is then unused). Validates the parameters
/// and configuration first.
pub fn spawn_loop_with(
    sampler: Box<dyn FrameSampler>,
    setup: SessionSetup,
) -> Result<LoopHandle, RuntimeError> {
    let SessionSetup {
        params,
        device,
        initial,
        config,
        feed,
        stop,
        parts,
    } = setup;
    params.validate("haptic parameters")?;
    config.validate(&params)?;
    let parts = match parts {
        None => None,
        Some(p) => {
            let recording = TraceRecording::of(config.record_trace, config.period, config.frames);
            Some(RunningParts::new(
                p,
                |part| config.validate(part),
                recording,
            )?)
        }
    };
    let running = RunningLoop {
        pool: sampler,
        params,
        device,
        state: initial,
        config,
        feed,
        stop,
        parts,
    };
    let thread = std::thread::Builder::new()
        .name("vps-frame".into())
        .spawn(move || running.run())
        .map_err(RuntimeError::Spawn)?;
    Ok(LoopHandle { thread })
}

/// Runs a session on a dedicated `vps-frame` thread and blocks the caller until it ends (see
/// [`spawn_loop`] to keep the caller free).
pub fn run_loop<L: VoxelLookup + Send + Sync + 'static>(
    map: Arc<L>,
    shell: Arc<ClassedShell>,
    setup: SessionSetup,
) -> Result<LoopReport, RuntimeError> {
    spawn_loop(map, shell, setup)?.join()
}

/// A session's loop while it runs on the `vps-frame` thread: the sampler, parameters, device and the
/// part's state, owned by that thread until the session ends.
struct RunningLoop {
    pool: Box<dyn FrameSampler>,
    params: HapticParams,
    device: Box<dyn HapticDevice>,
    state: PartState,
    config: LoopConfig,
    feed: Option<StateFeedSender>,
    stop: Arc<AtomicBool>,
    parts: Option<RunningParts>,
}

/// What one frame decided.
enum FrameFlow {
    /// Run the next frame.
    Next,
    /// End the session (the device is written zero next).
    End(SessionEnd),
}

/// The mutable state of a running session besides the [`RunningLoop`] itself.
struct FrameContext {
    clock: FrameClock,
    period_s: f64,
    limits: vps_device::DeviceLimits,
    recorder: Option<TraceRecorder>,
    trace_error: Option<String>,
    last_handle: Option<HandleSample>,
    stats: FrameStats,
    recent_compute: RecentMax,
    recent_lateness: RecentMax,
    frame: u64,
    max_device_force: f64,
}

impl RunningLoop {
    fn run(mut self) -> LoopReport {
        let rt = if self.config.realtime {
            request_realtime(self.config.core)
        } else {
            RtGrant::default()
        };
        let period_s = self.config.period.as_secs_f64();
        let recorder = TraceRecording::of(
            self.config.record_trace,
            self.config.period,
            self.config.frames,
        )
        .map(|r| r.recorder(self.device.name(), &self.state));
        let mut cx = FrameContext {
            clock: FrameClock::new(Instant::now(), self.config.period, self.config.spin_margin),
            period_s,
            limits: self.device.limits(),
            recorder,
            trace_error: None,
            last_handle: None,
            stats: FrameStats::new(),
            recent_compute: RecentMax::default(),
            recent_lateness: RecentMax::default(),
            frame: 0,
            max_device_force: 0.0,
        };
        let mut device_error = None;
        let end = loop {
            if self.config.frames.is_some_and(|n| cx.frame >= n) {
                break SessionEnd::FramesDone;
            }
            if self.stop.load(Ordering::SeqCst) {
                break SessionEnd::Stopped;
            }
            // A panic anywhere in the frame's work (device, sampler, core) ends the session here,
            // and the device is written zero below like for any other end.
            match catch_unwind(AssertUnwindSafe(|| self.frame(&mut cx))) {
                Ok(Ok(FrameFlow::Next)) => cx.frame += 1,
                Ok(Ok(FrameFlow::End(end))) => break end,
                Ok(Err(e)) => {
                    let end = SessionEnd::DeviceFailed(e.to_string());
                    device_error = Some(e);
                    break end;
                }
                Err(payload) => {
                    break SessionEnd::Panicked(format!(
                        "the frame thread panicked at frame {}: {}",
                        cx.frame,
                        panic_message(&*payload)
                    ))
                }
            }
        };
        // Release the hands whatever happened, first; a failure (or a panic) here cannot be
        // reported any better.
        let _ = catch_unwind(AssertUnwindSafe(|| self.device.write(&Wrench::ZERO)));
        if let Some(parts) = self.parts.as_mut() {
            parts.release();
        }
        let device_counters = catch_unwind(AssertUnwindSafe(|| self.device.counters()))
            .ok()
            .flatten();
        let (other_parts, pairs, last_pair_wrench, pair_contact_frames) = match self.parts {
            None => (Vec::new(), PairCounts::default(), Wrench::ZERO, 0),
            Some(parts) => parts.finish(),
        };
        LoopReport {
            end,
            device_error,
            stats: cx.stats.summary(),
            rt,
            final_state: self.state,
            final_handle: cx.last_handle,
            device_name: self.device.name().to_string(),
            trace: cx.recorder.map(TraceRecorder::finish),
            trace_error: cx.trace_error,
            device_counters,
            other_parts,
            pairs,
            last_pair_wrench,
            pair_contact_frames,
            max_device_force: cx.max_device_force,
        }
    }

    /// One frame: tick, read, sample, step, watchdog, write, statistics, feed. A device error is
    /// returned; the caller writes the zero wrench.
    fn frame(&mut self, cx: &mut FrameContext) -> Result<FrameFlow, DeviceError> {
        let tick = if self.config.free_running {
            cx.clock.next_immediate()
        } else {
            cx.clock.wait_next()
        };
        let time = tick.index as f64 * cx.period_s;
        let handle = self.device.read(time)?;
        cx.last_handle = Some(handle);
        if let Some(rec) = cx.recorder.as_mut() {
            if let Err(e) = rec.record(cx.frame, time, handle) {
                cx.trace_error = Some(e.to_string());
                cx.recorder = None;
            }
        }
        if let Some(parts) = self.parts.as_mut() {
            parts.read(cx.frame, time)?;
        }
        let pose = KernelPose::from_state(&self.state);
        let deadline = tick.started + self.config.watchdog / 2;
        let (gathered, mine) = match self.parts.as_mut() {
            None => {
                let gathered = self.pool.compute(&pose, deadline);
                if let Some(failure) = self.pool.failure() {
                    return Ok(FrameFlow::End(SessionEnd::Panicked(failure)));
                }
                (gathered, OtherParts::NONE)
            }
            Some(parts) => match parts.sample(&mut *self.pool, &self.state, &self.params, deadline)
            {
                Ok(both) => both,
                Err(failure) => return Ok(FrameFlow::End(SessionEnd::Panicked(failure))),
            },
        };
        let out = step_with_parts(&self.params, &self.state, &handle, &gathered.sums, &mine);
        let mut wrench = cx.limits.saturate(&out.device_wrench);
        let clamped = wrench != out.device_wrench;
        let watchdog_tripped = tick.started.elapsed() >= self.config.watchdog;
        if watchdog_tripped {
            wrench = Wrench::ZERO;
        }
        self.device.write(&wrench)?;
        cx.max_device_force = cx.max_device_force.max(wrench.force.length());
        self.state = out.next_state;
        if let Some(parts) = self.parts.as_mut() {
            parts.write(watchdog_tripped)?;
        }
        let compute_ns = u64::try_from(tick.started.elapsed().as_nanos()).unwrap_or(u64::MAX);
        let period_error_ns = (!self.config.free_running).then(|| tick.lateness_ns());
        cx.stats.record(&FrameRecord {
            compute_ns,
            period_error_ns,
            missed: tick.missed,
            watchdog_tripped,
            rejected_input: out.rejected_input,
            non_finite: out.non_finite,
            fallback_shares: gathered.fallback_shares,
            contact: out.contacts > 0,
            touching: out.touching,
            penetrating: out.penetrating,
            clamped,
        });
        if let Some(feed) = &self.feed {
            let c = cx.stats.counters();
            let (other_count, other_parts) = self.parts.as_ref().map_or(
                (0, [OtherPartFrame::default(); MAX_OTHER_PARTS]),
                RunningParts::feed_frames,
            );
            feed.publish(FeedFrame {
                frame: cx.frame,
                time,
                part: self.state,
                handle,
                device_wrench: wrench,
                contacts: out.contacts,
                touching: out.touching,
                penetrating: out.penetrating,
                missed_deadlines: c.missed_deadlines,
                watchdog_trips: c.watchdog_trips,
                penetrating_frames: c.penetrating_frames,
                touching_frames: c.touching_frames,
                compute_ns,
                recent_max_compute_ns: cx.recent_compute.record(compute_ns),
                period_error_ns: period_error_ns.unwrap_or(0),
                recent_max_period_error_ns: cx.recent_lateness.record(period_error_ns.unwrap_or(0)),
                other_count,
                other_parts,
            });
        }
        Ok(FrameFlow::Next)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::feed::state_feed;
    use glam::DQuat;
    use vps_device::{DeviceLimits, ReplayDevice};
    use vps_haptic::HandleSample;
    use vps_testkit::device::{LoggingDevice, Writes};
    use vps_testkit::hand::{approach_and_rest_on_wall, START};
    use vps_testkit::scene::{wall, ArmedWall, VOXEL, WALL_TOP};
    use vps_testkit::shell::{sphere_shell, SPHERE_RADIUS};
    use vps_voxmap::DenseGrid;

    fn hand() -> Box<dyn HapticDevice> {
        approach_and_rest_on_wall()
    }

    fn probe(inner: Box<dyn HapticDevice>) -> (LoggingDevice, Writes) {
        LoggingDevice::new(inner)
    }

    fn params() -> HapticParams {
        HapticParams::default()
            .with_scene(VOXEL, SPHERE_RADIUS)
            .unwrap()
    }

    /// Free-running, generous watchdog so that no frame is zeroed by a slow test machine.
    fn config(frames: u64, threads: usize) -> LoopConfig {
        LoopConfig {
            frames: Some(frames),
            threads,
            free_running: true,
            watchdog: Duration::from_secs(10),
            ..LoopConfig::default()
        }
    }

    /// A session's setup with the test parameters and the part at rest at [`START`].
    fn setup(
        device: Box<dyn HapticDevice>,
        config: LoopConfig,
        feed: Option<StateFeedSender>,
        stop: Arc<AtomicBool>,
    ) -> SessionSetup {
        SessionSetup {
            params: params(),
            device,
            initial: PartState::at_rest(START, DQuat::IDENTITY),
            config,
            feed,
            stop,
            parts: None,
        }
    }

    fn session(
        device: Box<dyn HapticDevice>,
        config: LoopConfig,
        classes: u32,
        feed: Option<StateFeedSender>,
    ) -> LoopReport {
        let map: Arc<DenseGrid> = Arc::new(wall());
        let shell = Arc::new(ClassedShell::new(&sphere_shell(400), classes));
        let stop = Arc::new(AtomicBool::new(false));
        run_loop(map, shell, setup(device, config, feed, stop)).unwrap()
    }

    #[test]
    fn a_hand_resting_on_a_wall_feels_bounded_contact_forces() {
        let (device, writes) = probe(hand());
        let (tx, mut rx) = state_feed();
        let report = session(Box::new(device), config(600, 2), 8, Some(tx));
        assert_eq!(report.end, SessionEnd::FramesDone);
        let s = &report.stats;
        assert_eq!(s.frames, 600);
        assert_eq!((s.missed_deadlines, s.watchdog_trips), (0, 0));
        assert!(
            s.contact_frames > 0 && s.touching_frames >= s.contact_frames,
            "{s:?}"
        );
        let writes = writes.lock().unwrap();
        assert_eq!(writes.len(), 601, "one per frame and the final release");
        assert!(writes.iter().all(|w| DeviceLimits::PAPER.admits(w)));
        assert!(
            writes.iter().any(|w| w.force.z > 0.1),
            "the wall must push the hand back up"
        );
        assert!(
            writes[..100].iter().all(|w| *w == Wrench::ZERO),
            "free space gives exactly zero"
        );
        assert_eq!(writes[600], Wrench::ZERO);
        let z = report.final_state.position.z;
        assert!(
            z > WALL_TOP + SPHERE_RADIUS - 2.0 * VOXEL && z < WALL_TOP + SPHERE_RADIUS + VOXEL,
            "z = {z}"
        );
        assert_eq!(rx.latest().map(|f| f.frame), Some(599));
    }

    #[test]
    fn any_thread_count_gives_the_identical_session() {
        let runs: Vec<(Vec<Wrench>, PartState)> = (1..=4)
            .map(|threads| {
                let (device, writes) = probe(hand());
                let report = session(Box::new(device), config(450, threads), 12, None);
                assert!(report.stats.contact_frames > 0);
                let w = writes.lock().unwrap().clone();
                (w, report.final_state)
            })
            .collect();
        for (threads, run) in runs.iter().enumerate().skip(1) {
            assert!(
                run.0 == runs[0].0,
                "device writes differ with {} threads",
                threads + 1
            );
            assert!(
                run.1 == runs[0].1,
                "final state differs with {} threads",
                threads + 1
            );
        }
    }

    #[test]
    fn a_recorded_session_replays_identically() {
        let (device, first) = probe(hand());
        let report = session(
            Box::new(device),
            LoopConfig {
                record_trace: true,
                ..config(400, 1)
            },
            4,
            None,
        );
        let trace = report.trace.expect("trace requested");
        assert_eq!(trace.frames.len(), 400);
        let (replay, second) = probe(Box::new(ReplayDevice::new(trace, DeviceLimits::PAPER)));
        let again = session(Box::new(replay), config(500, 3), 4, None);
        // The replay runs out after 400 frames: a clean device error, not a hang.
        assert!(matches!(
            again.device_error,
            Some(DeviceError::TraceExhausted { frames: 400, .. })
        ));
        assert_eq!(again.stats.frames, 400);
        assert!(*first.lock().unwrap() == *second.lock().unwrap());
        assert_eq!(again.final_state, report.final_state);
    }

    #[test]
    fn device_errors_end_the_session_after_a_zero_wrench() {
        let (mut device, writes) = probe(hand());
        device.fail_read_at = Some(20);
        let r = session(Box::new(device), config(100, 2), 4, None);
        assert!(matches!(r.end, SessionEnd::DeviceFailed(ref m) if m.contains("unplugged")));
        assert_eq!(r.stats.frames, 20);
        assert_eq!(writes.lock().unwrap().last(), Some(&Wrench::ZERO));

        let (mut device, writes) = probe(hand());
        device.fail_write_at = Some(5);
        let r = session(Box::new(device), config(100, 1), 4, None);
        assert!(matches!(r.device_error, Some(DeviceError::Hardware { .. })));
        assert_eq!(r.stats.frames, 5);
        let writes = writes.lock().unwrap();
        assert_eq!(
            writes.len(),
            7,
            "five frames, the failed write, the release"
        );
        assert_eq!(writes[6], Wrench::ZERO);
    }

    #[test]
    fn an_exhausted_watchdog_budget_zeroes_every_output() {
        let (device, writes) = probe(hand());
        let cfg = LoopConfig {
            watchdog: Duration::ZERO,
            ..config(500, 2)
        };
        let r = session(Box::new(device), cfg, 4, None);
        assert_eq!(r.stats.watchdog_trips, 500);
        assert!(
            r.stats.touching_frames > 0,
            "the part still moves and touches"
        );
        assert!(writes.lock().unwrap().iter().all(|w| *w == Wrench::ZERO));
    }

    #[test]
    fn the_stop_flag_ends_an_open_ended_session() {
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, mut rx) = state_feed();
        let cfg = LoopConfig {
            frames: None,
            ..config(0, 2)
        };
        let shell = Arc::new(ClassedShell::new(&sphere_shell(100), 4));
        let h = spawn_loop(
            Arc::new(wall()),
            shell,
            setup(hand(), cfg, Some(tx), stop.clone()),
        )
        .unwrap();
        while rx.latest().is_none_or(|f| f.frame < 50) {
            std::thread::yield_now();
        }
        stop.store(true, Ordering::Relaxed);
        let r = h.join().unwrap();
        assert_eq!(r.end, SessionEnd::Stopped);
        assert!(r.stats.frames > 50);
    }

    #[test]
    fn a_paced_session_runs_its_frames() {
        let cfg = LoopConfig {
            free_running: false,
            watchdog: Duration::from_secs(10),
            ..config(20, 2)
        };
        let r = session(hand(), cfg, 4, None);
        assert_eq!(r.end, SessionEnd::FramesDone);
        assert_eq!(r.stats.frames, 20);
        assert!(
            r.stats.period_error_ns.max > 0,
            "period errors are recorded when paced"
        );
    }

    #[test]
    fn a_panic_in_the_frame_ends_the_session_after_a_zero_wrench() {
        let (mut device, writes) = probe(hand());
        device.panic_read_at = Some(300);
        let r = session(Box::new(device), config(600, 2), 4, None);
        assert!(
            matches!(r.end, SessionEnd::Panicked(ref m) if m.contains("a bug in the driver") && m.contains("frame 300")),
            "{:?}",
            r.end
        );
        assert!(!r.end.is_complete());
        assert_eq!(r.stats.frames, 300);
        let writes = writes.lock().unwrap();
        assert_eq!(writes.len(), 301, "300 frames and the release");
        assert!(
            writes[..300].iter().any(|w| *w != Wrench::ZERO),
            "the hand was pressing the wall before the panic"
        );
        assert_eq!(writes[300], Wrench::ZERO);
    }

    /// The wall, except that once armed a lookup on the pool thread `vps-pool-1` panics and one
    /// on the frame thread is slowed down (so that the pool threads get classes to compute).
    fn panics_on_pool_thread() -> ArmedWall<(), impl Fn(&()) + Sync> {
        ArmedWall::new((), |_: &()| match std::thread::current().name() {
            Some("vps-pool-1") => panic!("lookup failed on a pool thread"),
            Some("vps-frame") => std::thread::sleep(Duration::from_micros(20)),
            _ => {}
        })
    }

    #[test]
    fn a_panic_on_a_pool_thread_ends_the_session_after_a_zero_wrench() {
        let map = Arc::new(panics_on_pool_thread());
        let (device, writes) = probe(hand());
        let stop = Arc::new(AtomicBool::new(false));
        let (tx, mut rx) = state_feed();
        let cfg = LoopConfig {
            frames: None,
            ..config(0, 3)
        };
        let h = spawn_loop(
            map.clone(),
            Arc::new(ClassedShell::new(&sphere_shell(400), 64)),
            setup(Box::new(device), cfg, Some(tx), stop.clone()),
        )
        .unwrap();
        while rx.latest().is_none_or(|f| f.frame < 20) {
            std::thread::yield_now();
        }
        map.armed.store(true, Ordering::Release);
        // The pool thread takes a class within a few frames; the session must end by itself. The
        // stop flag is a backstop so that a failing test does not hang.
        let backstop = std::time::Instant::now() + Duration::from_secs(60);
        while !h.is_finished() && std::time::Instant::now() < backstop {
            std::thread::sleep(Duration::from_millis(1));
        }
        stop.store(true, Ordering::Relaxed);
        let r = h.join().unwrap();
        assert!(
            matches!(r.end, SessionEnd::Panicked(ref m) if m.contains("vps-pool-1") && m.contains("lookup failed")),
            "{:?}",
            r.end
        );
        assert_eq!(writes.lock().unwrap().last(), Some(&Wrench::ZERO));
    }

    #[test]
    fn the_stop_flag_ends_the_session_with_a_zero_wrench_last() {
        let (device, writes) = probe(hand());
        let stop = Arc::new(AtomicBool::new(true));
        let r = run_loop(
            Arc::new(wall()),
            Arc::new(ClassedShell::new(&sphere_shell(100), 4)),
            setup(Box::new(device), config(100, 1), None, stop),
        )
        .unwrap();
        assert_eq!(r.end, SessionEnd::Stopped);
        assert_eq!(r.stats.frames, 0);
        assert_eq!(*writes.lock().unwrap(), vec![Wrench::ZERO]);
    }

    #[test]
    fn rejected_handle_samples_are_counted_as_zeroed_frames() {
        /// A hand whose samples are absurd (10 km away) from frame 100 to 249.
        struct Absurd(Box<dyn HapticDevice>, u64);
        impl HapticDevice for Absurd {
            fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError> {
                let mut s = self.0.read(t)?;
                self.1 += 1;
                if (101..=250).contains(&self.1) {
                    s.position.x = 1.0e4;
                }
                Ok(s)
            }
            fn write(&mut self, w: &Wrench) -> Result<(), DeviceError> {
                self.0.write(w)
            }
            fn limits(&self) -> DeviceLimits {
                self.0.limits()
            }
            fn name(&self) -> &str {
                "absurd"
            }
        }
        let r = session(Box::new(Absurd(hand(), 0)), config(400, 1), 4, None);
        assert_eq!(r.end, SessionEnd::FramesDone);
        assert_eq!(r.stats.rejected_input_frames, 150);
        assert_eq!(r.stats.zeroed_frames, 150);
        assert_eq!(r.stats.non_finite_frames, 0);
    }

    #[test]
    fn bad_configs_are_refused_before_starting() {
        let run = |cfg: LoopConfig| {
            let shell = Arc::new(ClassedShell::new(&sphere_shell(10), 1));
            run_loop(
                Arc::new(wall()),
                shell,
                setup(hand(), cfg, None, Arc::new(AtomicBool::new(false))),
            )
        };
        let period = LoopConfig {
            period: Duration::from_micros(500),
            ..LoopConfig::default()
        };
        let threads = LoopConfig {
            threads: 0,
            ..LoopConfig::default()
        };
        for (cfg, named) in [(period, "period"), (threads, "threads")] {
            let e = run(cfg).unwrap_err();
            assert!(
                matches!(e, RuntimeError::Config { field, .. } if field == named),
                "{e}"
            );
        }
    }

    /// Two spheres of 30 mm starting 20 mm apart along x, both hands on the same motion onto the
    /// wall (so the second is pulled into the first), `frames` frames; the second device fails
    /// its read `fail_read_at` when given. Returns the report and both write logs.
    fn two_spheres(frames: u64, fail_read_at: Option<u64>) -> (LoopReport, [Writes; 2]) {
        two_spheres_feeding(frames, fail_read_at, None)
    }

    /// [`two_spheres`], publishing every frame to `feed` when given.
    fn two_spheres_feeding(
        frames: u64,
        fail_read_at: Option<u64>,
        feed: Option<crate::feed::StateFeedSender>,
    ) -> (LoopReport, [Writes; 2]) {
        use crate::parts::{MovingPart, PartBody, PartsSetup};
        let shell = Arc::new(ClassedShell::new(&sphere_shell(300), 8));
        let map = Arc::new(wall());
        let body = PartBody {
            map: map.clone(),
            shell: shell.clone(),
            radius: SPHERE_RADIUS,
        };
        let (first, a) = LoggingDevice::new(approach_and_rest_on_wall());
        let (mut second, b) = LoggingDevice::new(approach_and_rest_on_wall());
        second.fail_read_at = fail_read_at;
        let config = LoopConfig {
            frames: Some(frames),
            free_running: true,
            watchdog: Duration::from_secs(10),
            ..LoopConfig::default()
        };
        let setup = SessionSetup {
            params: params(),
            device: Box::new(first),
            initial: PartState::at_rest(START, DQuat::IDENTITY),
            config,
            feed,
            stop: Arc::new(AtomicBool::new(false)),
            parts: Some(PartsSetup {
                first: body.clone(),
                others: vec![MovingPart {
                    name: "second".into(),
                    params: params(),
                    device: Box::new(second),
                    // The same hand motion: the second part is pulled onto the first.
                    initial: PartState::at_rest(START + glam::DVec3::X * 0.02, DQuat::IDENTITY),
                    sampler: Box::new(ClassPool::new(map, shell, 1).unwrap()),
                    body,
                }],
                margin: 2.0 * VOXEL,
            }),
        };
        let report = run_loop(
            Arc::new(wall()),
            setup.parts.as_ref().unwrap().first.shell.clone(),
            setup,
        )
        .unwrap();
        (report, [a, b])
    }

    /// The state feed carries the other part as its device saw it: the last frame's pose is the
    /// report's final state, its handle the device's last reading, and its wrench the last one
    /// written to that device before the release (non-zero: the part is pressed into the wall).
    #[test]
    fn the_feed_carries_each_other_part_s_pose_handle_and_device_wrench() {
        let (sender, mut receiver) = crate::feed::state_feed();
        let (report, writes) = two_spheres_feeding(300, None, Some(sender));
        let last = receiver.latest().expect("the loop published");
        assert_eq!(last.frame, 299);
        assert_eq!(last.others().len(), 1);
        let other = last.others()[0];
        let second = &report.other_parts[0];
        assert_eq!(other.part.position, second.final_state.position);
        assert_eq!(other.part.orientation, second.final_state.orientation);
        let handle = second.final_handle.expect("the second device was read");
        assert_eq!(other.handle.position, handle.position);
        assert_eq!(other.handle.orientation, handle.orientation);
        let written = writes[1].lock().unwrap();
        assert_eq!(other.device_wrench, written[written.len() - 2]);
        assert_ne!(other.device_wrench, Wrench::ZERO);
        assert_ne!(
            other.device_wrench, last.device_wrench,
            "the second part's own"
        );
    }

    /// Every part's device gets one wrench per frame and the exact zero wrench last, whether the
    /// session ran its frames or another part's device failed mid-session.
    #[test]
    fn every_device_is_released_with_an_exact_zero_however_the_session_ends() {
        let (report, writes) = two_spheres(300, None);
        assert_eq!(report.end, SessionEnd::FramesDone);
        assert_eq!(report.other_parts[0].wrenches_written, 300);
        assert!(report.pairs.sampled > 0, "{:?}", report.pairs);
        for w in &writes {
            let w = w.lock().unwrap();
            assert_eq!(w.len(), 301, "one per frame and the release");
            assert_eq!(w.last(), Some(&Wrench::ZERO));
        }
        let (report, writes) = two_spheres(300, Some(120));
        assert!(
            matches!(report.end, SessionEnd::DeviceFailed(_)),
            "{:?}",
            report.end
        );
        for w in &writes {
            assert_eq!(w.lock().unwrap().last(), Some(&Wrench::ZERO));
        }
    }
}
