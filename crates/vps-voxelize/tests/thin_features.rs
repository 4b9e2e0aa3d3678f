//! Wires and spikes thinner than a voxel (docs/architecture.md#voxmaps-and-point-shells): the 26-connected offset grows them into closed
//! layers. Checked criterion: Interior runs along the whole feature, and no Free or Proximity voxel
//! shares a face, edge or corner with an Interior voxel (so a shell point cannot slip from free space
//! into the interior without crossing Surface).

use crate::common;

use common::check_invariants;
use glam::{DQuat, DVec3};
use std::f64::consts::TAU;
use vps_mesh::builtin::cylinder;
use vps_mesh::TriMesh;
use vps_voxelize::{voxelize, VoxelizeOptions};
use vps_voxmap::{DenseGrid, Voxel};

const S: f64 = 0.005;

fn voxelize_k(mesh: &TriMesh, k: u32) -> DenseGrid {
    let opts = VoxelizeOptions {
        voxel_size: S,
        offset_layers: k,
        ..Default::default()
    };
    voxelize(std::slice::from_ref(mesh), &opts).unwrap()
}

/// Kinds of the voxels containing points of the segment `a`–`b` (sampled every 0.1 voxel).
fn along(grid: &DenseGrid, a: DVec3, b: DVec3) -> Vec<Voxel> {
    let n = ((b - a).length() / (0.1 * S)).ceil() as usize;
    (0..=n)
        .map(|i| grid.get(grid.spec.index_of(a + (b - a) * (i as f64 / n as f64))))
        .collect()
}

/// A closed cone of base radius `r` and height `h` along +z from the origin.
fn cone(r: f64, h: f64, segments: u32) -> TriMesh {
    let mut vertices: Vec<DVec3> = (0..segments)
        .map(|j| {
            let phi = TAU * j as f64 / segments as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), 0.0)
        })
        .collect();
    vertices.push(DVec3::new(0.0, 0.0, h)); // apex
    vertices.push(DVec3::ZERO); // base centre
    let (apex, base) = (segments, segments + 1);
    let mut triangles = Vec::new();
    for j in 0..segments {
        let k = (j + 1) % segments;
        triangles.push([j, k, apex]);
        triangles.push([base, k, j]);
    }
    TriMesh::new(vertices, triangles)
}

#[test]
fn diagonal_thin_wire_becomes_a_closed_layer() {
    // Radius 0.2 voxel, 40 voxels long, tilted off every axis.
    let rot = DQuat::from_euler(glam::EulerRot::XYZ, 0.7, 0.5, 0.2);
    let t = DVec3::new(0.0011, 0.0023, -0.0017);
    let wire = cylinder(0.2 * S, 20.0 * S, 12).transformed(1.0, rot, t);
    let (a, b) = (
        rot * DVec3::new(0.0, 0.0, -19.0 * S) + t,
        rot * DVec3::new(0.0, 0.0, 19.0 * S) + t,
    );
    for k in [0, 1, 2] {
        let grid = voxelize_k(&wire, k);
        let counts = check_invariants(&grid, k);
        let axis = along(&grid, a, b);
        if k == 0 {
            // Nothing fits inside; the wire is all Surface and never Free.
            assert!(axis.iter().all(|&v| v == Voxel::Surface));
        } else {
            assert!(axis.iter().all(|&v| v == Voxel::Interior), "k = {k}");
            assert!(counts[Voxel::Surface as usize] > 0);
        }
    }
}

#[test]
fn thin_spike_becomes_a_closed_layer_up_to_its_tip() {
    // A cone 1.5 voxels wide at the base and 30 voxels tall: most of it is thinner than a voxel.
    let rot = DQuat::from_euler(glam::EulerRot::XYZ, -0.4, 0.9, 0.3);
    let t = DVec3::new(-0.0007, 0.0031, 0.0013);
    let spike = cone(0.75 * S, 30.0 * S, 16).transformed(1.0, rot, t);
    let (base, tip) = (t, rot * DVec3::new(0.0, 0.0, 30.0 * S) + t);
    for k in [1, 2] {
        let grid = voxelize_k(&spike, k);
        check_invariants(&grid, k);
        assert!(
            along(&grid, base, tip)
                .iter()
                .all(|&v| v == Voxel::Interior),
            "k = {k}"
        );
        // Beyond the tip, k layers of Surface then Proximity before Free.
        let dir = (tip - base).normalize();
        let out = along(
            &grid,
            tip + dir * 0.01 * S,
            tip + dir * (k as f64 + 3.0) * S * 3f64.sqrt(),
        );
        assert!(out.contains(&Voxel::Surface) && out.contains(&Voxel::Proximity));
        assert_eq!(*out.last().unwrap(), Voxel::Free);
    }
}
