//! The fixed-depth `2^(3N)` voxel tree (DESIGN §2, McNeely et al. 1999 §4.3), in OpenVDB's shape:
//! a dense [`root`] array of upper [`internal`] nodes, lower internal nodes, and bit-packed [`leaf`]
//! nodes; a region that is uniform at any level is one tile value in its parent's slot.
//!
//! Lookup reads the root slot, at most two internal slots and one leaf word: a fixed number of index
//! computations with no loop over depth. Memory follows the scene's surface, not its volume.

mod accessor;
mod build;
mod config;
mod error;
mod internal;
mod leaf;
mod root;
mod validate;
mod walk;

pub use accessor::TreeAccessor;
pub use config::TreeConfig;
pub use error::TreeError;

use crate::{DenseGrid, GridSpec, Voxel, VoxelLookup};
use glam::{IVec3, UVec3};
use internal::InternalLevel;
use leaf::LeafShape;
use root::RootGrid;

/// A voxmap stored as a fixed-depth tree: root grid → upper node → lower node → leaf.
///
/// Invariants (established by [`VoxelTree::from_dense`] and checked when read from a file): nodes of
/// each level are stored in canonical breadth-first order (each parent's children are appended in slot
/// order, so equal content and config give equal arenas); no node is uniform (it would be a tile);
/// voxels and slots outside the grid dims are Free. Immutable once built; `Sync`.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelTree {
    spec: GridSpec,
    config: TreeConfig,
    root: RootGrid,
    upper: InternalLevel,
    lower: InternalLevel,
    leaf_shape: LeafShape,
    leaf_words: Vec<u64>,
}

/// Number of stored nodes per level (tiles are not nodes).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct NodeCounts {
    /// Bit-packed leaves.
    pub leaves: usize,
    /// Lower internal nodes.
    pub lower: usize,
    /// Upper internal nodes.
    pub upper: usize,
}

/// The end of a lookup path above the voxel: a tile or a leaf (by its first word in the leaf arena).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LeafRef {
    Tile(Voxel),
    Leaf(usize),
}

impl VoxelTree {
    /// Builds the tree from a dense grid, bottom-up: uniform leaves and uniform internal nodes become
    /// tiles. Parallel (rayon) over lower-node cubes. Allocates the arenas; the dense grid is only read.
    ///
    /// Errors: invalid `config`, invalid spec (non-finite or non-positive voxel size, non-finite
    /// origin, a dim of 0 or above `i32::MAX`), `grid.data` not `voxel_count` long, or more than
    /// `2^31` nodes in a level.
    pub fn from_dense(grid: &DenseGrid, config: TreeConfig) -> Result<VoxelTree, TreeError> {
        build::from_dense(grid, config)
    }

    /// The voxel at `ijk`; Free outside `spec().dims`. Constant cost: a bounds check, the root slot,
    /// at most two internal slots and one leaf word. Does not allocate or block.
    #[inline(always)]
    pub fn get(&self, ijk: IVec3) -> Voxel {
        if !self.spec.contains(ijk) {
            return Voxel::Free;
        }
        let p = ijk.as_uvec3();
        match self.locate(p) {
            LeafRef::Tile(v) => v,
            LeafRef::Leaf(first) => self.leaf_shape.read(&self.leaf_words, first, p),
        }
    }

    /// Walks root → upper → lower for in-grid voxel `p`: no loop, three slot reads at most.
    #[inline(always)]
    fn locate(&self, p: UVec3) -> LeafRef {
        let s = self.root.slot(p);
        if s.is_tile() {
            return LeafRef::Tile(s.tile_value());
        }
        let s = self.upper.slot(s.child_index(), p);
        if s.is_tile() {
            return LeafRef::Tile(s.tile_value());
        }
        let s = self.lower.slot(s.child_index(), p);
        if s.is_tile() {
            return LeafRef::Tile(s.tile_value());
        }
        LeafRef::Leaf(s.child_index() * self.leaf_shape.words_per_leaf())
    }

    /// A lookup cursor that caches the last leaf, for spatially coherent queries.
    pub fn accessor(&self) -> TreeAccessor<'_> {
        TreeAccessor::new(self)
    }

    /// The grid placement (origin and voxel size in m, dims in voxels).
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// The tree shape it was built with.
    pub fn config(&self) -> TreeConfig {
        self.config
    }

    /// Stored nodes per level.
    pub fn node_counts(&self) -> NodeCounts {
        NodeCounts {
            leaves: self.leaf_words.len() / self.leaf_shape.words_per_leaf(),
            lower: self.lower.node_count(),
            upper: self.upper.node_count(),
        }
    }

    /// Heap bytes held by the arenas (root, upper, lower slot tables and leaf words).
    pub fn memory_bytes(&self) -> usize {
        4 * (self.root.slots.capacity() + self.upper.slots.capacity() + self.lower.slots.capacity())
            + 8 * self.leaf_words.capacity()
    }

    /// Bytes a dense 2-bit array over the dims would take: `ceil(2 * voxel_count / 8)`.
    pub fn dense_equivalent_bytes(&self) -> u64 {
        (2 * self.spec.voxel_count()).div_ceil(8)
    }

    /// Voxels of each kind inside the dims, indexed by the kind's value, computed from tiles (clipped
    /// to the dims) and leaf popcounts without expanding the tree.
    pub fn counts(&self) -> [u64; 4] {
        walk::counts(self)
    }

    /// The dense grid with the same content (allocates `voxel_count` bytes; for tests and tools).
    pub fn to_dense(&self) -> DenseGrid {
        walk::to_dense(self)
    }

    /// blake3 of the canonical encoding (spec, config, arenas): equal to the `.vmap` file's trailer.
    /// Because the arenas are canonical, equal spec, config and voxel content give equal hashes.
    pub fn content_hash(&self) -> [u8; 32] {
        crate::file::voxmap_content_hash(self)
    }

    /// Parts in file order, for the `.vmap` writer: root slots, upper slots, lower slots, leaf words.
    pub(crate) fn arenas(&self) -> (&[u32], &[u32], &[u32], &[u64]) {
        (
            &self.root.slots,
            &self.upper.slots,
            &self.lower.slots,
            &self.leaf_words,
        )
    }

    /// Rebuilds a tree from stored parts, checking every invariant (see [`validate`]).
    pub(crate) fn from_parts(
        spec: GridSpec,
        config: TreeConfig,
        root_slots: Vec<u32>,
        upper_slots: Vec<u32>,
        lower_slots: Vec<u32>,
        leaf_words: Vec<u64>,
    ) -> Result<VoxelTree, TreeError> {
        let tree = VoxelTree::assemble(
            spec,
            config,
            root_slots,
            upper_slots,
            lower_slots,
            leaf_words,
        )?;
        validate::check_canonical(&tree)?;
        Ok(tree)
    }

    /// Wraps arenas in a tree after checking spec and config (not the arenas' content).
    fn assemble(
        spec: GridSpec,
        config: TreeConfig,
        root_slots: Vec<u32>,
        upper_slots: Vec<u32>,
        lower_slots: Vec<u32>,
        leaf_words: Vec<u64>,
    ) -> Result<VoxelTree, TreeError> {
        config.validate()?;
        validate::check_spec(&spec)?;
        let [n0, n1, n2] = config.log2_dims.map(u32::from);
        let root_shift = config.shift(2);
        Ok(VoxelTree {
            spec,
            config,
            root: RootGrid {
                dims: RootGrid::dims_for(spec.dims, root_shift),
                shift: root_shift,
                slots: root_slots,
            },
            upper: InternalLevel {
                shape: internal::InternalShape {
                    log2: n2,
                    child_shift: n0 + n1,
                },
                slots: upper_slots,
            },
            lower: InternalLevel {
                shape: internal::InternalShape {
                    log2: n1,
                    child_shift: n0,
                },
                slots: lower_slots,
            },
            leaf_shape: LeafShape { log2: n0 },
            leaf_words,
        })
    }
}

impl VoxelLookup for VoxelTree {
    fn spec(&self) -> &GridSpec {
        &self.spec
    }

    #[inline(always)]
    fn get(&self, ijk: IVec3) -> Voxel {
        VoxelTree::get(self, ijk)
    }
}
