//! Several moving parts in one session: every part's device, state and static sums, and the
//! part-against-part wrenches of every pair that may touch, in one frame.
//!
//! The session's first part is the loop's own (its device, sampler and state as in a one-part
//! session); [`PartsSetup`] adds the others ([`MovingPart`], each with its own device, parameters
//! and static sampler) and every part's [`PartBody`] (its voxmap in its own body frame, its
//! shell, its bounding radius). Per frame, after every part's static sums, the pair pass
//! visits the pairs `(i, j)`, `i < j`, in a fixed order; a pair whose bounding spheres (grown
//! by the margin) do not overlap ([`vps_haptic::pair::may_touch`]) is skipped and costs nothing;
//! the others are sampled both ways on the frame thread and their wrenches
//! ([`vps_haptic::pair::pair_wrenches`], with the lower-numbered part's parameters) are summed per
//! part into [`OtherParts`], which [`vps_haptic::step_with_parts`] adds to each part's frame.
//! The two forces of a pair are exact negations of each other.
//!
//! The pair pass itself is sans-IO (`vps_haptic::pair::PairPass`, with the [`BodyVoxmap`] trait
//! and [`PairCounts`]). The loop holds the parts as `RunningParts` (each part's device, state,
//! sums and counters, and the pair pass): read every device, sample, step, write every device,
//! release every device with the exact zero wrench at the end.
//!
//! A frame's sampling is a list of jobs ([`vps_haptic::job`]): the first part in the static
//! scene, every other part in it, then both directions of every pair the broad phase keeps.
//! A sampler that takes jobs ([`FrameSampler::compute_jobs`], the cluster's gatherer) computes
//! them all, split over its workers; otherwise the loop's own pool samples the first job, each
//! other part's pool its own, and the pairs are sampled on the frame thread. The sums are exact
//! integers either way, so every part's wrench is the same bits whoever sampled what.

use crate::feed::{OtherPartFrame, PartPose, MAX_OTHER_PARTS};
use crate::pool::{FrameSampler, PoolResult};
use crate::recording::TraceRecording;
use crate::RuntimeError;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use std::time::Instant;
use vps_device::trace::{Trace, TraceRecorder};
use vps_device::{DeviceError, DeviceLimits, HapticDevice};
use vps_haptic::job::{body_map, JobTarget, SampleJob, MAX_JOBS, SCENE_MAP};
use vps_haptic::pair::{pose_in, BodyVoxmap, PairCounts, PairPart, PairPass, PairSums};
use vps_haptic::{
    step_with_parts, ClassedShell, HandleSample, HapticParams, KernelPose, OtherParts, PartState,
    PartialSums, Wrench,
};

/// What part-against-part contact needs of a part: its voxmap in its body frame (origin at its
/// grip, the frame of its shell), its shell, and the radius of a sphere about its origin holding
/// both (m).
#[derive(Clone)]
pub struct PartBody {
    /// The part's own voxmap in its body frame.
    pub map: Arc<dyn BodyVoxmap>,
    /// The part's point shell in its body frame.
    pub shell: Arc<ClassedShell>,
    /// Radius about the origin holding the part's mesh and shell (m, finite, ≥ 0).
    pub radius: f64,
}

impl PartBody {
    /// This body as the pair pass sees it, at `state` with `params`.
    pub fn pair_part<'a>(&'a self, state: &'a PartState, params: &'a HapticParams) -> PairPart<'a> {
        PairPart {
            state,
            params,
            map: &*self.map,
            shell: &self.shell,
            radius: self.radius,
        }
    }
}

/// A moving part besides the session's first: its own device (read and written every frame),
/// parameters, state and static sampler.
pub struct MovingPart {
    /// The part's name in reports.
    pub name: String,
    /// Its haptic parameters (validated when the session starts).
    pub params: HapticParams,
    /// Its device.
    pub device: Box<dyn HapticDevice>,
    /// Its state at the first frame.
    pub initial: PartState,
    /// Its shell's sums in the static scene.
    pub sampler: Box<dyn FrameSampler>,
    /// Its body, for the pairs.
    pub body: PartBody,
}

/// The other parts of a session and every part's body (the first part's is `first`).
pub struct PartsSetup {
    /// The session's first part's body.
    pub first: PartBody,
    /// The other parts, in the scene file's order (part 1, 2, …).
    pub others: Vec<MovingPart>,
    /// How far apart (m) two bounding spheres may be and still be sampled: the force layer's
    /// reach beyond a surface (≥ 0, finite).
    pub margin: f64,
}

/// What became of one of the other parts (the first part's figures are the loop's own).
#[derive(Clone, Debug, serde::Serialize)]
pub struct PartReport {
    /// The part's name.
    pub name: String,
    /// Its device's name.
    pub device_name: String,
    /// Its state after the last frame.
    pub final_state: PartState,
    /// The handle its device gave in the last frame.
    pub final_handle: Option<HandleSample>,
    /// Wrenches written to its device (the final zero not counted).
    pub wrenches_written: u64,
    /// Frames whose wrench was clamped to its device's limits.
    pub clamped_frames: u64,
    /// Frames whose step gave a non-finite value (the part held, the device sent zero).
    pub non_finite_frames: u64,
    /// Frames its handle sample was rejected.
    pub rejected_frames: u64,
    /// Largest force magnitude written to its device (N).
    pub max_device_force: f64,
    /// Frames where a pair it belongs to had a point in a non-Free voxel.
    pub pair_contact_frames: u64,
    /// Its contact wrench from the other parts in the last frame (N, N·m about its origin).
    pub last_pair_wrench: Wrench,
    /// Its device's own counters, read after the last write.
    pub device_counters: Option<serde_json::Value>,
    /// Its handle trace, when the session recorded traces (`LoopConfig::record_trace`), with
    /// where it started; frame `k` of every part's trace was read in the same frame.
    #[serde(skip)]
    pub trace: Option<Trace>,
    /// Why its trace recording stopped early, if it did.
    #[serde(skip)]
    pub trace_error: Option<String>,
}

/// Part `k` of a running session as the pair pass sees it (0 the first part, at `first` with
/// `first_params`; `k` the `k`-th of `others`).
fn pair_parts<'a>(
    first_body: &'a PartBody,
    others: &'a [RunningPart],
    first: &'a PartState,
    first_params: &'a HapticParams,
) -> impl Fn(usize) -> PairPart<'a> {
    move |k| match k {
        0 => first_body.pair_part(first, first_params),
        k => {
            let o = &others[k - 1];
            o.part.body.pair_part(&o.state, &o.part.params)
        }
    }
}

/// The other parts of a running session, their bodies and the pair pass.
pub(crate) struct RunningParts {
    first: PartBody,
    others: Vec<RunningPart>,
    margin: f64,
    pass: PairPass,
    /// This frame's sampling jobs (see the module docs) and their sums.
    jobs: Vec<SampleJob>,
    job_sums: Vec<PartialSums>,
    /// Scratch: the sums of this frame's pairs, in the broad phase's order.
    pair_sums: Vec<PairSums>,
}

/// One of the other parts while the session runs.
struct RunningPart {
    part: MovingPart,
    state: PartState,
    limits: DeviceLimits,
    handle: Option<HandleSample>,
    sums: PartialSums,
    /// This frame's next state and device wrench (saturated), written after every part's step.
    next: Option<(PartState, Wrench)>,
    /// The wrench last written to its device (zero before the first write).
    written: Wrench,
    recorder: Option<TraceRecorder>,
    report: PartReport,
}

impl RunningParts {
    /// Validates every part's parameters (`loop_accepts`: the loop's own check of a part's
    /// parameters, its period) and the margin; `recording`: record every other part's handle
    /// trace too. Allocates; setup-time only.
    pub(crate) fn new(
        setup: PartsSetup,
        loop_accepts: impl Fn(&HapticParams) -> Result<(), RuntimeError>,
        recording: Option<TraceRecording>,
    ) -> Result<RunningParts, RuntimeError> {
        if !(setup.margin.is_finite() && setup.margin >= 0.0) {
            return Err(RuntimeError::Config {
                field: "parts.margin",
                message: format!("{} m: must be finite and ≥ 0", setup.margin),
            });
        }
        let bodies = std::iter::once(&setup.first).chain(setup.others.iter().map(|o| &o.body));
        if let Some(bad) = bodies
            .map(|b| b.radius)
            .find(|r| !(r.is_finite() && *r >= 0.0))
        {
            return Err(RuntimeError::Config {
                field: "parts.radius",
                message: format!("{bad} m: a part's radius must be finite and ≥ 0"),
            });
        }
        if setup.others.len() > MAX_OTHER_PARTS {
            return Err(RuntimeError::Config {
                field: "parts.others",
                message: format!(
                    "{} other parts; at most {MAX_OTHER_PARTS} are allowed",
                    setup.others.len()
                ),
            });
        }
        let mut others = Vec::with_capacity(setup.others.len());
        for part in setup.others {
            part.params
                .validate(&format!("haptic parameters of part '{}'", part.name))?;
            loop_accepts(&part.params)?;
            let report = PartReport {
                name: part.name.clone(),
                device_name: part.device.name().to_string(),
                final_state: part.initial,
                final_handle: None,
                wrenches_written: 0,
                clamped_frames: 0,
                non_finite_frames: 0,
                rejected_frames: 0,
                max_device_force: 0.0,
                pair_contact_frames: 0,
                last_pair_wrench: Wrench::ZERO,
                device_counters: None,
                trace: None,
                trace_error: None,
            };
            let recorder = recording.map(|r| r.recorder(part.device.name(), &part.initial));
            others.push(RunningPart {
                recorder,
                limits: part.device.limits(),
                state: part.initial,
                handle: None,
                sums: PartialSums::default(),
                next: None,
                written: Wrench::ZERO,
                report,
                part,
            });
        }
        let parts = others.len() + 1;
        let pairs = parts * (parts - 1) / 2;
        Ok(RunningParts {
            pass: PairPass::new(parts),
            first: setup.first,
            others,
            margin: setup.margin,
            jobs: Vec::with_capacity(MAX_JOBS),
            job_sums: vec![PartialSums::default(); MAX_JOBS],
            pair_sums: Vec::with_capacity(pairs),
        })
    }

    /// Reads every other part's device at `time` (s) for frame `frame`, and records the sample
    /// when recording. Blocks as the devices do; allocates only past the recorders' reserve.
    pub(crate) fn read(&mut self, frame: u64, time: f64) -> Result<(), DeviceError> {
        for o in &mut self.others {
            let handle = o.part.device.read(time)?;
            o.handle = Some(handle);
            if let Some(rec) = o.recorder.as_mut() {
                if let Err(e) = rec.record(frame, time, handle) {
                    o.report.trace_error = Some(e.to_string());
                    o.recorder = None;
                }
            }
        }
        Ok(())
    }

    /// Writes the exact zero wrench to every other part's device, whatever happens (a failure or
    /// a panic of one device does not keep the others from theirs).
    pub(crate) fn release(&mut self) {
        for o in &mut self.others {
            let _ = catch_unwind(AssertUnwindSafe(|| o.part.device.write(&Wrench::ZERO)));
        }
    }

    /// This frame's sampling: every job (see the module docs) on `sampler` when it takes jobs,
    /// else the first on `sampler`, every other part's on its own pool and the pairs on this
    /// thread; then every other part's step. Returns the first part's sums (with the shares
    /// computed as fallback) and its pair wrench; the other parts' next states and device
    /// wrenches wait in `next` for [`RunningParts::write`]. Errs with a sampler's failure. Does
    /// not allocate; blocks only as the samplers do (up to `deadline`).
    pub(crate) fn sample(
        &mut self,
        sampler: &mut dyn FrameSampler,
        first: &PartState,
        first_params: &HapticParams,
        deadline: Instant,
    ) -> Result<(PoolResult, OtherParts), String> {
        self.plan_jobs(first, first_params);
        let fallback_shares = match sampler.compute_jobs(&self.jobs, deadline, &mut self.job_sums) {
            Some(fallback_shares) => fallback_shares,
            None => {
                let first = sampler.compute(&self.jobs[0].pose, deadline);
                self.job_sums[0] = first.sums;
                self.sample_locally(deadline);
                first.fallback_shares
            }
        };
        if let Some(failure) = sampler.failure() {
            return Err(failure);
        }
        for o in &self.others {
            if let Some(failure) = o.part.sampler.failure() {
                return Err(format!("part '{}': {failure}", o.part.name));
            }
        }
        let others_count = self.others.len();
        for (o, sums) in self.others.iter_mut().zip(&self.job_sums[1..]) {
            o.sums = *sums;
        }
        self.pair_sums.clear();
        let pair_jobs = &self.job_sums[1 + others_count..self.jobs.len()];
        self.pair_sums
            .extend(pair_jobs.chunks_exact(2).map(|two| PairSums {
                a_in_b: two[0],
                b_in_a: two[1],
            }));
        let part = pair_parts(&self.first, &self.others, first, first_params);
        self.pass.apply(part, &self.pair_sums);
        for (o, with) in self.others.iter_mut().zip(&self.pass.others[1..]) {
            let Some(handle) = o.handle else { continue };
            let out = step_with_parts(&o.part.params, &o.state, &handle, &o.sums, with);
            let wrench = o.limits.saturate(&out.device_wrench);
            let r = &mut o.report;
            r.clamped_frames += u64::from(wrench != out.device_wrench);
            r.non_finite_frames += u64::from(out.non_finite);
            r.rejected_frames += u64::from(out.rejected_input);
            r.last_pair_wrench = with.wrench;
            o.next = Some((out.next_state, wrench));
        }
        let first_sums = PoolResult {
            sums: self.job_sums[0],
            fallback_shares,
        };
        Ok((first_sums, self.pass.others[0]))
    }

    /// Lists this frame's jobs in `self.jobs`: the first part in the scene, each other part in
    /// it, then for each pair `(i, j)` the broad phase keeps, `i`'s shell in `j`'s body voxmap
    /// and `j`'s in `i`'s. Does not allocate (at most [`MAX_JOBS`] jobs: 8 parts).
    fn plan_jobs(&mut self, first: &PartState, first_params: &HapticParams) {
        self.jobs.clear();
        let scene_job = |shell: usize, state: &PartState| SampleJob {
            target: JobTarget {
                shell: shell as u8,
                map: SCENE_MAP,
            },
            pose: KernelPose::from_state(state),
        };
        self.jobs.push(scene_job(0, first));
        for (k, o) in self.others.iter().enumerate() {
            self.jobs.push(scene_job(k + 1, &o.state));
        }
        let others = &self.others;
        let state = |k: usize| if k == 0 { first } else { &others[k - 1].state };
        let part = pair_parts(&self.first, others, first, first_params);
        for &(i, j) in self.pass.broad_phase(others.len() + 1, part, self.margin) {
            for (a, b) in [(i, j), (j, i)] {
                self.jobs.push(SampleJob {
                    target: JobTarget {
                        shell: a as u8,
                        map: body_map(b as u8),
                    },
                    pose: pose_in(state(a), state(b)),
                });
            }
        }
    }

    /// Samples jobs 1.. locally: each other part in the scene on its own pool, the pairs on this
    /// thread. Does not allocate; blocks as the pools do (up to `deadline`).
    fn sample_locally(&mut self, deadline: Instant) {
        for (job, sums) in self.jobs.iter().zip(self.job_sums.iter_mut()).skip(1) {
            let JobTarget { shell, map } = job.target;
            let shell = usize::from(shell);
            *sums = if map == SCENE_MAP {
                self.others[shell - 1]
                    .part
                    .sampler
                    .compute(&job.pose, deadline)
                    .sums
            } else {
                let body = |k: usize| {
                    if k == 0 {
                        &self.first
                    } else {
                        &self.others[k - 1].part.body
                    }
                };
                let owner = usize::from(map - 1);
                body(owner).map.sample(&body(shell).shell, &job.pose)
            };
        }
    }

    /// The other parts for the state feed: their count and each one's pose, handle and last
    /// device wrench (the rest default). Call after [`RunningParts::write`]. Does not allocate.
    pub(crate) fn feed_frames(&self) -> (u32, [OtherPartFrame; MAX_OTHER_PARTS]) {
        let mut frames = [OtherPartFrame::default(); MAX_OTHER_PARTS];
        for (frame, o) in frames.iter_mut().zip(&self.others) {
            let part = PartPose {
                position: o.state.position,
                orientation: o.state.orientation,
            };
            *frame = OtherPartFrame {
                part,
                handle: o.handle.map_or(part, |h| PartPose {
                    position: h.position,
                    orientation: h.orientation,
                }),
                device_wrench: o.written,
            };
        }
        (self.others.len().min(MAX_OTHER_PARTS) as u32, frames)
    }

    /// Writes every other part's device (zero when the watchdog tripped) and advances its state.
    pub(crate) fn write(&mut self, watchdog_tripped: bool) -> Result<(), DeviceError> {
        for o in &mut self.others {
            let Some((next, wrench)) = o.next.take() else {
                continue;
            };
            let wrench = if watchdog_tripped {
                Wrench::ZERO
            } else {
                wrench
            };
            o.part.device.write(&wrench)?;
            o.written = wrench;
            o.state = next;
            let r = &mut o.report;
            r.wrenches_written += 1;
            r.max_device_force = r.max_device_force.max(wrench.force.length());
        }
        Ok(())
    }

    /// The other parts' reports, the pair counts, and the first part's last pair wrench and pair
    /// contact frames. Reads each device's counters.
    pub(crate) fn finish(mut self) -> (Vec<PartReport>, PairCounts, Wrench, u64) {
        let contact = self.pass.contact_frames.clone();
        let reports = self
            .others
            .iter_mut()
            .zip(contact.iter().skip(1))
            .map(|(o, &frames)| {
                let mut r = o.report.clone();
                r.final_state = o.state;
                r.final_handle = o.handle;
                r.pair_contact_frames = frames;
                r.device_counters = catch_unwind(AssertUnwindSafe(|| o.part.device.counters()))
                    .ok()
                    .flatten();
                r.trace = o.recorder.take().map(TraceRecorder::finish);
                r
            })
            .collect();
        (
            reports,
            self.pass.counts,
            self.pass.others[0].wrench,
            contact[0],
        )
    }
}
