//! The leaf directory: a dense array with one slot per leaf-sized cube of the grid, holding what the
//! root → upper → lower walk would end at (a tile's code, or the leaf's index). With it a lookup
//! reads one directory slot and one leaf word instead of three slots and one word, and does a
//! third of the index arithmetic; the leaves themselves are the tree's.
//!
//! It costs 4 bytes per `8³` voxels (for the 512-tree): memory that follows the grid's volume, not
//! the surface. So that the voxmap's memory keeps following the surface, it is built only when it
//! is at most as large as the tree's own arenas (or [`DIRECTORY_ALLOWANCE_BYTES`], whichever is
//! larger) and under [`DIRECTORY_MAX_BYTES`]; otherwise lookups walk the tree (same results, more
//! instructions).
//! It is derived from the tree's content (equal trees have equal directories) and never stored in
//! a `.vmap` file.

use super::internal::Slot;
use super::leaf::LeafShape;
use super::{LeafRef, VoxelTree};
use crate::{BlockCells, WideBlockCells, BLOCK_LANES, WIDE_BLOCK_LANES};
use glam::UVec3;
use rayon::prelude::*;

/// Largest directory built (bytes): 64 MiB, i.e. 2^24 four-byte slots, one per 8³ leaf cube:
/// grids up to 2^33 voxels with the 512-tree (e.g. 2,048³ voxels; the aircraft bay at 5 mm needs
/// 0.62 MB, see [`DIRECTORY_ALLOWANCE_BYTES`]). Slot indices therefore fit a `u32`.
pub const DIRECTORY_MAX_BYTES: usize = 64 << 20;

/// A directory up to this size (bytes, 4 MiB) is built whatever the tree's size; a larger one
/// only when it is no larger than the tree's arenas ([`VoxelTree::memory_bytes`]). The aircraft
/// bay at 5 mm (2-bit): 624,624 B beside 7,445,128 B (`vps voxelize builtin:aircraft-bay -o bay.vmap`
/// then `vps inspect bay.vmap --json`). A large, mostly empty grid (a small part far from the rest
/// of the scene) gets no directory and walks the tree instead.
pub const DIRECTORY_ALLOWANCE_BYTES: usize = 4 << 20;

/// Whether a directory of `directory_bytes` is built beside arenas of `tree_bytes`.
fn directory_allowed(directory_bytes: u64, tree_bytes: u64) -> bool {
    directory_bytes <= DIRECTORY_MAX_BYTES as u64
        && directory_bytes <= tree_bytes.max(DIRECTORY_ALLOWANCE_BYTES as u64)
}

/// One slot per leaf cube, x fastest.
#[derive(Clone, Debug)]
pub(crate) struct LeafDirectory {
    /// Leaf cubes per axis: `ceil(grid dims / leaf edge)`.
    dims: [u32; 3],
    /// The tree's grid dims (voxels per axis): a block cell outside them reads Free.
    grid_dims: [u32; 3],
    /// Raw [`Slot`] words: a tile, or a child holding the leaf's index in the leaf arena.
    slots: Vec<u32>,
    /// Block reads use AVX2 and a gather of the slots (see [`LeafDirectory::read_block`]): the CPU
    /// has AVX2. Not part of the content.
    gathers: bool,
    /// Wide block reads use AVX-512F gathers (see [`LeafDirectory::read_wide_block`]): the CPU
    /// has AVX-512F and the leaf arena's word numbers fit the gathers' signed 32-bit offsets. Not
    /// part of the content.
    wide_gathers: bool,
}

/// Equal content: the dims, grid dims and slots (whether block reads gather is a property of the
/// host).
impl PartialEq for LeafDirectory {
    fn eq(&self, other: &Self) -> bool {
        self.dims == other.dims && self.grid_dims == other.grid_dims && self.slots == other.slots
    }
}

impl Eq for LeafDirectory {}

/// Whether this CPU can run [`LeafDirectory::read_wide_block`]'s AVX-512 path (AVX-512F), and the
/// tree's byte-shuffle decode of the codes it reads (SSSE3).
fn cpu_reads_wide() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("ssse3")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

impl LeafDirectory {
    /// The directory of `tree` (whose arenas must be canonical: built or validated), or `None`
    /// when it is too large (see [`DIRECTORY_ALLOWANCE_BYTES`]).
    /// Parallel (rayon) over z slices.
    pub(crate) fn build(tree: &VoxelTree) -> Option<LeafDirectory> {
        let shift = tree.leaf_shape.log2;
        let dims = tree
            .spec
            .dims
            .map(|d| ((d as u64 + (1u64 << shift) - 1) >> shift) as u32);
        let count = dims.iter().map(|&d| d as u64).product::<u64>();
        // Block reads index the leaf arena with u32 word numbers.
        if !directory_allowed(count.saturating_mul(4), tree.memory_bytes() as u64)
            || tree.leaf_words.len() > u32::MAX as usize
        {
            return None;
        }
        let mut slots = vec![0u32; count as usize];
        let slice = dims[0] as usize * dims[1] as usize;
        let word_shift = tree.leaf_shape.word_shift();
        slots
            .par_chunks_mut(slice.max(1))
            .enumerate()
            .for_each(|(z, plane)| {
                for (i, slot) in plane.iter_mut().enumerate() {
                    let cube = UVec3::new(
                        (i % dims[0] as usize) as u32,
                        (i / dims[0] as usize) as u32,
                        z as u32,
                    );
                    // The cube's minimum corner is inside the grid dims (cube < ceil(dims / edge)).
                    *slot = match tree.locate(cube << shift) {
                        LeafRef::Tile(code) => Slot::tile(code).0,
                        LeafRef::Leaf(first) => Slot::child((first >> word_shift) as u32).0,
                    };
                }
            });
        let gathers = crate::cpu::has_avx2();
        // The wide read gathers leaf words at signed 32-bit word offsets.
        let wide_gathers = cpu_reads_wide() && tree.leaf_words.len() <= i32::MAX as usize;
        Some(LeafDirectory {
            dims,
            grid_dims: tree.spec.dims,
            slots,
            gathers,
            wide_gathers,
        })
    }

    /// The same directory with block reads on the portable path (no AVX2 or AVX-512 gathers):
    /// for benchmarks of the gathers and tests that both paths agree.
    pub(crate) fn without_gathers(mut self) -> Self {
        self.gathers = false;
        self.wide_gathers = false;
        self
    }

    /// Heap bytes held.
    pub(crate) fn memory_bytes(&self) -> usize {
        4 * self.slots.capacity()
    }

    /// The code at in-grid voxel `p`; `leaf` must be the tree's leaf shape (passed in so a caller
    /// can make it a constant) and `leaf_words` its leaf arena.
    #[inline(always)]
    pub(crate) fn read(&self, leaf_words: &[u64], leaf: LeafShape, p: UVec3) -> u8 {
        let c = p >> leaf.log2;
        let i = c.x as usize
            + self.dims[0] as usize * (c.y as usize + self.dims[1] as usize * c.z as usize);
        debug_assert!(i < self.slots.len());
        // SAFETY: `p` is inside the grid dims, so `c < self.dims` per axis and `i` is below the
        // slot count (`build` makes one slot per cube).
        let slot = Slot(unsafe { *self.slots.get_unchecked(i) });
        if slot.is_tile() {
            return slot.tile_value();
        }
        let word = (slot.child_index() << leaf.word_shift()) + leaf.word_of(p);
        debug_assert!(word < leaf_words.len());
        // SAFETY: a child slot holds the index of a stored leaf (copied from the canonical tree's
        // lower level by `build`), and `word_of` is below the words per leaf.
        leaf.code_in_word(unsafe { *leaf_words.get_unchecked(word) }, p)
    }

    /// The codes at the cells of a block (`cells[axis][lane]`, any values; a cell outside the
    /// tree's grid dims reads 0, Free). `leaf` must be the tree's leaf shape and `leaf_words` its
    /// leaf arena. Same result per lane as [`LeafDirectory::read`]. With AVX2
    /// (detected when the directory is built): one gather of the eight slots and, if some lane is
    /// in a leaf, eight word loads ([`LeafDirectory::read_block_avx2`]); otherwise the
    /// portable lane loops ([`LeafDirectory::read_block_portable`]).
    #[inline(always)]
    pub(crate) fn read_block(
        &self,
        leaf_words: &[u64],
        leaf: LeafShape,
        cells: &BlockCells,
    ) -> [u8; BLOCK_LANES] {
        #[cfg(target_arch = "x86_64")]
        if self.gathers {
            // SAFETY: `gathers` is set only when the CPU has AVX2 (`build`).
            return unsafe { self.read_block_avx2(leaf_words, leaf, cells) };
        }
        self.read_block_portable(leaf_words, leaf, cells)
    }

    /// [`LeafDirectory::read_block`] in plain loops over lane arrays, so that the index
    /// arithmetic and the tile test vectorise where the caller is compiled for it, with eight
    /// independent slot loads and, only for lanes in a leaf, eight independent word loads.
    #[allow(clippy::needless_range_loop)] // lane loops: index form vectorises and reads as lanes
    #[inline(always)]
    pub(crate) fn read_block_portable(
        &self,
        leaf_words: &[u64],
        leaf: LeafShape,
        cells: &BlockCells,
    ) -> [u8; BLOCK_LANES] {
        const L: usize = BLOCK_LANES;
        // Lane masks are u32 words (0 or !0) rather than bools so that the loops vectorise.
        // Unsigned cells: a negative cell wraps above every dim.
        let p = cells.map(|axis| axis.map(|c| c as u32));
        // Dims are at most i32::MAX (checked on assembly): signed compares, which vectorise.
        let dims = self.grid_dims.map(|d| d as i32);
        let mut inside = [0u32; L];
        for (a, axis) in cells.iter().enumerate() {
            for l in 0..L {
                let low = 0u32.wrapping_sub(u32::from(axis[l] >= 0));
                let high = 0u32.wrapping_sub(u32::from(axis[l] < dims[a]));
                inside[l] = if a == 0 {
                    low & high
                } else {
                    inside[l] & low & high
                };
            }
        }
        let mut index = [0u32; L];
        for l in 0..L {
            let c = [
                p[0][l] >> leaf.log2,
                p[1][l] >> leaf.log2,
                p[2][l] >> leaf.log2,
            ];
            // Below the slot count (≤ 2^24) for in-grid lanes; wrapping garbage elsewhere, masked.
            let i = c[0].wrapping_add(
                self.dims[0].wrapping_mul(c[1].wrapping_add(self.dims[1].wrapping_mul(c[2]))),
            );
            index[l] = i & inside[l];
        }
        let mut slot = [0u32; L];
        for l in 0..L {
            debug_assert!((index[l] as usize) < self.slots.len());
            // SAFETY: an in-grid lane's index is below the slot count (see `read`); other lanes
            // read slot 0, which exists (the grid has at least one voxel, so one cube).
            slot[l] = unsafe { *self.slots.get_unchecked(index[l] as usize) };
        }
        // Out-of-grid lanes become Free tiles.
        let mut codes = [0u8; L];
        let mut leaf_lanes = 0u32;
        for l in 0..L {
            slot[l] = (slot[l] & inside[l]) | (Slot::TILE_BIT & !inside[l]);
            codes[l] = slot[l] as u8;
            leaf_lanes |= u32::from(slot[l] & Slot::TILE_BIT == 0) << l;
        }
        if leaf_lanes == 0 {
            return codes;
        }
        // Lanes in a leaf: the word holding the voxel and the voxel's bit in it. Tile lanes read
        // word 0 (the arena is not empty: some lane is in a leaf) and keep their tile code.
        let edge_mask = leaf.edge() - 1;
        let mut word = [0u32; L];
        let mut shift = [0u64; L];
        for l in 0..L {
            let local = (p[0][l] & edge_mask)
                | ((p[1][l] & edge_mask) << leaf.log2)
                | ((p[2][l] & edge_mask) << (2 * leaf.log2));
            let bit = local << leaf.bits_log2;
            let is_leaf = 0u32.wrapping_sub(u32::from(slot[l] & Slot::TILE_BIT == 0));
            // Fits a u32: `build` checks that the leaf arena has fewer than 2^32 words.
            word[l] = ((slot[l] << leaf.word_shift()) + (bit >> 6)) & is_leaf;
            shift[l] = u64::from(bit & 63);
        }
        let mut bits = [0u64; L];
        for l in 0..L {
            debug_assert!((word[l] as usize) < leaf_words.len());
            // SAFETY: a leaf lane's child slot holds a stored leaf's index (as in `read`), so its
            // word is inside the arena; other lanes read word 0, which exists (see above).
            bits[l] = unsafe { *leaf_words.get_unchecked(word[l] as usize) };
        }
        let code_mask = (1u64 << (1u32 << leaf.bits_log2)) - 1;
        for l in 0..L {
            let code = ((bits[l] >> shift[l]) & code_mask) as u8;
            codes[l] = if leaf_lanes >> l & 1 != 0 {
                code
            } else {
                codes[l]
            };
        }
        codes
    }

    /// [`LeafDirectory::read_block`] with AVX2: the in-grid masks and slot indices in one register
    /// per quantity, one gather of the eight slots, and only when some lane is in a leaf, eight
    /// independent word loads (two 64-bit gathers instead measured 4 % fewer instructions but no
    /// faster on the AMD EPYC of this project's VM) and a per-lane variable shift. Same results as
    /// [`LeafDirectory::read_block_portable`] (tested on random blocks).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn read_block_avx2(
        &self,
        leaf_words: &[u64],
        leaf: LeafShape,
        cells: &BlockCells,
    ) -> [u8; BLOCK_LANES] {
        use std::arch::x86_64::*;
        // SAFETY: each load reads the 32 bytes of one `[i32; 8]` axis; no alignment needed.
        let (x, y, z) = unsafe {
            (
                _mm256_loadu_si256(cells[0].as_ptr().cast()),
                _mm256_loadu_si256(cells[1].as_ptr().cast()),
                _mm256_loadu_si256(cells[2].as_ptr().cast()),
            )
        };
        let zero = _mm256_setzero_si256();
        // In the grid: 0 ≤ c < dim per axis; dims are at most i32::MAX (checked on assembly), so
        // signed compares.
        let dim = |d: u32| _mm256_set1_epi32(d as i32);
        let in_x = _mm256_andnot_si256(
            _mm256_cmpgt_epi32(zero, x),
            _mm256_cmpgt_epi32(dim(self.grid_dims[0]), x),
        );
        let in_y = _mm256_andnot_si256(
            _mm256_cmpgt_epi32(zero, y),
            _mm256_cmpgt_epi32(dim(self.grid_dims[1]), y),
        );
        let in_z = _mm256_andnot_si256(
            _mm256_cmpgt_epi32(zero, z),
            _mm256_cmpgt_epi32(dim(self.grid_dims[2]), z),
        );
        let inside = _mm256_and_si256(_mm256_and_si256(in_x, in_y), in_z);
        // The slot index of the lane's leaf cube (wrapping garbage outside the grid, masked to 0).
        let cube_shift = _mm_cvtsi32_si128(leaf.log2 as i32);
        let (cx, cy, cz) = (
            _mm256_srl_epi32(x, cube_shift),
            _mm256_srl_epi32(y, cube_shift),
            _mm256_srl_epi32(z, cube_shift),
        );
        let row = _mm256_add_epi32(cy, _mm256_mullo_epi32(dim(self.dims[1]), cz));
        let index = _mm256_add_epi32(cx, _mm256_mullo_epi32(dim(self.dims[0]), row));
        let index = _mm256_and_si256(index, inside);
        // SAFETY: an in-grid lane's index is below the slot count (see `read`); other lanes read
        // slot 0, which exists (the grid has at least one voxel, so one cube).
        let slot = unsafe { _mm256_i32gather_epi32::<4>(self.slots.as_ptr().cast(), index) };
        // Out-of-grid lanes become Free tiles.
        let tile_bit = _mm256_set1_epi32(Slot::TILE_BIT as i32);
        let slot = _mm256_or_si256(
            _mm256_and_si256(slot, inside),
            _mm256_andnot_si256(inside, tile_bit),
        );
        let byte = _mm256_set1_epi32(0xff);
        // Tile lanes have the top bit set; a tile's code is the slot's low byte.
        if _mm256_movemask_ps(_mm256_castsi256_ps(slot)) == 0xff {
            return narrow_bytes(_mm256_and_si256(slot, byte));
        }
        let is_leaf = _mm256_cmpgt_epi32(slot, _mm256_set1_epi32(-1));
        // Lanes in a leaf: the word holding the voxel and the voxel's bit in it. Tile lanes read
        // word 0 (the arena is not empty: some lane is in a leaf) and keep their tile code.
        let edge_mask = _mm256_set1_epi32((leaf.edge() - 1) as i32);
        let axis_shift = |n: u32| _mm_cvtsi32_si128(n as i32);
        let local = _mm256_or_si256(
            _mm256_or_si256(
                _mm256_and_si256(x, edge_mask),
                _mm256_sll_epi32(_mm256_and_si256(y, edge_mask), axis_shift(leaf.log2)),
            ),
            _mm256_sll_epi32(_mm256_and_si256(z, edge_mask), axis_shift(2 * leaf.log2)),
        );
        let bit = _mm256_sll_epi32(local, axis_shift(leaf.bits_log2));
        // Below `leaf_words.len()` < 2^32 for leaf lanes (`build` checks the arena size).
        let word = _mm256_and_si256(
            _mm256_add_epi32(
                _mm256_sll_epi32(slot, axis_shift(leaf.word_shift())),
                _mm256_srli_epi32::<6>(bit),
            ),
            is_leaf,
        );
        let shift = _mm256_and_si256(bit, _mm256_set1_epi32(63));
        // SAFETY: a leaf lane's slot holds a stored leaf's index (as in `read`), so its word is
        // inside the arena; other lanes read word 0, which exists (see above). The stores and
        // loads cover exactly the 32- and 64-byte lane arrays, unaligned.
        let (words_lo, words_hi) = unsafe {
            let mut index = [0u32; BLOCK_LANES];
            _mm256_storeu_si256(index.as_mut_ptr().cast(), word);
            let bits: [u64; BLOCK_LANES] =
                std::array::from_fn(|l| *leaf_words.get_unchecked(index[l] as usize));
            (
                _mm256_loadu_si256(bits.as_ptr().cast()),
                _mm256_loadu_si256(bits.as_ptr().add(4).cast()),
            )
        };
        let codes_lo = _mm256_srlv_epi64(
            words_lo,
            _mm256_cvtepu32_epi64(_mm256_castsi256_si128(shift)),
        );
        let codes_hi = _mm256_srlv_epi64(
            words_hi,
            _mm256_cvtepu32_epi64(_mm256_extracti128_si256::<1>(shift)),
        );
        // The low 32 bits of each 64-bit lane, back in lane order:
        // [lo0 lo1 hi0 hi1 | lo2 lo3 hi2 hi3] → [lo0 lo1 lo2 lo3 hi0 hi1 hi2 hi3].
        let interleaved = _mm256_castps_si256(_mm256_shuffle_ps::<0b10_00_10_00>(
            _mm256_castsi256_ps(codes_lo),
            _mm256_castsi256_ps(codes_hi),
        ));
        let leaf_codes = _mm256_permute4x64_epi64::<0b11_01_10_00>(interleaved);
        let code_mask = _mm256_set1_epi32(((1u32 << (1u32 << leaf.bits_log2)) - 1) as i32);
        let codes = _mm256_blendv_epi8(slot, _mm256_and_si256(leaf_codes, code_mask), is_leaf);
        narrow_bytes(_mm256_and_si256(codes, byte))
    }
}

impl LeafDirectory {
    /// The codes at the cells of a wide block (`cells[axis][lane]`, any values; a cell outside the
    /// tree's grid dims reads 0, Free), the same result per lane as [`LeafDirectory::read`]: one
    /// masked gather of the sixteen slots and, if some lane is in a leaf, two masked gathers of
    /// the leaf words ([`LeafDirectory::read_wide_block_avx512`]). `None` where the directory has
    /// no such read (no AVX-512F or SSSE3, detected when it is built): read the block as two
    /// blocks then.
    #[inline(always)]
    pub(crate) fn read_wide_block(
        &self,
        leaf_words: &[u64],
        leaf: LeafShape,
        cells: &WideBlockCells,
    ) -> Option<[u8; WIDE_BLOCK_LANES]> {
        #[cfg(target_arch = "x86_64")]
        if self.wide_gathers {
            // SAFETY: `wide_gathers` is set only when the CPU has AVX-512F and the leaf arena's
            // word numbers fit an i32 (`build`).
            return Some(unsafe { self.read_wide_block_avx512(leaf_words, leaf, cells) });
        }
        let _ = (leaf_words, leaf, cells);
        None
    }

    /// [`LeafDirectory::read_wide_block`] with AVX-512F: the in-grid test as a lane mask, one
    /// gather of the in-grid lanes' slots (the others read as Free tiles), and only when some lane
    /// is in a leaf, one gather of the leaf lanes' words per eight lanes and a per-lane variable
    /// shift. Same results as [`LeafDirectory::read_block_portable`] on each half (tested on
    /// random blocks).
    ///
    /// # Safety
    /// The CPU must support AVX-512F, and the leaf arena must hold at most `i32::MAX` words.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn read_wide_block_avx512(
        &self,
        leaf_words: &[u64],
        leaf: LeafShape,
        cells: &WideBlockCells,
    ) -> [u8; WIDE_BLOCK_LANES] {
        use std::arch::x86_64::*;
        // SAFETY: each load reads the 64 bytes of one `[i32; 16]` axis; no alignment needed.
        let (x, y, z) = unsafe {
            (
                _mm512_loadu_si512(cells[0].as_ptr().cast()),
                _mm512_loadu_si512(cells[1].as_ptr().cast()),
                _mm512_loadu_si512(cells[2].as_ptr().cast()),
            )
        };
        let dim = |d: u32| _mm512_set1_epi32(d as i32);
        // In the grid: c < dim per axis, unsigned (a negative cell wraps above every dim: dims
        // are at most i32::MAX, checked on assembly).
        let inside = _mm512_cmplt_epu32_mask(x, dim(self.grid_dims[0]));
        let inside = _mm512_mask_cmplt_epu32_mask(inside, y, dim(self.grid_dims[1]));
        let inside = _mm512_mask_cmplt_epu32_mask(inside, z, dim(self.grid_dims[2]));
        // The slot index of the lane's leaf cube (wrapping garbage outside the grid, not read).
        let cube_shift = _mm_cvtsi32_si128(leaf.log2 as i32);
        let (cx, cy, cz) = (
            _mm512_srl_epi32(x, cube_shift),
            _mm512_srl_epi32(y, cube_shift),
            _mm512_srl_epi32(z, cube_shift),
        );
        let row = _mm512_add_epi32(cy, _mm512_mullo_epi32(dim(self.dims[1]), cz));
        let index = _mm512_add_epi32(cx, _mm512_mullo_epi32(dim(self.dims[0]), row));
        // Out-of-grid lanes are not read and become Free tiles.
        let free_tile = _mm512_set1_epi32(Slot::TILE_BIT as i32);
        // SAFETY: an in-grid lane's index is below the slot count (see `read`), which is below
        // 2^24 (`DIRECTORY_MAX_BYTES`), so a non-negative i32; other lanes are masked off.
        let slot = unsafe {
            _mm512_mask_i32gather_epi32::<4>(free_tile, inside, index, self.slots.as_ptr().cast())
        };
        // Tile lanes have the top bit set; a tile's code is the slot's low byte.
        let is_leaf = _mm512_cmpge_epi32_mask(slot, _mm512_setzero_si512());
        if is_leaf == 0 {
            return narrow_wide_bytes(slot);
        }
        // Lanes in a leaf: the word holding the voxel and the voxel's bit in it.
        let edge_mask = _mm512_set1_epi32((leaf.edge() - 1) as i32);
        let axis_shift = |n: u32| _mm_cvtsi32_si128(n as i32);
        let local = _mm512_or_si512(
            _mm512_or_si512(
                _mm512_and_si512(x, edge_mask),
                _mm512_sll_epi32(_mm512_and_si512(y, edge_mask), axis_shift(leaf.log2)),
            ),
            _mm512_sll_epi32(_mm512_and_si512(z, edge_mask), axis_shift(2 * leaf.log2)),
        );
        let bit = _mm512_sll_epi32(local, axis_shift(leaf.bits_log2));
        // Below `leaf_words.len()` ≤ i32::MAX for leaf lanes (`build`).
        let word = _mm512_add_epi32(
            _mm512_sll_epi32(slot, axis_shift(leaf.word_shift())),
            _mm512_srli_epi32::<6>(bit),
        );
        let shift = _mm512_and_si512(bit, _mm512_set1_epi32(63));
        let zero = _mm512_setzero_si512();
        // SAFETY: a leaf lane's slot holds a stored leaf's index (as in `read`), so its word is
        // inside the arena (a non-negative i32, see above); tile lanes are masked off.
        let (words_lo, words_hi) = unsafe {
            (
                _mm512_mask_i32gather_epi64::<8>(
                    zero,
                    is_leaf as u8,
                    _mm512_castsi512_si256(word),
                    leaf_words.as_ptr().cast(),
                ),
                _mm512_mask_i32gather_epi64::<8>(
                    zero,
                    (is_leaf >> 8) as u8,
                    _mm512_extracti64x4_epi64::<1>(word),
                    leaf_words.as_ptr().cast(),
                ),
            )
        };
        let codes_lo = _mm512_srlv_epi64(
            words_lo,
            _mm512_cvtepu32_epi64(_mm512_castsi512_si256(shift)),
        );
        let codes_hi = _mm512_srlv_epi64(
            words_hi,
            _mm512_cvtepu32_epi64(_mm512_extracti64x4_epi64::<1>(shift)),
        );
        // The low 32 bits of each 64-bit lane, in lane order.
        let even = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
        let leaf_codes = _mm512_permutex2var_epi32(codes_lo, even, codes_hi);
        let code_mask = _mm512_set1_epi32(((1u32 << (1u32 << leaf.bits_log2)) - 1) as i32);
        narrow_wide_bytes(_mm512_mask_and_epi32(slot, is_leaf, leaf_codes, code_mask))
    }
}

/// The low byte of each of the sixteen 32-bit lanes of `v`, in lane order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn narrow_wide_bytes(v: std::arch::x86_64::__m512i) -> [u8; WIDE_BLOCK_LANES] {
    use std::arch::x86_64::*;
    let bytes = _mm512_cvtepi32_epi8(v);
    let mut out = [0u8; WIDE_BLOCK_LANES];
    // SAFETY: `out` is 16 bytes, stored unaligned.
    unsafe { _mm_storeu_si128(out.as_mut_ptr().cast(), bytes) };
    out
}

/// The eight 32-bit lanes of `v` (each 0..=255) as bytes, in lane order.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn narrow_bytes(v: std::arch::x86_64::__m256i) -> [u8; BLOCK_LANES] {
    use std::arch::x86_64::*;
    let words = _mm_packus_epi32(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
    let bytes = _mm_packus_epi16(words, words);
    (_mm_cvtsi128_si64(bytes) as u64).to_le_bytes()
}

#[cfg(test)]
mod tests {
    // The directory against the walk, and block reads against single reads:
    // `tests/directory.rs` (public API only).

    #[test]
    fn large_directories_are_built_only_beside_larger_trees() {
        use super::{directory_allowed, DIRECTORY_ALLOWANCE_BYTES, DIRECTORY_MAX_BYTES};
        let allowance = DIRECTORY_ALLOWANCE_BYTES as u64;
        // Small ones always, whatever the tree.
        assert!(directory_allowed(allowance, 1));
        // Larger ones up to the tree's size.
        assert!(directory_allowed(3 * allowance, 3 * allowance));
        assert!(!directory_allowed(3 * allowance + 1, 3 * allowance));
        // Never above the hard cap, nor a size that overflowed.
        assert!(!directory_allowed(DIRECTORY_MAX_BYTES as u64 + 1, u64::MAX));
        assert!(!directory_allowed(u64::MAX, u64::MAX));
    }
}
