//! Point shells.

use glam::{DVec3, Vec3};
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{MassProperties, PointShell};

use crate::scene::VOXEL;

/// Radius of the test sphere shell (m).
pub const SPHERE_RADIUS: f64 = 0.015;

/// `n` unit directions spread evenly over the sphere (Fibonacci lattice, in `f64`): direction `i`
/// has `z = 1 − 2 (i + ½) / n` and azimuth `i` times the golden angle.
pub fn fibonacci_directions(n: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// `n` points on a sphere of radius [`SPHERE_RADIUS`] centred on the body origin (a Fibonacci
/// lattice computed in `f32`, its axis along y), inward normals, [`VOXEL`] voxels.
pub fn sphere_shell(n: usize) -> PointShell {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let (points, normals) = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * i as f32;
            let dir = Vec3::new(r * phi.cos(), y, r * phi.sin());
            (dir * SPHERE_RADIUS as f32, -dir)
        })
        .unzip();
    PointShell {
        points,
        normals,
        voxel_size: VOXEL,
        method: ShellMethod::ExactSurface,
        mass: MassProperties {
            volume: 4.0 / 3.0 * std::f64::consts::PI * SPHERE_RADIUS.powi(3),
            center_of_mass: DVec3::ZERO,
            bounding_radius: SPHERE_RADIUS,
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_points_lie_on_the_sphere_with_inward_unit_normals() {
        let s = sphere_shell(300);
        assert_eq!((s.points.len(), s.normals.len()), (300, 300));
        for (p, n) in s.points.iter().zip(&s.normals) {
            assert!((p.length() as f64 - SPHERE_RADIUS).abs() < 1e-6, "{p}");
            assert!((n.length() - 1.0).abs() < 1e-5, "{n}");
            assert!(p.dot(*n) < 0.0, "{p} {n}");
        }
    }

    #[test]
    fn directions_are_unit_and_balanced() {
        let d = fibonacci_directions(1000);
        assert!(d.iter().all(|v| (v.length() - 1.0).abs() < 1e-12));
        let mean = d.iter().copied().sum::<DVec3>() / 1000.0;
        assert!(mean.length() < 1e-2, "{mean}");
    }
}
