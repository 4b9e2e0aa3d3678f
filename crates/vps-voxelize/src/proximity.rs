//! Step 3 of docs/architecture.md#voxmaps-and-point-shells: Proximity = Free voxels that share a face, edge or corner with a Surface
//! voxel.
//!
//! Computed as a 3×3×3 dilation of the Surface plane, separated into an x pass (word shifts), a y pass
//! and a z pass (word ORs of neighbouring rows and slices), parallel over z slices. That is 64 voxels
//! per operation over the whole box, which is cheaper than visiting the 26 neighbours of each of the
//! millions of Surface voxels of a large scene one by one.

use crate::bitgrid::BitGrid;
use rayon::prelude::*;

/// Every voxel within one voxel (Chebyshev distance ≤ 1) of a set voxel of `src`. Allocates two
/// planes.
pub(crate) fn dilate26(src: &BitGrid) -> BitGrid {
    let [_, ny, nz] = src.dims;
    let rw = src.row_words;
    let sw = src.slice_words();
    let last_mask = src.valid_mask(rw - 1);
    // x and y within each slice.
    let mut xy = BitGrid::zeros(src.dims);
    xy.words
        .par_chunks_mut(sw)
        .zip(src.words.par_chunks(sw))
        .for_each(|(out, slice)| {
            let xrow = |y: usize, w: usize| -> u64 {
                let row = &slice[y * rw..(y + 1) * rw];
                let v = row[w];
                let left = if w > 0 { row[w - 1] >> 63 } else { 0 };
                let right = if w + 1 < rw { row[w + 1] << 63 } else { 0 };
                v | v << 1 | v >> 1 | left | right
            };
            for y in 0..ny {
                for w in 0..rw {
                    let mut acc = xrow(y, w);
                    if y > 0 {
                        acc |= xrow(y - 1, w);
                    }
                    if y + 1 < ny {
                        acc |= xrow(y + 1, w);
                    }
                    if w + 1 == rw {
                        acc &= last_mask;
                    }
                    out[y * rw + w] = acc;
                }
            }
        });
    // z across slices.
    let mut out = BitGrid::zeros(src.dims);
    out.words
        .par_chunks_mut(sw)
        .enumerate()
        .for_each(|(z, slice)| {
            slice.copy_from_slice(&xy.words[z * sw..(z + 1) * sw]);
            for nzi in [z.wrapping_sub(1), z + 1] {
                if nzi < nz {
                    let other = &xy.words[nzi * sw..(nzi + 1) * sw];
                    for (a, &b) in slice.iter_mut().zip(other) {
                        *a |= b;
                    }
                }
            }
        });
    out
}

/// Proximity plane: voxels of `free` that are 26-neighbours of `surface`. Allocates.
pub(crate) fn proximity(surface: &BitGrid, free: &BitGrid) -> BitGrid {
    let mut p = dilate26(surface);
    p.combine(free, |d, f| d & f);
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dilation_matches_brute_force() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let dims = [131, 6, 5];
        let mut g = BitGrid::zeros(dims);
        for _ in 0..25 {
            g.set(
                rng.gen_range(0..131),
                rng.gen_range(0..6),
                rng.gen_range(0..5),
            );
        }
        g.set(63, 0, 0);
        g.set(64, 5, 4);
        g.set(130, 2, 2);
        let d = dilate26(&g);
        for z in 0..5i64 {
            for y in 0..6i64 {
                for x in 0..131i64 {
                    let mut expect = false;
                    for dz in -1..=1 {
                        for dy in -1..=1 {
                            for dx in -1..=1 {
                                expect |= g.get_signed(x + dx, y + dy, z + dz);
                            }
                        }
                    }
                    assert_eq!(
                        d.get(x as usize, y as usize, z as usize),
                        expect,
                        "{x} {y} {z}"
                    );
                }
            }
        }
        // Padding bits stay clear.
        assert_eq!(d.words[d.row_words - 1] & !d.valid_mask(d.row_words - 1), 0);
        let free = BitGrid::neither(&g, &BitGrid::zeros(dims));
        let p = proximity(&g, &free);
        assert_eq!(p.count(), d.count() - g.count());
    }
}
