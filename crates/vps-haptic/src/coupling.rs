//! The 6-DOF virtual coupling (DESIGN §3): a spring-damper between the handle and the part.

use crate::contact::clamp_length;
use crate::params::{Gains, HapticParams};
use crate::state::PartState;
use crate::{HandleSample, Wrench};
use glam::{DQuat, DVec3};

/// The coupling wrench on the part, and whether it was clamped.
///
/// `F_s = k_T (x_h − x) − b_T (v − v_h)`, clamped to `|F_s| ≤ k_T s / 2` (the paper's clamp: the
/// spring never pulls harder than its half-voxel stretch). `T_s = k_R θ − b_R (w − w_h)` with θ the
/// axis·angle of `R_h R^T` along the shortest arc, clamped likewise to `k_R s / (2 r_max)`: the
/// torque of the twist that moves the outermost point half a voxel (an extension of the paper,
/// which has no torque clamp, so that the user cannot twist the part through the force layer).
pub fn coupling_wrench(
    params: &HapticParams,
    gains: &Gains,
    state: &PartState,
    handle: &HandleSample,
) -> (Wrench, bool) {
    let force = gains.k_t * (handle.position - state.position)
        - gains.b_t * (state.linear_velocity - handle.linear_velocity);
    let theta = rotation_vector(handle.orientation.normalize() * state.orientation.conjugate());
    let torque = gains.k_r * theta - gains.b_r * (state.angular_velocity - handle.angular_velocity);
    let half_voxel = 0.5 * params.voxel_size;
    let (force, force_clamped) = clamp_length(force, gains.k_t * half_voxel);
    let (torque, torque_clamped) = clamp_length(torque, gains.k_r * half_voxel / params.max_radius);
    (Wrench { force, torque }, force_clamped || torque_clamped)
}

/// The rotation vector (axis × angle, rad, angle in [0, π]) of a unit quaternion, taking the
/// shortest arc (`q` and `−q` give the same result).
pub fn rotation_vector(q: DQuat) -> DVec3 {
    let q = if q.w < 0.0 { -q } else { q };
    let xyz = DVec3::new(q.x, q.y, q.z);
    let s = xyz.length();
    if s < 1e-12 {
        // sin(θ/2) ≈ θ/2: θ ≈ 2 xyz.
        2.0 * xyz
    } else {
        xyz * (2.0 * s.atan2(q.w) / s)
    }
}
