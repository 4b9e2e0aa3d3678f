//! `.vmap` round trips, and every kind of damage is an error (never a panic or a huge allocation).

use crate::common;

use common::{assert_every_flipped_byte_rejected, boxes, sparse};
use vps_voxmap::file::{load_voxmap, read_voxmap, save_voxmap, write_voxmap, VOXMAP_MAGIC};
use vps_voxmap::{FileError, TreeConfig, VoxelTree};

fn encode(tree: &VoxelTree) -> Vec<u8> {
    let mut bytes = Vec::new();
    write_voxmap(tree, &mut bytes).unwrap();
    bytes
}

/// A small tree with stored nodes at every level (a few KiB encoded).
fn small_tree() -> VoxelTree {
    VoxelTree::from_dense(&sparse([9, 7, 6], 0.1, 5), TreeConfig::uniform(1)).unwrap()
}

#[test]
fn round_trip_preserves_tree_and_hash() {
    for (i, config) in [
        TreeConfig::default(),
        TreeConfig::uniform(1),
        TreeConfig::uniform(5),
    ]
    .into_iter()
    .chain([TreeConfig {
        log2_dims: [2, 4, 1],
    }])
    .enumerate()
    {
        let tree = VoxelTree::from_dense(&boxes([60, 35, 41], 5, i as u64), config).unwrap();
        let bytes = encode(&tree);
        assert_eq!(&bytes[..8], &VOXMAP_MAGIC);
        let back = read_voxmap(bytes.as_slice()).unwrap();
        assert_eq!(back, tree, "{config:?}");
        assert_eq!(back.content_hash(), tree.content_hash());
        assert_eq!(
            &bytes[bytes.len() - 32..],
            &tree.content_hash(),
            "trailer is the content hash"
        );
    }
}

#[test]
fn save_and_load_by_path() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.vmap");
    let tree = small_tree();
    save_voxmap(&tree, &path).unwrap();
    assert_eq!(load_voxmap(&path).unwrap(), tree);

    let missing = dir.path().join("missing.vmap");
    let err = load_voxmap(&missing).unwrap_err();
    assert!(err.to_string().contains("missing.vmap"), "{err}");
}

#[test]
fn every_truncation_is_an_error() {
    let bytes = encode(&small_tree());
    assert!(bytes.len() > 100);
    for len in 0..bytes.len() {
        let err = read_voxmap(&bytes[..len]).unwrap_err();
        assert!(
            matches!(
                err,
                FileError::Truncated { .. } | FileError::InvalidField { .. }
            ),
            "cut at {len}: {err}"
        );
    }
}

#[test]
fn every_flipped_byte_is_an_error() {
    let bytes = encode(&small_tree());
    assert_every_flipped_byte_rejected(&bytes, |b| read_voxmap(b));
}

#[test]
fn trailing_data_is_an_error() {
    let mut bytes = encode(&small_tree());
    bytes.push(0);
    assert!(matches!(
        read_voxmap(bytes.as_slice()),
        Err(FileError::TrailingBytes)
    ));
}

/// Header fields: magic 8, version 4, voxel size 8, origin 24, dims 12, log2 dims 3.
const DIMS_AT: usize = 8 + 4 + 8 + 24;
const ROOT_LEN_AT: usize = DIMS_AT + 12 + 3;

#[test]
fn huge_length_fields_error_without_allocating() {
    let bytes = encode(&small_tree());
    let mut lying = bytes[..ROOT_LEN_AT + 8].to_vec();
    lying[ROOT_LEN_AT..].copy_from_slice(&u64::MAX.to_le_bytes());
    let err = read_voxmap(lying.as_slice()).unwrap_err();
    assert!(err.to_string().contains("root slots length"), "{err}");

    // Dims of ~2^39 voxels with an octree need 2^30 root slots (4 GiB) if trusted; the file has none.
    let mut huge = bytes[..ROOT_LEN_AT].to_vec();
    let dims = [i32::MAX as u32, 256, 1];
    for (axis, d) in dims.iter().enumerate() {
        huge[DIMS_AT + 4 * axis..DIMS_AT + 4 * axis + 4].copy_from_slice(&d.to_le_bytes());
    }
    let root_cells: u64 = dims.iter().map(|&d| (d as u64).div_ceil(8)).product();
    huge.extend_from_slice(&root_cells.to_le_bytes());
    huge.extend_from_slice(&[0u8; 100]);
    let err = read_voxmap(huge.as_slice()).unwrap_err();
    assert!(
        matches!(
            err,
            FileError::Truncated {
                field: "root slots"
            }
        ),
        "{err}"
    );
}

#[test]
fn header_errors_name_the_field() {
    let bytes = encode(&small_tree());
    let mut zero_dim = bytes.clone();
    zero_dim[DIMS_AT + 4..DIMS_AT + 8].copy_from_slice(&0u32.to_le_bytes());
    let err = read_voxmap(zero_dim.as_slice()).unwrap_err();
    assert!(err.to_string().contains("dims[1]"), "{err}");

    let mut bad_version = bytes.clone();
    bad_version[8] = 4;
    let err = read_voxmap(bad_version.as_slice()).unwrap_err();
    assert!(
        matches!(
            err,
            FileError::UnsupportedVersion {
                found: 4,
                supported: 3
            }
        ),
        "{err}"
    );

    let mut bad_config = bytes;
    bad_config[DIMS_AT + 12] = 6;
    let err = read_voxmap(bad_config.as_slice()).unwrap_err();
    assert!(err.to_string().contains("log2_dims[0]"), "{err}");
}

#[test]
fn dims_whose_product_overflows_u64_are_refused() {
    // (2^31 - 1)^3 overflows u64: found by the robustness suite (a multiply overflow panic in
    // debug builds; a wrapped, possibly small voxel count in release).
    let mut bytes = encode(&small_tree());
    for axis in 0..3 {
        bytes[DIMS_AT + 4 * axis..DIMS_AT + 4 * axis + 4]
            .copy_from_slice(&(i32::MAX as u32).to_le_bytes());
    }
    let err = read_voxmap(bytes.as_slice()).unwrap_err().to_string();
    assert!(err.starts_with("dims:") && err.contains("2^40"), "{err}");
}

#[test]
fn a_grid_reaching_a_non_finite_corner_is_refused() {
    let mut bytes = encode(&small_tree());
    bytes[12..20].copy_from_slice(&1e308f64.to_le_bytes());
    let err = read_voxmap(bytes.as_slice()).unwrap_err().to_string();
    assert!(
        err.starts_with("dims:") && err.contains("non-finite corner"),
        "{err}"
    );
}

#[test]
fn a_count_beyond_the_file_is_refused_before_reading() {
    use vps_voxmap::file::read_voxmap_sized;
    let bytes = encode(&small_tree());
    // The real root count, in a file cut just after it: the sized reader knows the slots cannot
    // be there and says so, naming the count and the bytes left.
    let cut = &bytes[..ROOT_LEN_AT + 8 + 4];
    let err = read_voxmap_sized(cut, cut.len() as u64).unwrap_err();
    assert!(
        matches!(
            err,
            FileError::CountExceedsFile {
                field: "root slots",
                remaining: 4,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("only 4 bytes remain"), "{err}");
}

#[test]
fn loading_an_empty_file_says_it_is_empty() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("empty.vmap");
    std::fs::write(&path, b"").unwrap();
    let err = load_voxmap(&path).unwrap_err().to_string();
    assert!(
        err.contains("empty.vmap") && err.contains("file is empty"),
        "{err}"
    );
}
