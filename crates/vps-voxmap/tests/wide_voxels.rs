//! 4- and 8-bit trees: built from a cube source, equal to the 2-bit path for 2-bit content, `.vmap`
//! round trips per width, and reserved codes rejected with a clear error.

use crate::common;

use common::{boxes, FnSource};
use glam::{DVec3, IVec3, UVec3};
use vps_voxmap::file::{read_voxmap, write_voxmap, VOXMAP_VERSION, VOXMAP_VERSION_2BIT};
use vps_voxmap::{
    FileError, GridSpec, LayeredVoxel, TreeConfig, TreeError, Voxel, VoxelTree, VoxelWidth,
};

fn spec(dims: [u32; 3]) -> GridSpec {
    GridSpec {
        origin: DVec3::new(-0.1, 0.2, 0.0),
        voxel_size: 0.01,
        dims,
    }
}

/// A layered pattern: spherical shells of every layer of `width`, Interior inside, Free outside.
fn shells(width: VoxelWidth) -> impl Fn(UVec3) -> u8 + Sync {
    move |p: UVec3| {
        let r = (p.as_vec3() - glam::Vec3::splat(40.0)).length() as i32;
        let (ls, lp) = (
            width.surface_layers() as i32,
            width.proximity_layers() as i32,
        );
        let v = if r < 20 - ls {
            LayeredVoxel {
                kind: Voxel::Interior,
                layer: 0,
            }
        } else if r < 20 {
            LayeredVoxel {
                kind: Voxel::Surface,
                layer: (19 - r) as u8,
            }
        } else if r < 20 + lp {
            LayeredVoxel {
                kind: Voxel::Proximity,
                layer: (r - 20) as u8,
            }
        } else {
            LayeredVoxel {
                kind: Voxel::Free,
                layer: 0,
            }
        };
        width.encode(v).unwrap()
    }
}

fn wide_tree(width: VoxelWidth, config: TreeConfig) -> VoxelTree {
    let dims = [83, 90, 77];
    let source = FnSource {
        dims,
        code: shells(width),
    };
    VoxelTree::from_source(spec(dims), width, config, &source).unwrap()
}

#[test]
fn from_source_matches_from_dense_for_two_bit_content() {
    let grid = boxes([70, 45, 66], 4, 3);
    for config in [
        TreeConfig::default(),
        TreeConfig::uniform(2),
        TreeConfig::uniform(4),
    ] {
        let source = FnSource {
            dims: grid.spec.dims,
            code: |p: UVec3| grid.get(p.as_ivec3()) as u8,
        };
        let a = VoxelTree::from_source(grid.spec, VoxelWidth::Two, config, &source).unwrap();
        let b = VoxelTree::from_dense(&grid, config).unwrap();
        assert_eq!(a, b, "{config:?}");
        assert_eq!(a.content_hash(), b.content_hash());
    }
}

#[test]
fn wide_trees_answer_every_voxel_and_round_trip() {
    for width in [VoxelWidth::Four, VoxelWidth::Eight] {
        let configs = [
            TreeConfig::default(),
            TreeConfig::uniform(1),
            TreeConfig {
                log2_dims: [2, 3, 2],
            },
        ];
        for config in configs {
            let tree = wide_tree(width, config);
            assert_eq!(tree.width(), width);
            let code = shells(width);
            for z in (-2..80).step_by(3) {
                for y in -2..93 {
                    for x in (-2..86).step_by(2) {
                        let p = IVec3::new(x, y, z);
                        let inside = tree.spec().contains(p);
                        let want = if inside {
                            width.decode(code(p.as_uvec3())).unwrap()
                        } else {
                            LayeredVoxel {
                                kind: Voxel::Free,
                                layer: 0,
                            }
                        };
                        assert_eq!(tree.get_layered(p), want, "{width:?} {config:?} {p}");
                        assert_eq!(tree.get(p), want.kind);
                        assert_eq!(tree.accessor().get(p), want.kind);
                    }
                }
            }
            // Layer counts agree with the source; kind counts with the dense expansion.
            let mut hist = std::collections::BTreeMap::new();
            for k in Voxel::ALL {
                hist.insert(
                    width.encode(LayeredVoxel { kind: k, layer: 0 }).unwrap(),
                    0u64,
                );
            }
            let d = tree.spec().dims;
            for z in 0..d[2] {
                for y in 0..d[1] {
                    for x in 0..d[0] {
                        *hist.entry(code(UVec3::new(x, y, z))).or_default() += 1;
                    }
                }
            }
            let want: Vec<(LayeredVoxel, u64)> = hist
                .into_iter()
                .map(|(c, n)| (width.decode(c).unwrap(), n))
                .collect();
            let layers = tree.layer_counts();
            assert_eq!(layers, want, "{width:?} {config:?}");
            assert!(layers.len() > 8);
            assert_eq!(tree.counts(), tree.to_dense().counts());
            let mut bytes = Vec::new();
            write_voxmap(&tree, &mut bytes).unwrap();
            assert_eq!(bytes[8..12], VOXMAP_VERSION.to_le_bytes());
            let back = read_voxmap(bytes.as_slice()).unwrap();
            assert_eq!(back, tree);
            assert_eq!(back.content_hash(), tree.content_hash());
        }
    }
    // 2-bit maps are still version 1.
    let two = VoxelTree::from_dense(&boxes([20, 20, 20], 2, 1), TreeConfig::default()).unwrap();
    let mut bytes = Vec::new();
    write_voxmap(&two, &mut bytes).unwrap();
    assert_eq!(bytes[8..12], VOXMAP_VERSION_2BIT.to_le_bytes());
}

#[test]
fn reserved_codes_are_rejected() {
    // From a source.
    let dims = [20, 20, 20];
    let bad = FnSource {
        dims,
        code: |p: UVec3| if p == UVec3::new(3, 4, 5) { 15 } else { 1 },
    };
    let err = VoxelTree::from_source(spec(dims), VoxelWidth::Four, TreeConfig::default(), &bad)
        .unwrap_err();
    assert!(
        matches!(
            err,
            TreeError::InvalidCode {
                code: 15,
                bits: 4,
                ..
            }
        ),
        "{err}"
    );
    assert!(
        err.to_string()
            .contains("code 15 is not a valid 4-bit voxel code"),
        "{err}"
    );

    // From a file: patch one leaf nibble to the reserved code 15 and fix the trailer.
    let tree = wide_tree(VoxelWidth::Four, TreeConfig::default());
    let mut bytes = Vec::new();
    write_voxmap(&tree, &mut bytes).unwrap();
    let body = bytes.len() - 32;
    let leaf_at = body - 8; // last word of the last leaf
    bytes[leaf_at] |= 0x0F;
    let hash = blake3::hash(&bytes[..body]);
    bytes[body..].copy_from_slice(hash.as_bytes());
    let err = read_voxmap(bytes.as_slice()).unwrap_err();
    assert!(
        matches!(
            err,
            FileError::Tree(TreeError::InvalidCode { code: 15, .. })
        ),
        "{err}"
    );
    assert!(err.to_string().contains("leaf words"), "{err}");

    // A wide leaf shape that does not fit a word is refused.
    let err = VoxelTree::from_source(spec(dims), VoxelWidth::Eight, TreeConfig::uniform(4), &bad)
        .unwrap_err();
    assert!(
        matches!(err, TreeError::LeafTooWide { bits: 8, log2: 4 }),
        "{err}"
    );
}
