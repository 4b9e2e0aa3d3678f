//! Step 1 of docs/architecture.md#voxmaps-and-point-shells: scan conversion. Every voxel whose closed cube overlaps a triangle (exact
//! separating-axis test, [`crate::tri_box`]) is marked. Work is parallel over triangles (rayon). Each
//! triangle visits only the grid columns (along its dominant normal axis) under its shadow, strip by
//! strip, and in each column only the few voxels its plane can cross, so the cost follows the
//! triangle's area in voxels, not its bounding-box volume.

use crate::bitgrid::BitGrid;
use crate::tri_box::PreparedTriangle;
use glam::DVec3;
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use vps_mesh::TriMesh;
use vps_voxmap::GridSpec;

/// A box of voxels inside a grid: voxel `(x, y, z)` of the window is voxel `offset + (x, y, z)` of
/// the grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Window {
    /// Grid index of the window's first voxel.
    pub offset: [usize; 3],
    /// Voxels along x, y, z (each ≥ 1).
    pub dims: [usize; 3],
}

impl Window {
    /// The whole grid.
    pub fn whole(spec: &GridSpec) -> Self {
        Window {
            offset: [0; 3],
            dims: spec.dims.map(|d| d as usize),
        }
    }

    /// Linear index (x fastest) of a window voxel.
    #[inline]
    pub fn linear(&self, v: [usize; 3]) -> usize {
        v[0] + self.dims[0] * (v[1] + self.dims[1] * v[2])
    }
}

/// Calls `f` with the window-relative index of every voxel of `window` that triangle `tri` (world
/// coordinates, m) overlaps, except voxels for which `known` answers true: those are skipped without
/// the exact test (a scan converter passes "already marked"). No allocation.
pub(crate) fn for_each_overlap(
    tri: &[DVec3; 3],
    spec: &GridSpec,
    window: &Window,
    known: impl Fn([usize; 3]) -> bool,
    mut f: impl FnMut([usize; 3]),
) {
    // Work in voxel units: voxel i spans [i, i + 1] along each axis.
    let inv = 1.0 / spec.voxel_size;
    let t = tri.map(|p| (p - spec.origin) * inv);
    let lo_t = t[0].min(t[1]).min(t[2]);
    let hi_t = t[0].max(t[1]).max(t[2]);
    let mut lo = [0i64; 3];
    let mut hi = [0i64; 3];
    for a in 0..3 {
        let first = window.offset[a] as i64;
        let last = first + window.dims[a] as i64 - 1;
        // Touching counts: a vertex exactly on plane i also touches voxel i - 1.
        lo[a] = (ceil_i(lo_t[a]) - 1).max(first);
        hi[a] = floor_i(hi_t[a]).min(last);
        if lo[a] > hi[a] {
            return;
        }
    }
    let n = (t[1] - t[0]).cross(t[2] - t[0]);
    // Columns run along the dominant normal axis `a`; the plane crosses each in at most ~3 voxels.
    let a = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
        0
    } else if n.y.abs() >= n.z.abs() {
        1
    } else {
        2
    };
    let (b, c) = ((a + 1) % 3, (a + 2) % 3);
    let scale = (hi_t - lo_t).max_element().max(1.0);
    let cull = n[a].abs() > 1e-12 * scale * scale;
    let (gb, gc, d) = if cull {
        (-n[b] / n[a], -n[c] / n[a], n.dot(t[0]) / n[a])
    } else {
        (0.0, 0.0, 0.0)
    };
    let half = DVec3::splat(0.5);
    let prepared = PreparedTriangle::new(&t, half);
    let eps = 1e-9 * scale;
    let proj = t.map(|p| [p[b], p[c]]);
    for j in lo[b]..=hi[b] {
        // Columns of this strip (b in [j, j + 1]) that the triangle's shadow can touch.
        let Some((c_lo, c_hi)) = strip_range(&proj, j as f64, j as f64 + 1.0) else {
            continue;
        };
        let k_lo = lo[c].max(ceil_i(c_lo - eps) - 1);
        let k_hi = hi[c].min(floor_i(c_hi + eps));
        for k in k_lo..=k_hi {
            let (mut ilo, mut ihi) = (lo[a], hi[a]);
            if cull {
                // Plane height p_a = d + gb * p_b + gc * p_c over the column's cross-section.
                let base = d + gb * j as f64 + gc * k as f64;
                let zmin = base + gb.min(0.0) + gc.min(0.0) - eps;
                let zmax = base + gb.max(0.0) + gc.max(0.0) + eps;
                ilo = ilo.max(ceil_i(zmin) - 1);
                ihi = ihi.min(floor_i(zmax));
            }
            for i in ilo..=ihi {
                let mut ijk = [0i64; 3];
                ijk[a] = i;
                ijk[b] = j;
                ijk[c] = k;
                let local = [0, 1, 2].map(|ax| (ijk[ax] - window.offset[ax] as i64) as usize);
                if known(local) {
                    continue;
                }
                let centre = DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64) + half;
                if prepared.overlaps(centre) {
                    f(local);
                }
            }
        }
    }
}

/// `x.floor()` as an integer without a libm call (saturating for huge values).
#[inline]
fn floor_i(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) > x {
        i - 1
    } else {
        i
    }
}

/// `x.ceil()` as an integer without a libm call (saturating for huge values).
#[inline]
fn ceil_i(x: f64) -> i64 {
    let i = x as i64;
    if (i as f64) < x {
        i + 1
    } else {
        i
    }
}

/// The range of the second coordinate over the part of the 2D triangle `p` with first coordinate in
/// `[u0, u1]`, or `None` when they do not meet. The part is a convex polygon whose corners are the
/// edges clipped to the strip, so the extremes are among the clipped edges' end points.
fn strip_range(p: &[[f64; 2]; 3], u0: f64, u1: f64) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    for e in 0..3 {
        let (a, b) = (p[e], p[(e + 1) % 3]);
        let (ua, ub) = (a[0], b[0]);
        if ua.max(ub) < u0 || ua.min(ub) > u1 {
            continue;
        }
        let at = |u: f64| {
            if ub == ua {
                (a[1].min(b[1]), a[1].max(b[1]))
            } else {
                let v = a[1] + (b[1] - a[1]) * ((u - ua) / (ub - ua));
                (v, v)
            }
        };
        let (s0, s1) = (ua.min(ub).max(u0), ua.max(ub).min(u1));
        for u in [s0, s1] {
            let (v0, v1) = at(u);
            lo = lo.min(v0);
            hi = hi.max(v1);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

/// Marks every voxel of `window` overlapped by a triangle of `mesh` (world pose, m). Parallel over
/// triangles; allocates the returned plane. The mesh must be validated (indices in range).
pub(crate) fn scan_convert(mesh: &TriMesh, spec: &GridSpec, window: &Window) -> BitGrid {
    let mut grid = BitGrid::zeros(window.dims);
    let row_words = grid.row_words;
    let dims = window.dims;
    let words: Vec<AtomicU64> = std::mem::take(&mut grid.words)
        .into_iter()
        .map(AtomicU64::new)
        .collect();
    (0..mesh.triangle_count())
        .into_par_iter()
        .with_min_len(64)
        .for_each(|t| {
            let word = |[x, y, z]: [usize; 3]| (y + dims[1] * z) * row_words + x / 64;
            let marked =
                |v: [usize; 3]| words[word(v)].load(Ordering::Relaxed) >> (v[0] % 64) & 1 == 1;
            for_each_overlap(&mesh.triangle(t), spec, window, marked, |v| {
                words[word(v)].fetch_or(1 << (v[0] % 64), Ordering::Relaxed);
            });
        });
    grid.words = words.into_iter().map(AtomicU64::into_inner).collect();
    grid
}

/// Every (window-linear voxel index, triangle index) overlap pair of `mesh` in `window`, sorted by
/// voxel then triangle. Parallel over triangles; allocates. Used by the point shell to find the
/// triangles that touch each Surface voxel.
pub(crate) fn overlap_pairs(mesh: &TriMesh, spec: &GridSpec, window: &Window) -> Vec<(u64, u32)> {
    let mut pairs: Vec<(u64, u32)> = (0..mesh.triangle_count())
        .into_par_iter()
        .with_min_len(64)
        .fold(Vec::new, |mut acc, t| {
            for_each_overlap(
                &mesh.triangle(t),
                spec,
                window,
                |_| false,
                |v| {
                    acc.push((window.linear(v) as u64, t as u32));
                },
            );
            acc
        })
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    pairs.par_sort_unstable();
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tri_box::triangle_box_overlap;

    fn spec(n: u32) -> GridSpec {
        GridSpec::at_origin(0.5, [n; 3])
    }

    /// Brute force: test every voxel of the window.
    fn brute(tri: &[DVec3; 3], spec: &GridSpec, w: &Window) -> Vec<[usize; 3]> {
        let mut out = Vec::new();
        let h = DVec3::splat(spec.voxel_size / 2.0);
        for z in 0..w.dims[2] {
            for y in 0..w.dims[1] {
                for x in 0..w.dims[0] {
                    let g = [x + w.offset[0], y + w.offset[1], z + w.offset[2]];
                    let c = spec.origin
                        + (DVec3::new(g[0] as f64, g[1] as f64, g[2] as f64) + 0.5)
                            * spec.voxel_size;
                    if triangle_box_overlap(tri, c, h) {
                        out.push([x, y, z]);
                    }
                }
            }
        }
        out
    }

    #[test]
    fn column_culling_matches_brute_force() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let s = spec(12);
        let windows = [
            Window::whole(&s),
            Window {
                offset: [2, 3, 1],
                dims: [7, 5, 9],
            },
        ];
        for n in 0..600 {
            let mut p = || {
                DVec3::new(
                    rng.gen_range(-0.5..6.5),
                    rng.gen_range(-0.5..6.5),
                    rng.gen_range(-0.5..6.5),
                )
            };
            let mut tri = [p(), p(), p()];
            if n % 2 == 1 {
                // Snap to quarter voxels: exact touching, axis-parallel edges, flat triangles.
                tri = tri.map(|v| (v * 8.0).round() / 8.0);
                if n % 3 == 0 {
                    let z = tri[0].z;
                    tri.iter_mut().for_each(|v| v.z = z);
                }
            }
            for w in &windows {
                let mut got = Vec::new();
                for_each_overlap(&tri, &s, w, |_| false, |v| got.push(v));
                got.sort_by_key(|v| (v[2], v[1], v[0]));
                assert_eq!(got, brute(&tri, &s, w), "{tri:?} {w:?}");
            }
        }
    }

    #[test]
    fn triangle_in_grid_plane_marks_both_sides() {
        let s = spec(8);
        // In plane z = 1.0 m = 2 voxels: touches voxel layers z = 1 and z = 2.
        let tri = [
            DVec3::new(0.6, 0.6, 1.0),
            DVec3::new(1.4, 0.6, 1.0),
            DVec3::new(0.6, 1.4, 1.0),
        ];
        let mut zs = Vec::new();
        for_each_overlap(&tri, &s, &Window::whole(&s), |_| false, |v| zs.push(v[2]));
        zs.sort();
        zs.dedup();
        assert_eq!(zs, vec![1, 2]);
    }

    #[test]
    fn scan_convert_and_pairs_agree() {
        let s = spec(10);
        let mesh = TriMesh::new(
            vec![
                DVec3::new(0.2, 0.3, 0.4),
                DVec3::new(4.1, 0.7, 1.9),
                DVec3::new(1.3, 4.6, 3.2),
                DVec3::new(3.3, 3.3, 0.1),
            ],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        let w = Window::whole(&s);
        let bits = scan_convert(&mesh, &s, &w);
        let pairs = overlap_pairs(&mesh, &s, &w);
        let mut voxels: Vec<u64> = pairs.iter().map(|p| p.0).collect();
        voxels.dedup();
        assert_eq!(bits.count(), voxels.len() as u64);
        for v in voxels {
            let v = v as usize;
            assert!(bits.get(v % 10, v / 10 % 10, v / 100));
        }
    }
}
