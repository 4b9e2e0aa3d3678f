//! Hand-made scenes for tests (the runtime's own, and other crates' through the `test-support`
//! feature): a flat wall and a sphere point shell.

use glam::{DVec3, IVec3, Vec3};
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{DenseGrid, GridSpec, MassProperties, PointShell, Voxel};

/// Voxel size of the test wall (m).
pub const VOXEL: f64 = 0.005;

/// Height of the wall's outer face (m): Interior below z index 8, Surface at 8 and 9, Proximity at
/// 10, Free above.
pub const WALL_TOP: f64 = 0.05;

/// A 20 × 20 × 20 grid of 5 mm voxels holding a horizontal wall whose face is at [`WALL_TOP`].
pub fn wall() -> DenseGrid {
    let spec = GridSpec {
        origin: DVec3::ZERO,
        voxel_size: VOXEL,
        dims: [20, 20, 20],
    };
    let mut g = DenseGrid::new(spec);
    for z in 0..11 {
        let kind = match z {
            0..=7 => Voxel::Interior,
            8 | 9 => Voxel::Surface,
            _ => Voxel::Proximity,
        };
        for y in 0..20 {
            for x in 0..20 {
                g.set(IVec3::new(x, y, z), kind);
            }
        }
    }
    g
}

/// Radius of the test sphere shell (m).
pub const SPHERE_RADIUS: f64 = 0.015;

/// `n` points on a sphere of radius [`SPHERE_RADIUS`] (Fibonacci lattice), inward normals.
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
