//! The signed-distance band of a voxmap ([`vps_voxmap::distance`]), computed from the exact
//! triangles: the `distance` force model's input.
//!
//! 1. **Cubes to store.** Every 8³ cube whose samples (voxel centres, with the one-sample apron)
//!    could lie within the band's reach of a triangle is marked: each triangle's box grown by the
//!    reach `standoff + 127/64 s` (plus half a code of rounding) marks the cubes it overlaps, and the triangle
//!    is listed with each (a compressed table: counts, offsets, indices).
//! 2. **Samples.** In each marked cube (parallel, rayon), each listed triangle visits only the
//!    samples inside its grown box and offers its exact distance (closest point on the triangle);
//!    each sample keeps the nearest triangle (as OpenVDB's mesh-to-volume conversion does). The
//!    nearest triangle then gives the sign: negative behind its angle-weighted pseudo-normal when
//!    its component is closed ([`vps_reference::ExactScene::signed_to_triangle_at`]), and negative
//!    wherever the voxmap's own classification says Interior (so an open mesh that the flood fill
//!    closed is inside here too, and a point inside one solid but nearest another's surface is
//!    inside). `e = d − standoff` is quantised to `s / 64` and saturated.
//! 3. **Unmarked cubes** lie farther than the reach from every triangle, so they hold no surface:
//!    the voxmap's voxel at the cube's centre says whether the cube is deep inside (Interior) or far
//!    outside.
//!
//! Cost: per triangle, one closest-point computation per sample in its grown box (about
//! `(2 reach / s + 1)³`); memory 4 bytes per cube of the grid for the directory and as much for
//! the triangle table's counts, 4 bytes per (triangle, cube) pair, and 729 bytes per stored cube,
//! checked against the budget before any sample is computed.

use glam::DVec3;
use rayon::prelude::*;
use vps_mesh::closest_point::closest_point;
use vps_mesh::TriMesh;
use vps_reference::ExactScene;
use vps_voxmap::distance::{
    self, CubeCodes, DistanceBand, BAND_VOXELS, BRICK_CODES, BRICK_EDGE, CUBE_EDGE,
    MAX_STANDOFF_VOXELS,
};
use vps_voxmap::{GridSpec, Voxel, VoxelTree};

/// Largest directory the band builds (cubes): 2^24, as the tree's leaf directory
/// ([`vps_voxmap::DIRECTORY_MAX_BYTES`]).
pub const MAX_BAND_CUBES: u64 = 1 << 24;

/// Why a band could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BandBuildError {
    /// The stand-off is negative, not finite or more than a voxel.
    #[error("standoff {standoff_m} m: must be within 0..={max_m} m (the voxel size {voxel_size} m); for a larger margin use a larger voxel_size")]
    Standoff {
        /// Given (m).
        standoff_m: f64,
        /// Largest allowed (m).
        max_m: f64,
        /// The voxel size (m).
        voxel_size: f64,
    },
    /// The grid has more cubes than the band's directory may hold.
    #[error("the distance band needs {cubes} cubes of 8³ voxels for a grid of {dims:?} voxels; at most {MAX_BAND_CUBES}: use a larger voxel_size or a [workspace] region")]
    TooManyCubes {
        /// Cubes the grid needs.
        cubes: u64,
        /// Grid dims (voxels).
        dims: [u32; 3],
    },
    /// The band would take more memory than the budget.
    #[error("the distance band would take {bytes} bytes ({bricks} cubes near the surface), over the budget of {budget} bytes: use a larger voxel_size or a [workspace] region")]
    OverBudget {
        /// Estimated bytes.
        bytes: u64,
        /// Cubes to store (0 when the triangle table alone was over the budget).
        bricks: u64,
        /// Budget (bytes).
        budget: u64,
    },
    /// The meshes cannot be measured (no triangles, a bad index, a non-finite vertex).
    #[error("the distance band's exact reference: {0}")]
    Reference(#[from] vps_reference::ReferenceError),
    /// The assembled band broke an invariant (a bug).
    #[error("the distance band: {0}")]
    Band(#[from] distance::BandError),
}

/// The band of `tree` (built from `meshes`, world frame, m) with the stand-off `standoff_m` (m,
/// `0..=` one voxel) baked in, within `max_memory_bytes`. Blocking, parallel (rayon),
/// allocates the band.
pub fn distance_band(
    tree: &VoxelTree,
    meshes: &[TriMesh],
    standoff_m: f64,
    max_memory_bytes: u64,
) -> Result<DistanceBand, BandBuildError> {
    let spec = *tree.spec();
    let s = spec.voxel_size;
    let max_m = MAX_STANDOFF_VOXELS * s;
    if !(standoff_m.is_finite() && (0.0..=max_m).contains(&standoff_m)) {
        return Err(BandBuildError::Standoff {
            standoff_m,
            max_m,
            voxel_size: s,
        });
    }
    let cube_dims = distance::cube_dims(&spec);
    let cubes: u64 = cube_dims.iter().map(|&d| u64::from(d)).product();
    if cubes > MAX_BAND_CUBES {
        return Err(BandBuildError::TooManyCubes {
            cubes,
            dims: spec.dims,
        });
    }
    // Beyond this distance from every triangle a sample's code saturates whatever its exact
    // distance (1/128 voxel of rounding slack), so no triangle needs to visit it.
    let reach = standoff_m + (f64::from(BAND_VOXELS) + 1.0 / 128.0) * s;
    let lists =
        CubeTriangles::new(&spec, cube_dims, meshes, reach, max_memory_bytes).map_err(|bytes| {
            BandBuildError::OverBudget {
                bytes,
                bricks: 0,
                budget: max_memory_bytes,
            }
        })?;
    let bricks = lists.marked_cubes() as u64;
    let bytes = 4 * cubes + bricks * BRICK_CODES as u64 + lists.memory_bytes() as u64;
    if bytes > max_memory_bytes {
        return Err(BandBuildError::OverBudget {
            bytes,
            bricks,
            budget: max_memory_bytes,
        });
    }
    let scene = ExactScene::new(meshes)?;
    let [nx, ny, _] = cube_dims;
    let index =
        |c: [u32; 3]| (c[2] as usize * ny as usize + c[1] as usize) * nx as usize + c[0] as usize;
    let marked: Vec<usize> = (0..lists.cube_count())
        .filter(|&i| !lists.of(i).is_empty())
        .collect();
    let stored: Vec<(usize, CubeCodes)> = marked
        .par_iter()
        .map(|&i| {
            let c = [
                (i % nx as usize) as u32,
                (i / nx as usize % ny as usize) as u32,
                (i / (nx as usize * ny as usize)) as u32,
            ];
            (
                i,
                sample_cube(tree, &scene, lists.of(i), c, standoff_m, reach),
            )
        })
        .collect();
    let mut stored = stored.into_iter().peekable();
    Ok(distance::assemble(&spec, standoff_m, |c| {
        let i = index(c);
        if stored.peek().is_some_and(|(j, _)| *j == i) {
            return stored
                .next()
                .map(|(_, codes)| codes)
                .unwrap_or(CubeCodes::Far);
        }
        // Farther than the reach from every triangle: uniform, as the voxmap says at its centre.
        let centre = glam::IVec3::from_array(c.map(|x| (x * CUBE_EDGE + CUBE_EDGE / 2) as i32));
        if tree.get(centre) == Voxel::Interior {
            CubeCodes::Deep
        } else {
            CubeCodes::Far
        }
    })?)
}

/// For every cube, the triangles whose box grown by the reach overlaps a sample of the cube
/// (apron included): a compressed table (offsets into one index array).
struct CubeTriangles {
    offsets: Vec<u32>,
    triangles: Vec<u32>,
}

impl CubeTriangles {
    /// The table, or `Err(bytes)` when the (triangle, cube) pairs alone would take more than
    /// `budget` bytes (counted before the index array is allocated).
    fn new(
        spec: &GridSpec,
        cube_dims: [u32; 3],
        meshes: &[TriMesh],
        reach: f64,
        budget: u64,
    ) -> Result<CubeTriangles, u64> {
        let [nx, ny, nz] = cube_dims;
        let cubes = nx as usize * ny as usize * nz as usize;
        let mut counts = vec![0u32; cubes + 1];
        for_each_cube_of_triangles(spec, cube_dims, meshes, reach, |cube, _| {
            counts[cube] += 1;
        });
        let pairs: u64 = counts.iter().map(|&c| u64::from(c)).sum();
        let bytes = 4 * pairs + 8 * (cubes as u64 + 1);
        if bytes > budget || pairs > u64::from(u32::MAX) {
            return Err(bytes);
        }
        let mut offsets = Vec::with_capacity(cubes + 1);
        let mut total = 0u32;
        for &c in &counts {
            offsets.push(total);
            total += c;
        }
        let mut fill = offsets.clone();
        let mut triangles = vec![0u32; total as usize];
        for_each_cube_of_triangles(spec, cube_dims, meshes, reach, |cube, t| {
            triangles[fill[cube] as usize] = t;
            fill[cube] += 1;
        });
        Ok(CubeTriangles { offsets, triangles })
    }

    fn cube_count(&self) -> usize {
        self.offsets.len() - 1
    }

    fn of(&self, cube: usize) -> &[u32] {
        &self.triangles[self.offsets[cube] as usize..self.offsets[cube + 1] as usize]
    }

    fn marked_cubes(&self) -> usize {
        self.offsets.windows(2).filter(|w| w[1] > w[0]).count()
    }

    fn memory_bytes(&self) -> usize {
        4 * (self.offsets.len() + self.triangles.len())
    }
}

/// The sample index range (inclusive, per axis, possibly empty) within `reach` (m) of the box of
/// `tri`: sample `i` sits at `(i + ½) s`.
fn sample_range(spec: &GridSpec, tri: &[DVec3; 3], reach: f64) -> [(i64, i64); 3] {
    let lo = tri[0].min(tri[1]).min(tri[2]) - DVec3::splat(reach);
    let hi = tri[0].max(tri[1]).max(tri[2]) + DVec3::splat(reach);
    [0, 1, 2].map(|a| {
        let to = |x: f64| (x - spec.origin[a]) / spec.voxel_size - 0.5;
        (to(lo[a]).ceil() as i64, to(hi[a]).floor() as i64)
    })
}

/// Calls `f(cube, triangle)` for every cube holding (as its own or as the apron of the cube
/// before) a sample within `reach` of the box of a triangle; triangles are numbered across
/// `meshes` in order, as [`ExactScene`] numbers them. Triangles naming a missing vertex are
/// skipped (the exact scene refuses them).
fn for_each_cube_of_triangles(
    spec: &GridSpec,
    cube_dims: [u32; 3],
    meshes: &[TriMesh],
    reach: f64,
    mut f: impl FnMut(usize, u32),
) {
    let [nx, ny, _] = cube_dims;
    let edge = i64::from(CUBE_EDGE);
    let mut global = 0u32;
    for mesh in meshes {
        for t in &mesh.triangles {
            let id = global;
            global += 1;
            let Some(v) = t
                .iter()
                .map(|&i| mesh.vertices.get(i as usize).copied())
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            let range = sample_range(spec, &[v[0], v[1], v[2]], reach);
            let cubes = [0, 1, 2].map(|a| {
                let (first, last) = range[a];
                let c0 = (first - 1).div_euclid(edge).max(0);
                let c1 = last.div_euclid(edge).min(i64::from(cube_dims[a]) - 1);
                (c0, c1)
            });
            for z in cubes[2].0..=cubes[2].1 {
                for y in cubes[1].0..=cubes[1].1 {
                    for x in cubes[0].0..=cubes[0].1 {
                        f(
                            (z as usize * ny as usize + y as usize) * nx as usize + x as usize,
                            id,
                        );
                    }
                }
            }
        }
    }
}

/// The 729 codes of cube `c` from its listed `triangles`, or its uniform kind when every code
/// saturates the same way.
fn sample_cube(
    tree: &VoxelTree,
    scene: &ExactScene,
    triangles: &[u32],
    c: [u32; 3],
    standoff_m: f64,
    reach: f64,
) -> CubeCodes {
    let spec = tree.spec();
    let s = spec.voxel_size;
    let first = c.map(|x| i64::from(x * CUBE_EDGE));
    let centre = |i: usize, a: usize| spec.origin[a] + ((first[a] + i as i64) as f64 + 0.5) * s;
    // Per sample, the nearest triangle of each nearby component (the scene's signed distance is
    // the minimum over components of the signed distance to each one's nearest triangle).
    let mut best = vec![Nearest::default(); BRICK_CODES];
    let reach_sq = reach * reach;
    for &t in triangles {
        let tri = scene.triangle(t);
        let component = scene.component_of(t);
        // The distance to the triangle's plane bounds the distance to the triangle from below:
        // a sample whose plane distance already exceeds its nearest so far (or the reach) skips
        // the closest-point computation, which could not have changed anything. (A degenerate
        // triangle has no plane: the bound is 0.)
        let normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
        let plane_offset = normal.dot(tri[0]);
        let range = sample_range(spec, &tri, reach);
        let local = [0, 1, 2].map(|a| {
            let lo = (range[a].0 - first[a]).max(0);
            let hi = (range[a].1 - first[a]).min(BRICK_EDGE as i64 - 1);
            (lo, hi)
        });
        for z in local[2].0..=local[2].1 {
            for y in local[1].0..=local[1].1 {
                for x in local[0].0..=local[0].1 {
                    let (x, y, z) = (x as usize, y as usize, z as usize);
                    let p = DVec3::new(centre(x, 0), centre(y, 1), centre(z, 2));
                    let nearest = &mut best[(z * BRICK_EDGE + y) * BRICK_EDGE + x];
                    let plane = normal.dot(p) - plane_offset;
                    // A relative margin of 1e-9 keeps rounding from skipping a triangle the
                    // exact comparison below would have taken.
                    let bound = nearest.improves_below(component).min(reach_sq);
                    if plane * plane > bound * (1.0 + 1e-9) {
                        continue;
                    }
                    let d_sq = closest_point(p, &tri).0.distance_squared(p);
                    if d_sq <= reach_sq {
                        nearest.offer(component, d_sq, t);
                    }
                }
            }
        }
    }
    let mut codes = Box::new([0i8; BRICK_CODES]);
    for z in 0..BRICK_EDGE {
        for y in 0..BRICK_EDGE {
            for x in 0..BRICK_EDGE {
                let i = (z * BRICK_EDGE + y) * BRICK_EDGE + x;
                let ijk = glam::IVec3::new(
                    (first[0] + x as i64) as i32,
                    (first[1] + y as i64) as i32,
                    (first[2] + z as i64) as i32,
                );
                let interior = tree.get(ijk) == Voxel::Interior;
                let p = DVec3::new(centre(x, 0), centre(y, 1), centre(z, 2));
                let d = match best[i].signed_distance(scene, p) {
                    None if interior => -reach,
                    None => reach,
                    Some(sd) if interior => -sd.abs(),
                    Some(sd) => sd,
                };
                codes[i] = distance::code_of(d - standoff_m, s);
            }
        }
    }
    CubeCodes::from_codes(codes)
}

/// Components tracked per sample; a sample near more distinct components than this keeps the
/// nearest ones.
const COMPONENTS_PER_SAMPLE: usize = 4;

/// The nearest triangle of each of up to [`COMPONENTS_PER_SAMPLE`] components near one sample:
/// (component, squared distance, triangle); unused entries have `u32::MAX` as component.
#[derive(Clone, Copy)]
struct Nearest {
    entries: [(u32, f64, u32); COMPONENTS_PER_SAMPLE],
}

impl Default for Nearest {
    fn default() -> Self {
        Nearest {
            entries: [(u32::MAX, f64::INFINITY, u32::MAX); COMPONENTS_PER_SAMPLE],
        }
    }
}

impl Nearest {
    /// The squared distance a triangle of `component` must be below for [`Nearest::offer`] to
    /// keep it: the component's nearest so far, else (a new component) the farthest entry's (an
    /// unused entry is infinitely far).
    fn improves_below(&self, component: u32) -> f64 {
        match self.entries.iter().find(|e| e.0 == component) {
            Some(e) => e.1,
            None => self
                .entries
                .iter()
                .map(|e| e.1)
                .fold(f64::NEG_INFINITY, f64::max),
        }
    }

    /// Triangle `t` of `component` at squared distance `d_sq`.
    fn offer(&mut self, component: u32, d_sq: f64, t: u32) {
        if let Some(e) = self.entries.iter_mut().find(|e| e.0 == component) {
            if d_sq < e.1 {
                *e = (component, d_sq, t);
            }
            return;
        }
        // A new component replaces the farthest entry (an unused one is infinitely far).
        if let Some(e) = self
            .entries
            .iter_mut()
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .filter(|e| d_sq < e.1)
        {
            *e = (component, d_sq, t);
        }
    }

    /// The minimum over the tracked components of the signed distance (m) from `p` to each one's
    /// nearest triangle; `None` when no triangle was offered.
    fn signed_distance(&self, scene: &ExactScene, p: DVec3) -> Option<f64> {
        self.entries
            .iter()
            .filter(|e| e.0 != u32::MAX)
            .map(|e| scene.signed_to_triangle_at(p, e.2).distance_m)
            .min_by(f64::total_cmp)
    }
}
