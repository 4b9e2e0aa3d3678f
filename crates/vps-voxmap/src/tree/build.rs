//! Bottom-up construction from a dense grid.
//!
//! The work items are the lower-node cubes in canonical order (root cell, then upper slot). Chunks of
//! them are built in parallel, each into its own lower-slot and leaf arenas with local indices; the
//! chunks are then concatenated in order with their child indices shifted, and the upper nodes and
//! root are assembled from the per-cube slots. The result is the same for any thread count.

use super::internal::{assemble_node, Slot};
use super::{TreeConfig, TreeError, VoxelTree};
use crate::DenseGrid;
use glam::UVec3;
use rayon::prelude::*;
use std::ops::Range;

/// Lower-node cubes built by one parallel task.
struct LowerChunk {
    /// One slot per cube (`None` outside the grid): a tile, or a child indexing `lower_slots` (local
    /// index).
    cube_slots: Vec<Option<Slot>>,
    /// Lower nodes; child slots index `leaf_words` (local leaf index).
    lower_slots: Vec<u32>,
    /// Leaves, `words_per_leaf` words each.
    leaf_words: Vec<u64>,
}

/// See [`VoxelTree::from_dense`].
pub(super) fn from_dense(grid: &DenseGrid, config: TreeConfig) -> Result<VoxelTree, TreeError> {
    let expected = grid.spec.voxel_count();
    if grid.data.len() as u64 != expected {
        return Err(TreeError::DataLength {
            expected,
            found: grid.data.len() as u64,
        });
    }
    let mut tree = VoxelTree::assemble(grid.spec, config, vec![], vec![], vec![], vec![])?;
    let root_cells = super::root::RootGrid::cell_count(tree.root.dims) as usize;
    let cubes = root_cells * tree.upper.shape.slots_per_node();
    let chunk_len = cubes.div_ceil(32 * rayon::current_num_threads()).max(1);
    let chunks: Vec<LowerChunk> = (0..cubes.div_ceil(chunk_len))
        .into_par_iter()
        .map(|c| build_chunk(&tree, grid, c * chunk_len..((c + 1) * chunk_len).min(cubes)))
        .collect();

    let wpl = tree.leaf_shape.words_per_leaf();
    let spn_lower = tree.lower.shape.slots_per_node();
    let total_leaf_words: usize = chunks.iter().map(|c| c.leaf_words.len()).sum();
    let total_lower_slots: usize = chunks.iter().map(|c| c.lower_slots.len()).sum();
    check_node_count(total_leaf_words / wpl, "leaf words")?;
    check_node_count(total_lower_slots / spn_lower, "lower slots")?;

    let mut cube_slots = Vec::with_capacity(cubes);
    tree.lower.slots.reserve_exact(total_lower_slots);
    tree.leaf_words.reserve_exact(total_leaf_words);
    for chunk in chunks {
        let lower_base = (tree.lower.slots.len() / spn_lower) as u32;
        let leaf_base = (tree.leaf_words.len() / wpl) as u32;
        cube_slots.extend(
            chunk
                .cube_slots
                .iter()
                .map(|s| s.map(|s| relocate(s, lower_base))),
        );
        tree.lower.slots.extend(
            chunk
                .lower_slots
                .iter()
                .map(|&w| relocate(Slot(w), leaf_base).0),
        );
        tree.leaf_words.extend_from_slice(&chunk.leaf_words);
    }

    tree.root.slots.reserve_exact(root_cells);
    for children in cube_slots.chunks_exact(tree.upper.shape.slots_per_node()) {
        let slot = assemble_node(children, &mut tree.upper.slots);
        tree.root.slots.push(slot.0);
    }
    tree.upper.slots.shrink_to_fit();
    Ok(tree)
}

/// Builds the lower-node cubes `range` (canonical cube indices).
fn build_chunk(tree: &VoxelTree, grid: &DenseGrid, range: Range<usize>) -> LowerChunk {
    let leaf_shape = tree.leaf_shape;
    let lower_shape = tree.lower.shape;
    let dims = grid.spec.dims;
    let outside = |o: UVec3| o.x >= dims[0] || o.y >= dims[1] || o.z >= dims[2];
    let mut chunk = LowerChunk {
        cube_slots: Vec::with_capacity(range.len()),
        lower_slots: Vec::new(),
        leaf_words: Vec::new(),
    };
    let mut children = Vec::with_capacity(lower_shape.slots_per_node());
    let mut leaf = vec![0u64; leaf_shape.words_per_leaf()];
    for cube in range {
        let origin = cube_origin(tree, cube);
        if outside(origin) {
            chunk.cube_slots.push(None);
            continue;
        }
        children.clear();
        for local in 0..lower_shape.slots_per_node() {
            let leaf_origin = origin + lower_shape.child_offset(local);
            if outside(leaf_origin) {
                children.push(None);
                continue;
            }
            leaf_shape.pack(grid, leaf_origin, &mut leaf);
            let slot = match leaf_shape.uniform_value(&leaf, leaf_origin, dims) {
                Some(v) => Slot::tile(v),
                None => {
                    let index = chunk.leaf_words.len() / leaf.len();
                    chunk.leaf_words.extend_from_slice(&leaf);
                    Slot::child(index as u32)
                }
            };
            children.push(Some(slot));
        }
        let slot = assemble_node(&children, &mut chunk.lower_slots);
        chunk.cube_slots.push(Some(slot));
    }
    chunk
}

/// Voxel origin of lower-node cube `cube`: root cell `cube / spn`, upper slot `cube % spn`.
fn cube_origin(tree: &VoxelTree, cube: usize) -> UVec3 {
    let spn = tree.upper.shape.slots_per_node();
    tree.root.cell_origin(cube / spn) + tree.upper.shape.child_offset(cube % spn)
}

/// Shifts a child slot's index by `base` (tiles unchanged). Totals were checked to fit.
fn relocate(slot: Slot, base: u32) -> Slot {
    if slot.is_tile() {
        slot
    } else {
        Slot::child(slot.0 + base)
    }
}

fn check_node_count(nodes: usize, arena: &'static str) -> Result<(), TreeError> {
    if nodes > Slot::MAX_CHILD as usize + 1 {
        return Err(TreeError::TooManyNodes { arena });
    }
    Ok(())
}
