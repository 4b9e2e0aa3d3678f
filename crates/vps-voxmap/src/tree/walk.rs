//! Whole-tree traversal in canonical order, and the summaries built on it (counts, dense expansion).

use super::internal::Slot;
use super::VoxelTree;
use crate::{DenseGrid, Voxel};
use glam::UVec3;

use std::ops::Range;

/// A maximal stored region: a tile at some level or a leaf.
enum Block<'a> {
    /// A uniform tile, clipped to the dims: a half-open range per axis (any may be empty).
    Tile {
        range: [Range<u32>; 3],
        /// The tile's code.
        value: u8,
    },
    /// A leaf at `origin` (may extend past the dims) and its words in the leaf arena.
    Leaf { origin: UVec3, words: &'a [u64] },
}

/// Calls `f` on every tile and leaf, in canonical order.
fn for_each_block<'a>(tree: &'a VoxelTree, mut f: impl FnMut(Block<'a>)) {
    for (cell, &raw) in tree.root.slots.iter().enumerate() {
        visit(tree, Slot(raw), 2, tree.root.cell_origin(cell), &mut f);
    }
}

/// Visits `slot`, which points at (or tiles) a node of `level` (2 = upper, 1 = lower, 0 = leaf).
fn visit<'a>(
    tree: &'a VoxelTree,
    slot: Slot,
    level: usize,
    origin: UVec3,
    f: &mut impl FnMut(Block<'a>),
) {
    if slot.is_tile() {
        let range = clip(origin, tree.config.shift(level), tree.spec.dims);
        let value = slot.tile_value();
        return f(Block::Tile { range, value });
    }
    let node = match level {
        2 => &tree.upper,
        1 => &tree.lower,
        _ => {
            let wpl = tree.leaf_shape.words_per_leaf();
            let first = slot.child_index() * wpl;
            let words = &tree.leaf_words[first..first + wpl];
            return f(Block::Leaf { origin, words });
        }
    };
    for (local, &raw) in node.node(slot.child_index()).iter().enumerate() {
        let child_origin = origin + node.shape.child_offset(local);
        visit(tree, Slot(raw), level - 1, child_origin, f);
    }
}

/// The part of the cube `[origin, origin + 2^shift)` inside `dims`, as a half-open range per axis.
fn clip(origin: UVec3, shift: u32, dims: [u32; 3]) -> [Range<u32>; 3] {
    let o = origin.to_array();
    std::array::from_fn(|a| {
        let end = (o[a] as u64 + (1u64 << shift)).min(dims[a] as u64) as u32;
        o[a].min(end)..end
    })
}

/// Voxels inside the dims holding each code (see [`VoxelTree::layer_counts`]).
pub(super) fn code_counts(tree: &VoxelTree) -> [u64; 256] {
    let mut c = [0u64; 256];
    for_each_block(tree, |block| match block {
        Block::Tile { range, value } => {
            if value != 0 {
                let [x, y, z] = range;
                c[value as usize] += x.len() as u64 * y.len() as u64 * z.len() as u64;
            }
        }
        Block::Leaf { words, .. } => {
            let mut hist = [0u64; 256];
            tree.leaf_shape.histogram(words, &mut hist);
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
    for_each_block(tree, |block| match block {
        Block::Tile { range, value } => {
            let kind = tree.kind_of(value);
            if kind != Voxel::Free {
                let [x, y, z] = range;
                for k in z {
                    for j in y.clone() {
                        let row = grid.spec.linear(UVec3::new(x.start, j, k).as_ivec3());
                        grid.data[row..row + x.len()].fill(kind as u8);
                    }
                }
            }
        }
        Block::Leaf { origin, words } => {
            tree.leaf_shape
                .unpack(words, origin, &mut grid, |code| tree.kind_of(code));
        }
    });
    grid
}

/// See [`VoxelTree::for_each_region_of`].
pub(super) fn regions_of(tree: &VoxelTree, kind: Voxel, mut f: impl FnMut(UVec3, UVec3)) {
    let dims = tree.spec.dims;
    for_each_block(tree, |block| match block {
        Block::Tile { range, value } => {
            let [x, y, z] = range;
            if tree.kind_of(value) == kind && !x.is_empty() && !y.is_empty() && !z.is_empty() {
                f(
                    UVec3::new(x.start, y.start, z.start),
                    UVec3::new(x.end, y.end, z.end),
                );
            }
        }
        Block::Leaf { origin, words } => {
            let inside = tree.leaf_shape.inside(origin, dims);
            for z in 0..inside[2] {
                for y in 0..inside[1] {
                    for x in 0..inside[0] {
                        let p = origin + UVec3::new(x, y, z);
                        if tree.kind_of(tree.leaf_shape.read(words, 0, p)) == kind {
                            f(p, p + UVec3::ONE);
                        }
                    }
                }
            }
        }
    });
}

#[cfg(test)]
mod tests {
    use crate::{DenseGrid, GridSpec, TreeConfig, Voxel, VoxelTree};
    use glam::IVec3;

    #[test]
    fn regions_cover_exactly_the_voxels_of_a_kind() {
        let spec = GridSpec::at_origin(0.01, [37, 21, 70]);
        let grid = DenseGrid::from_fn(spec, |IVec3 { x, y, z }| {
            // A solid block (tiles at the leaf level) and scattered voxels (leaves).
            let solid = (16..64).contains(&z) && y < 16 && x < 32;
            if solid || (x * 7 + y * 3 + z) % 11 == 0 {
                Voxel::Surface
            } else {
                Voxel::Free
            }
        });
        let tree = VoxelTree::from_dense(&grid, TreeConfig::uniform(2)).unwrap();
        let mut seen = DenseGrid::new(spec);
        let mut count = 0u64;
        tree.for_each_region_of(Voxel::Surface, |lo, hi| {
            for z in lo.z..hi.z {
                for y in lo.y..hi.y {
                    for x in lo.x..hi.x {
                        let p = IVec3::new(x as i32, y as i32, z as i32);
                        assert_eq!(seen.get(p), Voxel::Free, "{p} twice");
                        seen.set(p, Voxel::Surface);
                        count += 1;
                    }
                }
            }
        });
        assert_eq!(seen.data, grid.data);
        assert_eq!(count, tree.counts()[Voxel::Surface as usize]);
    }
}
