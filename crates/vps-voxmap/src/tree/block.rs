//! Eight lookups at once: the tree walk of [`VoxelTree::get_layered`] for a block of
//! [`BLOCK_LANES`] cells, one AVX2 gather per level instead of eight scalar walks.
//!
//! The walk is the scalar one lane for lane: an in-grid mask (one unsigned compare per axis), the
//! root slot, the upper and lower slots (a lane whose slot is a tile keeps it and drops out of the
//! later gathers through the gather mask), then one 32-bit word of the leaf and a variable shift.
//! Only memory the scalar walk would read is read: masked-off lanes load nothing. The result is
//! the same voxel, bit for bit, as `get_layered` per lane (tests below check every tree shape and
//! width against it, with cells inside, on the border and far outside the grid).

use super::VoxelTree;
use crate::{VoxelBlock, BLOCK_LANES};

/// Cells of a block: `cells[axis][lane]`, voxel indices (any value; outside the dims reads Free).
pub type BlockCells = [[i32; BLOCK_LANES]; 3];

/// The gathered lookup of `N` blocks, when this CPU and tree have one (AVX2 on x86-64, and every
/// arena indexable by an `i32` gather index); `None` otherwise, and the caller looks up lane by
/// lane. The `N` blocks walk the levels together (all root gathers, then all upper gathers, …):
/// their chains of dependent gathers overlap, which hides most of a gather's latency. Does not
/// allocate or block.
#[inline(always)]
pub(super) fn get_blocks<const N: usize>(
    tree: &VoxelTree,
    cells: &[BlockCells; N],
) -> Option<[VoxelBlock; N]> {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && gather_indices_fit(tree) {
        // SAFETY: AVX2 is present (checked just above) and every arena index fits an i32.
        let codes = unsafe { avx2::gather_codes(tree, cells) };
        return Some(codes.map(|c| decode(tree, c)));
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (tree, cells);
    None
}

/// Every arena is short enough that an index into it (in 32-bit elements) is a non-negative i32,
/// as the gather instructions require.
#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn gather_indices_fit(tree: &VoxelTree) -> bool {
    const MAX: usize = i32::MAX as usize;
    tree.root.slots.len() <= MAX
        && tree.upper.slots.len() <= MAX
        && tree.lower.slots.len() <= MAX
        && tree.leaf_words.len() <= MAX / 2
}

/// Kinds and layers of eight stored (valid) codes.
#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
fn decode(tree: &VoxelTree, codes: [u8; BLOCK_LANES]) -> VoxelBlock {
    if tree.width == crate::VoxelWidth::Two {
        // A 2-bit code is the kind's bits; layers are 0.
        return VoxelBlock {
            kinds: codes,
            layers: [0; BLOCK_LANES],
        };
    }
    let mut block = VoxelBlock::default();
    for (l, &code) in codes.iter().enumerate() {
        let v = tree.decode(code);
        block.kinds[l] = v.kind.bits();
        block.layers[l] = v.layer;
    }
    block
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    use super::super::{internal::InternalShape, internal::Slot, LookupShape, VoxelTree};
    use super::BlockCells;
    use crate::BLOCK_LANES;
    use std::arch::x86_64::*;

    /// The stored codes of the cells of `N` blocks (0 outside the dims).
    ///
    /// # Safety
    /// The CPU must support AVX2, and every arena of `tree` must pass `gather_indices_fit`.
    #[target_feature(enable = "avx2")]
    #[inline]
    pub(super) unsafe fn gather_codes<const N: usize>(
        tree: &VoxelTree,
        cells: &[BlockCells; N],
    ) -> [[u8; BLOCK_LANES]; N] {
        // The paper's 512-tree gets constant shifts, as in the scalar walk.
        if tree.paper_shape {
            walk(tree, cells, &LookupShape::TREE_512)
        } else {
            walk(tree, cells, &tree.lookup_shape())
        }
    }

    /// `v >> count` per lane, logical.
    #[inline(always)]
    unsafe fn shr(v: __m256i, count: u32) -> __m256i {
        _mm256_srl_epi32(v, _mm_cvtsi32_si128(count as i32))
    }

    /// `v << count` per lane.
    #[inline(always)]
    unsafe fn shl(v: __m256i, count: u32) -> __m256i {
        _mm256_sll_epi32(v, _mm_cvtsi32_si128(count as i32))
    }

    /// Lanes whose slot holds a child (tile flag, the sign bit, clear): all ones, else zero.
    #[inline(always)]
    unsafe fn is_child(slot: __m256i) -> __m256i {
        _mm256_cmpgt_epi32(slot, _mm256_set1_epi32(-1))
    }

    /// True when no lane of any block has a child slot (all reached a tile).
    #[inline(always)]
    unsafe fn all_tiles<const N: usize>(slots: &[__m256i; N]) -> bool {
        let mut any = _mm256_setzero_si256();
        for &s in slots {
            any = _mm256_or_si256(any, is_child(s));
        }
        _mm256_testz_si256(any, any) == 1
    }

    /// The local index `(x >> s) & m | ((y >> s) & m) << n | ((z >> s) & m) << 2n` of a node with
    /// `2^n` children per axis each spanning `2^s` voxels.
    #[inline(always)]
    unsafe fn local_index(p: &[__m256i; 3], log2: u32, child_shift: u32) -> __m256i {
        let mask = _mm256_set1_epi32((1 << log2) - 1);
        let x = _mm256_and_si256(shr(p[0], child_shift), mask);
        let y = _mm256_and_si256(shr(p[1], child_shift), mask);
        let z = _mm256_and_si256(shr(p[2], child_shift), mask);
        _mm256_or_si256(x, _mm256_or_si256(shl(y, log2), shl(z, 2 * log2)))
    }

    /// One internal level: lanes whose `slot` is a child read their slot in that child node;
    /// tile lanes keep `slot` (the gather's source operand) and read nothing.
    #[inline(always)]
    unsafe fn descend(
        arena: &[u32],
        shape: InternalShape,
        slot: __m256i,
        p: &[__m256i; 3],
    ) -> __m256i {
        let index = _mm256_or_si256(
            shl(slot, 3 * shape.log2),
            local_index(p, shape.log2, shape.child_shift),
        );
        // SAFETY (caller's invariants): a child slot holds a node index below this level's node
        // count, so `node << 3 log2 | local` is below the arena length, which fits an i32.
        _mm256_mask_i32gather_epi32::<4>(slot, arena.as_ptr() as *const i32, index, is_child(slot))
    }

    /// The root slots of one block; lanes outside the dims get a Free tile.
    #[inline(always)]
    unsafe fn root_slot(tree: &VoxelTree, p: &[__m256i; 3], root_shift: u32) -> __m256i {
        // In the dims: `p <u d` per axis, as a signed compare with both sides' sign bits flipped
        // (dims are at most i32::MAX, checked on assembly).
        let flip = _mm256_set1_epi32(i32::MIN);
        let dims = tree.spec.dims;
        let mut inside = _mm256_set1_epi32(-1);
        for axis in 0..3 {
            let below = _mm256_cmpgt_epi32(
                _mm256_xor_si256(_mm256_set1_epi32(dims[axis] as i32), flip),
                _mm256_xor_si256(p[axis], flip),
            );
            inside = _mm256_and_si256(inside, below);
        }
        // `cx + nx (cy + ny cz)`.
        let [nx, ny, _] = tree.root.dims;
        let (cx, cy, cz) = (
            shr(p[0], root_shift),
            shr(p[1], root_shift),
            shr(p[2], root_shift),
        );
        let index = _mm256_add_epi32(
            cx,
            _mm256_mullo_epi32(
                _mm256_set1_epi32(nx as i32),
                _mm256_add_epi32(cy, _mm256_mullo_epi32(_mm256_set1_epi32(ny as i32), cz)),
            ),
        );
        // SAFETY (caller's invariants): an in-grid lane's root cell is below the root dims, so
        // its index is below the slot count; other lanes read nothing.
        _mm256_mask_i32gather_epi32::<4>(
            _mm256_set1_epi32(Slot::tile(0).0 as i32),
            tree.root.slots.as_ptr() as *const i32,
            index,
            inside,
        )
    }

    /// The code of each lane from its final slot: the tile's code, or the voxel's bits in its leaf.
    #[inline(always)]
    unsafe fn leaf_code(
        tree: &VoxelTree,
        slot: __m256i,
        p: &[__m256i; 3],
        shape: &LookupShape,
    ) -> __m256i {
        let leaf = shape.leaf;
        let tile_code = _mm256_and_si256(slot, _mm256_set1_epi32(0xff));
        let leaf_lanes = is_child(slot);
        if _mm256_testz_si256(leaf_lanes, leaf_lanes) == 1 {
            return tile_code;
        }
        // The 32-bit half of the leaf word holding the voxel's bits.
        let bit = shl(local_index(p, leaf.log2, 0), leaf.bits_log2);
        let word_index = _mm256_add_epi32(
            shl(slot, leaf.word_shift() + 1),
            _mm256_srli_epi32::<5>(bit),
        );
        // SAFETY (caller's invariants): a lower child slot holds a leaf index below the leaf
        // count, so its first word plus the in-leaf word is inside the arena; as 32-bit halves
        // (little-endian) the index is twice the word index plus the half, below 2 × len ≤ i32::MAX.
        let word = _mm256_mask_i32gather_epi32::<4>(
            _mm256_setzero_si256(),
            tree.leaf_words.as_ptr() as *const i32,
            word_index,
            leaf_lanes,
        );
        let code_mask = _mm256_set1_epi32((1 << (1 << leaf.bits_log2)) - 1);
        let leaf_code = _mm256_and_si256(
            _mm256_srlv_epi32(word, _mm256_and_si256(bit, _mm256_set1_epi32(31))),
            code_mask,
        );
        _mm256_blendv_epi8(tile_code, leaf_code, leaf_lanes)
    }

    /// The walk with `shape` (equal to the tree's lookup shape), level by level over all blocks;
    /// stops descending once every lane has reached a tile.
    #[inline(always)]
    unsafe fn walk<const N: usize>(
        tree: &VoxelTree,
        cells: &[BlockCells; N],
        shape: &LookupShape,
    ) -> [[u8; BLOCK_LANES]; N] {
        // No closures here: a closure does not inherit `target_feature(enable = "avx2")`, and
        // the intrinsics would become calls.
        let zero = _mm256_setzero_si256();
        let mut p = [[zero; 3]; N];
        let mut slots = [zero; N];
        for b in 0..N {
            for axis in 0..3 {
                p[b][axis] = _mm256_loadu_si256(cells[b][axis].as_ptr() as *const __m256i);
            }
            slots[b] = root_slot(tree, &p[b], shape.root_shift);
        }
        if !all_tiles(&slots) {
            for b in 0..N {
                slots[b] = descend(&tree.upper.slots, shape.upper, slots[b], &p[b]);
            }
            if !all_tiles(&slots) {
                for b in 0..N {
                    slots[b] = descend(&tree.lower.slots, shape.lower, slots[b], &p[b]);
                }
            }
        }
        let mut out = [[0u8; BLOCK_LANES]; N];
        for b in 0..N {
            let code = leaf_code(tree, slots[b], &p[b], shape);
            // Codes are below 256: pack the eight 32-bit lanes to bytes.
            let words = _mm256_packus_epi32(code, code); // 16-bit: lanes 0-3, 0-3, 4-7, 4-7
            let bytes = _mm256_packus_epi16(words, words); // 8-bit, same pattern per 128-bit half
            let low = _mm256_cvtsi256_si32(bytes) as u32;
            let high = _mm256_extract_epi32::<4>(bytes) as u32;
            out[b] = (u64::from(low) | u64::from(high) << 32).to_le_bytes();
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{CubeSource, DenseGrid, GridSpec, TreeConfig, VoxelLookup, VoxelWidth};
    use glam::{DVec3, IVec3};

    /// xorshift64.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            self.0
        }
    }

    /// A tree of `width` with blobs of every valid code (so tiles at every level, mixed leaves).
    fn tree(config: TreeConfig, width: VoxelWidth, dims: [u32; 3], seed: u64) -> VoxelTree {
        let spec = GridSpec {
            origin: DVec3::ZERO,
            voxel_size: 0.01,
            dims,
        };
        let codes: Vec<u8> = (0..=255u8).filter(|&c| width.is_valid_code(c)).collect();
        let mut rng = Rng(seed);
        let mut data = vec![0u8; spec.voxel_count() as usize];
        let [nx, ny, nz] = dims.map(|d| d as usize);
        // Uniform boxes (tiles), then noise in a few places (leaves).
        for _ in 0..12 {
            let code = codes[rng.next() as usize % codes.len()];
            let lo = [nx, ny, nz].map(|n| rng.next() as usize % n);
            let hi: Vec<usize> = lo
                .iter()
                .zip([nx, ny, nz])
                .map(|(&l, n)| (l + 1 + rng.next() as usize % n).min(n))
                .collect();
            for z in lo[2]..hi[2] {
                for y in lo[1]..hi[1] {
                    for x in lo[0]..hi[0] {
                        data[x + nx * (y + ny * z)] = code;
                    }
                }
            }
        }
        for _ in 0..4000 {
            let i = rng.next() as usize % data.len();
            data[i] = codes[rng.next() as usize % codes.len()];
        }
        VoxelTree::from_source(spec, width, config, &Codes { dims, data }).unwrap()
    }

    /// A dense array of codes as a [`CubeSource`] (never reports a uniform cube).
    struct Codes {
        dims: [u32; 3],
        data: Vec<u8>,
    }

    impl CubeSource for Codes {
        fn cube(&self, origin: glam::UVec3, extent: u32, out: &mut [u8]) -> Option<u8> {
            let [nx, ny, nz] = self.dims;
            let e = extent as usize;
            for z in 0..extent {
                for y in 0..extent {
                    for x in 0..extent {
                        let (gx, gy, gz) = (origin.x + x, origin.y + y, origin.z + z);
                        let inside = gx < nx && gy < ny && gz < nz;
                        out[x as usize + e * (y as usize + e * z as usize)] = if inside {
                            self.data[(gx + nx * (gy + ny * gz)) as usize]
                        } else {
                            0
                        };
                    }
                }
            }
            None
        }
    }

    /// Groups of 1 and 4 blocks of random cells (inside, on the border, far outside; some blocks
    /// wholly outside, so groups mix early-finished and deep walks) against `get_layered`.
    fn check(tree: &VoxelTree, seed: u64) {
        let dims = tree.spec().dims.map(|d| d as i32);
        let mut rng = Rng(seed);
        let specials = [i32::MIN, -1, 0, i32::MAX, dims[0], dims[1], dims[2]];
        let random_block = |rng: &mut Rng| {
            let outside = rng.next().is_multiple_of(5);
            let mut cells: BlockCells = [[0; BLOCK_LANES]; 3];
            for (axis, lanes) in cells.iter_mut().enumerate() {
                for c in lanes.iter_mut() {
                    *c = match rng.next() % 10 {
                        _ if outside => -1 - (rng.next() % 1000) as i32,
                        0 => specials[rng.next() as usize % specials.len()],
                        1 => rng.next() as i32,
                        _ => (rng.next() % (dims[axis] as u64 + 4)) as i32 - 2,
                    };
                }
            }
            cells
        };
        let compare = |cells: &BlockCells, block: &VoxelBlock| {
            for (l, (&kind, &layer)) in block.kinds.iter().zip(&block.layers).enumerate() {
                let ijk = IVec3::new(cells[0][l], cells[1][l], cells[2][l]);
                let v = tree.get_layered(ijk);
                assert_eq!((kind, layer), (v.kind.bits(), v.layer), "lane {l} at {ijk}");
            }
        };
        for _ in 0..2000 {
            let one = [random_block(&mut rng)];
            let four: [BlockCells; 4] = std::array::from_fn(|_| random_block(&mut rng));
            let (Some(a), Some(b)) = (get_blocks(tree, &one), get_blocks(tree, &four)) else {
                // No gathered path: only acceptable on a CPU without AVX2.
                #[cfg(target_arch = "x86_64")]
                assert!(!std::arch::is_x86_feature_detected!("avx2"));
                return;
            };
            compare(&one[0], &a[0]);
            for (cells, block) in four.iter().zip(&b) {
                compare(cells, block);
            }
        }
    }

    #[test]
    fn gathered_blocks_equal_scalar_lookups_for_every_shape_and_width() {
        for (i, width) in [VoxelWidth::Two, VoxelWidth::Four, VoxelWidth::Eight]
            .into_iter()
            .enumerate()
        {
            for n in 1..=4u8 {
                if width.bits() << n > 64 {
                    continue;
                }
                let config = TreeConfig::uniform(n);
                let t = tree(config, width, [37, 29, 23], 7 + n as u64 + 10 * i as u64);
                check(&t, 99 + n as u64);
            }
            let mixed = TreeConfig {
                log2_dims: [2, 1, 3],
            };
            check(&tree(mixed, width, [70, 9, 40], 5), 17);
        }
        // The paper's 512-tree over several root cells (constant-shift path).
        let t = tree(TreeConfig::default(), VoxelWidth::Two, [1100, 30, 520], 3);
        check(&t, 4);
        assert!(t.node_counts().leaves > 0);
    }

    #[test]
    fn dense_grids_have_no_gathered_path() {
        let spec = GridSpec {
            origin: DVec3::ZERO,
            voxel_size: 0.01,
            dims: [4, 4, 4],
        };
        let grid = DenseGrid::new(spec);
        assert_eq!(grid.get_blocks(&[[[0; BLOCK_LANES]; 3]; 2]), None);
    }
}
