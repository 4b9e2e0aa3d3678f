//! The dynamic object's state (f64, integrated by [`crate::step`]) and its f32 image for the
//! sampling kernel ([`KernelPose`]).

use glam::{DQuat, DVec3, Mat3, Vec3};

/// Pose and velocities of the dynamic object (the part), in the world frame.
///
/// Invariants kept by [`crate::step`]: every component finite, `orientation` unit length.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PartState {
    /// Position of the body origin (m): the part's grip, which is its centre of mass unless a
    /// scene file sets `part.grip`. The dynamics ([`crate::dynamics`]) treat this point as the
    /// centre of mass.
    pub position: DVec3,
    /// Orientation: body frame → world frame (unit quaternion).
    pub orientation: DQuat,
    /// Linear velocity of the body origin (m/s).
    pub linear_velocity: DVec3,
    /// Angular velocity, world frame (rad/s).
    pub angular_velocity: DVec3,
}

impl PartState {
    /// The part at `position` (m) and `orientation` with zero velocities. The orientation is
    /// normalised (identity if it cannot be).
    pub fn at_rest(position: DVec3, orientation: DQuat) -> Self {
        let orientation = if orientation.is_finite() && orientation.length() > 1e-12 {
            orientation.normalize()
        } else {
            DQuat::IDENTITY
        };
        Self {
            position,
            orientation,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
        }
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.position.is_finite()
            && self.orientation.is_finite()
            && self.linear_velocity.is_finite()
            && self.angular_velocity.is_finite()
    }
}

/// The per-frame input of the sampling kernel: the part's pose and velocities in f32.
///
/// World point of body point `p`: `P = rotation * p + translation`; its velocity
/// `V = linear_velocity + angular_velocity × (P − translation)`.
///
/// f32 keeps the kernel narrow and fast; world positions keep about 7 significant digits, i.e.
/// ≈1 µm at 10 m from the world origin, well below any useful voxel size.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KernelPose {
    /// Rotation matrix, body → world.
    pub rotation: Mat3,
    /// Position of the body origin (m), [`PartState::position`].
    pub translation: Vec3,
    /// Linear velocity of the body origin (m/s).
    pub linear_velocity: Vec3,
    /// Angular velocity, world frame (rad/s).
    pub angular_velocity: Vec3,
}

impl KernelPose {
    /// The f32 image of `state` (the orientation is normalised first). Does not allocate.
    pub fn from_state(state: &PartState) -> Self {
        let q = state.orientation.normalize();
        Self {
            rotation: Mat3::from_quat(q.as_quat()),
            translation: state.position.as_vec3(),
            linear_velocity: state.linear_velocity.as_vec3(),
            angular_velocity: state.angular_velocity.as_vec3(),
        }
    }

    /// True when every component is finite and no magnitude is absurd (translation and velocities
    /// below 1e6, rotation entries within ±2): the kernel then cannot overflow to infinity. The
    /// kernel samples nothing for a pose that fails this check.
    pub fn is_sane(&self) -> bool {
        const LIMIT: f32 = 1.0e6;
        let rot_ok = self.rotation.is_finite()
            && self.rotation.to_cols_array().iter().all(|c| c.abs() <= 2.0);
        rot_ok
            && [
                self.translation,
                self.linear_velocity,
                self.angular_velocity,
            ]
            .iter()
            .all(|v| v.is_finite() && v.abs().max_element() <= LIMIT)
    }
}
