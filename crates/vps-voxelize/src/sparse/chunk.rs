//! The chunk lattice of the sparse voxelizer: cubes of [`CHUNK`]³ voxels (the default tree's
//! lower-node cube), clipped to the grid, and bit copies between chunk rows and wider rows.

/// Voxels per chunk edge. One chunk row is one `u64` word.
pub(crate) const CHUNK: usize = 64;

/// The chunks covering a grid of `dims` voxels, x fastest.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct ChunkGrid {
    /// Grid voxels per axis.
    pub dims: [usize; 3],
    /// Chunks per axis: `ceil(dims / CHUNK)`.
    pub n: [usize; 3],
}

impl ChunkGrid {
    /// The chunks of a grid of `dims` voxels.
    pub fn new(dims: [u32; 3]) -> Self {
        let dims = dims.map(|d| d as usize);
        Self {
            dims,
            n: dims.map(|d| d.div_ceil(CHUNK)),
        }
    }

    /// Number of chunks.
    pub fn count(&self) -> usize {
        self.n.iter().product()
    }

    /// Linear index of chunk `c`.
    #[inline]
    pub fn index(&self, c: [usize; 3]) -> usize {
        c[0] + self.n[0] * (c[1] + self.n[1] * c[2])
    }

    /// Chunk coordinates of linear index `i`.
    #[inline]
    pub fn coords(&self, i: usize) -> [usize; 3] {
        [
            i % self.n[0],
            i / self.n[0] % self.n[1],
            i / (self.n[0] * self.n[1]),
        ]
    }

    /// Voxel index of chunk `c`'s minimum corner.
    #[inline]
    pub fn origin(&self, c: [usize; 3]) -> [usize; 3] {
        c.map(|v| v * CHUNK)
    }

    /// Voxels per axis of chunk `c` inside the grid (1..=CHUNK).
    #[inline]
    pub fn chunk_dims(&self, c: [usize; 3]) -> [usize; 3] {
        std::array::from_fn(|a| (self.dims[a] - c[a] * CHUNK).min(CHUNK))
    }

    /// The chunks (inclusive coordinate ranges per axis) meeting voxel range `lo..=hi` (in grid).
    pub fn chunks_of(
        &self,
        lo: [usize; 3],
        hi: [usize; 3],
    ) -> [std::ops::RangeInclusive<usize>; 3] {
        std::array::from_fn(|a| lo[a] / CHUNK..=hi[a] / CHUNK)
    }
}

/// `n ≤ 64` bits of the bit string `src` starting at bit `from` (bits past the end read 0).
#[inline]
fn read_bits(src: &[u64], from: usize, n: usize) -> u64 {
    let (w, off) = (from / 64, from % 64);
    let mut v = src.get(w).copied().unwrap_or(0) >> off;
    if off > 0 {
        v |= src.get(w + 1).copied().unwrap_or(0) << (64 - off);
    }
    if n < 64 {
        v &= (1u64 << n) - 1;
    }
    v
}

/// ORs the low `n ≤ 64` bits of `v` into the bit string `dst` at bit `at` (must fit).
#[inline]
fn or_bits(dst: &mut [u64], at: usize, n: usize, v: u64) {
    let v = if n < 64 { v & ((1u64 << n) - 1) } else { v };
    let (w, off) = (at / 64, at % 64);
    dst[w] |= v << off;
    if off > 0 && off + n > 64 {
        dst[w + 1] |= v >> (64 - off);
    }
}

/// ORs `len` bits of `src` from bit `from` into `dst` at bit `at`.
pub(crate) fn copy_bits(src: &[u64], from: usize, len: usize, dst: &mut [u64], at: usize) {
    let mut done = 0;
    while done < len {
        let n = (len - done).min(64);
        or_bits(dst, at + done, n, read_bits(src, from + done, n));
        done += n;
    }
}

/// Sets `len` bits of `dst` from bit `at`.
pub(crate) fn set_bits(dst: &mut [u64], at: usize, len: usize) {
    let mut done = 0;
    while done < len {
        let n = (len - done).min(64);
        or_bits(dst, at + done, n, !0);
        done += n;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bit_copies_match_bit_by_bit() {
        let src = [0x0123_4567_89AB_CDEFu64, 0xFEDC_BA98_7654_3210, 0xDEAD_BEEF];
        for from in [0, 1, 37, 63, 64, 100] {
            for len in [1, 5, 64, 70, 120] {
                for at in [0, 3, 63, 64, 65] {
                    if from + len > 192 || at + len > 256 {
                        continue;
                    }
                    let mut dst = [0u64; 4];
                    copy_bits(&src, from, len, &mut dst, at);
                    for i in 0..256 {
                        let got = dst[i / 64] >> (i % 64) & 1;
                        let want = if i >= at && i < at + len {
                            src[(from + i - at) / 64] >> ((from + i - at) % 64) & 1
                        } else {
                            0
                        };
                        assert_eq!(got, want, "from {from} len {len} at {at} bit {i}");
                    }
                }
            }
        }
        let mut dst = [0u64; 3];
        set_bits(&mut dst, 60, 70);
        assert_eq!(dst[0], 0xF << 60);
        assert_eq!(dst[1], !0);
        assert_eq!(dst[2], 0b11);
    }

    #[test]
    fn chunk_lattice_clips_at_the_grid() {
        let g = ChunkGrid::new([130, 64, 1]);
        assert_eq!(g.n, [3, 1, 1]);
        assert_eq!(g.chunk_dims([2, 0, 0]), [2, 64, 1]);
        assert_eq!(g.coords(g.index([2, 0, 0])), [2, 0, 0]);
    }
}
