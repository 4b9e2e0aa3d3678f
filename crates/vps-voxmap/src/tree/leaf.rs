//! Leaves: cubes of `L³` voxels (`L = 2^N`), `W` bits per voxel (`W` = 2, 4 or 8, the tree's
//! [`crate::VoxelWidth`]), packed in `u64` words.
//!
//! Layout: voxel `(x, y, z)` of a leaf sits at bit `W * (x + L * (y + L * z))` of the leaf's bit
//! string and holds the voxel's code (for `W = 2` the [`Voxel`] value). A row of `L` voxels along x
//! is `W L ≤ 64` bits (checked when the tree is assembled) and never straddles a word. Voxels of a
//! leaf that lie outside the grid are stored as code 0 (Free), so equal content gives equal bits.

use crate::{DenseGrid, Voxel};
use glam::UVec3;

/// The word of a uniform run of code 1 in `W`-bit fields, indexed by `log2 W - 1`: multiplied by a
/// code, the word of a uniform run of that code.
const LOW_BITS: [u64; 3] = [
    0x5555_5555_5555_5555,
    0x1111_1111_1111_1111,
    0x0101_0101_0101_0101,
];

/// Codes of a box of voxels, one byte each, x fastest: a dense grid or a cube handed to the builder.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ByteBox<'a> {
    /// `dims[0] * dims[1] * dims[2]` codes.
    pub(crate) data: &'a [u8],
    /// Voxels per axis of the box.
    pub(crate) dims: [u32; 3],
}

/// The shape of a leaf.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LeafShape {
    /// log2 of the voxels per axis.
    pub(crate) log2: u32,
    /// log2 of the bits per voxel (1, 2 or 3).
    pub(crate) bits_log2: u32,
}

impl LeafShape {
    /// Voxels per axis.
    #[inline(always)]
    pub(crate) fn edge(self) -> u32 {
        1 << self.log2
    }

    /// Mask of one voxel's code.
    #[inline(always)]
    fn code_mask(self) -> u64 {
        (1u64 << (1 << self.bits_log2)) - 1
    }

    /// Bits holding voxels: `W L³`.
    #[inline(always)]
    fn used_bits(self) -> usize {
        1 << (3 * self.log2 + self.bits_log2)
    }

    /// `u64` words per leaf (at least one; a power of two).
    #[inline(always)]
    pub(crate) fn words_per_leaf(self) -> usize {
        1 << self.word_shift()
    }

    /// log2 of [`LeafShape::words_per_leaf`]: `W L³` bits is `2^(3N + log2 W)`, so that minus 6
    /// when positive, else one word.
    #[inline(always)]
    pub(crate) fn word_shift(self) -> u32 {
        (3 * self.log2 + self.bits_log2).saturating_sub(6)
    }

    /// Bit offset of in-grid voxel `p` inside its leaf.
    #[inline(always)]
    fn voxel_bit(self, p: UVec3) -> usize {
        let mask = self.edge() - 1;
        let local = (p.x & mask) | ((p.y & mask) << self.log2) | ((p.z & mask) << (2 * self.log2));
        (local as usize) << self.bits_log2
    }

    /// Index, within its leaf, of the word that holds voxel `p` (below `words_per_leaf`).
    #[inline(always)]
    pub(crate) fn word_of(self, p: UVec3) -> usize {
        self.voxel_bit(p) >> 6
    }

    /// The code of voxel `p` from the leaf word `word` that holds it (see [`LeafShape::word_of`]).
    #[inline(always)]
    pub(crate) fn code_in_word(self, word: u64, p: UVec3) -> u8 {
        ((word >> (self.voxel_bit(p) & 63)) & self.code_mask()) as u8
    }

    /// The code at `p` in the leaf whose words start at `words[first]`.
    #[inline(always)]
    pub(crate) fn read(self, words: &[u64], first: usize, p: UVec3) -> u8 {
        self.code_in_word(words[first + self.word_of(p)], p)
    }

    /// Bit offset of the row `(y, z)` (leaf-local).
    #[inline(always)]
    fn row_bit(self, y: u32, z: u32) -> usize {
        (((y + (z << self.log2)) << self.log2) as usize) << self.bits_log2
    }

    /// Packs the leaf cube whose minimum corner is voxel `at` of `src` into `out` (`words_per_leaf`
    /// words, overwritten), reading `inside` voxels per axis (the part inside the grid; the rest of
    /// the leaf becomes code 0). Only the low `W` bits of each byte are kept.
    pub(crate) fn pack(self, src: ByteBox<'_>, at: UVec3, inside: [u32; 3], out: &mut [u64]) {
        out.fill(0);
        let (sx, sy) = (src.dims[0] as usize, src.dims[1] as usize);
        let row_len = inside[0] as usize;
        for z in 0..inside[2] {
            for y in 0..inside[1] {
                let (gy, gz) = ((at.y + y) as usize, (at.z + z) as usize);
                let start = at.x as usize + sx * (gy + sy * gz);
                let bits = pack_row(&src.data[start..start + row_len], self.bits_log2);
                let at = self.row_bit(y, z);
                out[at >> 6] |= bits << (at & 63);
            }
        }
    }

    /// Voxels per axis of the leaf at `origin` that lie inside `dims` (`origin` inside `dims`).
    pub(crate) fn inside(self, origin: UVec3, dims: [u32; 3]) -> [u32; 3] {
        std::array::from_fn(|a| (dims[a] - origin[a]).min(self.edge()))
    }

    /// The code shared by every in-grid voxel of the leaf at `origin` (voxels outside `dims` do not
    /// matter: lookups never reach them), else `None`. `origin` must be inside `dims`.
    pub(crate) fn uniform_value(self, leaf: &[u64], origin: UVec3, dims: [u32; 3]) -> Option<u8> {
        let code = (leaf[0] & self.code_mask()) as u8;
        let pattern = LOW_BITS[self.bits_log2 as usize - 1].wrapping_mul(code as u64);
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
        uniform.then_some(code)
    }

    /// True when every bit that does not hold an in-grid voxel is zero, for the leaf at `origin`.
    pub(crate) fn padding_is_clear(self, leaf: &[u64], origin: UVec3, dims: [u32; 3]) -> bool {
        let used = self.used_bits();
        self.rows(leaf, origin, dims)
            .all(|(row, kept)| row & !kept == 0)
            && (used >= 64 || leaf[0] >> used == 0)
    }

    /// Every row of the leaf at `origin` as `(bits, in-grid mask)`: the row's `W L` bits shifted to
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
            let bits = n << self.bits_log2;
            if bits >= 64 {
                u64::MAX
            } else {
                (1u64 << bits) - 1
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

    /// Adds the number of voxels holding each code to `hist` (padding voxels count as code 0).
    pub(crate) fn histogram(self, leaf: &[u64], hist: &mut [u64; 256]) {
        if self.bits_log2 == 1 {
            for &w in leaf {
                let low = w & LOW_BITS[0];
                let high = (w >> 1) & LOW_BITS[0];
                hist[1] += (low & !high).count_ones() as u64;
                hist[2] += (high & !low).count_ones() as u64;
                hist[3] += (low & high).count_ones() as u64;
            }
            let fields = (leaf.len() * 32).min(self.used_bits() / 2) as u64;
            hist[0] += fields - hist[1..4].iter().sum::<u64>();
            return;
        }
        let per_word = 64 >> self.bits_log2;
        let voxels = 1usize << (3 * self.log2);
        for (i, &w) in leaf.iter().enumerate() {
            for f in 0..per_word.min(voxels.saturating_sub(i * per_word)) {
                hist[((w >> (f << self.bits_log2)) & self.code_mask()) as usize] += 1;
            }
        }
    }

    /// Writes the kinds (`kind_of(code)`) of the leaf's in-grid voxels into `grid` (the leaf's cube
    /// starts at `origin`).
    pub(crate) fn unpack(
        self,
        leaf: &[u64],
        origin: UVec3,
        grid: &mut DenseGrid,
        kind_of: impl Fn(u8) -> Voxel,
    ) {
        let inside = self.inside(origin, grid.spec.dims);
        for z in 0..inside[2] {
            for y in 0..inside[1] {
                for x in 0..inside[0] {
                    let p = origin + UVec3::new(x, y, z);
                    grid.set(p.as_ivec3(), kind_of(self.read(leaf, 0, p)));
                }
            }
        }
    }
}

/// Packs up to `64 / W` code bytes (one leaf row) into `W`-bit fields, byte `i` at bits
/// `W i..W (i + 1)`.
#[inline(always)]
fn pack_row(bytes: &[u8], bits_log2: u32) -> u64 {
    bytes.chunks(8).enumerate().fold(0, |acc, (c, chunk)| {
        let mut b = [0u8; 8];
        b[..chunk.len()].copy_from_slice(chunk);
        let x = u64::from_le_bytes(b);
        let packed = match bits_log2 {
            1 => pack8::<2>(x),
            2 => pack8::<4>(x),
            _ => x,
        };
        acc | packed.checked_shl((8 << bits_log2) * c as u32).unwrap_or(0)
    })
}

/// Packs the low `W` bits of each of 8 bytes into `8 W` bits (byte `i` → bits `W i..W (i + 1)`),
/// for `W` = 2 or 4: three steps, each closing the gaps between neighbouring fields in lanes twice
/// as wide as the step before. The masks are compile-time constants (`const` blocks).
#[inline(always)]
fn pack8<const W: u32>(x: u64) -> u64 {
    let gap = 8 - W;
    let x = x & const { lanes(8, W) };
    let x = (x | x >> gap) & const { lanes(16, 2 * W) };
    let x = (x | x >> (2 * gap)) & const { lanes(32, 4 * W) };
    (x | x >> (4 * gap)) & const { lanes(64, 8 * W) }
}

/// A word whose every `lane`-bit lane (`lane` = 8, 16, 32 or 64) holds `low` (< 64) one bits at
/// its bottom, e.g. `lanes(8, 2)` = `0x0303_0303_0303_0303`.
const fn lanes(lane: u32, low: u32) -> u64 {
    let one_per_lane = (u64::MAX as u128 / ((1u128 << lane) - 1)) as u64;
    one_per_lane * ((1u64 << low) - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pack8_places_each_byte_in_its_field() {
        let bytes = [0u8, 1, 2, 3, 3, 2, 1, 0];
        let packed = pack8::<2>(u64::from_le_bytes(bytes));
        for (i, &b) in bytes.iter().enumerate() {
            assert_eq!((packed >> (2 * i)) & 3, b as u64, "byte {i}");
        }
        assert_eq!(packed >> 16, 0);
    }

    #[test]
    fn lanes_are_the_packing_masks() {
        let w2 = [lanes(8, 2), lanes(16, 4), lanes(32, 8), lanes(64, 16)];
        assert_eq!(
            w2,
            [
                0x0303_0303_0303_0303,
                0x000F_000F_000F_000F,
                0x0000_00FF_0000_00FF,
                0xFFFF
            ]
        );
        let w4 = [lanes(8, 4), lanes(16, 8), lanes(32, 16), lanes(64, 32)];
        assert_eq!(
            w4,
            [
                0x0F0F_0F0F_0F0F_0F0F,
                0x00FF_00FF_00FF_00FF,
                0x0000_FFFF_0000_FFFF,
                0xFFFF_FFFF
            ]
        );
    }

    #[test]
    fn pack8_of_nibbles_places_each_byte_in_its_field() {
        let bytes = [0u8, 1, 0xF, 7, 0x18, 0xA, 0xFF, 3];
        let packed = pack8::<4>(u64::from_le_bytes(bytes));
        for (i, &b) in bytes.iter().enumerate() {
            assert_eq!((packed >> (4 * i)) & 0xF, b as u64 & 0xF, "byte {i}");
        }
        assert_eq!(packed >> 32, 0);
    }

    #[test]
    fn pack_row_handles_partial_and_long_rows() {
        for bits_log2 in 1..=3u32 {
            let w = 1usize << bits_log2;
            let max = 64 / w;
            let bytes: Vec<u8> = (0..max).map(|i| (i * 37 % 251) as u8).collect();
            let mask = (1u64 << w) - 1;
            for len in [1, 2, 5, 8, 13, max].into_iter().filter(|&l| l <= max) {
                let packed = pack_row(&bytes[..len], bits_log2);
                for (i, &b) in bytes[..len].iter().enumerate() {
                    let got = (packed >> (w * i)) & mask;
                    assert_eq!(got, b as u64 & mask, "W {w} len {len} byte {i}");
                }
                if len < max {
                    assert_eq!(packed >> (w * len), 0, "W {w} len {len}: padding must be 0");
                }
            }
        }
    }

    #[test]
    fn words_per_leaf_covers_the_used_bits_exactly() {
        for log2 in 1..=5 {
            for bits_log2 in 1..=3 {
                let shape = LeafShape { log2, bits_log2 };
                assert_eq!(shape.words_per_leaf(), shape.used_bits().div_ceil(64));
            }
        }
    }

    #[test]
    fn uniform_value_sees_a_single_odd_voxel() {
        for log2 in 1..=5 {
            let shape = LeafShape { log2, bits_log2: 1 };
            let mut leaf = vec![LOW_BITS[0] * 2; shape.words_per_leaf()];
            if shape.used_bits() < 64 {
                leaf[0] &= (1 << shape.used_bits()) - 1;
            }
            let full = [64; 3];
            assert_eq!(shape.uniform_value(&leaf, UVec3::ZERO, full), Some(2));
            let last = UVec3::splat(shape.edge() - 1);
            let bit = shape.voxel_bit(last);
            leaf[bit >> 6] ^= 1 << (bit & 63);
            assert_eq!(shape.read(&leaf, 0, last), 3);
            assert_eq!(
                shape.uniform_value(&leaf, UVec3::ZERO, full),
                None,
                "log2 {log2}"
            );
            // Clipped so the odd voxel is outside the grid: uniform again, but padding not clear.
            let clipped = [shape.edge() - 1, 64, 64];
            let uniform = shape.uniform_value(&leaf, UVec3::ZERO, clipped);
            assert_eq!(uniform, Some(2), "log2 {log2}");
            assert!(!shape.padding_is_clear(&leaf, UVec3::ZERO, clipped));
            let mut hist = [0u64; 256];
            shape.histogram(&leaf, &mut hist);
            assert_eq!(hist[3], 1);
            assert_eq!(hist[2], (1 << (3 * log2)) - 1);
        }
    }
}
