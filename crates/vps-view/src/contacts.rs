//! The contact points of the part at a pose, for drawing: the shell points in Surface voxels (with
//! their depth, as the sampling kernel defines it) and in Interior voxels.
//!
//! This is the viewer's own re-sampling, on the viewer's thread at the state rate, never the frame
//! loop's: the loop publishes only the pose. Depth per point (docs/architecture.md#the-haptic-frame, `vps_haptic::kernel`):
//! `d = max(0, N·(C − P) + ℓ s)` with `P = R p + x` the world point, `N = R n` its inward normal,
//! `C` the centre of its voxel and `ℓ` the voxel's distance layer (0 in a 2-bit map); here in f64,
//! so it may differ from the kernel's f32 figure in the last bits.

use glam::{DQuat, DVec3, Vec3};
use vps_voxmap::{PointShell, Voxel, VoxelTree};

/// One shell point in a non-free voxel of the static scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactSample {
    /// World position of the point (m).
    pub position: Vec3,
    /// Depth along its normal into the force layer (m); 0 for an Interior point.
    pub depth: f32,
    /// The point is in an Interior voxel (the part has gone through the force layer).
    pub interior: bool,
}

/// Replaces `out` with the shell points of `shell` at pose (`position` m, `orientation`) that are in
/// contact: in a Surface voxel with depth > 0, or in an Interior voxel. If there are more than
/// `max_points`, keeps the Interior points first and then the deepest. Reuses `out`'s capacity;
/// cost is one voxel lookup per shell point.
pub fn sample_contacts(
    tree: &VoxelTree,
    shell: &PointShell,
    position: DVec3,
    orientation: DQuat,
    max_points: usize,
    out: &mut Vec<ContactSample>,
) {
    out.clear();
    let spec = tree.spec();
    for (p, n) in shell.points.iter().zip(&shell.normals) {
        let world = orientation * p.as_dvec3() + position;
        let ijk = spec.index_of(world);
        let voxel = tree.get_layered(ijk);
        let sample = match voxel.kind {
            Voxel::Surface => {
                let normal = orientation * n.as_dvec3();
                let layer_depth = voxel.layer as f64 * spec.voxel_size;
                let depth = (normal.dot(spec.center_of(ijk) - world) + layer_depth).max(0.0);
                if depth <= 0.0 {
                    continue;
                }
                ContactSample {
                    position: world.as_vec3(),
                    depth: depth as f32,
                    interior: false,
                }
            }
            Voxel::Interior => ContactSample {
                position: world.as_vec3(),
                depth: 0.0,
                interior: true,
            },
            Voxel::Free | Voxel::Proximity => continue,
        };
        out.push(sample);
    }
    if out.len() > max_points {
        let deepest_first = |a: &ContactSample, b: &ContactSample| {
            b.interior
                .cmp(&a.interior)
                .then(b.depth.total_cmp(&a.depth))
        };
        if max_points > 0 {
            out.select_nth_unstable_by(max_points - 1, deepest_first);
        }
        out.truncate(max_points);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::content::tests::{slab, square_shell};

    /// The slab's Surface layer spans z ∈ [0.10, 0.11) m (centre 0.105); Interior below.
    fn at_height(z: f64, max_points: usize) -> Vec<ContactSample> {
        tilted(z, 0.0, max_points)
    }

    /// The square's contacts at height `z` (m), tilted by `angle` (rad) about x, keeping at most
    /// `max_points` (sampled into a non-empty vector: it must be cleared first).
    fn tilted(z: f64, angle: f64, max_points: usize) -> Vec<ContactSample> {
        let mut out = vec![ContactSample {
            position: Vec3::ZERO,
            depth: 9.0,
            interior: false,
        }];
        sample_contacts(
            &slab(),
            &square_shell(),
            DVec3::new(0.2, 0.2, z),
            DQuat::from_rotation_x(angle),
            max_points,
            &mut out,
        );
        out
    }

    #[test]
    fn free_space_gives_no_contacts() {
        assert!(at_height(0.2, 100).is_empty());
    }

    #[test]
    fn a_face_pressed_into_the_force_layer_gives_its_depth() {
        let c = at_height(0.102, 100);
        assert_eq!(c.len(), 25);
        for s in &c {
            assert!(!s.interior);
            assert!((s.depth - 0.003).abs() < 1e-6, "depth {}", s.depth);
            assert!((s.position.z - 0.102).abs() < 1e-6);
        }
        // Above the voxel centre the normal (+z) points away from it: depth 0, no contact.
        assert!(at_height(0.108, 100).is_empty());
    }

    #[test]
    fn interior_points_are_marked_and_the_cap_keeps_them() {
        let c = at_height(0.05, 100);
        assert_eq!(c.len(), 25);
        assert!(c.iter().all(|s| s.interior));
        // Tilt the square about x: one edge dips into the Interior, the rest stays in the force
        // layer at various depths.
        let rotated = tilted(0.1035, 0.2, 6);
        assert_eq!(rotated.len(), 6);
        assert!(rotated.iter().any(|s| s.interior));
        let kept_min = rotated
            .iter()
            .filter(|s| !s.interior)
            .map(|s| s.depth)
            .fold(f32::INFINITY, f32::min);
        let all = tilted(0.1035, 0.2, usize::MAX);
        assert!(all.len() > 6);
        let dropped_max = all
            .iter()
            .filter(|s| !s.interior && !rotated.contains(s))
            .map(|s| s.depth)
            .fold(0.0, f32::max);
        assert!(dropped_max <= kept_min, "the cap keeps the deepest");
    }
}
