//! Merging objects by precedence and the position of the offset force layer.

use crate::common;

use common::{check_invariants, voxels};
use glam::{DQuat, DVec3, IVec3};
use vps_mesh::builtin::cuboid;
use vps_voxelize::{grid_for, voxelize, voxelize_in, voxelize_with_stats, VoxelizeOptions};
use vps_voxmap::Voxel;

const S: f64 = 0.005;

fn at(c: DVec3) -> impl Fn(vps_mesh::TriMesh) -> vps_mesh::TriMesh {
    move |m| m.transformed(1.0, DQuat::IDENTITY, c)
}

#[test]
fn overlapping_cubes_merge_to_interior() {
    // Two 20-voxel cubes overlapping by 12 voxels along x: each one's inner faces lie inside the
    // other and must read Interior, not Surface.
    let h = 10.0 * S;
    let a = at(DVec3::new(0.0013, 0.0007, -0.0021))(cuboid(DVec3::splat(h)));
    let b = at(DVec3::new(0.0013 + 8.0 * S, 0.0007, -0.0021))(cuboid(DVec3::splat(h)));
    let opts = VoxelizeOptions {
        voxel_size: S,
        ..Default::default()
    };
    let grid = voxelize(&[a.clone(), b.clone()], &opts).unwrap();
    check_invariants(&grid, opts.offset_layers);
    let inside_union = |p: DVec3| {
        let da = (p - a.bounds().center()).abs().max_element();
        let db = (p - b.bounds().center()).abs().max_element();
        da.min(db) - h // negative inside the union (an approximation valid here)
    };
    let mut checked_faces = 0;
    for (ijk, v) in voxels(&grid) {
        let p = grid.spec.center_of(ijk);
        if inside_union(p) < -S * 3f64.sqrt() {
            assert_eq!(v, Voxel::Interior, "{ijk}");
            // Voxels on a's +x face (inside b) or b's -x face (inside a).
            let ax = a.bounds().max.x;
            let bx = b.bounds().min.x;
            if (p.x - ax).abs() < S || (p.x - bx).abs() < S {
                checked_faces += 1;
            }
        }
    }
    assert!(checked_faces > 200, "{checked_faces}");
    // At offset 0 the contrast is visible: as separate objects no Surface lies deep inside the
    // union, while the same triangles as one object keep their enclosed inner faces as Surface.
    let opts0 = VoxelizeOptions {
        offset_layers: 0,
        ..opts
    };
    let deep_surface = |grid: &vps_voxmap::DenseGrid| {
        voxels(grid)
            .filter(|(ijk, v)| {
                *v == Voxel::Surface && inside_union(grid.spec.center_of(*ijk)) < -S * 3f64.sqrt()
            })
            .count()
    };
    let separate = voxelize(&[a.clone(), b.clone()], &opts0).unwrap();
    assert_eq!(deep_surface(&separate), 0);
    let mut joined = a.clone();
    joined.append(&b);
    let single = voxelize(&[joined], &opts0).unwrap();
    assert!(deep_surface(&single) > 200);
}

#[test]
fn nested_object_vanishes_into_interior() {
    let outer = cuboid(DVec3::splat(12.0 * S));
    let inner = cuboid(DVec3::splat(4.0 * S));
    let opts = VoxelizeOptions {
        voxel_size: S,
        ..Default::default()
    };
    let both = voxelize(&[outer.clone(), inner], &opts).unwrap();
    let alone = voxelize(&[outer], &opts).unwrap();
    assert_eq!(both, alone);
}

#[test]
fn two_layer_offset_puts_surface_two_voxels_outside_the_face() {
    let h = 20.0 * S;
    let c = DVec3::new(0.0017, -0.0009, 0.0004);
    let cube = at(c)(cuboid(DVec3::splat(h)));
    let opts = VoxelizeOptions {
        voxel_size: S,
        offset_layers: 2,
        ..Default::default()
    };
    let (grid, stats) = voxelize_with_stats(&[cube], &opts).unwrap();
    check_invariants(&grid, 2);
    assert_eq!(stats.surface_voxels, grid.counts()[Voxel::Surface as usize]);
    // Signed distance to the +x face along rows through the face's middle part.
    let face_x = c.x + h;
    let mut rows = 0;
    for (ijk, v) in voxels(&grid) {
        let p = grid.spec.center_of(ijk);
        let off_axis = (p - c).abs();
        if v == Voxel::Surface {
            // Never deeper inside the cube than one voxel.
            let depth = h - (p - c).abs().max_element();
            assert!(depth <= S, "Surface voxel {ijk} {depth} m inside");
        }
        if v == Voxel::Surface && off_axis.y < h - 4.0 * S && off_axis.z < h - 4.0 * S && p.x > c.x
        {
            // The only Surface voxel of this row: 2 voxels out (1.5 to 2.5 s, face off-lattice).
            let d = p.x - face_x;
            assert!((1.5 * S - 1e-9..=2.5 * S + 1e-9).contains(&d), "{ijk}: {d}");
            let row_surface = (0..grid.spec.dims[0] as i32)
                .filter(|&x| grid.get(IVec3::new(x, ijk.y, ijk.z)) == Voxel::Surface)
                .count();
            assert_eq!(row_surface, 2, "one Surface voxel per face in row {ijk}");
            rows += 1;
        }
    }
    assert!(rows > 900, "{rows}");
}

#[test]
fn voxelize_in_uses_the_given_grid() {
    let cube = cuboid(DVec3::splat(5.0 * S));
    let opts = VoxelizeOptions {
        voxel_size: S,
        ..Default::default()
    };
    let big = grid_for(
        &vps_mesh::Aabb {
            min: DVec3::splat(-0.2),
            max: DVec3::splat(0.2),
        },
        &opts,
    )
    .unwrap();
    let in_big = voxelize_in(std::slice::from_ref(&cube), big, &opts).unwrap();
    assert_eq!(in_big.spec, big);
    let own = voxelize(&[cube], &opts).unwrap();
    // Same lattice (origins on multiples of s): identical kinds at identical world points.
    assert_eq!(own.counts()[1..], in_big.counts()[1..]);
    for (ijk, v) in voxels(&own) {
        let p = own.spec.center_of(ijk);
        assert_eq!(in_big.get(in_big.spec.index_of(p)), v);
    }
}
