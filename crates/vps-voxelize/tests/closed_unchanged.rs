//! Closed, consistently oriented meshes keep the plain flood fill (docs/voxelize.md, "Open and
//! leaky meshes"): their voxmaps are bit-identical to those of the voxelizer before the winding
//! number was added. The fingerprints below were printed by this test's `print_fingerprints` run
//! against commit e5e24c3 (the flood fill alone) and must not change.

use crate::common;

use common::voxels;
use std::path::Path;
use vps_mesh::builtin::by_name;
use vps_mesh::load::load_mesh_scaled;
use vps_mesh::TriMesh;
use vps_voxelize::{voxelize, voxelize_tree, VoxelizeOptions};
use vps_voxmap::TreeConfig;

/// FNV-1a over the dims and every voxel kind in x-fastest order.
fn fingerprint(objects: &[TriMesh], voxel_size: f64) -> u64 {
    let opts = VoxelizeOptions {
        voxel_size,
        ..Default::default()
    };
    let grid = voxelize(objects, &opts).unwrap();
    let (tree, _) = voxelize_tree(objects, &opts, TreeConfig::default()).unwrap();
    assert_eq!(tree.to_dense(), grid, "sparse and dense differ");
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    let mut eat = |b: u8| h = (h ^ b as u64).wrapping_mul(0x0100_0000_01b3);
    for d in grid.spec.dims {
        d.to_le_bytes().into_iter().for_each(&mut eat);
    }
    for (_, v) in voxels(&grid) {
        eat(v as u8);
    }
    h
}

fn asset(name: &str) -> TriMesh {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../assets/scenes")
        .join(name);
    load_mesh_scaled(&path, 0.001).unwrap().mesh
}

/// The closed test scenes: built-in solids and the scene assets (in their file poses).
fn scenes() -> Vec<(&'static str, Vec<TriMesh>, f64)> {
    let b = |n: &str| by_name(n).unwrap();
    vec![
        ("box", vec![b("box")], 0.005),
        ("sphere", vec![b("sphere")], 0.003),
        ("cylinder", vec![b("cylinder")], 0.002),
        ("solids", vec![b("box"), b("sphere"), b("cylinder")], 0.004),
        ("peg", vec![asset("peg.obj")], 0.001),
        ("peg-fixture", vec![asset("peg-fixture.stl")], 0.002),
        ("bracket", vec![asset("bracket.obj")], 0.002),
        ("bay", vec![b("aircraft-bay")], 0.04),
    ]
}

/// Fingerprints of [`scenes`] from the flood-fill-only voxelizer (commit e5e24c3).
const EXPECTED: [(&str, u64); 8] = [
    ("box", 0x64fe4530c852fb3b),
    ("sphere", 0xe21c6e36e941f52f),
    ("cylinder", 0x6e7ac6bfe8eec61e),
    ("solids", 0x0ff24391143f7f0f),
    ("peg", 0x7e35bef03a7d3d50),
    ("peg-fixture", 0x31e3c33036dab758),
    ("bracket", 0x4f5e22c9eac02400),
    ("bay", 0x02a7bd428f4dca1f),
];

#[test]
fn closed_scenes_are_bit_identical_to_the_flood_fill() {
    let mut wrong = Vec::new();
    for ((name, objects, s), (expected_name, expected)) in scenes().into_iter().zip(EXPECTED) {
        assert_eq!(name, expected_name);
        let got = fingerprint(&objects, s);
        println!("(\"{name}\", 0x{got:016x}),");
        if got != expected {
            wrong.push(name);
        }
    }
    assert!(wrong.is_empty(), "changed: {wrong:?}");
}
