//! The sans-IO haptic core of vps (docs/architecture.md#the-haptic-frame): no threads, clocks, sockets or allocation on the frame
//! path. Everything here is a pure function of its arguments, so a frame can be tested without a
//! process, a port or a sleep, and every mode (local threads, child processes, LAN workers) calls the
//! same code.
//!
//! The contract other crates rely on (the runtime, the device layer, the cluster):
//! - [`HandleSample`], [`Wrench`]: what a device reports and receives (SI units).
//! - [`PartState`]: pose and velocities of the dynamic object (f64).
//! - [`KernelPose`]: the f32 per-frame input of the sampling kernel, made from a [`PartState`].
//! - [`ClassedShell`]: the point shell split cyclically into `C` classes in runs of `R`
//!   consecutive points (point `i` is in class `(i / R) mod C`, [`classed::run_length`]);
//!   `sample_class` returns that class's [`PartialSums`].
//! - [`PartialSums`]: integer fixed-point sums that merge exactly in any grouping and order.
//! - [`HapticParams`]: validated parameters with derived defaults (TOML-loadable).
//! - [`step`]: merged sums + handle + state → device wrench, next state, flags ([`FrameOutput`]).
//!
//! Module map: [`state`] (part state, kernel pose), [`classed`] (cyclic classes), [`kernel`]
//! (sampling), [`sums`] (fixed-point sums), [`params`] and [`stability`] (parameters and the bound
//! behind the default gains), [`contact`] (force field, braking), [`coupling`] (virtual coupling),
//! [`dynamics`] (integration, tunnelling guard), [`frame`] (one frame), [`job`] (a frame's sampling jobs), [`pair`] (contact between
//! two moving parts, forces equal and opposite to the bit).

#![warn(missing_docs)]

#[doc(hidden)]
pub mod avx2_only;
pub mod classed;
pub mod contact;
pub mod coupling;
pub mod dynamics;
pub mod frame;
pub mod job;
pub mod kernel;
mod lanes;
pub mod pair;
pub mod params;
pub mod stability;
pub mod state;
pub mod sums;

pub use classed::ClassedShell;
pub use frame::{step, step_with_parts, FrameOutput, OtherParts};
pub use job::{JobTarget, SampleJob};
pub use kernel::{
    sample_all, sample_class, sample_class_in, sample_classes, sample_mask, KernelFrame,
};
pub use params::{Gains, HapticParams, ParamsError, StabilityIndices};
pub use state::{KernelPose, PartState};
pub use sums::PartialSums;

use glam::{DQuat, DVec3};

/// One reading of the haptic handle, in the world frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct HandleSample {
    /// Handle position (m).
    pub position: DVec3,
    /// Handle orientation (unit quaternion).
    pub orientation: DQuat,
    /// Linear velocity (m/s).
    pub linear_velocity: DVec3,
    /// Angular velocity (rad/s).
    pub angular_velocity: DVec3,
}

/// A force and torque applied at a point (the device handle or the part's centre of mass).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Wrench {
    /// Force (N).
    pub force: DVec3,
    /// Torque (N·m).
    pub torque: DVec3,
}

impl Wrench {
    /// The zero wrench.
    pub const ZERO: Wrench = Wrench {
        force: DVec3::ZERO,
        torque: DVec3::ZERO,
    };
}
