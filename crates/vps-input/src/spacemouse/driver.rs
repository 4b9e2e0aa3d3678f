//! [`SpaceMouse`]: a rate-controlled, input-only [`HapticDevice`] over hidapi.
//!
//! The hidapi-touching code is the [`ReportSource`] impl for `hidapi::HidDevice` and the `open*`
//! constructors; the rest is [`parse_report`] and [`RateControl`], so the driver logic is tested
//! with an in-memory source.
//!
//! Permissions: on Linux the user needs read access to `/dev/hidraw*` (a udev rule such as
//! `KERNEL=="hidraw*", ATTRS{idVendor}=="256f", MODE="0660", TAG+="uaccess"`, likewise for 046d).
//! spacenavd, if running, may hold the device too.

use std::ffi::CString;

use vps_device::{DeviceError, DeviceLimits, HapticDevice};
use vps_haptic::{HandleSample, Wrench};

use super::devices::{list_devices, HidDeviceInfo};
use super::rate_control::{RateControl, SpaceMouseConfig};
use super::report::{parse_report, Layout, ReportError};
use crate::InputError;

/// Size of the read buffer (bytes): the largest full-speed USB HID report.
const REPORT_BUFFER: usize = 64;
/// At most this many reports are drained per [`HapticDevice::read`] (a device sends ≤ 125 per
/// second, so this bound is never reached in practice; it keeps `read` bounded regardless).
const MAX_REPORTS_PER_READ: usize = 256;

/// Where input reports come from: one non-blocking poll per call.
pub trait ReportSource: Send {
    /// Copies the next pending report (report id first) into `buf` and returns its length, or
    /// `Ok(0)` when none is pending. Must not block. `Err` means the device is gone.
    fn poll_report(&mut self, buf: &mut [u8]) -> Result<usize, String>;
}

impl ReportSource for hidapi::HidDevice {
    /// `read_timeout(buf, 0)`: a zero-timeout `poll` then `read` on Linux; never blocks.
    fn poll_report(&mut self, buf: &mut [u8]) -> Result<usize, String> {
        self.read_timeout(buf, 0).map_err(|e| e.to_string())
    }
}

/// Counts of reports seen by a [`SpaceMouse`] since it was opened.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReportCounters {
    /// Reports decoded and applied.
    pub accepted: u64,
    /// Reports that failed to decode (unknown ids such as battery reports, wrong lengths).
    pub rejected: u64,
}

/// A SpaceMouse as a 6-DOF handle: deflection sets the handle velocity (see
/// [`rate_control`](super::rate_control)). Input only: [`HapticDevice::write`] records the
/// (saturated) wrench for display and logging and never fails.
///
/// `read` drains every pending report without blocking (at most 256 per call), applies them, then
/// advances the rate control by the time since the previous `read`. It does not allocate except
/// to build an error.
pub struct SpaceMouse<S: ReportSource = hidapi::HidDevice> {
    source: S,
    name: String,
    layout: Layout,
    control: RateControl,
    limits: DeviceLimits,
    last_t: Option<f64>,
    last_wrench: Wrench,
    counters: ReportCounters,
    last_report_error: Option<ReportError>,
    buf: [u8; REPORT_BUFFER],
}

impl SpaceMouse<hidapi::HidDevice> {
    /// Opens the first drivable device from [`list_devices`] (preferring the interface with
    /// usage page 1 / usage 8, multi-axis controller). Blocks for enumeration and open.
    pub fn open_first(config: SpaceMouseConfig) -> Result<Self, InputError> {
        let devices = list_devices()?;
        let multi_axis = |d: &&HidDeviceInfo| d.usage_page == 1 && d.usage == 8;
        let chosen = devices
            .iter()
            .filter(|d| d.drivable)
            .find(multi_axis)
            .or_else(|| devices.iter().find(|d| d.drivable))
            .ok_or(InputError::NoDevice {
                found: devices.len(),
            })?;
        Self::open(chosen, config)
    }

    /// Opens the device described by `info` (from [`list_devices`]); an unknown device is parsed
    /// with [`Layout::Auto`]. Blocks for the open.
    pub fn open(info: &HidDeviceInfo, config: SpaceMouseConfig) -> Result<Self, InputError> {
        let layout = info.layout.unwrap_or(Layout::Auto);
        let name = if info.name.is_empty() {
            format!("SpaceMouse {:04x}:{:04x}", info.vendor_id, info.product_id)
        } else {
            info.name.clone()
        };
        Self::open_path(&info.path, &name, layout, config)
    }

    /// Opens the HID device at `path` (e.g. `/dev/hidraw3`) with the given layout. Blocks for the
    /// open.
    pub fn open_path(
        path: &str,
        name: &str,
        layout: Layout,
        config: SpaceMouseConfig,
    ) -> Result<Self, InputError> {
        let open_err = |message: String| InputError::Open {
            path: path.to_string(),
            message,
        };
        let c_path = CString::new(path).map_err(|e| open_err(e.to_string()))?;
        let api = hidapi::HidApi::new().map_err(|e| InputError::HidInit {
            message: e.to_string(),
        })?;
        let device = api
            .open_path(&c_path)
            .map_err(|e| open_err(e.to_string()))?;
        device
            .set_blocking_mode(false)
            .map_err(|e| open_err(e.to_string()))?;
        Self::from_source(device, name, layout, config)
    }
}

impl<S: ReportSource> SpaceMouse<S> {
    /// This device with other wrench limits (N, N·m; default [`DeviceLimits::PAPER`]). The
    /// SpaceMouse renders no force; written wrenches are saturated to these limits and kept for
    /// inspection. `limits` must satisfy [`DeviceLimits::validate`] (checked by the caller).
    pub fn with_limits(mut self, limits: DeviceLimits) -> Self {
        self.limits = limits;
        self
    }

    /// A SpaceMouse over any report source (used by tests and by other transports).
    pub fn from_source(
        source: S,
        name: &str,
        layout: Layout,
        config: SpaceMouseConfig,
    ) -> Result<Self, InputError> {
        Ok(Self {
            source,
            name: name.to_string(),
            layout,
            control: RateControl::new(config)?,
            limits: DeviceLimits::PAPER,
            last_t: None,
            last_wrench: Wrench::ZERO,
            counters: ReportCounters::default(),
            last_report_error: None,
            buf: [0; REPORT_BUFFER],
        })
    }

    /// The last wrench written (after saturation to [`HapticDevice::limits`]; zero before any
    /// write or after a non-finite one) (N, N·m, world frame). Nothing renders it.
    pub fn last_wrench(&self) -> Wrench {
        self.last_wrench
    }

    /// Report counters since opening.
    pub fn counters(&self) -> ReportCounters {
        self.counters
    }

    /// The most recent report that failed to decode, if any.
    pub fn last_report_error(&self) -> Option<ReportError> {
        self.last_report_error
    }

    /// The rate-control state (grab, buttons, deflection).
    pub fn control(&self) -> &RateControl {
        &self.control
    }

    /// The report layout used for parsing.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    fn drain(&mut self) -> Result<(), DeviceError> {
        for _ in 0..MAX_REPORTS_PER_READ {
            let n = self.source.poll_report(&mut self.buf).map_err(|message| {
                DeviceError::Hardware {
                    device: self.name.clone(),
                    message: format!("SpaceMouse {} disconnected: {message}", self.name),
                }
            })?;
            if n == 0 {
                break;
            }
            match parse_report(&self.buf[..n.min(REPORT_BUFFER)], self.layout) {
                Ok(report) => {
                    self.control.on_report(&report);
                    self.counters.accepted += 1;
                }
                Err(e) => {
                    self.last_report_error = Some(e);
                    self.counters.rejected += 1;
                }
            }
        }
        Ok(())
    }
}

impl<S: ReportSource> HapticDevice for SpaceMouse<S> {
    fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError> {
        let previous = self.last_t.unwrap_or(t);
        if !t.is_finite() || t < previous {
            return Err(DeviceError::TimeWentBackwards {
                device: self.name.clone(),
                previous,
                now: t,
            });
        }
        self.last_t = Some(t);
        self.drain()?;
        Ok(self.control.advance(t - previous))
    }

    fn write(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        self.last_wrench = self.limits.saturate(wrench);
        Ok(())
    }

    vps_device::limits_and_name_from_fields!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::VecDeque;

    /// Reports queued per `read`; `None` marks an unplug.
    struct FakeSource {
        queue: VecDeque<Option<Vec<u8>>>,
    }

    impl ReportSource for FakeSource {
        fn poll_report(&mut self, buf: &mut [u8]) -> Result<usize, String> {
            match self.queue.pop_front() {
                None => Ok(0),
                Some(None) => Err("hidapi error: device disconnected".into()),
                Some(Some(r)) => {
                    let n = r.len().min(buf.len());
                    buf[..n].copy_from_slice(&r[..n]);
                    Ok(n)
                }
            }
        }
    }

    fn mouse() -> SpaceMouse<FakeSource> {
        let cfg = SpaceMouseConfig {
            axis_map: [0, 1, 2, 3, 4, 5],
            axis_sign: [1.0; 6],
            ..Default::default()
        };
        let src = FakeSource {
            queue: VecDeque::new(),
        };
        SpaceMouse::from_source(src, "test mouse", Layout::Split, cfg).unwrap()
    }

    fn translation(x: i16) -> Vec<u8> {
        let mut r = vec![1u8];
        r.extend(x.to_le_bytes());
        r.extend([0; 4]);
        r
    }

    #[test]
    fn drains_all_pending_reports_and_keeps_the_newest() {
        let mut m = mouse();
        m.read(0.0).unwrap();
        for x in [100, 200, 350] {
            m.source.queue.push_back(Some(translation(x)));
        }
        m.source.queue.push_back(Some(vec![0x17, 1, 2, 3])); // battery-style report: rejected
        let s = m.read(0.001).unwrap();
        assert!(m.source.queue.is_empty());
        assert_eq!(
            m.counters(),
            ReportCounters {
                accepted: 3,
                rejected: 1
            }
        );
        assert!(matches!(
            m.last_report_error(),
            Some(ReportError::UnknownId { id: 0x17, .. })
        ));
        assert!((s.linear_velocity.x - 0.1).abs() < 1e-12, "full deflection");
        assert!((s.position.x - 1e-4).abs() < 1e-15);
    }

    #[test]
    fn unplug_is_a_hardware_error_naming_the_device() {
        let mut m = mouse();
        m.source.queue.push_back(Some(translation(10)));
        m.source.queue.push_back(None);
        let e = m.read(0.0).unwrap_err();
        match e {
            DeviceError::Hardware { device, message } => {
                assert_eq!(device, "test mouse");
                assert!(
                    message.contains("SpaceMouse test mouse disconnected"),
                    "{message}"
                );
            }
            other => panic!("expected Hardware, got {other:?}"),
        }
    }

    #[test]
    fn write_records_the_saturated_wrench_and_never_fails() {
        let mut m = mouse();
        let w = Wrench {
            force: glam::DVec3::new(0.0, 30.0, 0.0),
            torque: glam::DVec3::ZERO,
        };
        m.write(&w).unwrap();
        assert!((m.last_wrench().force.y - 15.0).abs() < 1e-12);
        let nan = Wrench {
            force: glam::DVec3::NAN,
            torque: glam::DVec3::ZERO,
        };
        m.write(&nan).unwrap();
        assert_eq!(m.last_wrench(), Wrench::ZERO);
    }

    #[test]
    fn time_going_backwards_is_rejected() {
        let mut m = mouse();
        m.read(1.0).unwrap();
        assert!(matches!(
            m.read(0.5),
            Err(DeviceError::TimeWentBackwards { .. })
        ));
        assert!(m.read(f64::NAN).is_err());
    }

    #[test]
    fn open_first_without_a_spacemouse_says_so() {
        let devices = list_devices().unwrap();
        if devices.iter().any(|d| d.drivable) {
            return; // a real SpaceMouse is attached: opening it is not this test's business
        }
        let e = SpaceMouse::open_first(SpaceMouseConfig::default())
            .err()
            .expect("no SpaceMouse here");
        assert_eq!(
            e,
            InputError::NoDevice {
                found: devices.len()
            }
        );
    }

    #[test]
    fn open_path_of_a_missing_device_is_a_clear_error() {
        let e = SpaceMouse::open_path(
            "/dev/hidraw-does-not-exist",
            "x",
            Layout::Auto,
            SpaceMouseConfig::default(),
        )
        .err()
        .expect("no such device");
        assert!(e.to_string().contains("/dev/hidraw-does-not-exist"), "{e}");
    }
}
