//! The fixed-depth `2^(3N)` voxel tree (docs/architecture.md#voxmaps-and-point-shells, McNeely et al. 1999 §4.3), in OpenVDB's shape:
//! a dense root array (module `root`) of upper internal nodes (module `internal`), lower internal
//! nodes, and bit-packed leaf nodes (module `leaf`); a region that is uniform at any level is one
//! tile value in its parent's slot.
//!
//! Lookup reads the root slot, at most two internal slots and one leaf word: a fixed number of index
//! computations with no loop over depth. Memory follows the scene's surface, not its volume.

mod accessor;
mod build;
mod config;
mod directory;
mod error;
mod internal;
mod leaf;
mod root;
mod validate;
mod walk;

pub use accessor::TreeAccessor;
pub use build::CubeSource;
pub use config::TreeConfig;
pub use directory::{DIRECTORY_ALLOWANCE_BYTES, DIRECTORY_MAX_BYTES};
pub use error::TreeError;

use crate::DistanceBand;
use crate::{
    BlockCells, DenseGrid, GridSpec, LayeredVoxel, LookupTask, Voxel, VoxelBlock, VoxelLookup,
    VoxelWidth, WideBlockCells, WideVoxelBlock, BLOCK_LANES, WIDE_BLOCK_LANES,
};
use directory::LeafDirectory;
use glam::{IVec3, UVec3};
use internal::InternalLevel;
use leaf::LeafShape;
use root::RootGrid;
use std::sync::Arc;

/// A voxmap stored as a fixed-depth tree: root grid → upper node → lower node → leaf, holding
/// [`VoxelWidth`] bits per voxel (2: the kind only; 4 or 8: kind and distance layer, see
/// [`LayeredVoxel`]).
///
/// Invariants (established by the constructors and checked when read from a file): nodes of
/// each level are stored in canonical breadth-first order (each parent's children are appended in slot
/// order, so equal content and config give equal arenas); no node is uniform (it would be a tile);
/// voxels and slots outside the grid dims are Free (code 0); every code is valid for the width.
/// Immutable once built; `Sync`.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelTree {
    spec: GridSpec,
    config: TreeConfig,
    width: VoxelWidth,
    /// `config` is the paper's 512-tree and `width` is 2 bits: `get` takes the constant-shift walk.
    paper_shape: bool,
    /// `log2(width bits)` (1, 2 or 3) when `config` is the 512-tree, else 0: which copy of the
    /// lookups a [`ShapedTree`] of this tree may run besides the general one.
    fixed_shape: u32,
    /// Each code's voxel for `width`, so that decoding a looked-up code is one load.
    codes: CodeTable,
    root: RootGrid,
    upper: InternalLevel,
    lower: InternalLevel,
    leaf_shape: LeafShape,
    leaf_words: Vec<u64>,
    /// The flattened upper levels, when small enough (module `directory`); lookups use it
    /// instead of the walk.
    directory: Option<LeafDirectory>,
    /// The signed-distance band of the `distance` force model, when the map carries one
    /// ([`VoxelTree::with_distance_band`]); part of the content (file and hash).
    distance: Option<Arc<DistanceBand>>,
}

/// A tree's stored parts in file order, for [`VoxelTree::from_parts`]: root slots, upper slots,
/// lower slots (`u32` slots: a tile or a child index) and the bit-packed leaf words.
#[derive(Default)]
pub(crate) struct Arenas {
    pub(crate) root: Vec<u32>,
    pub(crate) upper: Vec<u32>,
    pub(crate) lower: Vec<u32>,
    pub(crate) leaves: Vec<u64>,
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

/// The shifts of a lookup path, taken from the tree's levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LookupShape {
    /// log2 of the upper node's extent in voxels.
    root_shift: u32,
    upper: internal::InternalShape,
    lower: internal::InternalShape,
    leaf: LeafShape,
}

impl LookupShape {
    /// The shape of [`TreeConfig::default`] (`N = 3` at every level), as constants.
    const TREE_512: LookupShape = LookupShape::tree_512(1);

    /// The shape of the 512-tree of `2^bits_log2` bits per voxel, as constants.
    const fn tree_512(bits_log2: u32) -> LookupShape {
        LookupShape {
            root_shift: 9,
            upper: internal::InternalShape {
                log2: 3,
                child_shift: 6,
            },
            lower: internal::InternalShape {
                log2: 3,
                child_shift: 3,
            },
            leaf: LeafShape { log2: 3, bits_log2 },
        }
    }
}

/// The voxel of every code of one width (a reserved code reads Free, layer 0, as
/// [`VoxelTree::get_layered`] reads it), indexed by the code: decoding is one load instead of the
/// comparisons of [`VoxelWidth::decode`]. Derived from the width, so equal widths give equal tables.
#[derive(Clone, PartialEq)]
struct CodeTable {
    /// The voxel of each code.
    voxels: [LayeredVoxel; 256],
    /// The kind bits of codes 0..16 (every code of a 4-bit tree), for a byte shuffle.
    low_kinds: [u8; 16],
    /// The layers of codes 0..16.
    low_layers: [u8; 16],
}

impl CodeTable {
    /// The table of `width`.
    fn new(width: VoxelWidth) -> CodeTable {
        let voxels: [LayeredVoxel; 256] = std::array::from_fn(|code| {
            width.decode(code as u8).unwrap_or(LayeredVoxel {
                kind: Voxel::Free,
                layer: 0,
            })
        });
        CodeTable {
            voxels,
            low_kinds: std::array::from_fn(|code| voxels[code].kind.bits()),
            low_layers: std::array::from_fn(|code| voxels[code].layer),
        }
    }

    /// The voxel stored as `code`.
    #[inline(always)]
    fn get(&self, code: u8) -> LayeredVoxel {
        self.voxels[usize::from(code)]
    }

    /// The voxels of sixteen codes below 16 (a 4-bit tree's), as [`CodeTable::get`] per lane:
    /// one byte shuffle per table.
    ///
    /// # Safety
    /// The CPU must support SSSE3; every code must be below 16.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "ssse3")]
    #[inline]
    unsafe fn decode_low(&self, codes: [u8; WIDE_BLOCK_LANES]) -> WideVoxelBlock {
        use std::arch::x86_64::*;
        debug_assert!(codes.iter().all(|&c| c < 16));
        let mut block = WideVoxelBlock::default();
        // SAFETY: 16-byte arrays, loaded and stored unaligned.
        unsafe {
            let codes = _mm_loadu_si128(codes.as_ptr().cast());
            let kinds = _mm_loadu_si128(self.low_kinds.as_ptr().cast());
            let layers = _mm_loadu_si128(self.low_layers.as_ptr().cast());
            _mm_storeu_si128(
                block.kinds.as_mut_ptr().cast(),
                _mm_shuffle_epi8(kinds, codes),
            );
            _mm_storeu_si128(
                block.layers.as_mut_ptr().cast(),
                _mm_shuffle_epi8(layers, codes),
            );
        }
        block
    }
}

/// Not the 256 entries: they follow from the tree's width.
impl std::fmt::Debug for CodeTable {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("CodeTable(..)")
    }
}

/// The end of a lookup path above the voxel: a tile or a leaf (by its first word in the leaf arena).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LeafRef {
    /// A uniform region of this code.
    Tile(u8),
    Leaf(usize),
}

impl VoxelTree {
    /// Builds the tree from a dense grid, bottom-up: uniform leaves and uniform internal nodes become
    /// tiles. Parallel (rayon) over lower-node cubes. Allocates the arenas; the dense grid is only read.
    ///
    /// Errors: invalid `config`, invalid spec (non-finite or non-positive voxel size, non-finite
    /// origin, a dim of 0 or above `i32::MAX`), `grid.data` not `voxel_count` long, or more than
    /// `2^31` nodes in a level.
    /// The result is a 2-bit tree ([`VoxelWidth::Two`]).
    pub fn from_dense(grid: &DenseGrid, config: TreeConfig) -> Result<VoxelTree, TreeError> {
        build::from_dense(grid, config)
    }

    /// Builds a tree of `width` over `spec` from `source`, which hands over one lower-node cube
    /// (`config.extent(1)` voxels per axis) at a time, so no dense grid of the whole scene is ever
    /// held: memory is the tree plus one cube buffer per worker thread. Parallel (rayon) over
    /// lower-node cubes; equal content gives the same tree as [`VoxelTree::from_dense`].
    ///
    /// Errors: as `from_dense`, plus a code invalid for `width` ([`TreeError::InvalidCode`]) and a
    /// leaf row wider than 64 bits (`width.bits() * 2^log2_dims[0] > 64`).
    pub fn from_source(
        spec: GridSpec,
        width: VoxelWidth,
        config: TreeConfig,
        source: &dyn CubeSource,
    ) -> Result<VoxelTree, TreeError> {
        build::from_source(spec, width, config, source)
    }

    /// The voxel kind at `ijk`; Free outside `spec().dims`. Constant cost: a bounds check, the root
    /// slot, at most two internal slots and one leaf word. Does not allocate or block.
    #[inline(always)]
    pub fn get(&self, ijk: IVec3) -> Voxel {
        if self.paper_shape {
            self.get_as::<PAPER_SHAPE>(ijk)
        } else {
            self.get_as::<ANY_SHAPE>(ijk)
        }
    }

    /// [`VoxelTree::get`] on the copy of the lookup for `SHAPE` (see [`ShapedTree`]): `SHAPE` must
    /// be [`ANY_SHAPE`] or this tree's [`VoxelTree::fixed_shape`].
    #[inline(always)]
    fn get_as<const SHAPE: u32>(&self, ijk: IVec3) -> Voxel {
        debug_assert!(SHAPE == ANY_SHAPE || SHAPE == self.fixed_shape);
        let Some(p) = self.in_grid(ijk) else {
            return Voxel::Free;
        };
        // The paper's 2-bit 512-tree (the default) gets a copy of the walk with constant shifts: on
        // baseline x86-64 a shift by a register amount costs several micro-ops.
        if SHAPE == PAPER_SHAPE {
            Voxel::from_bits(self.read(p, &LookupShape::TREE_512))
        } else {
            self.kind_of(self.read(p, &self.lookup_shape_as::<SHAPE>()))
        }
    }

    /// The voxel at `ijk` with its distance layer (layer 0 in a 2-bit tree); Free outside the dims.
    /// Same cost as [`VoxelTree::get`] plus a decode. Does not allocate or block.
    #[inline(always)]
    pub fn get_layered(&self, ijk: IVec3) -> LayeredVoxel {
        if self.paper_shape {
            self.get_layered_as::<PAPER_SHAPE>(ijk)
        } else {
            self.get_layered_as::<ANY_SHAPE>(ijk)
        }
    }

    /// [`VoxelTree::get_layered`] on the copy of the lookup for `SHAPE` (as
    /// [`VoxelTree::get_as`]).
    #[inline(always)]
    fn get_layered_as<const SHAPE: u32>(&self, ijk: IVec3) -> LayeredVoxel {
        debug_assert!(SHAPE == ANY_SHAPE || SHAPE == self.fixed_shape);
        let Some(p) = self.in_grid(ijk) else {
            return LayeredVoxel {
                kind: Voxel::Free,
                layer: 0,
            };
        };
        if SHAPE == PAPER_SHAPE {
            return LayeredVoxel {
                kind: Voxel::from_bits(self.read(p, &LookupShape::TREE_512)),
                layer: 0,
            };
        }
        self.decode(self.read(p, &self.lookup_shape_as::<SHAPE>()))
    }

    /// The voxels of a block of cells, lane by lane as [`VoxelTree::get_layered`]. With the leaf
    /// directory, one vectorisable pass over the block (see `directory::LeafDirectory::read_block`);
    /// without it, one walk per lane. Does not allocate or block.
    #[inline(always)]
    pub fn get_block(&self, cells: &BlockCells) -> VoxelBlock {
        if self.paper_shape {
            self.get_block_as::<PAPER_SHAPE>(cells)
        } else {
            self.get_block_as::<ANY_SHAPE>(cells)
        }
    }

    /// [`VoxelTree::get_block`] on the copy of the lookup for `SHAPE` (as [`VoxelTree::get_as`]).
    #[allow(clippy::needless_range_loop)] // lane loops: index form vectorises and reads as lanes
    #[inline(always)]
    fn get_block_as<const SHAPE: u32>(&self, cells: &BlockCells) -> VoxelBlock {
        debug_assert!(SHAPE == ANY_SHAPE || SHAPE == self.fixed_shape);
        let Some(directory) = &self.directory else {
            return crate::block_by_lanes(ShapedTree::<SHAPE>::of(self), cells);
        };
        if SHAPE == PAPER_SHAPE {
            // 2-bit codes are the kinds' bits.
            let kinds = directory.read_block(&self.leaf_words, LookupShape::TREE_512.leaf, cells);
            return VoxelBlock {
                kinds,
                layers: [0; BLOCK_LANES],
            };
        }
        let codes = directory.read_block(
            &self.leaf_words,
            self.lookup_shape_as::<SHAPE>().leaf,
            cells,
        );
        let mut block = VoxelBlock::default();
        for l in 0..BLOCK_LANES {
            let v = self.decode(codes[l]);
            block.kinds[l] = v.kind.bits();
            block.layers[l] = v.layer;
        }
        block
    }

    /// The voxels of a wide block of cells, lane by lane as [`VoxelTree::get_layered`]. With the
    /// leaf directory and AVX-512F, one pass over the sixteen lanes (see
    /// `directory::LeafDirectory::read_wide_block`); otherwise [`VoxelTree::get_block`] on each
    /// half. Does not allocate or block.
    #[inline(always)]
    pub fn get_wide_block(&self, cells: &WideBlockCells) -> WideVoxelBlock {
        if self.paper_shape {
            self.get_wide_block_as::<PAPER_SHAPE>(cells)
        } else {
            self.get_wide_block_as::<ANY_SHAPE>(cells)
        }
    }

    /// [`VoxelTree::get_wide_block`] on the copy of the lookup for `SHAPE` (as
    /// [`VoxelTree::get_as`]).
    #[allow(clippy::needless_range_loop)] // lane loops: index form vectorises and reads as lanes
    #[inline(always)]
    fn get_wide_block_as<const SHAPE: u32>(&self, cells: &WideBlockCells) -> WideVoxelBlock {
        debug_assert!(SHAPE == ANY_SHAPE || SHAPE == self.fixed_shape);
        let leaf = if SHAPE == PAPER_SHAPE {
            LookupShape::TREE_512.leaf
        } else {
            self.lookup_shape_as::<SHAPE>().leaf
        };
        let directory = self.directory.as_ref();
        let wide = directory.and_then(|d| d.read_wide_block(&self.leaf_words, leaf, cells));
        let Some(codes) = wide else {
            return crate::wide_block_by_halves(cells, |half| self.get_block_as::<SHAPE>(half));
        };
        if SHAPE == PAPER_SHAPE {
            // 2-bit codes are the kinds' bits.
            return WideVoxelBlock {
                kinds: codes,
                layers: [0; WIDE_BLOCK_LANES],
            };
        }
        #[cfg(target_arch = "x86_64")]
        if SHAPE == FOUR_BIT_SHAPE {
            // SAFETY: the directory reads wide blocks only where the CPU has AVX-512F and SSSE3
            // (`LeafDirectory::read_wide_block`); a 4-bit tree's codes are below 16.
            return unsafe { self.codes.decode_low(codes) };
        }
        let mut block = WideVoxelBlock::default();
        for l in 0..WIDE_BLOCK_LANES {
            let v = self.decode(codes[l]);
            block.kinds[l] = v.kind.bits();
            block.layers[l] = v.layer;
        }
        block
    }

    /// The kind of a stored (valid) code.
    #[inline(always)]
    fn kind_of(&self, code: u8) -> Voxel {
        match self.width {
            VoxelWidth::Two => Voxel::from_bits(code),
            _ => self.codes.get(code).kind,
        }
    }

    /// The voxel of a stored (valid) code.
    #[inline(always)]
    fn decode(&self, code: u8) -> LayeredVoxel {
        self.codes.get(code)
    }

    /// `ijk` as unsigned coordinates when it is inside the dims. Dims are at most `i32::MAX`
    /// (checked on assembly), so a negative coordinate cast to `u32` is never below a dim and one
    /// unsigned compare per axis covers both ends.
    #[inline(always)]
    fn in_grid(&self, ijk: IVec3) -> Option<UVec3> {
        let p = ijk.as_uvec3();
        let d = self.spec.dims;
        ((p.x < d[0]) & (p.y < d[1]) & (p.z < d[2])).then_some(p)
    }

    /// The code at in-grid `p`, walking with `shape` (equal to [`VoxelTree::lookup_shape`]).
    #[inline(always)]
    fn read(&self, p: UVec3, shape: &LookupShape) -> u8 {
        if let Some(directory) = &self.directory {
            return directory.read(&self.leaf_words, shape.leaf, p);
        }
        match self.locate_with(p, shape) {
            LeafRef::Tile(v) => v,
            LeafRef::Leaf(first) => {
                let word = first + shape.leaf.word_of(p);
                debug_assert!(word < self.leaf_words.len());
                // SAFETY: `first` is the first word of a stored leaf (`child << word_shift` for a
                // child index below the leaf count: every child index in the lower arena is, by the
                // canonical-form invariant that `from_dense` establishes and `from_parts` checks),
                // and `word_of` is below the words per leaf, so `word < leaf_words.len()`.
                let bits = unsafe { *self.leaf_words.get_unchecked(word) };
                shape.leaf.code_in_word(bits, p)
            }
        }
    }

    /// The shifts of this tree's lookup path.
    #[inline(always)]
    fn lookup_shape(&self) -> LookupShape {
        LookupShape {
            root_shift: self.root.shift,
            upper: self.upper.shape,
            lower: self.lower.shape,
            leaf: self.leaf_shape,
        }
    }

    /// [`VoxelTree::lookup_shape`] as constants where `SHAPE` fixes it (the 512-tree of
    /// `2^SHAPE` bits per voxel), read from the tree for [`ANY_SHAPE`].
    #[inline(always)]
    fn lookup_shape_as<const SHAPE: u32>(&self) -> LookupShape {
        if SHAPE == ANY_SHAPE {
            self.lookup_shape()
        } else {
            LookupShape::tree_512(SHAPE)
        }
    }

    /// Walks root → upper → lower for in-grid voxel `p`: no loop, three slot reads at most.
    #[inline(always)]
    fn locate(&self, p: UVec3) -> LeafRef {
        self.locate_with(p, &self.lookup_shape())
    }

    /// [`VoxelTree::locate`] with the shifts passed in (constants for the 512-tree).
    #[inline(always)]
    fn locate_with(&self, p: UVec3, shape: &LookupShape) -> LeafRef {
        let s = self.root.slot(p, shape.root_shift);
        if s.is_tile() {
            return LeafRef::Tile(s.tile_value());
        }
        let s = self.upper.slot_of(shape.upper, s.child_index(), p);
        if s.is_tile() {
            return LeafRef::Tile(s.tile_value());
        }
        let s = self.lower.slot_of(shape.lower, s.child_index(), p);
        if s.is_tile() {
            return LeafRef::Tile(s.tile_value());
        }
        LeafRef::Leaf(s.child_index() << shape.leaf.word_shift())
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

    /// Bits stored per voxel.
    pub fn width(&self) -> VoxelWidth {
        self.width
    }

    /// Stored nodes per level.
    pub fn node_counts(&self) -> NodeCounts {
        NodeCounts {
            leaves: self.leaf_words.len() / self.leaf_shape.words_per_leaf(),
            lower: self.lower.node_count(),
            upper: self.upper.node_count(),
        }
    }

    /// Heap bytes held by the arenas (root, upper, lower slot tables and leaf words): the voxmap
    /// itself, what a `.vmap` file stores. The lookup directory derived from it is counted apart
    /// ([`VoxelTree::directory_bytes`], see [`DIRECTORY_ALLOWANCE_BYTES`]).
    pub fn memory_bytes(&self) -> usize {
        4 * (self.root.slots.capacity() + self.upper.slots.capacity() + self.lower.slots.capacity())
            + 8 * self.leaf_words.capacity()
    }

    /// This tree carrying `band` (built for this tree's grid, see
    /// [`crate::distance`]): the sampling kernel then runs the `distance` force model on it.
    /// Replaces any band it had.
    pub fn with_distance_band(mut self, band: DistanceBand) -> VoxelTree {
        self.distance = Some(Arc::new(band));
        self
    }

    /// The signed-distance band, when the map carries one.
    pub fn distance_band(&self) -> Option<&DistanceBand> {
        self.distance.as_deref()
    }

    /// Bytes a dense array of the same width over the dims would take:
    /// `ceil(W * voxel_count / 8)`.
    pub fn dense_equivalent_bytes(&self) -> u64 {
        (self.width.bits() as u64 * self.spec.voxel_count()).div_ceil(8)
    }

    /// Voxels of each kind inside the dims, indexed by the kind's value, computed from tiles (clipped
    /// to the dims) and leaf contents without expanding the tree.
    pub fn counts(&self) -> [u64; 4] {
        let mut c = [0u64; 4];
        for (v, n) in self.layer_counts() {
            c[v.kind as usize] += n;
        }
        c
    }

    /// Voxels inside the dims per (kind, layer), in code order: every kind at layer 0 (even when
    /// absent) and every deeper layer that occurs. For a 2-bit tree: the four kinds. Computed without expanding the tree.
    pub fn layer_counts(&self) -> Vec<(LayeredVoxel, u64)> {
        walk::code_counts(self)
            .iter()
            .enumerate()
            .filter_map(|(code, &n)| Some((self.width.decode(code as u8)?, n)))
            .filter(|&(v, n)| n > 0 || v.layer == 0)
            .collect()
    }

    /// Calls `f(min, max)` for every region of voxels of `kind` inside the dims, as half-open voxel
    /// index boxes `[min, max)`: one box per uniform tile (clipped to the dims) and one unit box per
    /// matching voxel of a leaf, in canonical order. Reads the tree without expanding it: no
    /// allocation, time linear in the stored leaves and tiles (not in the grid's volume).
    pub fn for_each_region_of(&self, kind: Voxel, f: impl FnMut(UVec3, UVec3)) {
        walk::regions_of(self, kind, f)
    }

    /// The dense grid with the same content (allocates `voxel_count` bytes; for tests and tools).
    pub fn to_dense(&self) -> DenseGrid {
        walk::to_dense(self)
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
        width: VoxelWidth,
        arenas: Arenas,
    ) -> Result<VoxelTree, TreeError> {
        let mut tree = VoxelTree::assemble(spec, config, width, arenas)?;
        // Arenas read from a stream grow as bytes arrive (so that a corrupt count cannot allocate
        // more than the stream holds) and end with growth slack: drop it, so that a loaded tree
        // holds what its file says, as a built one does (`memory_bytes` equal).
        tree.root.slots.shrink_to_fit();
        tree.upper.slots.shrink_to_fit();
        tree.lower.slots.shrink_to_fit();
        tree.leaf_words.shrink_to_fit();
        validate::check_canonical(&tree)?;
        Ok(tree.with_directory())
    }

    /// Wraps arenas in a tree after checking spec, config and width (not the arenas' content).
    fn assemble(
        spec: GridSpec,
        config: TreeConfig,
        width: VoxelWidth,
        arenas: Arenas,
    ) -> Result<VoxelTree, TreeError> {
        config.validate()?;
        validate::check_spec(&spec)?;
        let [n0, n1, n2] = config.log2_dims.map(u32::from);
        if width.bits() << n0 > 64 {
            return Err(TreeError::LeafTooWide {
                bits: width.bits(),
                log2: n0 as u8,
            });
        }
        let root_shift = config.shift(2);
        Ok(VoxelTree {
            distance: None,
            spec,
            config,
            width,
            paper_shape: config == TreeConfig::default() && width == VoxelWidth::Two,
            fixed_shape: if config == TreeConfig::default() {
                width.bits_log2()
            } else {
                ANY_SHAPE
            },
            codes: CodeTable::new(width),
            root: RootGrid {
                dims: RootGrid::dims_for(spec.dims, root_shift),
                shift: root_shift,
                slots: arenas.root,
            },
            upper: InternalLevel {
                shape: internal::InternalShape {
                    log2: n2,
                    child_shift: n0 + n1,
                },
                slots: arenas.upper,
            },
            lower: InternalLevel {
                shape: internal::InternalShape {
                    log2: n1,
                    child_shift: n0,
                },
                slots: arenas.lower,
            },
            leaf_shape: LeafShape {
                log2: n0,
                bits_log2: width.bits_log2(),
            },
            leaf_words: arenas.leaves,
            directory: None,
        })
    }

    /// Adds the leaf directory when it fits [`DIRECTORY_MAX_BYTES`] and
    /// [`DIRECTORY_ALLOWANCE_BYTES`]. The arenas must be canonical (built or checked).
    pub(crate) fn with_directory(mut self) -> Self {
        self.directory = LeafDirectory::build(&self);
        self
    }

    /// The same tree without its leaf directory: its memory is freed and lookups walk the tree
    /// (the same voxels, more instructions per lookup). For memory-tight hosts, and for tests of
    /// the walking path.
    pub fn without_directory(mut self) -> Self {
        self.directory = None;
        self
    }

    /// The same tree with block lookups ([`VoxelTree::get_block`]) on the portable path, without
    /// AVX2 gathers (the same voxels): for benchmarks of the gathers and tests of the portable
    /// path on AVX2 hosts.
    pub fn without_gathers(mut self) -> Self {
        self.directory = self.directory.map(LeafDirectory::without_gathers);
        self
    }

    /// Heap bytes of the leaf directory, the lookup index derived from the tree (0 when the tree
    /// has none: see [`DIRECTORY_ALLOWANCE_BYTES`]); not counted in [`VoxelTree::memory_bytes`].
    pub fn directory_bytes(&self) -> usize {
        self.directory
            .as_ref()
            .map_or(0, LeafDirectory::memory_bytes)
    }
}

impl VoxelLookup for VoxelTree {
    fn spec(&self) -> &GridSpec {
        &self.spec
    }

    #[inline(always)]
    fn distance_band(&self) -> Option<&DistanceBand> {
        self.distance.as_deref()
    }

    #[inline(always)]
    fn get(&self, ijk: IVec3) -> Voxel {
        VoxelTree::get(self, ijk)
    }

    #[inline(always)]
    fn get_layered(&self, ijk: IVec3) -> LayeredVoxel {
        VoxelTree::get_layered(self, ijk)
    }

    #[inline(always)]
    fn get_block(&self, cells: &BlockCells) -> VoxelBlock {
        VoxelTree::get_block(self, cells)
    }

    #[inline(always)]
    fn get_wide_block(&self, cells: &WideBlockCells) -> WideVoxelBlock {
        VoxelTree::get_wide_block(self, cells)
    }

    /// `task` on a `ShapedTree` of this tree: which copy of the lookups, chosen once here.
    #[inline(always)]
    fn specialised<T: LookupTask>(&self, task: T) -> T::Output {
        match self.fixed_shape {
            PAPER_SHAPE => task.run(ShapedTree::<PAPER_SHAPE>::of(self)),
            FOUR_BIT_SHAPE => task.run(ShapedTree::<FOUR_BIT_SHAPE>::of(self)),
            _ => task.run(ShapedTree::<ANY_SHAPE>::of(self)),
        }
    }
}

/// [`ShapedTree`]'s general copy: shifts read from the tree, codes decoded by table. Right for
/// every tree.
const ANY_SHAPE: u32 = 0;
/// [`ShapedTree`]'s copy for the paper's 2-bit 512-tree (the default): constant shifts, and the
/// codes are the kinds.
const PAPER_SHAPE: u32 = 1;
/// [`ShapedTree`]'s copy for the 4-bit 512-tree: constant shifts, codes decoded by table.
const FOUR_BIT_SHAPE: u32 = 2;

/// A tree whose lookups run one copy of the lookup code, chosen by `SHAPE` instead of tested per
/// lookup: [`ANY_SHAPE`] for any tree, or (only for a tree of that shape, its
/// [`VoxelTree::fixed_shape`]) [`PAPER_SHAPE`] or [`FOUR_BIT_SHAPE`]. The same voxels as the tree.
/// The tree itself (not a reference to it), so that a loop over lookups reads the tree's fields
/// through one reference, as it would the tree's.
#[repr(transparent)]
struct ShapedTree<const SHAPE: u32>(VoxelTree);

impl<const SHAPE: u32> ShapedTree<SHAPE> {
    /// `tree` as a [`ShapedTree`]; `SHAPE` must be [`ANY_SHAPE`] or the tree's `fixed_shape`
    /// (checked in debug builds by every lookup).
    #[inline(always)]
    fn of(tree: &VoxelTree) -> &ShapedTree<SHAPE> {
        // SAFETY: `ShapedTree` is a `repr(transparent)` wrapper of `VoxelTree`, so the pointer
        // casts to a reference of the same layout, alignment and lifetime.
        unsafe { &*(tree as *const VoxelTree).cast::<ShapedTree<SHAPE>>() }
    }
}

impl<const SHAPE: u32> VoxelLookup for ShapedTree<SHAPE> {
    fn spec(&self) -> &GridSpec {
        &self.0.spec
    }

    #[inline(always)]
    fn distance_band(&self) -> Option<&DistanceBand> {
        self.0.distance.as_deref()
    }

    #[inline(always)]
    fn get(&self, ijk: IVec3) -> Voxel {
        self.0.get_as::<SHAPE>(ijk)
    }

    #[inline(always)]
    fn get_layered(&self, ijk: IVec3) -> LayeredVoxel {
        self.0.get_layered_as::<SHAPE>(ijk)
    }

    #[inline(always)]
    fn get_block(&self, cells: &BlockCells) -> VoxelBlock {
        self.0.get_block_as::<SHAPE>(cells)
    }

    #[inline(always)]
    fn get_wide_block(&self, cells: &WideBlockCells) -> WideVoxelBlock {
        self.0.get_wide_block_as::<SHAPE>(cells)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_512_shape_matches_the_default_tree() {
        let spec = GridSpec::at_origin(0.01, [700, 20, 9]);
        let tree = VoxelTree::from_dense(&DenseGrid::new(spec), TreeConfig::default()).unwrap();
        assert_eq!(tree.lookup_shape(), LookupShape::TREE_512);
        let other = VoxelTree::from_dense(&DenseGrid::new(spec), TreeConfig::uniform(2)).unwrap();
        assert_ne!(other.lookup_shape(), LookupShape::TREE_512);
    }
}
