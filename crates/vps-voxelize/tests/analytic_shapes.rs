//! Sphere and box voxmaps against analytic inside/outside: voxels whose centres are farther than
//! (offset + 1.5)·s·√3 from the surface must be Interior inside and Free outside.

use crate::common;

use common::{check_invariants, voxels};
use glam::{DQuat, DVec3};
use vps_mesh::builtin::{cuboid, uv_sphere};
use vps_mesh::TriMesh;
use vps_voxelize::{voxelize, VoxelizeOptions};
use vps_voxmap::Voxel;

const S: f64 = 0.005;

/// Voxelizes `mesh` and checks every voxel far from the surface against the signed distance `sdf`
/// (negative inside). Returns how many voxels were checked inside and outside.
fn check_against_sdf(mesh: &TriMesh, k: u32, sdf: impl Fn(DVec3) -> f64) -> (usize, usize) {
    let opts = VoxelizeOptions {
        voxel_size: S,
        offset_layers: k,
        ..Default::default()
    };
    let grid = voxelize(std::slice::from_ref(mesh), &opts).unwrap();
    check_invariants(&grid, k);
    let margin = (k as f64 + 1.5) * S * 3f64.sqrt();
    let (mut inside, mut outside) = (0, 0);
    for (ijk, v) in voxels(&grid) {
        let d = sdf(grid.spec.center_of(ijk));
        if d < -margin {
            assert_eq!(v, Voxel::Interior, "voxel {ijk} at depth {d}");
            inside += 1;
        } else if d > margin {
            assert_eq!(v, Voxel::Free, "voxel {ijk} at distance {d}");
            outside += 1;
        }
    }
    (inside, outside)
}

#[test]
fn sphere_matches_analytic_inside_outside() {
    let r = 0.08;
    let c = DVec3::new(0.0123, -0.0371, 0.2219);
    // 64 x 32 facets stay within 0.3 mm of the true sphere, far inside the margin.
    let mesh = uv_sphere(r, 64, 32).transformed(1.0, DQuat::IDENTITY, c);
    for k in [0, 2] {
        let (inside, outside) = check_against_sdf(&mesh, k, |p| p.distance(c) - r);
        assert!(inside > 1000 && outside > 1000, "{inside} {outside}");
    }
}

#[test]
fn rotated_box_matches_analytic_inside_outside() {
    let half = DVec3::new(0.07, 0.05, 0.04);
    let rot = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1);
    let t = DVec3::new(-0.11, 0.07, 0.013);
    let mesh = cuboid(half).transformed(1.0, rot, t);
    let sdf = |p: DVec3| {
        let q = (rot.inverse() * (p - t)).abs() - half;
        q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
    };
    for k in [0, 1, 2] {
        let (inside, outside) = check_against_sdf(&mesh, k, sdf);
        assert!(inside > 100 && outside > 1000, "{inside} {outside}");
    }
}

#[test]
fn interior_volume_tracks_the_sphere() {
    // At offset 0, Interior + half the Surface approximates the enclosed volume.
    let r = 0.05;
    let mesh = uv_sphere(r, 64, 32);
    let opts = VoxelizeOptions {
        voxel_size: S,
        offset_layers: 0,
        ..Default::default()
    };
    let grid = voxelize(&[mesh], &opts).unwrap();
    let [_, interior, surface, _] = grid.counts();
    let v = (interior as f64 + 0.5 * surface as f64) * S.powi(3);
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!((v / exact - 1.0).abs() < 0.05, "{v} vs {exact}");
}
