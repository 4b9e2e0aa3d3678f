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
//! Not here yet: pair points split over cluster workers (a cluster session's other parts sample
//! the static scene on local threads and their pairs on the frame thread).

use crate::feed::{PartPose, MAX_OTHER_PARTS};
use crate::pool::FrameSampler;
use crate::recording::TraceRecording;
use crate::RuntimeError;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;
use std::time::Instant;
use vps_device::trace::{Trace, TraceRecorder};
use vps_device::{DeviceError, DeviceLimits, HapticDevice};
use vps_haptic::pair::{BodyVoxmap, PairCounts, PairPart, PairPass};
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

/// The other parts of a running session, their bodies and the pair pass.
pub(crate) struct RunningParts {
    first: PartBody,
    others: Vec<RunningPart>,
    margin: f64,
    pass: PairPass,
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
                report,
                part,
            });
        }
        Ok(RunningParts {
            pass: PairPass::new(others.len() + 1),
            first: setup.first,
            others,
            margin: setup.margin,
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

    /// Every other part's static sums and step, and every pair's wrenches: returns the first
    /// part's pair wrench; the other parts' next states and device wrenches wait in `next` for
    /// [`RunningParts::write`]. Errs with a sampler's failure. Does not allocate; blocks only as
    /// the samplers do (up to `deadline`).
    pub(crate) fn sample(
        &mut self,
        first: &PartState,
        first_params: &HapticParams,
        deadline: Instant,
    ) -> Result<OtherParts, String> {
        for o in &mut self.others {
            let pose = KernelPose::from_state(&o.state);
            o.sums = o.part.sampler.compute(&pose, deadline).sums;
            if let Some(failure) = o.part.sampler.failure() {
                return Err(format!("part '{}': {failure}", o.part.name));
            }
        }
        let (firsts, others) = (&self.first, &self.others);
        self.pass.run(
            others.len() + 1,
            |k| match k {
                0 => firsts.pair_part(first, first_params),
                k => {
                    let o = &others[k - 1];
                    o.part.body.pair_part(&o.state, &o.part.params)
                }
            },
            self.margin,
        );
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
        Ok(self.pass.others[0])
    }

    /// The other parts' poses for the state feed: their count and the poses (the rest default).
    /// Does not allocate.
    pub(crate) fn poses(&self) -> (u32, [PartPose; MAX_OTHER_PARTS]) {
        let mut poses = [PartPose::default(); MAX_OTHER_PARTS];
        for (pose, o) in poses.iter_mut().zip(&self.others) {
            *pose = PartPose {
                position: o.state.position,
                orientation: o.state.orientation,
            };
        }
        (self.others.len().min(MAX_OTHER_PARTS) as u32, poses)
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
