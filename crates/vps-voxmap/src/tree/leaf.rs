//! Leaves: cubes of `L³` voxels (`L = 2^N`), two bits per voxel, packed in `u64` words.
//!
//! Layout: voxel `(x, y, z)` of a leaf sits at bit `2 * (x + L * (y + L * z))` of the leaf's bit
//! string. A row of `L` voxels along x is `2L ≤ 64` bits and never straddles a word. Voxels of a leaf
//! that lie outside the grid are stored as Free (canonical form, so equal content gives equal bits).

use crate::{DenseGrid, Voxel};
use glam::UVec3;

/// `0b01` in every 2-bit field: multiplied by a voxel value, the word of a uniform run.
const LOW_BITS: u64 = 0x5555_5555_5555_5555;

/// The shape of a leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LeafShape {
    /// log2 of the voxels per axis.
    pub(crate) log2: u32,
}

impl LeafShape {
    /// Voxels per axis.
    #[inline(always)]
    pub(crate) fn edge(self) -> u32 {
        1 << self.log2
    }

    /// Bits holding voxels: `2 L³`.
    #[inline(always)]
    fn used_bits(self) -> usize {
        2 << (3 * self.log2)
    }

    /// `u64` words per leaf (at least one; a power of two).
    #[inline(always)]
    pub(crate) fn words_per_leaf(self) -> usize {
        1 << self.word_shift()
    }

    /// log2 of [`LeafShape::words_per_leaf`]: `2 L³` bits is `2^(3N + 1)`, so `3N + 1 − 6` when
    /// that is positive, else one word.
    #[inline(always)]
    pub(crate) fn word_shift(self) -> u32 {
        (3 * self.log2 + 1).saturating_sub(6)
    }

    /// Bit offset of in-grid voxel `p` inside its leaf.
    #[inline(always)]
    fn voxel_bit(self, p: UVec3) -> usize {
        let mask = self.edge() - 1;
        let local = (p.x & mask) | ((p.y & mask) << self.log2) | ((p.z & mask) << (2 * self.log2));
        2 * local as usize
    }

    /// Index, within its leaf, of the word that holds voxel `p` (below `words_per_leaf`).
    #[inline(always)]
    pub(crate) fn word_of(self, p: UVec3) -> usize {
        self.voxel_bit(p) >> 6
    }

    /// The voxel `p` from the leaf word `word` that holds it (see [`LeafShape::word_of`]).
    #[inline(always)]
    pub(crate) fn voxel_in_word(self, word: u64, p: UVec3) -> Voxel {
        Voxel::from_bits((word >> (self.voxel_bit(p) & 63)) as u8)
    }

    /// The voxel at `p` in the leaf whose words start at `words[first]`.
    #[inline(always)]
    pub(crate) fn read(self, words: &[u64], first: usize, p: UVec3) -> Voxel {
        self.voxel_in_word(words[first + self.word_of(p)], p)
    }

    /// Bit offset of the row `(y, z)` (leaf-local).
    #[inline(always)]
    fn row_bit(self, y: u32, z: u32) -> usize {
        2 * ((y + (z << self.log2)) << self.log2) as usize
    }

    /// Packs the leaf cube at `origin` from `grid` into `out` (`words_per_leaf` words, overwritten).
    /// Voxels outside the grid become Free.
    pub(crate) fn pack(self, grid: &DenseGrid, origin: UVec3, out: &mut [u64]) {
        out.fill(0);
        let dims = grid.spec.dims;
        let edge = self.edge();
        let row_len = (dims[0] - origin.x).min(edge) as usize;
        for z in 0..edge.min(dims[2] - origin.z) {
            for y in 0..edge.min(dims[1] - origin.y) {
                let (gy, gz) = ((origin.y + y) as usize, (origin.z + z) as usize);
                let start = origin.x as usize + dims[0] as usize * (gy + dims[1] as usize * gz);
                let bits = pack_row(&grid.data[start..start + row_len]);
                let at = self.row_bit(y, z);
                out[at >> 6] |= bits << (at & 63);
            }
        }
    }

    /// The value shared by every in-grid voxel of the leaf at `origin` (voxels outside `dims` do not
    /// matter: lookups never reach them), else `None`. `origin` must be inside `dims`.
    pub(crate) fn uniform_value(
        self,
        leaf: &[u64],
        origin: UVec3,
        dims: [u32; 3],
    ) -> Option<Voxel> {
        let v = Voxel::from_bits(leaf[0] as u8);
        let pattern = LOW_BITS * v.bits() as u64;
        let edge = self.edge();
        let fully_inside = (0..3).all(|a| dims[a] - origin[a] >= edge);
        let uniform = if fully_inside {
            let used = self.used_bits();
            let last_mask = if used >= 64 {
                u64::MAX
            } else {
                (1u64 << used) - 1
            };
            leaf.iter().all(|&w| w & last_mask == pattern & last_mask)
        } else {
            self.rows(leaf, origin, dims)
                .all(|(row, kept)| row & kept == pattern & kept)
        };
        uniform.then_some(v)
    }

    /// True when every bit that does not hold an in-grid voxel is zero, for the leaf at `origin`.
    pub(crate) fn padding_is_clear(self, leaf: &[u64], origin: UVec3, dims: [u32; 3]) -> bool {
        let used = self.used_bits();
        self.rows(leaf, origin, dims)
            .all(|(row, kept)| row & !kept == 0)
            && (used >= 64 || leaf[0] >> used == 0)
    }

    /// Every row of the leaf at `origin` as `(bits, in-grid mask)`: the row's `2L` bits shifted to
    /// the bottom, and the mask of its bits that hold in-grid voxels (0 for rows outside the grid).
    fn rows<'l>(
        self,
        leaf: &'l [u64],
        origin: UVec3,
        dims: [u32; 3],
    ) -> impl Iterator<Item = (u64, u64)> + 'l {
        let edge = self.edge();
        let inside = |axis: usize, o: u32| dims[axis].saturating_sub(o).min(edge);
        let (nx, ny, nz) = (
            inside(0, origin.x),
            inside(1, origin.y),
            inside(2, origin.z),
        );
        let low_bits = |n: u32| {
            if n >= 32 {
                u64::MAX
            } else {
                (1u64 << (2 * n)) - 1
            }
        };
        let (row_mask, kept_mask) = (low_bits(edge), low_bits(nx));
        (0..edge * edge).map(move |r| {
            let (y, z) = (r & (edge - 1), r >> self.log2);
            let at = self.row_bit(y, z);
            let row = (leaf[at >> 6] >> (at & 63)) & row_mask;
            (row, if y < ny && z < nz { kept_mask } else { 0 })
        })
    }

    /// Voxels of each non-Free kind in a leaf: `[Interior, Surface, Proximity]`.
    pub(crate) fn count_non_free(self, leaf: &[u64]) -> [u64; 3] {
        let mut c = [0u64; 3];
        for &w in leaf {
            let low = w & LOW_BITS;
            let high = (w >> 1) & LOW_BITS;
            c[0] += (low & !high).count_ones() as u64;
            c[1] += (high & !low).count_ones() as u64;
            c[2] += (low & high).count_ones() as u64;
        }
        c
    }

    /// Writes the leaf's in-grid voxels into `grid` (the leaf's cube starts at `origin`).
    pub(crate) fn unpack(self, leaf: &[u64], origin: UVec3, grid: &mut DenseGrid) {
        let dims = grid.spec.dims;
        let edge = self.edge();
        for z in 0..edge.min(dims[2] - origin.z) {
            for y in 0..edge.min(dims[1] - origin.y) {
                for x in 0..edge.min(dims[0] - origin.x) {
                    let p = origin + UVec3::new(x, y, z);
                    grid.set(p.as_ivec3(), self.read(leaf, 0, p));
                }
            }
        }
    }
}

/// Packs up to 32 voxel bytes (one leaf row) into 2-bit fields, byte `i` at bits `2i..2i+2`.
#[inline(always)]
fn pack_row(bytes: &[u8]) -> u64 {
    bytes.chunks(8).enumerate().fold(0, |acc, (c, chunk)| {
        let mut b = [0u8; 8];
        b[..chunk.len()].copy_from_slice(chunk);
        acc | pack8(u64::from_le_bytes(b)) << (16 * c)
    })
}

/// Packs the low two bits of each of 8 bytes into 16 bits (byte `i` → bits `2i..2i+2`).
#[inline(always)]
fn pack8(x: u64) -> u64 {
    let x = x & 0x0303_0303_0303_0303;
    let x = (x | x >> 6) & 0x000F_000F_000F_000F;
    let x = (x | x >> 12) & 0x0000_00FF_0000_00FF;
    (x | x >> 24) & 0xFFFF
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack8_places_each_byte_in_its_field() {
        let bytes = [0u8, 1, 2, 3, 3, 2, 1, 0];
        let packed = pack8(u64::from_le_bytes(bytes));
        for (i, &b) in bytes.iter().enumerate() {
            assert_eq!((packed >> (2 * i)) & 3, b as u64, "byte {i}");
        }
        assert_eq!(packed >> 16, 0);
    }

    #[test]
    fn pack_row_handles_partial_and_long_rows() {
        let bytes: Vec<u8> = (0..32).map(|i| (i * 7 % 4) as u8).collect();
        for len in [1, 2, 5, 8, 13, 32] {
            let packed = pack_row(&bytes[..len]);
            for (i, &b) in bytes[..len].iter().enumerate() {
                assert_eq!((packed >> (2 * i)) & 3, b as u64, "len {len} byte {i}");
            }
            if len < 32 {
                assert_eq!(packed >> (2 * len), 0, "len {len}: padding must be Free");
            }
        }
    }

    #[test]
    fn words_per_leaf_covers_the_used_bits_exactly() {
        for log2 in 1..=5 {
            let shape = LeafShape { log2 };
            assert_eq!(shape.words_per_leaf(), shape.used_bits().div_ceil(64));
        }
    }

    #[test]
    fn uniform_value_sees_a_single_odd_voxel() {
        for log2 in 1..=5 {
            let shape = LeafShape { log2 };
            let mut leaf = vec![LOW_BITS * 2; shape.words_per_leaf()];
            if shape.used_bits() < 64 {
                leaf[0] &= (1 << shape.used_bits()) - 1;
            }
            let full = [64; 3];
            assert_eq!(
                shape.uniform_value(&leaf, UVec3::ZERO, full),
                Some(Voxel::Surface)
            );
            let last = UVec3::splat(shape.edge() - 1);
            let bit = shape.voxel_bit(last);
            leaf[bit >> 6] ^= 1 << (bit & 63);
            assert_eq!(shape.read(&leaf, 0, last), Voxel::Proximity);
            assert_eq!(
                shape.uniform_value(&leaf, UVec3::ZERO, full),
                None,
                "log2 {log2}"
            );
            // Clipped so the odd voxel is outside the grid: uniform again, but padding not clear.
            let clipped = [shape.edge() - 1, 64, 64];
            let uniform = shape.uniform_value(&leaf, UVec3::ZERO, clipped);
            assert_eq!(uniform, Some(Voxel::Surface), "log2 {log2}");
            assert!(!shape.padding_is_clear(&leaf, UVec3::ZERO, clipped));
            assert_eq!(shape.count_non_free(&leaf)[2], 1);
        }
    }
}
