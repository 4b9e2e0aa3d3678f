//! One bit per voxel over a box of voxels: the voxelizer's working representation. Rows run along x
//! and are padded to whole 64-bit words, so that whole-word operations (dilation, flood-fill spans,
//! merging) handle 64 voxels at a time. Padding bits beyond `dims[0]` are always zero.

use rayon::prelude::*;

/// A bit plane of `dims[0] × dims[1] × dims[2]` voxels, x fastest, rows padded to words.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct BitGrid {
    /// Voxels along x, y, z.
    pub dims: [usize; 3],
    /// Words per x row.
    pub row_words: usize,
    /// `row_words * dims[1] * dims[2]` words.
    pub words: Vec<u64>,
}

impl BitGrid {
    /// An all-zero plane.
    pub fn zeros(dims: [usize; 3]) -> Self {
        let row_words = dims[0].div_ceil(64);
        Self {
            dims,
            row_words,
            words: vec![0; row_words * dims[1] * dims[2]],
        }
    }

    /// Words per z slice.
    pub fn slice_words(&self) -> usize {
        self.row_words * self.dims[1]
    }

    /// Mask of the valid bits of word `w` of a row (all ones except in the last word).
    #[inline]
    pub fn valid_mask(&self, w: usize) -> u64 {
        let rem = self.dims[0] - 64 * w;
        if rem >= 64 {
            !0
        } else {
            (1u64 << rem) - 1
        }
    }

    /// Word index and bit of voxel `(x, y, z)`.
    #[inline]
    pub fn locate(&self, x: usize, y: usize, z: usize) -> (usize, u32) {
        let row = y + self.dims[1] * z;
        (row * self.row_words + x / 64, (x % 64) as u32)
    }

    /// The bit of voxel `(x, y, z)`; indices must be in range.
    #[inline]
    pub fn get(&self, x: usize, y: usize, z: usize) -> bool {
        let (w, b) = self.locate(x, y, z);
        self.words[w] >> b & 1 == 1
    }

    /// The bit at signed indices; false outside the box.
    #[inline]
    pub fn get_signed(&self, x: i64, y: i64, z: i64) -> bool {
        let d = self.dims;
        x >= 0
            && y >= 0
            && z >= 0
            && (x as usize) < d[0]
            && (y as usize) < d[1]
            && (z as usize) < d[2]
            && self.get(x as usize, y as usize, z as usize)
    }

    /// Sets the bit of voxel `(x, y, z)`; indices must be in range.
    pub fn set(&mut self, x: usize, y: usize, z: usize) {
        let (w, b) = self.locate(x, y, z);
        self.words[w] |= 1 << b;
    }

    /// Heap bytes of the words.
    pub fn bytes(&self) -> usize {
        self.words.capacity() * 8
    }

    /// True when every valid bit is set.
    pub fn is_full(&self) -> bool {
        let rw = self.row_words;
        self.words
            .iter()
            .enumerate()
            .all(|(i, &w)| w == self.valid_mask(i % rw))
    }

    /// True when no bit is set.
    pub fn is_empty(&self) -> bool {
        self.words.iter().all(|&w| w == 0)
    }

    /// Number of set bits.
    pub fn count(&self) -> u64 {
        self.words.par_iter().map(|w| w.count_ones() as u64).sum()
    }

    /// `self = f(self, other)` word by word (same dims), in parallel.
    pub fn combine(&mut self, other: &BitGrid, f: impl Fn(u64, u64) -> u64 + Sync) {
        debug_assert_eq!(self.dims, other.dims);
        self.words
            .par_iter_mut()
            .zip(other.words.par_iter())
            .for_each(|(a, &b)| *a = f(*a, b));
    }

    /// The complement of `a | b` restricted to valid bits: voxels in neither plane.
    pub fn neither(a: &BitGrid, b: &BitGrid) -> BitGrid {
        debug_assert_eq!(a.dims, b.dims);
        let row_words = a.row_words;
        let masks: Vec<u64> = (0..row_words).map(|w| a.valid_mask(w)).collect();
        let words = a
            .words
            .par_iter()
            .zip(b.words.par_iter())
            .enumerate()
            .map(|(i, (&x, &y))| !(x | y) & masks[i % row_words])
            .collect();
        BitGrid {
            dims: a.dims,
            row_words,
            words,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn set_get_count_and_padding() {
        let mut g = BitGrid::zeros([70, 3, 2]);
        assert_eq!(g.row_words, 2);
        g.set(0, 0, 0);
        g.set(69, 2, 1);
        g.set(64, 1, 1);
        assert!(g.get(0, 0, 0) && g.get(69, 2, 1) && g.get(64, 1, 1));
        assert!(!g.get(1, 0, 0));
        assert!(!g.get_signed(-1, 0, 0) && !g.get_signed(70, 2, 1));
        assert_eq!(g.count(), 3);
        assert_eq!(g.valid_mask(0), !0);
        assert_eq!(g.valid_mask(1), 0b11_1111);
        let empty = BitGrid::zeros([70, 3, 2]);
        let n = BitGrid::neither(&g, &empty);
        assert_eq!(n.count(), 70 * 6 - 3);
    }
}
