//! Haptic devices for vps: the [`HapticDevice`] trait the 1 kHz loop drives, a closed-loop
//! [`SimulatedHand`] that follows a scripted motion and feels the wrench written to it, built-in
//! [`Script`]s placed against a contact geometry, and trace record/replay.
//!
//! Module map:
//! - [`device`]: the trait, [`DeviceLimits`], [`DeviceError`].
//! - [`norm`]: vector lengths against a limit without rounding up (saturation never overshoots).
//! - [`script`]: timed waypoint scripts and the built-in motions.
//! - [`sim_hand`]: the mass-spring-damper hand.
//! - [`trace`]: [`TraceRecorder`], [`Trace`] files (JSON lines), [`ReplayDevice`].
//!
//! No clock is read anywhere in this crate: time is always passed in by the caller, so every device
//! here is deterministic and testable without sleeping.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod device;
pub mod norm;
mod rotation;
pub mod script;
pub mod sim_hand;
pub mod trace;

pub use device::{DeviceError, DeviceLimits, HapticDevice};
pub use script::{
    CornerContact, Pace, Script, ScriptBuilder, ScriptError, SurfaceContact, Waypoint,
};
pub use sim_hand::{HandParams, SimulatedHand};
pub use trace::{
    load_trace, save_trace, ReplayDevice, Trace, TraceError, TraceFrame, TraceRecorder,
};
