//! The sparse (chunked) voxelizer builds exactly the tree the dense reference pipeline gives:
//! equal content hashes on the builtin scenes and on random triangle soups (open meshes, thin
//! plates, several objects), for several tree shapes, with and without a workspace.

use glam::DVec3;
use rand::{Rng, SeedableRng};
use vps_mesh::{builtin, Aabb, TriMesh};
use vps_voxelize::{
    clip_to_workspace, grid_for, voxelize, voxelize_in, voxelize_tree, voxelize_tree_in,
    VoxelizeOptions,
};
use vps_voxmap::{TreeConfig, VoxelTree};

/// Dense reference tree and sparse tree of the same scene; asserts equal hashes and counts.
fn assert_same(objects: &[TriMesh], opts: &VoxelizeOptions, config: TreeConfig, what: &str) {
    let dense = voxelize(objects, opts).unwrap();
    let reference = VoxelTree::from_dense(&dense, config).unwrap();
    let (sparse, stats) = voxelize_tree(objects, opts, config).unwrap();
    assert_eq!(sparse.spec(), reference.spec(), "{what}: grid");
    assert_eq!(sparse.counts(), dense.counts(), "{what}: counts");
    assert_eq!(
        sparse.content_hash(),
        reference.content_hash(),
        "{what}: content hash"
    );
    assert_eq!(
        [
            stats.free_voxels,
            stats.interior_voxels,
            stats.surface_voxels,
            stats.proximity_voxels
        ],
        dense.counts(),
        "{what}: stats"
    );
}

fn opts(voxel_size: f64, offset_layers: u32) -> VoxelizeOptions {
    VoxelizeOptions {
        voxel_size,
        offset_layers,
        ..VoxelizeOptions::default()
    }
}

#[test]
fn builtin_shapes_match_the_dense_pipeline() {
    for (name, s) in [("box", 0.004), ("sphere", 0.003), ("teapot", 0.0015)] {
        let mesh = builtin::by_name(name).unwrap();
        for k in [0, 2] {
            let what = format!("{name} at {s} m, k = {k}");
            assert_same(
                std::slice::from_ref(&mesh),
                &opts(s, k),
                TreeConfig::default(),
                &what,
            );
        }
    }
}

#[test]
fn other_tree_shapes_match() {
    // Lower nodes of 16³ (inside one chunk) and 256³ voxels (spanning chunks).
    let mesh = builtin::by_name("sphere").unwrap();
    for config in [
        TreeConfig::uniform(2),
        TreeConfig::uniform(4),
        TreeConfig {
            log2_dims: [1, 2, 1],
        },
    ] {
        assert_same(
            std::slice::from_ref(&mesh),
            &opts(0.0012, 2),
            config,
            &format!("{config:?}"),
        );
    }
}

#[test]
fn aircraft_bay_at_a_coarse_size_matches() {
    let bay = builtin::aircraft_bay();
    assert_same(
        std::slice::from_ref(&bay),
        &opts(0.03, 2),
        TreeConfig::default(),
        "bay at 30 mm",
    );
}

/// A random soup: `n` triangles, some big, some tiny, in a box of `extent` m.
fn soup(rng: &mut impl Rng, n: usize, extent: f64) -> TriMesh {
    let mut vertices = Vec::new();
    let mut triangles = Vec::new();
    for t in 0..n {
        let c = DVec3::new(
            rng.gen_range(0.0..extent),
            rng.gen_range(0.0..extent),
            rng.gen_range(0.0..extent),
        );
        let size = if t % 3 == 0 {
            extent * 0.6
        } else {
            extent * 0.05
        };
        for _ in 0..3 {
            let d = DVec3::new(
                rng.gen_range(-size..size),
                rng.gen_range(-size..size),
                rng.gen_range(-size..size),
            );
            vertices.push(c + d);
        }
        let i = 3 * t as u32;
        triangles.push([i, i + 1, i + 2]);
    }
    TriMesh::new(vertices, triangles)
}

/// A thin closed plate (thinner than a voxel) and an open half box.
fn plate_and_open_box() -> (TriMesh, TriMesh) {
    let mut plate = builtin::cuboid(DVec3::new(0.2, 0.15, 0.0004));
    plate
        .vertices
        .iter_mut()
        .for_each(|v| *v += DVec3::splat(0.25));
    let mut open = builtin::cuboid(DVec3::splat(0.12));
    let top: Vec<usize> = (0..open.triangles.len())
        .filter(|&t| open.triangle(t).iter().all(|v| v.z > 0.1))
        .collect();
    let kept: Vec<[u32; 3]> = open
        .triangles
        .iter()
        .enumerate()
        .filter(|(t, _)| !top.contains(t))
        .map(|(_, tri)| *tri)
        .collect();
    open.triangles = kept;
    open.vertices
        .iter_mut()
        .for_each(|v| *v += DVec3::new(0.5, 0.2, 0.3));
    (plate, open)
}

#[test]
fn random_soups_thin_plates_and_open_meshes_match() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    for round in 0..4 {
        let a = soup(&mut rng, 40, 0.5);
        let b = soup(&mut rng, 15, 0.3);
        let s = [0.004, 0.007, 0.011, 0.013][round];
        assert_same(
            std::slice::from_ref(&a),
            &opts(s, 2),
            TreeConfig::default(),
            "soup",
        );
        assert_same(
            &[a, b],
            &opts(s, round as u32),
            TreeConfig::default(),
            "two soups",
        );
    }
    let (plate, open) = plate_and_open_box();
    for k in [0, 1, 3] {
        assert_same(
            &[plate.clone(), open.clone()],
            &opts(0.005, k),
            TreeConfig::default(),
            &format!("plate and open box, k = {k}"),
        );
    }
    // Nested objects: Interior of the outer one wins over the inner one's Surface.
    let outer = builtin::cuboid(DVec3::splat(0.2));
    let inner = builtin::uv_sphere(0.08, 24, 12);
    assert_same(
        &[outer, inner],
        &opts(0.006, 2),
        TreeConfig::default(),
        "nested",
    );
}

#[test]
fn workspace_clips_like_voxelize_in() {
    let bay = builtin::aircraft_bay();
    let ws = Aabb {
        min: DVec3::new(0.3, -0.2, 0.1),
        max: DVec3::new(1.4, 0.9, 1.2),
    };
    let o = VoxelizeOptions {
        workspace: Some(ws),
        ..opts(0.03, 2)
    };
    let (sparse, _) = voxelize_tree(std::slice::from_ref(&bay), &o, TreeConfig::default()).unwrap();
    let full = grid_for(&bay.bounds(), &o).unwrap();
    let clipped = clip_to_workspace(&full, &ws).unwrap();
    assert_eq!(*sparse.spec(), clipped);
    assert!(clipped.voxel_count() < full.voxel_count());
    let dense = voxelize_in(std::slice::from_ref(&bay), clipped, &o).unwrap();
    let reference = VoxelTree::from_dense(&dense, TreeConfig::default()).unwrap();
    assert_eq!(sparse.content_hash(), reference.content_hash());
    // The dense entry point honours the workspace too.
    assert_eq!(voxelize(std::slice::from_ref(&bay), &o).unwrap(), dense);
    let (again, _) = voxelize_tree_in(
        std::slice::from_ref(&bay),
        clipped,
        &o,
        TreeConfig::default(),
    )
    .unwrap();
    assert_eq!(again.content_hash(), sparse.content_hash());

    let far = Aabb {
        min: DVec3::splat(50.0),
        max: DVec3::splat(51.0),
    };
    let err = voxelize_tree(
        std::slice::from_ref(&bay),
        &VoxelizeOptions {
            workspace: Some(far),
            ..o
        },
        TreeConfig::default(),
    )
    .unwrap_err();
    assert!(err.to_string().contains("does not overlap"), "{err}");
}
