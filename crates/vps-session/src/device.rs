//! The device a session is driven by: parsed from `--device` or a scene's `[device] kind`, and
//! opened.

use anyhow::{Context, Result};
use glam::DQuat;
use std::path::{Path, PathBuf};
use vps_device::script::Script;
use vps_device::trace::{load_trace, ReplayDevice};
use vps_device::{DeviceLimits, HandParams, HapticDevice, SimulatedHand};
use vps_haptic::PartState;
use vps_input::{BridgeConfig, BridgeDevice, SpaceMouse, SpaceMouseConfig};

/// The default address of the UDP device bridge.
pub const DEFAULT_BRIDGE_ADDR: &str = "127.0.0.1:7700";

/// The device a session is driven by.
#[derive(Clone, Debug, PartialEq)]
pub enum DeviceChoice {
    /// The simulated hand on the scene's script.
    Simulated,
    /// The first SpaceMouse-family HID device found (input only).
    SpaceMouse,
    /// The UDP device bridge, bound to the address (loopback unless a token is given).
    Bridge(std::net::SocketAddr),
    /// A recorded handle trace, played back exactly.
    Replay(PathBuf),
}

impl DeviceChoice {
    /// Parses `sim`, `spacemouse`, `bridge[:ADDR]` or `replay:FILE`; the error says what is
    /// allowed.
    pub fn parse(text: &str) -> Result<DeviceChoice, String> {
        Ok(match text.split_once(':') {
            None if text == "sim" => DeviceChoice::Simulated,
            None if text == "spacemouse" => DeviceChoice::SpaceMouse,
            None if text == "bridge" => {
                DeviceChoice::Bridge(DEFAULT_BRIDGE_ADDR.parse().expect("a valid address"))
            }
            Some(("bridge", addr)) => DeviceChoice::Bridge(addr.parse().map_err(|_| {
                format!("bridge:{addr}: not an address like {DEFAULT_BRIDGE_ADDR}")
            })?),
            Some(("replay", path)) if !path.is_empty() => DeviceChoice::Replay(path.into()),
            _ => {
                return Err(format!(
                    "'{text}': expected sim, spacemouse, bridge[:ADDR] or replay:FILE"
                ))
            }
        })
    }

    /// A replay path taken relative to `base` (a scene file's directory) unless absolute.
    pub fn relative_to(self, base: &Path) -> DeviceChoice {
        match self {
            DeviceChoice::Replay(p) if p.is_relative() => DeviceChoice::Replay(base.join(p)),
            other => other,
        }
    }

    /// Frames a session with this device runs: a replay's trace length, else `seconds / dt`.
    /// Blocking for a replay (reads the trace).
    pub fn frames(&self, seconds: f64, dt: f64) -> Result<u64> {
        Ok(match self {
            DeviceChoice::Replay(path) => load_trace(path)?.frames.len() as u64,
            _ => (seconds / dt).round().max(1.0) as u64,
        })
    }

    /// Opens the device; `script` drives the simulated hand and gives the others their start pose.
    /// Returns the device and the part's state at frame 0. Blocking (opens files, sockets, HID).
    pub fn open(&self, script: Script) -> Result<(Box<dyn HapticDevice>, PartState)> {
        let (start, orientation) = script.sample(0.0);
        let at_start = PartState::at_rest(start, orientation);
        Ok(match self {
            DeviceChoice::Simulated => (
                Box::new(SimulatedHand::new(script, HandParams::default())?),
                at_start,
            ),
            DeviceChoice::SpaceMouse => {
                let config = SpaceMouseConfig {
                    start_position: start,
                    start_orientation: DQuat::IDENTITY,
                    ..Default::default()
                };
                let device = SpaceMouse::open_first(config).context(
                    "opening a SpaceMouse (`vps devices` lists what this machine sees; /dev/hidraw* must be readable)",
                )?;
                (Box::new(device), at_start)
            }
            DeviceChoice::Bridge(addr) => {
                let config = BridgeConfig {
                    bind: *addr,
                    initial_position: start,
                    ..Default::default()
                };
                let device = BridgeDevice::bind(config)
                    .with_context(|| format!("binding the device bridge on {addr}"))?;
                eprintln!("device bridge listening on {}", device.local_addr());
                (Box::new(device), at_start)
            }
            DeviceChoice::Replay(path) => {
                let trace = load_trace(path)?;
                let first = trace
                    .frames
                    .first()
                    .with_context(|| format!("{}: the trace has no frames", path.display()))?;
                let state = PartState::at_rest(first.sample.position, first.sample.orientation);
                (
                    Box::new(ReplayDevice::new(trace, DeviceLimits::PAPER)),
                    state,
                )
            }
        })
    }
}
