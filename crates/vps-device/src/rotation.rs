//! Rotation vectors (axis × angle) on the shortest path.

use glam::{DQuat, DVec3};

/// The rotation vector (axis × angle, rad, angle in [0, π]) of unit quaternion `q`.
pub(crate) fn rotation_vector(q: DQuat) -> DVec3 {
    let q = if q.w < 0.0 { -q } else { q };
    q.to_scaled_axis()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn takes_the_short_way_round() {
        let q = DQuat::from_rotation_z(1.0);
        assert!((rotation_vector(q) - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-12);
        assert!((rotation_vector(-q) - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-12);
        let r = DQuat::from_rotation_z(-3.0);
        assert!((rotation_vector(r) - DVec3::new(0.0, 0.0, -3.0)).length() < 1e-12);
    }
}
