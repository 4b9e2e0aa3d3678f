//! A lookup cursor that remembers the last leaf-sized cube it resolved (OpenVDB's ValueAccessor, one
//! level deep): consecutive queries in the same cube skip the root and internal slots.

use super::{LeafRef, VoxelTree};
use crate::Voxel;
use glam::{IVec3, UVec3};

/// Cached lookups into one [`VoxelTree`]. Cheap to create; one per thread (`get` takes `&mut self`).
#[derive(Clone, Debug)]
pub struct TreeAccessor<'a> {
    tree: &'a VoxelTree,
    /// Leaf-cube coordinates (voxel index >> leaf log2) of the cached path; `UVec3::MAX` when empty.
    key: UVec3,
    cached: LeafRef,
}

impl<'a> TreeAccessor<'a> {
    /// An accessor with an empty cache.
    pub fn new(tree: &'a VoxelTree) -> Self {
        Self {
            tree,
            key: UVec3::MAX,
            cached: LeafRef::Tile(0),
        }
    }

    /// The voxel at `ijk` (same result as [`VoxelTree::get`]); Free outside the dims. Does not
    /// allocate or block.
    #[inline]
    pub fn get(&mut self, ijk: IVec3) -> Voxel {
        if !self.tree.spec.contains(ijk) {
            return Voxel::Free;
        }
        let p = ijk.as_uvec3();
        let key = p >> self.tree.leaf_shape.log2;
        if key != self.key {
            self.cached = self.tree.locate(p);
            self.key = key;
        }
        let code = match self.cached {
            LeafRef::Tile(code) => code,
            LeafRef::Leaf(first) => self.tree.leaf_shape.read(&self.tree.leaf_words, first, p),
        };
        self.tree.kind_of(code)
    }
}
