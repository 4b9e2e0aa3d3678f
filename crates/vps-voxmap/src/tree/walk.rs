//! Whole-tree traversal in canonical order, and the summaries built on it (counts, dense expansion).

use super::internal::Slot;
use super::VoxelTree;
use crate::{DenseGrid, Voxel};
use glam::UVec3;

/// A maximal stored region: a tile at some level or a leaf.
enum Block {
    /// A uniform cube of `2^shift` voxels per axis at `origin` (may extend past the dims).
    Tile {
        origin: UVec3,
        shift: u32,
        /// The tile's code.
        value: u8,
    },
    /// A leaf at `origin` whose words start at `first_word` in the leaf arena.
    Leaf { origin: UVec3, first_word: usize },
}

/// Calls `f` on every tile and leaf, in canonical order.
fn for_each_block(tree: &VoxelTree, mut f: impl FnMut(Block)) {
    for (cell, &raw) in tree.root.slots.iter().enumerate() {
        visit(tree, Slot(raw), 2, tree.root.cell_origin(cell), &mut f);
    }
}

/// Visits `slot`, which points at (or tiles) a node of `level` (2 = upper, 1 = lower, 0 = leaf).
fn visit(tree: &VoxelTree, slot: Slot, level: usize, origin: UVec3, f: &mut impl FnMut(Block)) {
    if slot.is_tile() {
        let shift = tree.config.shift(level);
        f(Block::Tile {
            origin,
            shift,
            value: slot.tile_value(),
        });
        return;
    }
    let node = match level {
        2 => &tree.upper,
        1 => &tree.lower,
        _ => {
            let first_word = slot.child_index() * tree.leaf_shape.words_per_leaf();
            return f(Block::Leaf { origin, first_word });
        }
    };
    for (local, &raw) in node.node(slot.child_index()).iter().enumerate() {
        let child_origin = origin + node.shape.child_offset(local);
        visit(tree, Slot(raw), level - 1, child_origin, f);
    }
}

/// The part of the cube `[origin, origin + 2^shift)` inside `dims`, as a half-open range per axis.
fn clip(origin: UVec3, shift: u32, dims: [u32; 3]) -> [std::ops::Range<u32>; 3] {
    let o = origin.to_array();
    std::array::from_fn(|a| {
        let end = (o[a] as u64 + (1u64 << shift)).min(dims[a] as u64) as u32;
        o[a].min(end)..end
    })
}

/// Voxels inside the dims holding each code (see [`VoxelTree::layer_counts`]).
pub(super) fn code_counts(tree: &VoxelTree) -> [u64; 256] {
    let mut c = [0u64; 256];
    let wpl = tree.leaf_shape.words_per_leaf();
    let dims = tree.spec.dims;
    for_each_block(tree, |block| match block {
        Block::Tile {
            origin,
            shift,
            value,
        } => {
            if value != 0 {
                let [x, y, z] = clip(origin, shift, dims);
                c[value as usize] += x.len() as u64 * y.len() as u64 * z.len() as u64;
            }
        }
        Block::Leaf { first_word, .. } => {
            let leaf = &tree.leaf_words[first_word..first_word + wpl];
            let mut hist = [0u64; 256];
            tree.leaf_shape.histogram(leaf, &mut hist);
            for (total, n) in c.iter_mut().zip(hist).skip(1) {
                *total += n;
            }
        }
    });
    c[0] = tree.spec.voxel_count() - c[1..].iter().sum::<u64>();
    c
}

/// See [`VoxelTree::to_dense`].
pub(super) fn to_dense(tree: &VoxelTree) -> DenseGrid {
    let mut grid = DenseGrid::new(tree.spec);
    let wpl = tree.leaf_shape.words_per_leaf();
    let dims = tree.spec.dims;
    for_each_block(tree, |block| match block {
        Block::Tile {
            origin,
            shift,
            value,
        } => {
            let kind = tree.kind_of(value);
            if kind != Voxel::Free {
                let [x, y, z] = clip(origin, shift, dims);
                for k in z {
                    for j in y.clone() {
                        let row = grid.spec.linear(UVec3::new(x.start, j, k).as_ivec3());
                        grid.data[row..row + x.len()].fill(kind as u8);
                    }
                }
            }
        }
        Block::Leaf { origin, first_word } => {
            let leaf = &tree.leaf_words[first_word..first_word + wpl];
            tree.leaf_shape
                .unpack(leaf, origin, &mut grid, |code| tree.kind_of(code));
        }
    });
    grid
}
