//! The part's path, recomputed from a handle trace: every frame of the session run again off the
//! clock, with the same haptic core the 1 kHz loop runs ([`vps_haptic::step`] on the sums of the
//! whole shell). Sums are exact integers in any split, so the part's poses are the session's to
//! the bit whenever every frame's sums were computed (not stood in for by an earlier frame's, which
//! a cluster does for a late share only when told to) and the recording started with the session.

use glam::{DQuat, DVec3};
use vps_device::trace::Trace;
use vps_device::DeviceLimits;
use vps_haptic::{sample_all, ClassedShell, HapticParams, KernelPose, PartState};
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
    /// The scene's force on the part (the force field after averaging) this frame (N).
    pub contact_force_n: DVec3,
    /// Shell points in the force layer or deeper this frame.
    pub contacts: u32,
    /// At least one shell point in a Surface or Interior voxel.
    pub touching: bool,
    /// At least one shell point in an Interior voxel.
    pub penetrating: bool,
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
            contacts: 0,
            touching: false,
            penetrating: false,
        }
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
        let sent = limits.saturate(&out.device_wrench);
        frames.push(PathFrame {
            frame: f.frame,
            time_s: f.time,
            part_position_m: state.position,
            part_orientation: state.orientation,
            handle_position_m: f.sample.position,
            handle_orientation: f.sample.orientation,
            device_force_n: sent.force,
            device_torque_nm: sent.torque,
            contact_force_n: out.contact_wrench.force,
            contacts: out.contacts,
            touching: out.touching,
            penetrating: out.penetrating,
        });
        state = out.next_state;
    }
    (frames, state)
}

#[cfg(test)]
mod tests {
    /// The size `crate::MAX_STUDY_FRAMES`'s memory figure is worked out from.
    #[test]
    fn a_path_frame_is_208_bytes() {
        assert_eq!(std::mem::size_of::<super::PathFrame>(), 208);
    }
}
