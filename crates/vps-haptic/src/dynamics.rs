//! Newton–Euler integration with a fixed step (semi-implicit Euler, isotropic inertia) and the
//! tunnelling guard.

use crate::params::{Gains, HapticParams};
use crate::state::PartState;
use crate::Wrench;
use glam::DQuat;

/// The state after one step under `net` (force and torque at the body origin, taken as the centre
/// of mass: see [`PartState::position`]), and whether the tunnelling guard limited the velocities.
///
/// `v' = v + dt F/m`, `w' = w + dt T/I` (isotropic inertia: no gyroscopic term); then, if
/// `|v'| + |w'| r_max > f s / dt`, both are scaled down by the same factor so that no point moves
/// more than `f s` in a frame; then `x' = x + dt v'` and `q' = normalise(exp(w' dt / 2) q)` (the
/// exact rotation by `w' dt`, renormalised). Does not allocate or block.
pub fn integrate(
    params: &HapticParams,
    gains: &Gains,
    state: &PartState,
    net: &Wrench,
) -> (PartState, bool) {
    let dt = params.dt;
    let mut v = state.linear_velocity + net.force * (dt / params.mass);
    let mut w = state.angular_velocity + net.torque * (dt / gains.inertia);
    let speed = v.length() + w.length() * params.max_radius;
    let limit = params.velocity_guard_fraction * params.voxel_size / dt;
    let limited = speed > limit;
    if limited {
        let k = limit / speed;
        v *= k;
        w *= k;
    }
    let orientation = (DQuat::from_scaled_axis(w * dt) * state.orientation).normalize();
    let next = PartState {
        position: state.position + v * dt,
        orientation,
        linear_velocity: v,
        angular_velocity: w,
    };
    (next, limited)
}
