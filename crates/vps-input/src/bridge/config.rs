//! Bridge configuration, its validation, and the bridge's errors.

use std::net::{Ipv4Addr, SocketAddr};

use glam::{DQuat, DVec3};
use vps_device::DeviceLimits;

use super::error::BridgeError;
use super::mapping::WorkspaceMapping;
use super::protocol::Token;

/// Longest accepted `wrench_log_frames`: one hour at 1 kHz (56 bytes each, about 200 MB).
pub const MAX_WRENCH_LOG_FRAMES: usize = 3_600_000;

/// Allowed `pose_timeout` (s), both ends included.
pub const POSE_TIMEOUT_RANGE_S: std::ops::RangeInclusive<f64> = 0.002..=10.0;

/// Settings of a [`BridgeDevice`](super::BridgeDevice) (TOML/JSON loadable; defaults for all).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BridgeConfig {
    /// Address to bind. Default `127.0.0.1:0` (loopback, any free port).
    pub bind: SocketAddr,
    /// Must be true to bind a non-loopback address. Default false.
    pub allow_remote: bool,
    /// Shared secret every datagram must carry. Required (and non-zero) for a non-loopback bind;
    /// optional on loopback (when `None` the token field is ignored).
    pub token: Option<Token>,
    /// Handle position reported before any pose arrives (m, world frame; finite).
    pub initial_position: DVec3,
    /// Handle orientation reported before any pose arrives (unit quaternion within 1e-6).
    pub initial_orientation: DQuat,
    /// When the newest pose is older than this, its velocities are reported as zero (the pose is
    /// held) (s; finite, > 0). Default 0.1.
    pub velocity_timeout: f64,
    /// When the newest pose is older than this, the device holds: the handle stays at its last
    /// scene pose with zero velocities, zero wrenches are sent, and the next fresh pose re-anchors
    /// the mapping so the part does not jump (s; finite, in [0.002, 10]). Default 0.05.
    pub pose_timeout: f64,
    /// Device frame → scene frame, and scene wrench → device wrench. Default: the identity.
    pub mapping: WorkspaceMapping,
    /// Saturation limits applied to written wrenches, in the device frame after the mapping's
    /// force scale. Default [`DeviceLimits::PAPER`].
    pub limits: DeviceLimits,
    /// Keep every wrench sent, up to this many, for [`BridgeMonitor`](super::BridgeMonitor)
    /// (0: none; at most [`MAX_WRENCH_LOG_FRAMES`]; reserved when the device is bound).
    pub wrench_log_frames: usize,
    /// Device name used in errors and reports. Default "udp bridge".
    pub name: String,
}

impl Default for BridgeConfig {
    fn default() -> Self {
        Self {
            bind: SocketAddr::from((Ipv4Addr::LOCALHOST, 0)),
            allow_remote: false,
            token: None,
            initial_position: DVec3::ZERO,
            initial_orientation: DQuat::IDENTITY,
            velocity_timeout: 0.1,
            pose_timeout: 0.05,
            mapping: WorkspaceMapping::default(),
            limits: DeviceLimits::PAPER,
            wrench_log_frames: 0,
            name: "udp bridge".to_string(),
        }
    }
}

fn bad(field: &'static str, message: impl Into<String>) -> BridgeError {
    BridgeError::Config {
        field,
        message: message.into(),
    }
}

impl BridgeConfig {
    /// Checks every field; the error names the first bad one. A non-loopback `bind` needs
    /// `allow_remote` and a non-zero `token`.
    pub fn validate(&self) -> Result<(), BridgeError> {
        if !self.bind.ip().is_loopback() {
            if !self.allow_remote {
                return Err(bad(
                    "allow_remote",
                    format!(
                        "binding non-loopback address {} requires allow_remote = true",
                        self.bind
                    ),
                ));
            }
            match self.token {
                None => {
                    return Err(bad(
                        "token",
                        format!(
                            "binding non-loopback address {} requires a token",
                            self.bind
                        ),
                    ))
                }
                Some(t) if t == [0; 16] => {
                    return Err(bad("token", "an all-zero token is not a secret"))
                }
                Some(_) => {}
            }
        }
        crate::check_start_pose(
            self.initial_position,
            self.initial_orientation,
            ["initial_position", "initial_orientation"],
        )
        .map_err(|(field, message)| bad(field, message))?;
        if !(self.velocity_timeout.is_finite() && self.velocity_timeout > 0.0) {
            return Err(bad(
                "velocity_timeout",
                format!("{} s must be finite and > 0", self.velocity_timeout),
            ));
        }
        if !(self.pose_timeout.is_finite() && POSE_TIMEOUT_RANGE_S.contains(&self.pose_timeout)) {
            return Err(bad(
                "pose_timeout",
                format!(
                    "{} s must be finite and within [{}, {}]",
                    self.pose_timeout,
                    POSE_TIMEOUT_RANGE_S.start(),
                    POSE_TIMEOUT_RANGE_S.end()
                ),
            ));
        }
        self.mapping.validate()?;
        if self.wrench_log_frames > MAX_WRENCH_LOG_FRAMES {
            return Err(bad(
                "wrench_log_frames",
                format!(
                    "{} exceeds the maximum {MAX_WRENCH_LOG_FRAMES}",
                    self.wrench_log_frames
                ),
            ));
        }
        let l = self.limits;
        if !(l.max_force.is_finite() && l.max_force > 0.0) {
            return Err(bad(
                "limits",
                format!("max_force {} N must be finite and > 0", l.max_force),
            ));
        }
        if !(l.max_torque.is_finite() && l.max_torque > 0.0) {
            return Err(bad(
                "limits",
                format!("max_torque {} N·m must be finite and > 0", l.max_torque),
            ));
        }
        Ok(())
    }
}

/// Parses a token written as 32 hex digits (e.g. from a command line or environment variable).
pub fn parse_token_hex(text: &str) -> Result<Token, BridgeError> {
    let text = text.trim();
    let digits = text.as_bytes();
    if digits.len() != 32 {
        return Err(bad(
            "token",
            format!("expected 32 hex digits, got {} characters", digits.len()),
        ));
    }
    let mut token = [0u8; 16];
    for (i, (byte, pair)) in token.iter_mut().zip(digits.chunks_exact(2)).enumerate() {
        let hex = |c: u8| (c as char).to_digit(16);
        match (hex(pair[0]), hex(pair[1])) {
            (Some(h), Some(l)) => *byte = (h * 16 + l) as u8,
            _ => {
                return Err(bad(
                    "token",
                    format!("character {} or {} is not a hex digit", 2 * i, 2 * i + 1),
                ))
            }
        }
    }
    Ok(token)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_is_valid_loopback() {
        let c = BridgeConfig::default();
        c.validate().unwrap();
        assert!(c.bind.ip().is_loopback());
    }

    #[test]
    fn remote_bind_needs_permission_and_a_token() {
        let remote = SocketAddr::from(([0, 0, 0, 0], 0));
        let mut c = BridgeConfig {
            bind: remote,
            ..Default::default()
        };
        let e = c.validate().unwrap_err();
        assert!(
            matches!(
                e,
                BridgeError::Config {
                    field: "allow_remote",
                    ..
                }
            ),
            "{e}"
        );
        c.allow_remote = true;
        assert!(matches!(
            c.validate(),
            Err(BridgeError::Config { field: "token", .. })
        ));
        c.token = Some([0; 16]);
        assert!(matches!(
            c.validate(),
            Err(BridgeError::Config { field: "token", .. })
        ));
        c.token = Some([9; 16]);
        c.validate().unwrap();
    }

    #[test]
    fn other_fields_are_named() {
        /// An edit of the default config, and the field its error must name.
        type Case = (fn(&mut BridgeConfig), &'static str);
        let cases: [Case; 5] = [
            (|c| c.velocity_timeout = 0.0, "velocity_timeout"),
            (
                |c| c.initial_orientation = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0),
                "initial_orientation",
            ),
            (|c| c.pose_timeout = 0.0, "pose_timeout"),
            (
                |c| c.wrench_log_frames = MAX_WRENCH_LOG_FRAMES + 1,
                "wrench_log_frames",
            ),
            (
                |c| {
                    c.limits = DeviceLimits {
                        max_force: f64::INFINITY,
                        max_torque: 0.1,
                    }
                },
                "limits",
            ),
        ];
        for (edit, field) in cases {
            let mut c = BridgeConfig::default();
            edit(&mut c);
            match c.validate() {
                Err(BridgeError::Config { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
    }

    #[test]
    fn hex_tokens() {
        let t = parse_token_hex("000102030405060708090a0b0c0d0eFF").unwrap();
        assert_eq!(t[1], 1);
        assert_eq!(t[15], 0xff);
        assert!(parse_token_hex("abc").is_err());
        assert!(parse_token_hex("zz0102030405060708090a0b0c0d0e0f").is_err());
        assert!(parse_token_hex("é00102030405060708090a0b0c0d0e0").is_err());
    }
}
