//! Step 1 of DESIGN §2: scan conversion. Every voxel whose closed cube overlaps a triangle (exact
//! separating-axis test, [`crate::tri_box`]) is marked. Work is parallel over triangles (rayon) and
//! each triangle tests only the few voxels of each grid column that its plane can cross, so the cost
//! follows the triangle's area in voxels, not its bounding-box volume.

use crate::bitgrid::BitGrid;
use crate::tri_box::triangle_box_overlap;
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
/// coordinates, m) overlaps. No allocation.
pub(crate) fn for_each_overlap(
    tri: &[DVec3; 3],
    spec: &GridSpec,
    window: &Window,
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
        lo[a] = (lo_t[a].ceil() as i64 - 1).max(first);
        hi[a] = (hi_t[a].floor() as i64).min(last);
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
    let eps = 1e-9 * scale;
    for j in lo[b]..=hi[b] {
        for k in lo[c]..=hi[c] {
            let (mut ilo, mut ihi) = (lo[a], hi[a]);
            if cull {
                // Plane height p_a = d + gb * p_b + gc * p_c over the column's cross-section.
                let base = d + gb * j as f64 + gc * k as f64;
                let zmin = base + gb.min(0.0) + gc.min(0.0) - eps;
                let zmax = base + gb.max(0.0) + gc.max(0.0) + eps;
                ilo = ilo.max(zmin.ceil() as i64 - 1);
                ihi = ihi.min(zmax.floor() as i64);
            }
            for i in ilo..=ihi {
                let mut ijk = [0i64; 3];
                ijk[a] = i;
                ijk[b] = j;
                ijk[c] = k;
                let centre = DVec3::new(ijk[0] as f64, ijk[1] as f64, ijk[2] as f64) + half;
                if triangle_box_overlap(&t, centre, half) {
                    f([0, 1, 2].map(|ax| (ijk[ax] - window.offset[ax] as i64) as usize));
                }
            }
        }
    }
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
            for_each_overlap(&mesh.triangle(t), spec, window, |[x, y, z]| {
                let w = (y + dims[1] * z) * row_words + x / 64;
                words[w].fetch_or(1 << (x % 64), Ordering::Relaxed);
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
            for_each_overlap(&mesh.triangle(t), spec, window, |v| {
                acc.push((window.linear(v) as u64, t as u32));
            });
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

    fn spec(n: u32) -> GridSpec {
        GridSpec {
            origin: DVec3::ZERO,
            voxel_size: 0.5,
            dims: [n; 3],
        }
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
        for _ in 0..300 {
            let mut p = || {
                DVec3::new(
                    rng.gen_range(-0.5..6.5),
                    rng.gen_range(-0.5..6.5),
                    rng.gen_range(-0.5..6.5),
                )
            };
            let tri = [p(), p(), p()];
            for w in &windows {
                let mut got = Vec::new();
                for_each_overlap(&tri, &s, w, |v| got.push(v));
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
        for_each_overlap(&tri, &s, &Window::whole(&s), |v| zs.push(v[2]));
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
