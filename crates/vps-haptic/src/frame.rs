//! One haptic frame (docs/architecture.md#the-haptic-frame): merged sums + handle + state → device wrench and next state.

use crate::contact::{brake_wrench, contact_wrench};
use crate::coupling::coupling_wrench;
use crate::dynamics::integrate;
use crate::params::HapticParams;
use crate::state::PartState;
use crate::sums::PartialSums;
use crate::{HandleSample, Wrench};

/// A handle position farther than this from the world origin (m) is rejected as absurd.
pub const MAX_HANDLE_POSITION: f64 = 1.0e3;
/// A handle speed above this (m/s) is rejected as absurd.
pub const MAX_HANDLE_SPEED: f64 = 1.0e3;
/// A handle angular speed above this (rad/s) is rejected as absurd.
pub const MAX_HANDLE_ANGULAR_SPEED: f64 = 1.0e4;
/// A handle quaternion whose norm differs from 1 by more than this is rejected (smaller deviations
/// are normalised away).
pub const HANDLE_QUATERNION_TOLERANCE: f64 = 1.0e-2;

/// Everything one frame produces.
///
/// Invariant: `device_wrench` is always finite. It is not limited here: the device layer owns the
/// limit (`vps_device::DeviceLimits`, applied by the loop before every write).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrameOutput {
    /// What to send to the device before its limits: `−F_s`, `−T_s`; exactly zero when every point
    /// is in a Free voxel, when the input was rejected or when a result was non-finite.
    pub device_wrench: Wrench,
    /// The part's state for the next frame (the input state when rejected or non-finite).
    pub next_state: PartState,
    /// Force-field wrench on the part (N, N·m), after averaging.
    pub contact_wrench: Wrench,
    /// Coupling wrench on the part (N, N·m), after its clamp.
    pub coupling_wrench: Wrench,
    /// Braking wrench on the part (N, N·m).
    pub brake_wrench: Wrench,
    /// Contact count N (points with d > 0), saturated to `u32::MAX`.
    pub contacts: u32,
    /// At least one point in a Surface or Interior voxel.
    pub touching: bool,
    /// At least one point in an Interior voxel (a potential exact-surface penetration).
    pub penetrating: bool,
    /// The coupling force or torque hit its half-voxel clamp.
    pub coupling_clamped: bool,
    /// The tunnelling guard scaled the velocities down.
    pub velocity_limited: bool,
    /// The handle sample was non-finite or absurd: zero device wrench, state kept.
    pub rejected_input: bool,
    /// The state or a computed quantity was non-finite: zero device wrench, state kept.
    pub non_finite: bool,
}

impl FrameOutput {
    /// Zero wrenches, `state` kept, with the contact flags of `sums`.
    fn hold(state: &PartState, sums: &PartialSums) -> Self {
        Self {
            device_wrench: Wrench::ZERO,
            next_state: *state,
            contact_wrench: Wrench::ZERO,
            coupling_wrench: Wrench::ZERO,
            brake_wrench: Wrench::ZERO,
            contacts: u32::try_from(sums.contacts).unwrap_or(u32::MAX),
            touching: sums.surface + sums.interior > 0,
            penetrating: sums.interior > 0,
            coupling_clamped: false,
            velocity_limited: false,
            rejected_input: false,
            non_finite: false,
        }
    }
}

/// True when `handle` is finite and not absurd (see the `MAX_HANDLE_*` constants).
pub fn handle_is_valid(handle: &HandleSample) -> bool {
    let q_norm = handle.orientation.length();
    handle.position.is_finite()
        && handle.linear_velocity.is_finite()
        && handle.angular_velocity.is_finite()
        && handle.orientation.is_finite()
        && handle.position.length() <= MAX_HANDLE_POSITION
        && handle.linear_velocity.length() <= MAX_HANDLE_SPEED
        && handle.angular_velocity.length() <= MAX_HANDLE_ANGULAR_SPEED
        && (q_norm - 1.0).abs() <= HANDLE_QUATERNION_TOLERANCE
}

/// One frame: the force model on the merged `sums` (sampled at `state`), the coupling to `handle`,
/// one integration step, and the device wrench.
///
/// Net force on the part = coupling + contact + braking. The device wrench is `−F_s, −T_s`, not
/// limited here (the device layer saturates it to its `DeviceLimits` before every write), or
/// exactly zero when no point is in a non-Free voxel (the paper's free-space rule). A rejected handle sample or a non-finite state or result gives a zero device wrench and
/// keeps `state`. `params` should have passed [`HapticParams::validate`]; invalid parameters
/// produce non-finite results and therefore the same safe output. Pure; does not allocate or block.
pub fn step(
    params: &HapticParams,
    state: &PartState,
    handle: &HandleSample,
    sums: &PartialSums,
) -> FrameOutput {
    step_with_parts(params, state, handle, sums, &OtherParts::NONE)
}

/// What the other moving parts do to this one in a frame ([`crate::pair`]): the sum of its pairs'
/// wrenches on it (world frame, N and N·m about its origin) and whether any of their points or
/// its own lay in a non-Free voxel of a pair.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OtherParts {
    /// Σ of the pair wrenches on this part.
    pub wrench: Wrench,
    /// Some point of a pair lay in a non-Free voxel (the free-space rule then no longer holds).
    pub near: bool,
}

impl OtherParts {
    /// No other part (the one-part scene).
    pub const NONE: OtherParts = OtherParts {
        wrench: Wrench::ZERO,
        near: false,
    };
}

/// [`step`] for a part among several: the pair wrench `others.wrench` is added to its contact
/// wrench (so [`FrameOutput::contact_wrench`] holds both), and the device wrench is zero only when
/// neither the static scene nor any pair has a point in a non-Free voxel. With
/// [`OtherParts::NONE`] it is [`step`] bit for bit. Pure; does not allocate or block.
pub fn step_with_parts(
    params: &HapticParams,
    state: &PartState,
    handle: &HandleSample,
    sums: &PartialSums,
    others: &OtherParts,
) -> FrameOutput {
    let mut out = FrameOutput::hold(state, sums);
    if !handle_is_valid(handle) {
        out.rejected_input = true;
        return out;
    }
    if !state.is_finite() {
        out.non_finite = true;
        return out;
    }
    let gains = params.gains();
    let (coupling, coupling_clamped) = coupling_wrench(params, &gains, state, handle);
    let mut contact = contact_wrench(params, &gains, sums);
    if *others != OtherParts::NONE {
        contact.force += others.wrench.force;
        contact.torque += others.wrench.torque;
    }
    let brake = brake_wrench(params, &gains, state, sums);
    let net = Wrench {
        force: coupling.force + contact.force + brake.force,
        torque: coupling.torque + contact.torque + brake.torque,
    };
    let (next_state, velocity_limited) = integrate(params, &gains, state, &net);
    let all_finite = next_state.is_finite()
        && [coupling, contact, brake]
            .iter()
            .all(|w| w.force.is_finite() && w.torque.is_finite());
    if !all_finite {
        out.non_finite = true;
        return out;
    }
    let device_wrench = if sums.non_free == 0 && !others.near {
        Wrench::ZERO
    } else {
        Wrench {
            force: -coupling.force,
            torque: -coupling.torque,
        }
    };
    FrameOutput {
        device_wrench,
        next_state,
        contact_wrench: contact,
        coupling_wrench: coupling,
        brake_wrench: brake,
        coupling_clamped,
        velocity_limited,
        ..out
    }
}
