//! The force model of docs/architecture.md#the-haptic-frame applied to merged sums: contact (force field with averaging) and
//! pre-contact braking. Pure functions; no allocation.

use crate::params::{Gains, HapticParams};
use crate::state::PartState;
use crate::sums::PartialSums;
use crate::Wrench;
use glam::DVec3;

/// The contact wrench on the part about its body origin `x`: `K_ff Σ d N` and `K_ff Σ (P−x) × d N`
/// (N, N·m), scaled by `threshold / N` once the contact count N reaches the averaging threshold
/// (default 10). Pure; does not allocate or block.
pub fn contact_wrench(params: &HapticParams, gains: &Gains, sums: &PartialSums) -> Wrench {
    let n = sums.contacts;
    let threshold = u64::from(params.contact_average_threshold);
    let scale = if n >= threshold {
        gains.k_ff * threshold as f64 / n as f64
    } else {
        gains.k_ff
    };
    Wrench {
        force: sums.depth_normal_si() * scale,
        torque: sums.depth_torque_si() * scale,
    }
}

/// The pre-contact braking wrench (zero when braking is off or no Proximity point approaches).
///
/// `u = S_f / |S_f|` is the approach direction (the braking force `−b S_f` points against it) and
/// `v_n = v·u` the part's approach speed. Braking viscosity `b = m v_n² / (2 dt S_q)` (remove the
/// approach kinetic energy in one frame), capped at `m v_n / (dt |S_f|)` so that one frame's braking
/// impulse can at most stop the approach, never reverse it (which keeps braking dissipative when
/// the points' approach speeds differ, e.g. under rotation). Force `−b S_f`; torque `−b S_t` only
/// with `braking_torque`, capped so one frame can at most stop the angular velocity. Pure; does not
/// allocate or block.
pub fn brake_wrench(
    params: &HapticParams,
    gains: &Gains,
    state: &PartState,
    sums: &PartialSums,
) -> Wrench {
    let Some(b) = brake_viscosity(params, params.mass, state.linear_velocity, sums) else {
        return Wrench::ZERO;
    };
    let torque = if params.braking_torque {
        let t = -b * sums.brake_torque_si();
        let max = gains.inertia * state.angular_velocity.length() / params.dt;
        clamp_length(t, max).0
    } else {
        DVec3::ZERO
    };
    Wrench {
        force: -b * sums.brake_force_si(),
        torque,
    }
}

/// The braking viscosity `b` (N·s/m) of `sums`' Proximity points for a body of mass `mass` (kg)
/// whose origin moves at `velocity` (m/s, in the frame the sums were sampled in): with
/// `u = S_f / |S_f|` and `v_n = velocity·u`, `b = mass v_n² / (2 dt S_q)` capped at
/// `mass v_n / (dt |S_f|)`, so that the force `−b S_f` at most stops the approach in one frame.
/// `None` when braking is off, nothing approaches, or the body is not moving towards the points.
/// The static scene's braking ([`brake_wrench`]) and a pair's (`crate::pair::pair_braking`, with
/// the pair's reduced mass and relative velocity) both use it. Pure.
pub(crate) fn brake_viscosity(
    params: &HapticParams,
    mass: f64,
    velocity: DVec3,
    sums: &PartialSums,
) -> Option<f64> {
    let s_q = sums.brake_sq_si();
    let s_f = sums.brake_force_si();
    let s_f_len = s_f.length();
    if !params.braking || sums.approaching == 0 || s_q <= 0.0 || s_f_len <= 0.0 {
        return None;
    }
    let v_n = velocity.dot(s_f / s_f_len);
    if v_n.is_nan() || v_n <= 0.0 {
        return None;
    }
    let dt = params.dt;
    Some((mass * v_n * v_n / (2.0 * dt * s_q)).min(mass * v_n / (dt * s_f_len)))
}

/// `v` scaled down to length `max` if longer (to just under `max`, so rounding cannot leave it
/// above); the flag says whether it was.
pub(crate) fn clamp_length(v: DVec3, max: f64) -> (DVec3, bool) {
    let len = v.length();
    if len > max {
        (v * (max * (1.0 - 1e-12) / len), true)
    } else {
        (v, false)
    }
}
