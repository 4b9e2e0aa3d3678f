//! [`WorkspaceMapping`]: the device's small workspace placed in the scene, and the scene's wrench
//! scaled back to the device; [`Anchor`], the re-anchorable part of it (clutch, pose timeout).
//!
//! With `R` the fixed rotation ([`WorkspaceMapping::rotation`]), `s` the scale and the anchor
//! `(a, A)` (a position in m and a rotation, initially `(offset, identity)`):
//!
//! ```text
//! position          p_scene = a + s · R · p_device
//! orientation       q_scene = A · R · q_device
//! linear velocity   v_scene = s · R · v_device
//! angular velocity  ω_scene = A · R · ω_device
//! force  back       F_device = force_scale · R⁻¹ · F_scene
//! torque back       T_device = force_scale · (A · R)⁻¹ · T_scene
//! ```
//!
//! Re-anchoring at a device pose keeps `R` and `s` (moving the handle right still moves the part
//! right) and solves for `(a, A)` so that pose maps exactly onto a held scene pose. Nothing here
//! allocates or blocks.

use glam::{DQuat, DVec3};
use vps_haptic::{HandleSample, Wrench};

use super::error::BridgeError;

/// How device coordinates map into the scene (TOML/JSON loadable, e.g. from a scene file's
/// `[device]` section; every field has a default, and the default is the identity).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorkspaceMapping {
    /// Scene metres per device metre (finite, in [1e-3, 1e3]). Default 1.
    pub scale: f64,
    /// Rotation from device axes to scene axes, as angles about X, Y, Z (degrees, finite),
    /// composed as `R = Rz · Ry · Rx` (X applied first). Default `[0, 0, 0]`.
    pub rotate_deg: [f64; 3],
    /// Scene position of the device's origin (m, finite) until the first re-anchoring.
    /// Default `[0, 0, 0]`.
    pub offset: [f64; 3],
    /// Device force per scene force, also applied to torques (finite, in (0, 1e3]). The result
    /// is then saturated to the device's limits. Default 1.
    pub force_scale: f64,
}

impl Default for WorkspaceMapping {
    fn default() -> Self {
        Self {
            scale: 1.0,
            rotate_deg: [0.0; 3],
            offset: [0.0; 3],
            force_scale: 1.0,
        }
    }
}

/// Allowed `scale` (scene metres per device metre), both ends included.
pub const SCALE_RANGE: std::ops::RangeInclusive<f64> = 1e-3..=1e3;

/// Largest `force_scale` (device force per scene force); it must also be above 0.
pub const MAX_FORCE_SCALE: f64 = 1e3;

fn bad(field: &'static str, message: String) -> BridgeError {
    BridgeError::Config { field, message }
}

impl WorkspaceMapping {
    /// Checks every field; the error names the first bad one and its allowed range.
    pub fn validate(&self) -> Result<(), BridgeError> {
        if !(self.scale.is_finite() && SCALE_RANGE.contains(&self.scale)) {
            return Err(bad(
                "mapping.scale",
                format!(
                    "{} must be finite and within [{}, {}]",
                    self.scale,
                    SCALE_RANGE.start(),
                    SCALE_RANGE.end()
                ),
            ));
        }
        if !self.rotate_deg.iter().all(|d| d.is_finite()) {
            return Err(bad(
                "mapping.rotate_deg",
                format!(
                    "{:?} must be three finite angles (degrees)",
                    self.rotate_deg
                ),
            ));
        }
        if !self.offset.iter().all(|d| d.is_finite()) {
            return Err(bad(
                "mapping.offset",
                format!("{:?} must be three finite coordinates (m)", self.offset),
            ));
        }
        if !(self.force_scale.is_finite()
            && self.force_scale > 0.0
            && self.force_scale <= MAX_FORCE_SCALE)
        {
            return Err(bad(
                "mapping.force_scale",
                format!(
                    "{} must be finite and within (0, {MAX_FORCE_SCALE}]",
                    self.force_scale
                ),
            ));
        }
        Ok(())
    }

    /// The fixed rotation `R = Rz · Ry · Rx` from device axes to scene axes.
    pub fn rotation(&self) -> DQuat {
        let [x, y, z] = self.rotate_deg.map(f64::to_radians);
        (DQuat::from_rotation_z(z) * DQuat::from_rotation_y(y) * DQuat::from_rotation_x(x))
            .normalize()
    }
}

/// A [`WorkspaceMapping`] with its current anchor: maps device samples into the scene and scene
/// wrenches back, and re-anchors so a device pose lands on a given scene pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Anchor {
    rotation: DQuat,
    scale: f64,
    force_scale: f64,
    position: DVec3,
    orientation: DQuat,
}

impl Anchor {
    /// The mapping anchored at its `offset` with no extra rotation. `mapping` should be
    /// validated first (see [`WorkspaceMapping::validate`]).
    pub fn new(mapping: &WorkspaceMapping) -> Self {
        Self {
            rotation: mapping.rotation(),
            scale: mapping.scale,
            force_scale: mapping.force_scale,
            position: DVec3::from_array(mapping.offset),
            orientation: DQuat::IDENTITY,
        }
    }

    /// `device` (device frame) in the scene frame.
    pub fn to_scene(&self, device: &HandleSample) -> HandleSample {
        let turn = self.orientation * self.rotation;
        HandleSample {
            position: self.position + self.scale * (self.rotation * device.position),
            orientation: (turn * device.orientation).normalize(),
            linear_velocity: self.scale * (self.rotation * device.linear_velocity),
            angular_velocity: turn * device.angular_velocity,
        }
    }

    /// `scene` (N, N·m, scene frame) in the device frame, scaled by the force scale (not yet
    /// saturated).
    pub fn to_device(&self, scene: &Wrench) -> Wrench {
        let turn = self.orientation * self.rotation;
        Wrench {
            force: self.force_scale * (self.rotation.inverse() * scene.force),
            torque: self.force_scale * (turn.inverse() * scene.torque),
        }
    }

    /// Re-anchors so that the device pose `device` maps onto the scene pose `held`
    /// (position m, unit orientation); scale and rotation are kept.
    pub fn reanchor(&mut self, device: &HandleSample, held_position: DVec3, held: DQuat) {
        self.position = held_position - self.scale * (self.rotation * device.position);
        self.orientation = (held * (self.rotation * device.orientation).inverse()).normalize();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(p: DVec3, q: DQuat) -> HandleSample {
        HandleSample {
            position: p,
            orientation: q,
            linear_velocity: DVec3::new(0.1, 0.0, 0.0),
            angular_velocity: DVec3::new(0.0, 0.0, 1.0),
        }
    }

    #[test]
    fn identity_by_default() {
        let a = Anchor::new(&WorkspaceMapping::default());
        let s = sample(DVec3::new(0.1, 0.2, 0.3), DQuat::from_rotation_x(0.4));
        let m = a.to_scene(&s);
        assert!((m.position - s.position).length() < 1e-15);
        assert!((m.orientation - s.orientation).length() < 1e-15);
        let w = Wrench {
            force: DVec3::new(1.0, 2.0, 3.0),
            torque: DVec3::new(0.01, 0.0, 0.0),
        };
        assert_eq!(a.to_device(&w), w);
    }

    #[test]
    fn scale_rotation_offset_and_force_scale() {
        let mapping = WorkspaceMapping {
            scale: 5.0,
            rotate_deg: [0.0, 0.0, 90.0],
            offset: [1.0, 2.0, 3.0],
            force_scale: 0.5,
        };
        mapping.validate().unwrap();
        let a = Anchor::new(&mapping);
        // Device +X (0.1 m) becomes scene +Y (0.5 m) from the offset.
        let m = a.to_scene(&sample(DVec3::new(0.1, 0.0, 0.0), DQuat::IDENTITY));
        assert!((m.position - DVec3::new(1.0, 2.5, 3.0)).length() < 1e-12);
        assert!((m.linear_velocity - DVec3::new(0.0, 0.5, 0.0)).length() < 1e-12);
        // A scene force along +Y pushes the device along +X, halved.
        let back = a.to_device(&Wrench {
            force: DVec3::new(0.0, 4.0, 0.0),
            torque: DVec3::ZERO,
        });
        assert!((back.force - DVec3::new(2.0, 0.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn reanchoring_lands_the_device_pose_on_the_held_pose() {
        let mapping = WorkspaceMapping {
            scale: 3.0,
            rotate_deg: [10.0, -20.0, 30.0],
            offset: [0.5, 0.0, 0.0],
            force_scale: 2.0,
        };
        let mut a = Anchor::new(&mapping);
        let device = sample(DVec3::new(0.05, -0.02, 0.07), DQuat::from_rotation_y(0.3));
        let held_p = DVec3::new(-1.0, 0.25, 2.0);
        let held_q = DQuat::from_rotation_z(-0.8);
        a.reanchor(&device, held_p, held_q);
        let m = a.to_scene(&device);
        assert!((m.position - held_p).length() < 1e-12);
        assert!(m.orientation.dot(held_q).abs() > 1.0 - 1e-12);
        // Motion after re-anchoring still follows scale and rotation.
        let moved = sample(device.position + DVec3::X * 0.01, device.orientation);
        let d = a.to_scene(&moved).position - m.position;
        assert!((d - 3.0 * (mapping.rotation() * DVec3::X * 0.01)).length() < 1e-12);
    }

    #[test]
    fn invalid_fields_are_named() {
        for (m, field) in [
            (
                WorkspaceMapping {
                    scale: 0.0,
                    ..Default::default()
                },
                "mapping.scale",
            ),
            (
                WorkspaceMapping {
                    rotate_deg: [f64::NAN, 0.0, 0.0],
                    ..Default::default()
                },
                "mapping.rotate_deg",
            ),
            (
                WorkspaceMapping {
                    offset: [0.0, f64::INFINITY, 0.0],
                    ..Default::default()
                },
                "mapping.offset",
            ),
            (
                WorkspaceMapping {
                    force_scale: -1.0,
                    ..Default::default()
                },
                "mapping.force_scale",
            ),
        ] {
            match m.validate() {
                Err(BridgeError::Config { field: f, .. }) => assert_eq!(f, field),
                other => panic!("{field}: {other:?}"),
            }
        }
        let toml_text = "scale = 4.0\nrotate_deg = [0.0, 90.0, 0.0]\nforce_scale = 0.25\n";
        let m: WorkspaceMapping = toml::from_str(toml_text).unwrap();
        assert_eq!((m.scale, m.offset, m.force_scale), (4.0, [0.0; 3], 0.25));
        assert!(toml::from_str::<WorkspaceMapping>("scael = 1.0").is_err());
    }
}
