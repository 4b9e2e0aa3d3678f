//! Step 2 of docs/architecture.md#voxmaps-and-point-shells: flood-fill free space inward from the six walls of the box, 6-connected,
//! stopping at Surface; what is not reached and not Surface is Interior.
//!
//! A scanline (span) fill on bit planes with an explicit stack: a popped seed grows to its whole run
//! of open voxels along x with word operations, the run is claimed, and every open run of the four
//! neighbouring rows (y ± 1, z ± 1) that touches it is pushed once. Each voxel is scanned a small
//! constant number of times, 64 at a time. Single-threaded; no recursion.

use crate::bitgrid::BitGrid;

/// The Interior plane of a box whose Surface plane is `surface`: every voxel that is neither Surface
/// nor 6-connected through non-Surface voxels to a voxel on the box's walls. Allocates one plane
/// (returned) and the seed stack.
pub(crate) fn flood_fill(surface: &BitGrid) -> BitGrid {
    // `open` starts as every non-Surface voxel; the fill clears what it reaches.
    let mut open = BitGrid::neither(surface, &BitGrid::zeros(surface.dims));
    let [nx, ny, nz] = open.dims;
    let rw = open.row_words;
    let mut stack: Vec<(u32, u32)> = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            let row = y + ny * z;
            if z == 0 || z == nz - 1 || y == 0 || y == ny - 1 {
                push_runs(
                    &open.words[row * rw..(row + 1) * rw],
                    row,
                    0,
                    nx - 1,
                    &mut stack,
                );
            } else {
                for x in [0, nx - 1] {
                    if open.words[row * rw + x / 64] >> (x % 64) & 1 == 1 {
                        stack.push((row as u32, x as u32));
                    }
                }
            }
        }
    }
    fill_from(&mut open, &mut stack);
    open
}

/// [`flood_fill`] where a wall voxel seeds the fill only when `may_seed(x, y, z)` (window-local
/// indices) holds: for a window cut by the grid's boundary, whose wall there may lie inside the
/// solid. Visits every wall voxel once (no word-wise seeding).
pub(crate) fn flood_fill_filtered(
    surface: &BitGrid,
    may_seed: impl Fn(usize, usize, usize) -> bool,
) -> BitGrid {
    let mut open = BitGrid::neither(surface, &BitGrid::zeros(surface.dims));
    let [nx, ny, nz] = open.dims;
    let mut stack: Vec<(u32, u32)> = Vec::new();
    for z in 0..nz {
        for y in 0..ny {
            let wall_row = z == 0 || z == nz - 1 || y == 0 || y == ny - 1;
            for x in 0..nx {
                let wall = wall_row || x == 0 || x == nx - 1;
                if wall && open.get(x, y, z) && may_seed(x, y, z) {
                    stack.push(((y + ny * z) as u32, x as u32));
                }
            }
        }
    }
    fill_from(&mut open, &mut stack);
    open
}

/// Runs the span fill on `open` (set bits: open voxels not yet reached) from the seeds on `stack`
/// (`(row, x)` with `row = y + ny * z`), clearing every open voxel 6-connected to a seed. Seeds on
/// closed voxels are skipped. Leaves `stack` empty.
pub(crate) fn fill_from(open: &mut BitGrid, stack: &mut Vec<(u32, u32)>) {
    let [_, ny, nz] = open.dims;
    let rw = open.row_words;
    while let Some((row, x)) = stack.pop() {
        let (row, x) = (row as usize, x as usize);
        let words = &mut open.words[row * rw..(row + 1) * rw];
        if words[x / 64] >> (x % 64) & 1 == 0 {
            continue; // already reached through another seed
        }
        let (l, r) = run_around(words, x);
        clear_span(words, l, r);
        let (y, z) = (row % ny, row / ny);
        let mut visit = |nrow: usize| {
            let nwords = &open.words[nrow * rw..(nrow + 1) * rw];
            push_runs(nwords, nrow, l, r, stack);
        };
        if y > 0 {
            visit(row - 1);
        }
        if y + 1 < ny {
            visit(row + 1);
        }
        if z > 0 {
            visit(row - ny);
        }
        if z + 1 < nz {
            visit(row + ny);
        }
    }
}

/// Mask of bits `l..=r` (row bit positions) that fall in word `w`.
#[inline]
fn span_mask(w: usize, l: usize, r: usize) -> u64 {
    let lo = l.max(64 * w) - 64 * w;
    let hi = r.min(64 * w + 63) - 64 * w;
    (!0u64 >> (63 - hi)) & (!0u64 << lo)
}

/// Pushes one seed per run of set bits of `words` (one row) within `l..=r`.
pub(crate) fn push_runs(
    words: &[u64],
    row: usize,
    l: usize,
    r: usize,
    stack: &mut Vec<(u32, u32)>,
) {
    let mut carry = 0u64; // bit 63 of the previous masked word, so runs crossing words push once
    for (w, &word) in words.iter().enumerate().take(r / 64 + 1).skip(l / 64) {
        let m = word & span_mask(w, l, r);
        let mut starts = m & !((m << 1) | carry);
        carry = m >> 63;
        while starts != 0 {
            let b = starts.trailing_zeros() as usize;
            stack.push((row as u32, (64 * w + b) as u32));
            starts &= starts - 1;
        }
    }
}

/// The maximal run `l..=r` of set bits containing the set bit `x`.
fn run_around(words: &[u64], x: usize) -> (usize, usize) {
    let (w0, b) = (x / 64, x % 64);
    // Left end: highest clear bit at or below b.
    let below = !words[w0] & (!0u64 >> (63 - b));
    let l = if below != 0 {
        64 * w0 + (64 - below.leading_zeros() as usize)
    } else {
        let mut w = w0;
        while w > 0 && words[w - 1] == !0 {
            w -= 1;
        }
        if w == 0 {
            0
        } else {
            64 * (w - 1) + (64 - (!words[w - 1]).leading_zeros() as usize)
        }
    };
    // Right end: lowest clear bit at or above b.
    let above = !words[w0] & (!0u64 << b);
    let r = if above != 0 {
        64 * w0 + above.trailing_zeros() as usize - 1
    } else {
        let mut w = w0;
        while w + 1 < words.len() && words[w + 1] == !0 {
            w += 1;
        }
        if w + 1 == words.len() {
            64 * words.len() - 1
        } else {
            64 * (w + 1) + (!words[w + 1]).trailing_zeros() as usize - 1
        }
    };
    (l, r)
}

/// Clears bits `l..=r`.
fn clear_span(words: &mut [u64], l: usize, r: usize) {
    for (w, word) in words.iter_mut().enumerate().take(r / 64 + 1).skip(l / 64) {
        *word &= !span_mask(w, l, r);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: breadth-first fill voxel by voxel.
    fn reference(surface: &BitGrid) -> BitGrid {
        let [nx, ny, nz] = surface.dims;
        let mut reached = BitGrid::zeros(surface.dims);
        let mut queue = Vec::new();
        for z in 0..nz {
            for y in 0..ny {
                for x in 0..nx {
                    let wall =
                        x == 0 || y == 0 || z == 0 || x == nx - 1 || y == ny - 1 || z == nz - 1;
                    if wall && !surface.get(x, y, z) {
                        reached.set(x, y, z);
                        queue.push([x as i64, y as i64, z as i64]);
                    }
                }
            }
        }
        while let Some([x, y, z]) = queue.pop() {
            for d in [
                [1, 0, 0],
                [-1, 0, 0],
                [0, 1, 0],
                [0, -1, 0],
                [0, 0, 1],
                [0, 0, -1],
            ] {
                let (a, b, c) = (x + d[0], y + d[1], z + d[2]);
                let inside = a >= 0
                    && b >= 0
                    && c >= 0
                    && (a as usize) < nx
                    && (b as usize) < ny
                    && (c as usize) < nz;
                if inside && !surface.get_signed(a, b, c) && !reached.get_signed(a, b, c) {
                    reached.set(a as usize, b as usize, c as usize);
                    queue.push([a, b, c]);
                }
            }
        }
        BitGrid::neither(surface, &reached)
    }

    #[test]
    fn span_helpers() {
        assert_eq!(span_mask(0, 3, 5), 0b111000);
        assert_eq!(span_mask(1, 3, 200), !0);
        assert_eq!(span_mask(1, 70, 72), 0b1_1100_0000);
        let words = [!0u64 << 60, !0u64, 0b1011];
        assert_eq!(run_around(&words, 100), (60, 129));
        assert_eq!(run_around(&words, 131), (131, 131));
        let mut w = words;
        clear_span(&mut w, 62, 128);
        assert_eq!(w, [0b11u64 << 60, 0, 0b1010]);
    }

    #[test]
    fn hollow_box_interior_and_random_agree_with_reference() {
        use rand::{Rng, SeedableRng};
        // A closed shell: interior is everything strictly inside.
        let mut s = BitGrid::zeros([70, 9, 8]);
        for z in 1..7 {
            for y in 1..8 {
                for x in 1..69 {
                    if z == 1 || z == 6 || y == 1 || y == 7 || x == 1 || x == 68 {
                        s.set(x, y, z);
                    }
                }
            }
        }
        let interior = flood_fill(&s);
        assert_eq!(interior.count(), 66 * 5 * 4);
        assert_eq!(interior, reference(&s));
        // A one-voxel hole in the shell lets free space in.
        let (w, b) = s.locate(40, 1, 3);
        s.words[w] &= !(1 << b);
        assert_eq!(flood_fill(&s).count(), 0);
        // Random solids of several densities, including rows wider than one word.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for p in [0.2, 0.35, 0.5, 0.65] {
            let mut g = BitGrid::zeros([130, 7, 6]);
            for z in 0..6 {
                for y in 0..7 {
                    for x in 0..130 {
                        if rng.gen_bool(p) {
                            g.set(x, y, z);
                        }
                    }
                }
            }
            let got = flood_fill(&g);
            assert_eq!(got, reference(&g), "density {p}");
        }
    }
}
