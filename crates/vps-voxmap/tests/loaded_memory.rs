//! A voxmap read from a `.vmap` stream holds exactly the memory of the tree that was written: the
//! loader keeps no growth slack.

use crate::common;

use common::*;
use vps_voxmap::file::{read_voxmap, write_voxmap};
use vps_voxmap::{TreeConfig, VoxelTree};

#[test]
fn loaded_tree_takes_the_memory_of_the_built_tree() {
    // Large enough that the loader reads each arena in several chunks.
    for (dims, count, seed) in [([300, 260, 200], 400, 1), ([64, 64, 64], 20, 2)] {
        let grid = boxes(dims, count, seed);
        let built = VoxelTree::from_dense(&grid, TreeConfig::default()).expect("valid grid");
        let mut bytes = Vec::new();
        write_voxmap(&built, &mut bytes).expect("in memory");
        let loaded = read_voxmap(bytes.as_slice()).expect("own output");
        assert_eq!(loaded, built);
        assert_eq!(loaded.memory_bytes(), built.memory_bytes(), "{dims:?}");
        assert_eq!(loaded.directory_bytes(), built.directory_bytes());
        // The arenas are what the file holds: the file is the arenas plus a short header.
        assert!(built.memory_bytes() <= bytes.len());
        assert!(
            bytes.len() - built.memory_bytes() < 4096,
            "file {} B, tree {} B",
            bytes.len(),
            built.memory_bytes()
        );
    }
}
