//! The tree answers exactly like the dense grid it was built from, for every tree shape.

use crate::common;

use common::{boxes, empty, fill_box, rng, sparse};
use glam::IVec3;
use rand::Rng;
use vps_voxmap::{DenseGrid, TreeConfig, TreeError, Voxel, VoxelLookup, VoxelTree};

/// Every shape of the Figure-6 sweep plus mixed ones.
fn configs() -> Vec<TreeConfig> {
    let mut c: Vec<TreeConfig> = (1..=5).map(TreeConfig::uniform).collect();
    for log2_dims in [[1, 2, 3], [3, 1, 5], [5, 5, 1], [2, 4, 3], [4, 1, 2]] {
        c.push(TreeConfig { log2_dims });
    }
    c
}

/// Builds `grid` with `config` and checks lookups, counts and expansion against the dense grid.
fn assert_matches_dense(grid: &DenseGrid, config: TreeConfig, seed: u64) -> VoxelTree {
    let tree = VoxelTree::from_dense(grid, config).expect("valid grid and config");
    let dims = IVec3::new(
        grid.spec.dims[0] as i32,
        grid.spec.dims[1] as i32,
        grid.spec.dims[2] as i32,
    );
    let mut r = rng(seed);
    let mut accessor = tree.accessor();
    for _ in 0..20_000 {
        let ijk = IVec3::new(
            r.gen_range(-9..dims.x + 9),
            r.gen_range(-9..dims.y + 9),
            r.gen_range(-9..dims.z + 9),
        );
        let want = grid.get(ijk);
        assert_eq!(tree.get(ijk), want, "{config:?} at {ijk}");
        assert_eq!(
            VoxelLookup::get(&tree, ijk),
            want,
            "{config:?} via trait at {ijk}"
        );
        assert_eq!(accessor.get(ijk), want, "{config:?} accessor at {ijk}");
    }
    for far in [IVec3::MIN, IVec3::MAX, IVec3::new(-1, 0, 0), dims, dims - 1] {
        assert_eq!(tree.get(far), grid.get(far), "{config:?} at {far}");
    }
    assert_eq!(tree.counts(), grid.counts(), "{config:?} counts");
    assert!(tree.to_dense() == *grid, "{config:?}: to_dense differs");
    assert_eq!(tree.spec(), &grid.spec);
    assert_eq!(tree.config(), config);
    tree
}

#[test]
fn sparse_random_grids_match_dense_for_every_config() {
    for (i, config) in configs().into_iter().enumerate() {
        let grid = sparse([37, 21, 29], 0.05, i as u64);
        assert_matches_dense(&grid, config, 100 + i as u64);
    }
}

#[test]
fn grids_with_large_uniform_regions_match_dense_for_every_config() {
    for (i, config) in configs().into_iter().enumerate() {
        let grid = boxes([70, 45, 33], 6, i as u64);
        let tree = assert_matches_dense(&grid, config, 200 + i as u64);
        let counts = grid.counts();
        assert!(counts[1] > 0 && counts[0] > 0, "the scene must mix kinds");
        if config == TreeConfig::default() {
            // Solid interiors tile: far fewer leaves than non-Free leaf cubes.
            assert!(tree.memory_bytes() < tree.dense_equivalent_bytes() as usize);
        }
    }
}

#[test]
fn a_single_voxel_at_each_corner_is_found() {
    for config in configs() {
        let dims = [19, 8, 33];
        let mut grid = empty(dims);
        for c in 0..8 {
            let pick = |axis: usize| {
                if c >> axis & 1 == 1 {
                    dims[axis] as i32 - 1
                } else {
                    0
                }
            };
            grid.set(IVec3::new(pick(0), pick(1), pick(2)), Voxel::ALL[1 + c % 3]);
        }
        assert_matches_dense(&grid, config, 7);
    }
}

#[test]
fn uniform_grids_are_all_tiles() {
    for config in configs() {
        for v in Voxel::ALL {
            let mut grid = empty([150, 120, 90]);
            grid.data.fill(v as u8);
            let tree = VoxelTree::from_dense(&grid, config).unwrap();
            let nodes = tree.node_counts();
            assert_eq!(nodes.leaves, 0, "{config:?} {v:?}");
            if v == Voxel::Free {
                assert_eq!((nodes.lower, nodes.upper), (0, 0), "{config:?}");
                // Only the root slots remain: 4 bytes per upper-node cube.
                let cells: usize = grid
                    .spec
                    .dims
                    .iter()
                    .map(|&d| d.div_ceil(config.extent(2)) as usize)
                    .product();
                assert_eq!(tree.memory_bytes(), 4 * cells, "{config:?}");
            }
            let mut want = [0u64; 4];
            want[v as usize] = grid.spec.voxel_count();
            assert_eq!(tree.counts(), want, "{config:?} {v:?}");
            assert_eq!(tree.get(IVec3::new(149, 119, 89)), v);
            assert_eq!(tree.get(IVec3::new(150, 0, 0)), Voxel::Free);
        }
    }
}

#[test]
fn memory_follows_surface_not_volume() {
    let config = TreeConfig::default();
    let mut grid = empty([256, 256, 256]);
    fill_box(
        &mut grid,
        IVec3::splat(37),
        IVec3::splat(203),
        Voxel::Interior,
    );
    let tree = VoxelTree::from_dense(&grid, config).unwrap();
    let nodes = tree.node_counts();
    // Box faces at 37 and 203 are not leaf aligned (8): only leaves cut by a face are stored.
    let per_axis_leaves = (203 - 37) / 8 + 2;
    assert!(
        nodes.leaves <= 6 * per_axis_leaves * per_axis_leaves,
        "{nodes:?}"
    );
    assert!(nodes.leaves > 0);
    // ~2.7k leaves of 128 B plus 64 lower nodes of 2 KiB, against 4 MiB dense.
    assert!(tree.memory_bytes() * 5 < tree.dense_equivalent_bytes() as usize);
    assert_eq!(tree.counts(), grid.counts());
}

#[test]
fn equal_content_gives_equal_hash_and_different_content_does_not() {
    let grid = boxes([50, 40, 30], 4, 3);
    let a = VoxelTree::from_dense(&grid, TreeConfig::default()).unwrap();
    let b = VoxelTree::from_dense(&grid.clone(), TreeConfig::default()).unwrap();
    assert_eq!(a, b);
    assert_eq!(a.content_hash(), b.content_hash());
    let mut changed = grid.clone();
    let ijk = IVec3::new(49, 39, 29);
    changed.set(
        ijk,
        if grid.get(ijk) == Voxel::Free {
            Voxel::Surface
        } else {
            Voxel::Free
        },
    );
    let c = VoxelTree::from_dense(&changed, TreeConfig::default()).unwrap();
    assert_ne!(a.content_hash(), c.content_hash());
    let d = VoxelTree::from_dense(&grid, TreeConfig::uniform(2)).unwrap();
    assert_ne!(
        a.content_hash(),
        d.content_hash(),
        "the config is part of the hash"
    );
}

#[test]
fn invalid_configs_and_grids_are_rejected() {
    let grid = empty([4, 4, 4]);
    for log2_dims in [[0, 3, 3], [3, 6, 3], [3, 3, 0], [9, 9, 9]] {
        let err = VoxelTree::from_dense(&grid, TreeConfig { log2_dims }).unwrap_err();
        assert!(
            matches!(err, TreeError::InvalidConfig { .. }),
            "{log2_dims:?}: {err}"
        );
    }
    let mut short = grid.clone();
    short.data.pop();
    let err = VoxelTree::from_dense(&short, TreeConfig::default()).unwrap_err();
    assert_eq!(
        err,
        TreeError::DataLength {
            expected: 64,
            found: 63
        }
    );
    let mut bad_size = grid.clone();
    bad_size.spec.voxel_size = f64::NAN;
    let err = VoxelTree::from_dense(&bad_size, TreeConfig::default()).unwrap_err();
    assert!(err.to_string().contains("voxel_size"), "{err}");
}
