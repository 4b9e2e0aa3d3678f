//! The device contract: what the haptic loop reads and writes once per frame.

use vps_haptic::{HandleSample, Wrench};

/// The largest wrench a device can render: the one wrench limit of vps.
///
/// The device layer is the safety boundary. Who clamps: the haptic loop (`vps-runtime`) saturates
/// every frame's wrench to [`HapticDevice::limits`] before writing it, and every device saturates
/// again on write; the haptic frame itself (`vps-haptic`) does not limit the wrench. Set from a
/// scene file's `[device]` `max_force` (N) and `max_torque` (N·m); default [`DeviceLimits::PAPER`].
///
/// Invariant: both maxima finite and > 0 ([`DeviceLimits::validate`]; at most
/// [`DeviceLimits::MAX_FORCE`] N and [`DeviceLimits::MAX_TORQUE`] N·m).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeviceLimits {
    /// Largest force magnitude (N).
    pub max_force: f64,
    /// Largest torque magnitude (N·m).
    pub max_torque: f64,
}

impl DeviceLimits {
    /// The limits of the device in McNeely et al. 1999: 15 N and 0.1 N·m.
    pub const PAPER: DeviceLimits = DeviceLimits {
        max_force: 15.0,
        max_torque: 0.1,
    };

    /// The largest `max_force` accepted (N).
    pub const MAX_FORCE: f64 = 1e4;
    /// The largest `max_torque` accepted (N·m).
    pub const MAX_TORQUE: f64 = 1e3;

    /// Checks both maxima: finite, > 0 and at most [`DeviceLimits::MAX_FORCE`] N /
    /// [`DeviceLimits::MAX_TORQUE`] N·m. The error names the key (`max_force` or `max_torque`),
    /// the value and the allowed range.
    pub fn validate(&self) -> Result<(), String> {
        for (key, value, hi, unit) in [
            ("max_force", self.max_force, Self::MAX_FORCE, "N"),
            ("max_torque", self.max_torque, Self::MAX_TORQUE, "N·m"),
        ] {
            if !(value.is_finite() && value > 0.0 && value <= hi) {
                return Err(format!(
                    "`{key}` = {value} must be finite and in (0, {hi}] ({unit})"
                ));
            }
        }
        Ok(())
    }

    /// `wrench` with force and torque each scaled down (direction kept) to fit the limits, so that
    /// the exact Euclidean lengths satisfy |F| ≤ `max_force` and |T| ≤ `max_torque`: not one ulp
    /// over, however a client computes the length ([`crate::norm::clamp_length`]). A wrench
    /// within the limits is returned unchanged (but for one within about 8 ulps of a limit, scaled
    /// below it). A non-finite component yields the zero wrench. Does not allocate or block.
    pub fn saturate(&self, wrench: &Wrench) -> Wrench {
        if !wrench.force.is_finite() || !wrench.torque.is_finite() {
            return Wrench::ZERO;
        }
        Wrench {
            force: crate::norm::clamp_length(wrench.force, self.max_force),
            torque: crate::norm::clamp_length(wrench.torque, self.max_torque),
        }
    }

    /// True when `wrench` is finite and within both maxima exactly (no slack; conservative by a
    /// few ulps, [`crate::norm::length_within`]): what [`DeviceLimits::saturate`] returns always
    /// is.
    pub fn admits(&self, wrench: &Wrench) -> bool {
        crate::norm::length_within(wrench.force, self.max_force)
            && crate::norm::length_within(wrench.torque, self.max_torque)
    }
}

impl Default for DeviceLimits {
    fn default() -> Self {
        Self::PAPER
    }
}

/// Why a device could not be read or written. Any of these ends a haptic session (after the loop
/// has written a zero wrench).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DeviceError {
    /// The caller passed a time earlier than the previous call's.
    #[error("device {device}: time went backwards from {previous} s to {now} s")]
    TimeWentBackwards {
        /// Device name.
        device: String,
        /// The previous time (s).
        previous: f64,
        /// The time passed now (s).
        now: f64,
    },
    /// A value read from or written to the device was NaN or infinite.
    #[error("device {device}: non-finite {what}")]
    NonFinite {
        /// Device name.
        device: String,
        /// Which value ("written force", "handle position", ...).
        what: &'static str,
    },
    /// A replayed trace has no more frames.
    #[error("device {device}: trace exhausted after {frames} frames")]
    TraceExhausted {
        /// Device name.
        device: String,
        /// Number of frames the trace held.
        frames: u64,
    },
    /// The device was configured with invalid parameters.
    #[error("device {device}: invalid configuration: {message}")]
    Config {
        /// Device name.
        device: String,
        /// Which parameter and why.
        message: String,
    },
    /// The hardware or its driver failed.
    #[error("device {device}: {message}")]
    Hardware {
        /// Device name.
        device: String,
        /// The driver's message.
        message: String,
    },
}

/// A 6-DOF haptic device, driven by one thread at the frame rate.
///
/// Per frame the loop calls [`HapticDevice::read`] once, then [`HapticDevice::write`] once. Time is
/// passed in (seconds since the session started, the frame's scheduled tick), never read from a clock
/// inside the device, so simulated devices are deterministic.
///
/// Blocking: implementations must return within a small fraction of a frame (the loop's watchdog
/// counts a frame whose compute overruns its budget). The devices in this crate never block, never
/// sleep and do not allocate in `read`/`write` (except [`TraceRecorder`](crate::TraceRecorder)
/// growth, which is not a device). A hardware driver may block for its bus transfer; it must document
/// how long.
pub trait HapticDevice: Send {
    /// The handle's pose and velocities at time `t` (s since start; non-decreasing between calls).
    fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError>;
    /// Commands the wrench the device applies to the user's hand (N, N·m, world frame) until the
    /// next write. A device saturates a wrench beyond its [`DeviceLimits`]; a non-finite wrench is
    /// an error and the device keeps its previous output.
    fn write(&mut self, wrench: &Wrench) -> Result<(), DeviceError>;
    /// The largest wrench this device renders.
    fn limits(&self) -> DeviceLimits;
    /// A short human-readable name, used in errors and reports.
    fn name(&self) -> &str;
    /// The device's own counters for the session report (for a network bridge: datagrams
    /// accepted, stale, malformed, unauthorized, sent), as a JSON object; `None` (the default)
    /// when it keeps none. Called once, after the session's last write; may allocate.
    fn counters(&self) -> Option<serde_json::Value> {
        None
    }
}

/// Writes [`HapticDevice::limits`] and [`HapticDevice::name`] inside an `impl HapticDevice`
/// block, for a device that keeps its limits in a field `limits: DeviceLimits` and its name in a
/// field `name: String` (the replay device here, the SpaceMouse driver in `vps-input`).
#[macro_export]
macro_rules! limits_and_name_from_fields {
    () => {
        fn limits(&self) -> $crate::DeviceLimits {
            self.limits
        }

        fn name(&self) -> &str {
            &self.name
        }
    };
}

/// Checks every component of a handle sample is finite.
pub(crate) fn check_sample(device: &str, s: &HandleSample) -> Result<(), DeviceError> {
    let what = if !s.position.is_finite() {
        "handle position"
    } else if !s.orientation.is_finite() {
        "handle orientation"
    } else if !s.linear_velocity.is_finite() {
        "handle linear velocity"
    } else if !s.angular_velocity.is_finite() {
        "handle angular velocity"
    } else {
        return Ok(());
    };
    Err(DeviceError::NonFinite {
        device: device.to_string(),
        what,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn saturate_keeps_direction_and_fits_limits() {
        let lim = DeviceLimits::PAPER;
        let w = Wrench {
            force: DVec3::new(30.0, 40.0, 0.0),
            torque: DVec3::new(0.0, 0.0, -0.05),
        };
        let s = lim.saturate(&w);
        assert!((s.force.length() - 15.0).abs() < 1e-12);
        assert!((s.force.normalize() - w.force.normalize()).length() < 1e-12);
        assert_eq!(s.torque, w.torque);
        assert!(lim.admits(&s));
        assert!(!lim.admits(&w));
    }

    #[test]
    fn saturate_zeroes_non_finite() {
        let w = Wrench {
            force: DVec3::new(f64::NAN, 0.0, 0.0),
            torque: DVec3::ZERO,
        };
        assert_eq!(DeviceLimits::PAPER.saturate(&w), Wrench::ZERO);
        assert!(!DeviceLimits::PAPER.admits(&w));
    }

    #[test]
    fn validate_names_the_key_and_range() {
        assert_eq!(DeviceLimits::PAPER.validate(), Ok(()));
        for (limits, key) in [
            (
                DeviceLimits {
                    max_force: 0.0,
                    max_torque: 0.1,
                },
                "max_force",
            ),
            (
                DeviceLimits {
                    max_force: f64::NAN,
                    max_torque: 0.1,
                },
                "max_force",
            ),
            (
                DeviceLimits {
                    max_force: 15.0,
                    max_torque: 2e3,
                },
                "max_torque",
            ),
        ] {
            let err = limits.validate().unwrap_err();
            assert!(err.contains(key) && err.contains("(0, "), "{err}");
        }
    }
}
