//! The 6-DOF virtual coupling (docs/architecture.md#the-haptic-frame): a spring-damper between the handle and the part.

use crate::contact::clamp_length;
use crate::params::{Gains, HapticParams};
use crate::state::PartState;
use crate::{HandleSample, Wrench};
use glam::{DQuat, DVec3};

/// The coupling wrench on the part, and whether it was clamped.
///
/// `F_s = k_T (x_h − x) − b_T (v − v_h)` with `|F_s| ≤ k_T s / 2` (the paper's clamp: the coupling
/// never pulls harder than its half-voxel stretch). The spring term is clamped to that bound
/// *before* the damper is added, and the sum is clamped again: clamping only the sum would let a
/// long stretch mask the damper completely (the spring alone saturates the bound), leaving resting
/// contact with no dissipation at all; clamping the spring first keeps the damper working whenever
/// it opposes the spring (e.g. while the part is pressed into the force layer), and the bound on
/// `|F_s|` still holds.
///
/// `T_s = k_R θ − b_R (w − w_h)`, θ the axis·angle of `R_h R^T` along the shortest arc, clamped the
/// same way to `k_R s / (2 r_max)`: the torque of the twist that moves the outermost point half a
/// voxel (an extension: the paper has no torque clamp; without one the user could twist the part
/// through the force layer). Pure; does not allocate or block.
pub fn coupling_wrench(
    params: &HapticParams,
    gains: &Gains,
    state: &PartState,
    handle: &HandleSample,
) -> (Wrench, bool) {
    let half_voxel = 0.5 * params.voxel_size;
    let (force, force_clamped) = spring_damper(
        gains.k_t * (handle.position - state.position),
        gains.b_t * (handle.linear_velocity - state.linear_velocity),
        gains.k_t * half_voxel,
    );
    let theta = rotation_vector(handle.orientation.normalize() * state.orientation.conjugate());
    let (torque, torque_clamped) = spring_damper(
        gains.k_r * theta,
        gains.b_r * (handle.angular_velocity - state.angular_velocity),
        gains.k_r * half_voxel / params.max_radius,
    );
    (Wrench { force, torque }, force_clamped || torque_clamped)
}

/// `clamp(clamp(spring, max) + damper, max)` and whether either clamp acted.
fn spring_damper(spring: DVec3, damper: DVec3, max: f64) -> (DVec3, bool) {
    let (spring, spring_clamped) = clamp_length(spring, max);
    let (total, total_clamped) = clamp_length(spring + damper, max);
    (total, spring_clamped || total_clamped)
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
