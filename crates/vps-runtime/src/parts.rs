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
//! Not here yet: pair points split over cluster workers (a cluster session's other parts sample
//! the static scene on local threads and their pairs on the frame thread), pre-contact braking
//! between parts.

use crate::pool::FrameSampler;
use std::sync::Arc;
use vps_device::HapticDevice;
use vps_haptic::pair::{may_touch, pair_wrenches, pose_in, PairSums};
use vps_haptic::{
    sample_all, ClassedShell, HandleSample, HapticParams, KernelPose, OtherParts, PartState,
    PartialSums, Wrench,
};
use vps_voxmap::VoxelLookup;

/// A voxmap a part carries in its own body frame, sampled by another part's shell. Blanket
/// implemented for every [`VoxelLookup`] (a `VoxelTree` in sessions, a `DenseGrid` in tests).
pub trait BodyVoxmap: Send + Sync {
    /// The merged sums of every class of `shell` at `pose` (in this voxmap's frame). Does not
    /// allocate or block.
    fn sample(&self, shell: &ClassedShell, pose: &KernelPose) -> PartialSums;
}

impl<L: VoxelLookup + Send + Sync> BodyVoxmap for L {
    fn sample(&self, shell: &ClassedShell, pose: &KernelPose) -> PartialSums {
        sample_all(self, shell, pose)
    }
}

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
}

/// The pairs of a session, counted.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PairCounts {
    /// Pairs sampled (both ways) over the session, after the broad phase.
    pub sampled: u64,
    /// Pairs the broad phase skipped.
    pub skipped: u64,
    /// Frames where some pair had a point in a non-Free voxel.
    pub contact_frames: u64,
}

/// One frame's pair work: every part's [`OtherParts`] (index 0 the first part), written in place.
pub(crate) struct PairPass {
    /// Per part, this frame's pair wrench sum and nearness.
    pub(crate) others: Vec<OtherParts>,
    /// The session's counts.
    pub(crate) counts: PairCounts,
    /// Per part, frames in contact with another part.
    pub(crate) contact_frames: Vec<u64>,
}

impl PairPass {
    /// A pass for `parts` parts. Allocates; setup-time only.
    pub(crate) fn new(parts: usize) -> PairPass {
        PairPass {
            others: vec![OtherParts::NONE; parts],
            counts: PairCounts::default(),
            contact_frames: vec![0; parts],
        }
    }

    /// Samples every pair of the `count` parts (`part(k)`: state, body, parameters; 0 the first) that
    /// may touch, and leaves each part's summed pair wrench in `self.others`. Pairs are visited
    /// in the order (0,1), (0,2), …, (1,2), …, so the sums are the same every run. Does not
    /// allocate or block.
    pub(crate) fn run<'a>(
        &mut self,
        count: usize,
        part: impl Fn(usize) -> (&'a PartState, &'a PartBody, &'a HapticParams),
        margin: f64,
    ) {
        self.others.iter_mut().for_each(|o| *o = OtherParts::NONE);
        let mut any_contact = false;
        for i in 0..count {
            for j in i + 1..count {
                let ((a, body_a, params), (b, body_b, _)) = (part(i), part(j));
                if !may_touch(a, body_a.radius, b, body_b.radius, margin) {
                    self.counts.skipped += 1;
                    continue;
                }
                self.counts.sampled += 1;
                let sums = PairSums {
                    a_in_b: body_b.map.sample(&body_a.shell, &pose_in(a, b)),
                    b_in_a: body_a.map.sample(&body_b.shell, &pose_in(b, a)),
                };
                let near = sums.a_in_b.non_free > 0 || sums.b_in_a.non_free > 0;
                if !near {
                    continue;
                }
                any_contact = true;
                let w = pair_wrenches(params, &params.gains(), a, b, &sums);
                for (k, on) in [(i, w.on_a), (j, w.on_b)] {
                    let o = &mut self.others[k];
                    o.wrench.force += on.force;
                    o.wrench.torque += on.torque;
                    o.near = true;
                }
            }
        }
        for (o, frames) in self.others.iter().zip(&mut self.contact_frames) {
            *frames += u64::from(o.near);
        }
        self.counts.contact_frames += u64::from(any_contact);
    }
}
