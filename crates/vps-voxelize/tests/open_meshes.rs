//! Open meshes (docs/architecture.md#voxmaps-and-point-shells): cracks narrower than a voxel do not leak, because scan conversion marks
//! every voxel touching either side of the crack and the 6-connected flood fill cannot pass; a hole
//! wider than a voxel does leak, and the inside of a genuinely open box is Free.

mod common;

use common::{check_invariants, voxels};
use glam::DVec3;
use vps_mesh::builtin::cuboid;
use vps_mesh::TriMesh;
use vps_voxelize::{voxelize, VoxelizeOptions};
use vps_voxmap::{DenseGrid, Voxel};

const S: f64 = 0.005;
/// Half extent of the test boxes (m): 10 voxels.
const H: f64 = 0.05;
/// Centre of the test boxes, off the voxel lattice.
const C: DVec3 = DVec3::new(0.0012, -0.0021, 0.0033);

/// A box with its +z face removed.
fn box_without_top() -> TriMesh {
    let mut m = cuboid(DVec3::splat(H));
    // Drop the two triangles whose vertices all have z = +H.
    m.triangles
        .retain(|t| !t.iter().all(|&v| m.vertices[v as usize].z == H));
    assert_eq!(m.triangles.len(), 10);
    m
}

/// Appends the axis-aligned quad z = `z`, |x|, |y| <= `half` (two triangles).
fn add_top(m: &mut TriMesh, half: f64, z: f64) {
    let quad = TriMesh::new(
        vec![
            DVec3::new(-half, -half, z),
            DVec3::new(half, -half, z),
            DVec3::new(half, half, z),
            DVec3::new(-half, half, z),
        ],
        vec![[0, 1, 2], [0, 2, 3]],
    );
    m.append(&quad);
}

fn voxelize0(m: &TriMesh) -> DenseGrid {
    let m = m.transformed(1.0, glam::DQuat::IDENTITY, C);
    let opts = VoxelizeOptions {
        voxel_size: S,
        offset_layers: 0,
        ..Default::default()
    };
    let grid = voxelize(&[m], &opts).unwrap();
    check_invariants(&grid, 0);
    grid
}

/// Kinds of the voxels whose centres lie inside the box deeper than one voxel.
fn deep_inside(grid: &DenseGrid) -> Vec<Voxel> {
    voxels(grid)
        .filter(|(ijk, _)| {
            let p = (grid.spec.center_of(*ijk) - C).abs();
            p.max_element() < H - S
        })
        .map(|(_, v)| v)
        .collect()
}

#[test]
fn in_plane_crack_narrower_than_a_voxel_does_not_leak() {
    // The lid is 0.4 voxel smaller than the opening on every side.
    let mut m = box_without_top();
    add_top(&mut m, H - 0.4 * S, H);
    let inside = deep_inside(&voxelize0(&m));
    assert!(inside.len() > 4000);
    assert!(inside.iter().all(|&v| v == Voxel::Interior));
}

#[test]
fn raised_lid_slit_narrower_than_a_voxel_does_not_leak() {
    // The lid covers the opening but floats 0.6 voxel above the walls: a horizontal slit all round.
    let mut m = box_without_top();
    add_top(&mut m, H, H + 0.6 * S);
    let inside = deep_inside(&voxelize0(&m));
    assert!(inside.iter().all(|&v| v == Voxel::Interior));
}

#[test]
fn crack_wider_than_a_voxel_leaks() {
    // Lid 1.5 voxels short on every side: free space floods in.
    let mut m = box_without_top();
    add_top(&mut m, H - 2.5 * S, H);
    assert_flooded(&voxelize0(&m));
}

/// Free space reached the inside: no Interior, only Free (and Proximity near the walls), and the
/// centre is Free.
fn assert_flooded(grid: &DenseGrid) {
    let inside = deep_inside(grid);
    assert!(inside
        .iter()
        .all(|&v| v == Voxel::Free || v == Voxel::Proximity));
    let free = inside.iter().filter(|&&v| v == Voxel::Free).count();
    assert!(free * 2 > inside.len(), "{free} of {}", inside.len());
    assert_eq!(grid.get(grid.spec.index_of(C)), Voxel::Free);
}

#[test]
fn open_box_is_free_inside() {
    let grid = voxelize0(&box_without_top());
    assert_flooded(&grid);
    assert_eq!(grid.counts()[Voxel::Interior as usize], 0);
    // The walls are still there.
    assert!(grid.counts()[Voxel::Surface as usize] > 2000);
}
