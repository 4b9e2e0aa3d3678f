//! The part's path, recomputed from a handle trace: every frame of the session run again off the
//! clock, with the same haptic core the 1 kHz loop runs ([`vps_haptic::step`] on the sums of the
//! whole shell). Sums are exact integers in any split, so the part's poses are the session's to
//! the bit whenever every frame's sums were computed (not stood in for by an earlier frame's, which
//! a cluster does for a late share only when told to) and the recording started with the session.
//!
//! A session of several moving parts is recomputed all parts together ([`recompute_paths`]), one
//! trace per part: each frame, every part's static sums, the frame loop's own pair pass
//! ([`PairPass`]) on the states at the frame's start, then every part's
//! [`vps_haptic::step_with_parts`], in the loop's order, so each part's poses are the session's to
//! the bit too.

use glam::{DQuat, DVec3};
use vps_device::trace::Trace;
use vps_device::DeviceLimits;
use vps_haptic::pair::{BodyVoxmap, PairPart, PairPass};
use vps_haptic::{
    sample_all, step_with_parts, ClassedShell, FrameOutput, HapticParams, KernelPose, PartState,
    Wrench,
};
use vps_voxmap::VoxelLookup;

/// One frame of a recomputed session.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathFrame {
    /// Frame index (0-based).
    pub frame: u64,
    /// Time of the frame's handle reading (s since the start).
    pub time_s: f64,
    /// The part's grip position at the start of the frame (m).
    pub part_position_m: DVec3,
    /// The part's orientation at the start of the frame (part frame → world).
    pub part_orientation: DQuat,
    /// The handle's position read this frame (m).
    pub handle_position_m: DVec3,
    /// The handle's orientation read this frame.
    pub handle_orientation: DQuat,
    /// Force sent to the device this frame, within its limits (N).
    pub device_force_n: DVec3,
    /// Torque sent to the device this frame, within its limits (N·m).
    pub device_torque_nm: DVec3,
    /// The contact force on the part this frame (N): the scene's (the force field after
    /// averaging) plus the other moving parts' (`other_parts_force_n`).
    pub contact_force_n: DVec3,
    /// The other moving parts' force on the part this frame (N; zero with one moving part).
    pub other_parts_force_n: DVec3,
    /// Shell points in the force layer or deeper this frame.
    pub contacts: u32,
    /// At least one shell point in a Surface or Interior voxel.
    pub touching: bool,
    /// At least one shell point in an Interior voxel.
    pub penetrating: bool,
    /// The other moving parts in contact with the part this frame, as bits: bit `k` for part `k`
    /// of the session (0 the first), set when either part's shell reached a non-free voxel of
    /// the other's voxmap (the pair pass's contact). 0 with one moving part.
    pub parts_in_contact: u8,
}

impl PathFrame {
    /// Frame `frame` at `time_s` (s) with the part and the handle both at `position_m` (m) and
    /// `orientation`, no force and no contact: a pose of a path that is given rather than
    /// recomputed (analytic motions, swept-volume checks).
    pub fn at_pose(frame: u64, time_s: f64, position_m: DVec3, orientation: DQuat) -> PathFrame {
        PathFrame {
            frame,
            time_s,
            part_position_m: position_m,
            part_orientation: orientation,
            handle_position_m: position_m,
            handle_orientation: orientation,
            device_force_n: DVec3::ZERO,
            device_torque_nm: DVec3::ZERO,
            contact_force_n: DVec3::ZERO,
            other_parts_force_n: DVec3::ZERO,
            contacts: 0,
            touching: false,
            penetrating: false,
            parts_in_contact: 0,
        }
    }

    /// Whether part `k` (0 the session's first) was in contact with this part this frame
    /// ([`PathFrame::parts_in_contact`]).
    pub fn in_contact_with(&self, k: usize) -> bool {
        k < 8 && self.parts_in_contact & (1 << k) != 0
    }
}

/// The grip's speed (m/s) at frame `i` of `path`, from the frame before (0 at the first frame);
/// `None` when the two frames have the same time.
pub fn grip_speed(path: &[PathFrame], i: usize) -> Option<f64> {
    let Some(before) = i.checked_sub(1) else {
        return Some(0.0);
    };
    let (prev, here) = (&path[before], &path[i]);
    let dt = here.time_s - prev.time_s;
    (dt > 0.0).then(|| here.part_position_m.distance(prev.part_position_m) / dt)
}

/// Runs every frame of `trace` again from `initial` on `map` and `shell` with `params`, the device
/// wrench saturated by `limits` as the loop does. Returns one [`PathFrame`] per trace frame, plus
/// the part's state after the last frame. Blocking; allocates the result; single-threaded (each
/// frame needs the one before).
pub fn recompute_path<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    params: &HapticParams,
    limits: &DeviceLimits,
    initial: PartState,
    trace: &Trace,
) -> (Vec<PathFrame>, PartState) {
    let mut state = initial;
    let mut frames = Vec::with_capacity(trace.frames.len());
    for f in &trace.frames {
        let pose = KernelPose::from_state(&state);
        let sums = sample_all(map, shell, &pose);
        let out = vps_haptic::step(params, &state, &f.sample, &sums);
        frames.push(path_frame(f, &state, &out, limits, Wrench::ZERO));
        state = out.next_state;
    }
    (frames, state)
}

/// The path frame of trace frame `f`, the part at `state` at its start, the step's `out`, the
/// device wrench saturated by `limits`, `others` the other parts' wrench on the part.
fn path_frame(
    f: &vps_device::trace::TraceFrame,
    state: &PartState,
    out: &FrameOutput,
    limits: &DeviceLimits,
    others: Wrench,
) -> PathFrame {
    let sent = limits.saturate(&out.device_wrench);
    PathFrame {
        frame: f.frame,
        time_s: f.time,
        part_position_m: state.position,
        part_orientation: state.orientation,
        handle_position_m: f.sample.position,
        handle_orientation: f.sample.orientation,
        device_force_n: sent.force,
        device_torque_nm: sent.torque,
        contact_force_n: out.contact_wrench.force,
        other_parts_force_n: others.force,
        contacts: out.contacts,
        touching: out.touching,
        penetrating: out.penetrating,
        parts_in_contact: 0,
    }
}

/// One moving part of a session of several, as [`recompute_paths`] runs it again.
#[derive(Clone, Copy)]
pub struct PathPart<'a> {
    /// Its point shell in its grip frame, in classes (sampled in the static voxmap and in the
    /// other parts' own voxmaps).
    pub shell: &'a ClassedShell,
    /// Its haptic parameters.
    pub params: &'a HapticParams,
    /// Its device's limits.
    pub limits: DeviceLimits,
    /// Its state at the first frame.
    pub initial: PartState,
    /// Its handle trace; every part's has the same frames.
    pub trace: &'a Trace,
    /// Its own voxmap in its grip frame.
    pub body: &'a dyn BodyVoxmap,
    /// Radius about its grip holding its mesh and shell (m).
    pub radius: f64,
}

/// Runs every frame of a session of several moving parts again: each frame, every part's sums in
/// `map`, the pair pass over the states at the frame's start (pairs whose spheres, grown by
/// `margin` m, do not overlap skipped, as in the loop), then each part's step with its pair
/// wrench, its device wrench saturated by its limits. Returns each part's path and final state,
/// in `parts`' order. Every trace must have as many frames as the first (the caller checks;
/// extra frames are ignored). Blocking; allocates the results; single-threaded.
pub fn recompute_paths<L: VoxelLookup>(
    map: &L,
    parts: &[PathPart<'_>],
    margin: f64,
) -> Vec<(Vec<PathFrame>, PartState)> {
    let frames = parts.first().map_or(0, |p| p.trace.frames.len());
    let mut states: Vec<PartState> = parts.iter().map(|p| p.initial).collect();
    let mut paths: Vec<Vec<PathFrame>> = parts.iter().map(|_| Vec::with_capacity(frames)).collect();
    let mut pass = PairPass::new(parts.len());
    let mut outs = Vec::with_capacity(parts.len());
    let mut sums = Vec::with_capacity(parts.len());
    for i in 0..frames {
        sums.clear();
        sums.extend(
            parts
                .iter()
                .zip(&states)
                .map(|(p, s)| sample_all(map, p.shell, &KernelPose::from_state(s))),
        );
        pass.run(
            parts.len(),
            |k| PairPart {
                state: &states[k],
                params: parts[k].params,
                map: parts[k].body,
                shell: parts[k].shell,
                radius: parts[k].radius,
            },
            margin,
        );
        outs.clear();
        for (k, p) in parts.iter().enumerate() {
            let f = &p.trace.frames[i];
            let others = &pass.others[k];
            let out = step_with_parts(p.params, &states[k], &f.sample, &sums[k], others);
            let mut frame = path_frame(f, &states[k], &out, &p.limits, others.wrench);
            for &(a, b) in pass.near_pairs() {
                let other = if a == k {
                    b
                } else if b == k {
                    a
                } else {
                    continue;
                };
                // A session holds at most 8 parts (the scene file's limit).
                frame.parts_in_contact |= 1u8.checked_shl(other as u32).unwrap_or(0);
            }
            paths[k].push(frame);
            outs.push(out.next_state);
        }
        states.copy_from_slice(&outs);
    }
    paths.into_iter().zip(states).collect()
}

#[cfg(test)]
mod tests {
    /// The size `crate::MAX_STUDY_FRAMES`'s memory figure is worked out from.
    #[test]
    fn a_path_frame_is_232_bytes() {
        assert_eq!(std::mem::size_of::<super::PathFrame>(), 232);
    }
}
