//! The device a session is driven by: parsed from `--device` or a scene's `[device] kind`, and
//! opened ([`DeviceChoice::open`]); the bridge with its [`BridgeSettings`] (mapping, pose timeout,
//! wrench log), returning its [`BridgeMonitor`] beside the device in an [`OpenedDevice`].

use crate::error::{field_error, SceneError};
use crate::file::DeviceSection;
use anyhow::{Context, Result};
use glam::DQuat;
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use vps_device::script::Script;
use vps_device::trace::{load_trace, ReplayDevice, Trace};
use vps_device::{DeviceLimits, HandParams, HapticDevice, SimulatedHand};
use vps_haptic::PartState;
use vps_input::{
    list_devices, BridgeConfig, BridgeDevice, BridgeError, BridgeMonitor, InputError, SpaceMouse,
    SpaceMouseConfig, WorkspaceMapping,
};

/// What an error opening a SpaceMouse adds.
const SPACEMOUSE_HINT: &str =
    "opening a SpaceMouse (`vps devices` lists what this machine sees; /dev/hidraw* must be readable)";

pub use vps_scene_file::device_kind::{DeviceKind, DEFAULT_BRIDGE_ADDR};

/// How the UDP device bridge is set up when it is the session's device: the scene file's
/// `[device]` `mapping` and `pose_timeout_ms`, overridden by command-line flags. Ignored by the
/// other devices.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BridgeSettings {
    /// Device frame to scene frame, and scene wrench back to the device. Default: the identity.
    pub mapping: WorkspaceMapping,
    /// A device silent this long is held with zero output and re-anchored when it resumes
    /// (s; finite, in [0.002, 10]). Default 0.05.
    pub pose_timeout: f64,
    /// Keep up to this many sent wrenches for the session's report (0: none; see
    /// [`vps_input::bridge::config::MAX_WRENCH_LOG_FRAMES`]). Reserved when the bridge is bound. Default 0.
    pub wrench_log_frames: usize,
    /// The device's wrench limits (N, N·m), used by every device, not only the bridge: the scene
    /// file's `[device]` `max_force` and `max_torque`. Default [`DeviceLimits::PAPER`].
    pub limits: DeviceLimits,
}

impl Default for BridgeSettings {
    fn default() -> Self {
        let defaults = BridgeConfig::default();
        Self {
            mapping: defaults.mapping,
            pose_timeout: defaults.pose_timeout,
            wrench_log_frames: defaults.wrench_log_frames,
            limits: DeviceLimits::PAPER,
        }
    }
}

/// An opened device: what the frame loop drives, the part's state at frame 0, and, for the
/// bridge, a handle onto its counters and wrench log that stays readable after the device has
/// moved into the loop.
pub struct OpenedDevice {
    /// The device.
    pub device: Box<dyn HapticDevice>,
    /// The part's state at frame 0.
    pub initial: PartState,
    /// The bridge's counters and wrench log (`None` for every other device).
    pub bridge: Option<BridgeMonitor>,
}

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
    Replay(ReplaySource),
}

/// A recorded trace to replay: its file, read the first time anything asks for the trace (the
/// availability check, the frame count, the device, a study) and shared by every clone after.
#[derive(Clone, Debug)]
pub struct ReplaySource {
    /// The trace file.
    pub path: PathBuf,
    loaded: Arc<OnceLock<Arc<Trace>>>,
}

impl ReplaySource {
    /// The trace in `path`, not read yet.
    pub fn new(path: impl Into<PathBuf>) -> ReplaySource {
        ReplaySource {
            path: path.into(),
            loaded: Arc::default(),
        }
    }

    /// The trace: read from the file the first time (blocking; errors name the file and line),
    /// the same shared copy after.
    pub fn trace(&self) -> Result<Arc<Trace>> {
        if let Some(trace) = self.loaded.get() {
            return Ok(trace.clone());
        }
        let trace = Arc::new(load_trace(&self.path)?);
        Ok(self.loaded.get_or_init(|| trace).clone())
    }
}

/// Two sources are the same when they name the same file (read or not).
impl PartialEq for ReplaySource {
    fn eq(&self, other: &Self) -> bool {
        self.path == other.path
    }
}

impl DeviceChoice {
    /// Parses `sim`, `spacemouse`, `bridge[:ADDR]` or `replay:FILE` ([`DeviceKind::parse`]);
    /// the error says what is allowed.
    pub fn parse(text: &str) -> Result<DeviceChoice, String> {
        Ok(match DeviceKind::parse(text)? {
            DeviceKind::Simulated => DeviceChoice::Simulated,
            DeviceKind::SpaceMouse => DeviceChoice::SpaceMouse,
            DeviceKind::Bridge(addr) => DeviceChoice::Bridge(addr),
            DeviceKind::Replay(path) => DeviceChoice::Replay(ReplaySource::new(path)),
        })
    }

    /// A replay path taken relative to `base` (a scene file's directory) unless absolute.
    pub fn relative_to(self, base: &Path) -> DeviceChoice {
        match self {
            DeviceChoice::Replay(source) if source.path.is_relative() => {
                DeviceChoice::Replay(ReplaySource::new(base.join(&source.path)))
            }
            other => other,
        }
    }

    /// Frames a session with this device runs: a replay's trace length, else `seconds / dt`.
    /// Blocking for a replay (reads the trace).
    pub fn frames(&self, seconds: f64, dt: f64) -> Result<u64> {
        Ok(match self {
            DeviceChoice::Replay(source) => source.trace()?.frames.len() as u64,
            _ => (seconds / dt).round().max(1.0) as u64,
        })
    }

    /// Checks, before anything slow is built, that the device can be opened: a drivable
    /// SpaceMouse is listed, the bridge's address can be bound (the socket is closed again), a
    /// replay's trace reads. The simulated hand always passes. Opening can still fail later (a
    /// device unplugged meanwhile). Blocking (HID enumeration, a bind, a file read); setup-time
    /// only.
    pub fn check_available(&self) -> Result<()> {
        match self {
            DeviceChoice::Simulated => Ok(()),
            DeviceChoice::SpaceMouse => {
                let devices = list_devices().context(SPACEMOUSE_HINT)?;
                if devices.iter().any(|d| d.drivable) {
                    Ok(())
                } else {
                    Err(InputError::NoDevice {
                        found: devices.len(),
                    })
                    .context(SPACEMOUSE_HINT)
                }
            }
            DeviceChoice::Bridge(addr) => {
                UdpSocket::bind(addr)
                    .with_context(|| format!("binding the device bridge on {addr}"))?;
                Ok(())
            }
            DeviceChoice::Replay(source) => {
                source.trace().context("reading the trace to replay")?;
                Ok(())
            }
        }
    }

    /// Opens the device; `script` drives the simulated hand and gives the others their start pose;
    /// `bridge` sets up the UDP bridge (its `limits` apply to every device). Blocking (opens
    /// files, sockets, HID).
    pub fn open(&self, script: Script, bridge: &BridgeSettings) -> Result<OpenedDevice> {
        let (start, orientation) = script.sample(0.0);
        let at_start = PartState::at_rest(start, orientation);
        let (device, initial, monitor): (Box<dyn HapticDevice>, _, _) = match self {
            DeviceChoice::Simulated => (
                Box::new(SimulatedHand::new(
                    script,
                    HandParams {
                        limits: bridge.limits,
                        ..HandParams::default()
                    },
                )?),
                at_start,
                None,
            ),
            DeviceChoice::SpaceMouse => {
                let config = SpaceMouseConfig {
                    start_position: start,
                    start_orientation: DQuat::IDENTITY,
                    ..Default::default()
                };
                let device = SpaceMouse::open_first(config)
                    .context(SPACEMOUSE_HINT)?
                    .with_limits(bridge.limits);
                (Box::new(device), at_start, None)
            }
            DeviceChoice::Bridge(addr) => {
                let config = BridgeConfig {
                    bind: *addr,
                    initial_position: start,
                    pose_timeout: bridge.pose_timeout,
                    mapping: bridge.mapping,
                    wrench_log_frames: bridge.wrench_log_frames,
                    limits: bridge.limits,
                    ..Default::default()
                };
                let device = BridgeDevice::bind(config)
                    .with_context(|| format!("binding the device bridge on {addr}"))?;
                eprintln!("device bridge listening on {}", device.local_addr());
                let monitor = device.monitor();
                (Box::new(device), at_start, Some(monitor))
            }
            DeviceChoice::Replay(source) => {
                let trace = source.trace()?;
                let first = trace.frames.first().with_context(|| {
                    format!("{}: the trace has no frames", source.path.display())
                })?;
                // Where the recorded session's part started, else (an old trace) at the first
                // handle sample.
                let state = match trace.part_start {
                    Some(start) => PartState::at_rest(start.position, start.orientation),
                    None => PartState::at_rest(first.sample.position, first.sample.orientation),
                };
                (
                    Box::new(ReplayDevice::new(trace, bridge.limits)),
                    state,
                    None,
                )
            }
        };
        Ok(OpenedDevice {
            device,
            initial,
            bridge: monitor,
        })
    }
}

/// The bridge settings of a `[device]` section (defaults where absent), its mapping, pose timeout
/// and wrench limits checked against the device layer's ranges; errors name `path` and the field
/// under `table`, where the section sits (`device`, `part[1].device`).
pub fn bridge_settings(
    d: &DeviceSection,
    path: &str,
    table: &str,
) -> Result<BridgeSettings, SceneError> {
    let mut settings = BridgeSettings::default();
    if let Some(m) = d.mapping {
        let identity = WorkspaceMapping::default();
        let mapping = WorkspaceMapping {
            scale: m.scale.unwrap_or(identity.scale),
            rotate_deg: m.rotate_deg.unwrap_or(identity.rotate_deg),
            offset: m.offset.unwrap_or(identity.offset),
            force_scale: m.force_scale.unwrap_or(identity.force_scale),
        };
        mapping.validate().map_err(|e| match e {
            BridgeError::Config { field, message } => {
                field_error(path, &format!("{table}.{field}"), message)
            }
            other => field_error(path, &format!("{table}.mapping"), other.to_string()),
        })?;
        settings.mapping = mapping;
    }
    if let Some(ms) = d.pose_timeout_ms {
        if !(ms.is_finite() && (2.0..=10_000.0).contains(&ms)) {
            return Err(field_error(
                path,
                &format!("{table}.pose_timeout_ms"),
                format!("{ms} must be finite and within [2, 10000] (ms)"),
            ));
        }
        settings.pose_timeout = ms / 1e3;
    }
    let limits = DeviceLimits {
        max_force: d.max_force.unwrap_or(DeviceLimits::PAPER.max_force),
        max_torque: d.max_torque.unwrap_or(DeviceLimits::PAPER.max_torque),
    };
    limits.validate().map_err(|message| {
        let key = if message.contains("max_force") {
            "max_force"
        } else {
            "max_torque"
        };
        field_error(path, &format!("{table}.{key}"), message)
    })?;
    settings.limits = limits;
    Ok(settings)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use vps_device::trace::{save_trace, TraceRecorder};
    use vps_haptic::HandleSample;

    /// A replay's trace is read once: every later ask (and every clone of the choice) gets the
    /// same copy, even after the file is gone; the file is not read before it is asked for.
    #[test]
    fn a_replay_reads_its_trace_once_and_shares_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.jsonl");
        let sample = HandleSample {
            position: DVec3::new(0.1, 0.2, 0.3),
            orientation: DQuat::IDENTITY,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
        };
        let mut recorder = TraceRecorder::with_capacity("sim", 1e-3, 3);
        for k in 0..3 {
            recorder.record(k, k as f64 * 1e-3, sample).unwrap();
        }
        let choice = DeviceChoice::parse(&format!("replay:{}", path.display())).unwrap();
        let DeviceChoice::Replay(source) = &choice else {
            panic!("{choice:?}")
        };
        assert!(source.trace().is_err(), "no file yet");
        save_trace(&path, &recorder.finish()).unwrap();
        assert_eq!(choice.frames(1.0, 1e-3).unwrap(), 3);
        let first = source.trace().unwrap();
        std::fs::remove_file(&path).unwrap();
        choice.check_available().unwrap();
        let copy = choice.clone();
        let DeviceChoice::Replay(copied) = &copy else {
            unreachable!()
        };
        assert!(Arc::ptr_eq(&first, &copied.trace().unwrap()));
        assert_eq!(copy, choice);
    }
}
