//! The teapot point shell: normals point inward even when the tessellation's winding is scrambled.

use glam::DVec3;
use vps_mesh::builtin::teapot;
use vps_mesh::TriMesh;
use vps_voxelize::{point_shell, voxelize, ShellMethod, VoxelizeOptions};
use vps_voxmap::{PointShell, Voxel};

const S: f64 = 0.001;

/// Of the shell points where the object's offset-0 voxelization tells the sides apart (probing 1.5
/// then 3 voxels along ± the normal; Interior > Surface > Free), the fraction whose normal points to
/// the deeper side, and how many points could be told. Points on sheets with free space on both
/// sides (the spout's wall) cannot be told.
fn inward_fraction(mesh: &TriMesh, shell: &PointShell) -> (f64, usize) {
    let opts = VoxelizeOptions {
        voxel_size: S,
        offset_layers: 0,
        ..Default::default()
    };
    let grid = voxelize(std::slice::from_ref(mesh), &opts).unwrap();
    let rank = |p: DVec3| match grid.get(grid.spec.index_of(p)) {
        Voxel::Interior => 2,
        Voxel::Surface => 1,
        _ => 0,
    };
    let (mut told, mut good) = (0, 0);
    for (p, n) in shell.points.iter().zip(&shell.normals) {
        let q = p.as_dvec3() + shell.mass.center_of_mass;
        let n = n.as_dvec3();
        for k in [1.5, 3.0] {
            let (ahead, behind) = (rank(q + k * S * n), rank(q - k * S * n));
            if ahead != behind {
                told += 1;
                good += (ahead > behind) as usize;
                break;
            }
        }
    }
    (good as f64 / told as f64, told)
}

#[test]
fn teapot_normals_point_inward_even_with_scrambled_winding() {
    let pot = teapot();
    let mut scrambled = pot.clone();
    for t in scrambled.triangles.iter_mut().step_by(3) {
        t.swap(0, 1);
    }
    let clean = point_shell(&pot, S, ShellMethod::ExactSurface).unwrap();
    let mixed = point_shell(&scrambled, S, ShellMethod::ExactSurface).unwrap();
    for (mesh, shell) in [(&pot, &clean), (&scrambled, &mixed)] {
        assert!(shell.len() > 5000, "{}", shell.len());
        let (f, told) = inward_fraction(mesh, shell);
        assert!(told as f64 > 0.9 * shell.len() as f64, "{told}");
        assert!(f > 0.99, "inward fraction {f}");
    }
    // Same voxels, same order: the scrambled winding changes no normal. Where the voxelization
    // can orient a triangle it does; where it cannot (the spout's zero-thickness wall, free space
    // on both sides) the winding of the triangles turned outward decides, which is the clean
    // mesh's.
    assert_eq!(clean.len(), mixed.len());
    let agree = clean
        .normals
        .iter()
        .zip(&mixed.normals)
        .filter(|(a, b)| a.dot(**b) > 0.9)
        .count();
    assert_eq!(agree, clean.len());
    // Mass: divergence theorem for the clean mesh, voxel estimate for the scrambled one.
    let (a, b) = (clean.mass, mixed.mass);
    assert!(
        (a.volume / b.volume - 1.0).abs() < 0.05,
        "{} {}",
        a.volume,
        b.volume
    );
    assert!(
        a.center_of_mass.distance(b.center_of_mass) < S,
        "{} {}",
        a.center_of_mass,
        b.center_of_mass
    );
}
