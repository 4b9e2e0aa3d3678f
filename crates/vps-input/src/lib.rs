//! Real input devices for vps, each implementing [`vps_device::HapticDevice`]:
//!
//! - [`spacemouse`]: 3Dconnexion SpaceMouse-family 6-axis controllers over hidapi, used as
//!   rate-controlled handles (deflection → velocity → pose). Input only: no force is rendered;
//!   the written wrench is recorded for display. [`list_devices`] enumerates every HID device.
//! - [`bridge`]: a UDP device bridge: another process streams handle poses in and receives the
//!   wrenches back ([`BridgeDevice`], [`BridgeClient`], datagram format in [`bridge::protocol`]).
//!
//! SI units throughout (m, s, rad, N, N·m). Parsers and protocol codecs are pure functions that
//! never panic on any input; device `read`/`write` never block.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod bridge;
mod error;
pub mod spacemouse;

pub use bridge::{
    BridgeClient, BridgeConfig, BridgeCounters, BridgeDevice, BridgeError, BridgeMonitor,
    WorkspaceMapping,
};
pub use error::InputError;
pub use spacemouse::{list_devices, HidDeviceInfo, SpaceMouse, SpaceMouseConfig};

/// Checks a configured start pose: the position (m) must be finite and the orientation a finite
/// unit quaternion (length within 1e-6). The error names the first bad one of `fields`
/// (position's, orientation's) with the reason.
fn check_start_pose(
    position: glam::DVec3,
    orientation: glam::DQuat,
    fields: [&'static str; 2],
) -> Result<(), (&'static str, String)> {
    if !position.is_finite() {
        return Err((fields[0], "must be finite".into()));
    }
    let q = orientation;
    if !q.is_finite() || (q.length() - 1.0).abs() > 1e-6 {
        return Err((fields[1], format!("{q:?} must be a finite unit quaternion")));
    }
    Ok(())
}
