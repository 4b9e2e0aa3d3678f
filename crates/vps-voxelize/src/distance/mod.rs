//! The signed-distance band of a voxmap ([`vps_voxmap::distance`]), computed from the exact
//! triangles: the `distance` force model's input.
//!
//! 1. **Cubes to store.** Every 8³ cube whose samples (voxel centres, with the one-sample apron)
//!    could lie within the band's reach of a triangle is marked: each triangle's box grown by the
//!    reach `standoff + 127/64 s` (plus half a code of rounding) marks the cubes it overlaps, and the triangle
//!    is listed with each (a compressed table: counts, offsets, indices).
//! 2. **Samples.** In each marked cube (parallel, rayon), each listed triangle, nearest to the
//!    cube's middle first, computes its squared distance to every sample of each row within the
//!    reach of its box (branch-free, several samples per instruction: `row`) and offers it where
//!    it could change what the sample keeps; each sample keeps the nearest triangle of each nearby
//!    component (as OpenVDB's mesh-to-volume conversion keeps the nearest). The
//!    nearest triangle then gives the sign: negative behind its angle-weighted pseudo-normal when
//!    its component is closed ([`vps_reference::ExactScene::signed_distance_to_triangle`]). A sample
//!    that the inside map (the scene's classification with no force-layer offset: [`InsideMap`])
//!    puts wholly inside a solid is negative whatever: an open mesh the flood fill closed is
//!    inside here too, and a sample deep in a solid whose surface is beyond the reach is `−reach`
//!    (deep) even when it is near another solid's surface. `e = d − standoff` is quantised to
//!    `s / 64` and saturated.
//! 3. **Unmarked cubes** lie farther than the reach from every triangle, so they hold no surface:
//!    the inside map's voxel at the cube's centre says whether the cube is deep inside or far
//!    outside.
//!
//! Overlapping solids: where one solid's surface lies inside another and the enclosing solid's
//! own surface is beyond the reach, the band holds the distance to the inner surface (a shallower
//! depth than the union's), with that surface's normal.
//!
//! Cost: the inside map (none when the voxelization that built the tree kept its own:
//! [`crate::voxelize_tree_keeping_inside`], [`distance_band_with_inside`]; else the sparse
//! pipeline's scan, flood fill and merge again, beside the exact scene's build); per triangle, a distance per
//! sample of the rows within its reach (about `(2 reach / s + 1)³` samples); per sample, one exact
//! closest point for the triangle it keeps; memory 4 bytes per cube of the grid for the directory
//! and as much for the triangle table's counts, 4 bytes per (triangle, cube) pair, and 729 bytes
//! per stored cube, checked against the budget before any sample is computed.

use crate::InsideMap;
use glam::DVec3;
use rayon::prelude::*;
use std::time::Instant;
use vps_mesh::TriMesh;
use vps_reference::ExactScene;
use vps_voxmap::distance::{
    self, CubeCodes, DistanceBand, BAND_VOXELS, BRICK_CODES, BRICK_EDGE, CUBE_EDGE,
    MAX_STANDOFF_VOXELS,
};
use vps_voxmap::{GridSpec, Voxel, VoxelTree};

mod row;
use row::RowTriangle;

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
    /// The inside/outside classification the band takes its signs from could not be made.
    #[error("the distance band's inside/outside classification: {0}")]
    Inside(#[from] crate::VoxelizeError),
    /// The inside map given is not on the tree's grid (a bug in the caller).
    #[error("the distance band: the inside map given is not on the voxmap's grid")]
    InsideGrid,
    /// The assembled band broke an invariant (a bug).
    #[error("the distance band: {0}")]
    Band(#[from] distance::BandError),
}

/// Where a band build's time went (wall-clock ms, one build): what `vps bench voxelize`
/// reports beside the build's total.
#[derive(Clone, Copy, Debug, Default)]
pub struct BandBuildPhases {
    /// Step 1: the cubes to store and their triangle lists (serial).
    pub lists_ms: f64,
    /// The exact scene (edge and vertex normals, components, search tree; serial), run beside
    /// the inside map.
    pub exact_scene_ms: f64,
    /// The inside map: the sparse voxelizer's scan, flood fill and merge (parallel), run beside
    /// the exact scene; 0 when the voxelization's own map was given.
    pub inside_map_ms: f64,
    /// The two above together (the longer of them, on two or more threads).
    pub scene_and_inside_ms: f64,
    /// Step 2: every stored cube's samples (parallel).
    pub samples_ms: f64,
    /// Step 3 and the directory: the band assembled (serial).
    pub assemble_ms: f64,
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
    distance_band_timed(tree, meshes, standoff_m, max_memory_bytes).map(|(band, _)| band)
}

/// [`distance_band`], with where its time went.
pub fn distance_band_timed(
    tree: &VoxelTree,
    meshes: &[TriMesh],
    standoff_m: f64,
    max_memory_bytes: u64,
) -> Result<(DistanceBand, BandBuildPhases), BandBuildError> {
    band_timed(tree, None, meshes, standoff_m, max_memory_bytes)
}

/// [`distance_band`] with the signs taken from `inside`, the inside map the voxelization of
/// `tree` kept ([`crate::voxelize_tree_keeping_inside`]) instead of a second voxelization of
/// `meshes`: the same band, sooner. `inside` must be on `tree`'s grid. With where its time went
/// (`inside_map_ms` 0).
pub fn distance_band_with_inside(
    tree: &VoxelTree,
    inside: &InsideMap,
    meshes: &[TriMesh],
    standoff_m: f64,
    max_memory_bytes: u64,
) -> Result<(DistanceBand, BandBuildPhases), BandBuildError> {
    if inside.spec() != tree.spec() {
        return Err(BandBuildError::InsideGrid);
    }
    band_timed(tree, Some(inside), meshes, standoff_m, max_memory_bytes)
}

/// The band, with the inside map `given` or made here.
fn band_timed(
    tree: &VoxelTree,
    given: Option<&InsideMap>,
    meshes: &[TriMesh],
    standoff_m: f64,
    max_memory_bytes: u64,
) -> Result<(DistanceBand, BandBuildPhases), BandBuildError> {
    let ms = |since: Instant| since.elapsed().as_secs_f64() * 1e3;
    let mut phases = BandBuildPhases::default();
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
    let started = Instant::now();
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
    phases.lists_ms = ms(started);
    // The exact scene's build is serial: it runs beside the inside map's voxelization when
    // there is one to make.
    let started = Instant::now();
    let exact_scene = || {
        let started = Instant::now();
        (ExactScene::new(meshes), ms(started))
    };
    let made: InsideMap;
    let (scene, inside) = match given {
        Some(inside) => {
            let (scene, exact_scene_ms) = exact_scene();
            phases.exact_scene_ms = exact_scene_ms;
            (scene?, inside)
        }
        None => {
            let ((scene, exact_scene_ms), (inside, inside_map_ms)) =
                rayon::join(exact_scene, || {
                    let started = Instant::now();
                    let inside = crate::inside_map_in(meshes, spec, max_memory_bytes);
                    (inside, ms(started))
                });
            (phases.exact_scene_ms, phases.inside_map_ms) = (exact_scene_ms, inside_map_ms);
            made = inside?;
            (scene?, &made)
        }
    };
    phases.scene_and_inside_ms = ms(started);
    let started = Instant::now();
    let [nx, ny, _] = cube_dims;
    let index =
        |c: [u32; 3]| (c[2] as usize * ny as usize + c[1] as usize) * nx as usize + c[0] as usize;
    let sampler = CubeSampler {
        inside,
        scene: &scene,
        standoff_m,
        reach,
        with_avx2: vps_voxmap::cpu::has_avx2(),
    };
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
            (i, sampler.cube(lists.of(i), c))
        })
        .collect();
    phases.samples_ms = ms(started);
    let started = Instant::now();
    let mut stored = stored.into_iter().peekable();
    let band = distance::assemble(&spec, standoff_m, |c| {
        let i = index(c);
        if stored.peek().is_some_and(|(j, _)| *j == i) {
            return stored
                .next()
                .map(|(_, codes)| codes)
                .unwrap_or(CubeCodes::Far);
        }
        // Farther than the reach from every triangle: uniform, as the inside map says at its
        // centre.
        let centre = glam::IVec3::from_array(c.map(|x| (x * CUBE_EDGE + CUBE_EDGE / 2) as i32));
        if Placement::of(inside.get(centre)) == Placement::Inside {
            CubeCodes::Deep
        } else {
            CubeCodes::Far
        }
    })?;
    phases.assemble_ms = ms(started);
    Ok((band, phases))
}

/// Where a voxel lies, by the [`InsideMap`] (the scene's classification before any force-layer
/// offset, on the band's grid; Interior means inside and clear of every triangle). The band's own
/// map cannot say it: its offset rings turn voxels outside the surface into Interior (2-bit) and
/// its depth layers turn voxels deep inside into Surface (4- and 8-bit). A sample farther than
/// the band's reach from every triangle lies in no Surface voxel of the inside map, so for it the
/// map is exact.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placement {
    /// Wholly inside a solid (clear of every triangle).
    Inside,
    /// Crossed by a triangle.
    OnSurface,
    /// Wholly outside every solid (clear of every triangle).
    Outside,
}

impl Placement {
    /// Where a voxel of the inside map's kind `kind` lies.
    fn of(kind: Voxel) -> Placement {
        match kind {
            Voxel::Interior => Placement::Inside,
            Voxel::Surface => Placement::OnSurface,
            Voxel::Free | Voxel::Proximity => Placement::Outside,
        }
    }
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

/// The corners of the box of `tri` (m).
fn triangle_box(tri: &[DVec3; 3]) -> (DVec3, DVec3) {
    (
        tri[0].min(tri[1]).min(tri[2]),
        tri[0].max(tri[1]).max(tri[2]),
    )
}

/// The sample index range (inclusive, per axis, possibly empty) within `reach` (m) of the box
/// `lo..=hi` (m): sample `i` sits at `(i + ½) s`.
fn sample_range(spec: &GridSpec, lo: DVec3, hi: DVec3, reach: f64) -> [(i64, i64); 3] {
    let lo = lo - DVec3::splat(reach);
    let hi = hi + DVec3::splat(reach);
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
            let (lo, hi) = triangle_box(&[v[0], v[1], v[2]]);
            let range = sample_range(spec, lo, hi, reach);
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

/// What every cube's samples are computed from, the same for one band.
struct CubeSampler<'a> {
    inside: &'a InsideMap,
    scene: &'a ExactScene,
    /// The stand-off baked into the codes (m).
    standoff_m: f64,
    /// Beyond this distance (m) from every triangle a code saturates.
    reach: f64,
    /// Whether the CPU has AVX2 ([`vps_voxmap::cpu::has_avx2`]): the AVX2 copy runs.
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    with_avx2: bool,
}

impl CubeSampler<'_> {
    /// The 729 codes of cube `c` from its listed `triangles`, or its uniform kind when every code
    /// saturates the same way: [`cube_codes`] compiled for AVX2 where the CPU has it, else for
    /// the baseline. The same codes either way (the row distances use no fused multiply-add).
    fn cube(&self, triangles: &[u32], c: [u32; 3]) -> CubeCodes {
        #[cfg(target_arch = "x86_64")]
        if self.with_avx2 {
            // SAFETY: `with_avx2` is only set where the CPU has AVX2.
            return unsafe { self.cube_avx2(triangles, c) };
        }
        cube_codes(self, triangles, c)
    }

    /// [`cube_codes`] compiled for AVX2 (the row distances four samples per instruction).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    unsafe fn cube_avx2(&self, triangles: &[u32], c: [u32; 3]) -> CubeCodes {
        cube_codes(self, triangles, c)
    }
}

/// The codes of [`CubeSampler::cube`].
#[inline(always)]
fn cube_codes(sampler: &CubeSampler, triangles: &[u32], c: [u32; 3]) -> CubeCodes {
    let CubeSampler {
        inside,
        scene,
        standoff_m,
        reach,
        ..
    } = *sampler;
    let spec = inside.spec();
    let s = spec.voxel_size;
    let first = c.map(|x| i64::from(x * CUBE_EDGE));
    let centre = |i: usize, a: usize| spec.origin[a] + ((first[a] + i as i64) as f64 + 0.5) * s;
    // Per sample, the nearest triangle of each nearby component (the scene's signed distance is
    // the minimum over components of the signed distance to each one's nearest triangle).
    let mut best = vec![Nearest::default(); BRICK_CODES];
    let reach_sq = reach * reach;
    // Where the inside map puts each sample's voxel. A sample wholly outside every solid has a
    // positive distance to every component, so its signed distance is that of its nearest
    // triangle of any component: one bound serves every component.
    let placed: Vec<Placement> = (0..BRICK_CODES)
        .map(|i| {
            let l = [
                i % BRICK_EDGE,
                i / BRICK_EDGE % BRICK_EDGE,
                i / (BRICK_EDGE * BRICK_EDGE),
            ];
            Placement::of(inside.get(glam::IVec3::from_array(
                [0, 1, 2].map(|a| (first[a] + l[a] as i64) as i32),
            )))
        })
        .collect();
    // Per sample outside every solid, the squared distance (m²) a triangle must be within for
    // its offer to count: the reach, and the nearest so far. (Elsewhere the bound is per
    // component: `Nearest::improves_below`.)
    let mut limit = vec![reach_sq; BRICK_CODES];
    // Nearest to the cube's middle first, so that each sample's nearest so far soon bounds the
    // triangles still to come. The order does not change the result: ties keep the
    // lower-numbered triangle whatever comes first.
    let middle = DVec3::from_array([0, 1, 2].map(|a| centre(BRICK_EDGE / 2, a)));
    // Sorted as (key, triangle) pairs, then prepared in that order: the prepared triangles are
    // large to move.
    let mut order: Vec<(f64, u32)> = triangles
        .iter()
        .map(|&t| {
            let (lo, hi) = triangle_box(&scene.triangle(t));
            (box_distance_sq(lo, hi, middle), t)
        })
        .collect();
    order.sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let listed: Vec<Listed> = order.iter().map(|&(_, t)| Listed::new(scene, t)).collect();
    let xs: [f64; row::ROW] = std::array::from_fn(|x| centre(x, 0));
    let mut row_sq = [0.0; row::ROW];
    for l in &listed {
        let range = sample_range(spec, l.lo, l.hi, reach);
        let local = [0, 1, 2].map(|a| {
            let lo = (range[a].0 - first[a]).max(0);
            let hi = (range[a].1 - first[a]).min(BRICK_EDGE as i64 - 1);
            (lo, hi)
        });
        for z in local[2].0..=local[2].1 {
            for y in local[1].0..=local[1].1 {
                let (y, z) = (y as usize, z as usize);
                // A row wholly beyond the reach of the triangle's box has nothing to offer.
                let box_sq = l.box_distance_sq(DVec3::new(l.lo.x, centre(y, 1), centre(z, 2)));
                if box_sq > reach_sq {
                    continue;
                }
                // The whole row at once (the compiler vectorizes it), then the offers of the
                // samples within the reach of the triangle's box along x; a sample beyond the
                // reach of the triangle is beyond every sample's limit.
                let (x0, x1) = (local[0].0 as usize, local[0].1 as usize);
                l.row
                    .distances_sq(centre(y, 1), centre(z, 2), &xs, (x0, x1), &mut row_sq);
                let first_of_row = (z * BRICK_EDGE + y) * BRICK_EDGE;
                for (x, &d_sq) in row_sq.iter().enumerate().take(x1 + 1).skip(x0) {
                    let i = first_of_row + x;
                    let within = match placed[i] {
                        Placement::Outside => d_sq <= limit[i],
                        _ => d_sq <= best[i].improves_below(l.component).min(reach_sq),
                    };
                    if !within {
                        continue;
                    }
                    let nearest = &mut best[i];
                    nearest.offer(l.component, d_sq, l.t);
                    if placed[i] == Placement::Outside {
                        limit[i] = nearest.nearest_sq().min(reach_sq);
                    }
                }
            }
        }
    }
    // Beyond this distance from the surface a code saturates: `code_of` rounds `e / s · 64` and
    // clamps at ±127, so half a code inside the clamp is already saturated.
    let saturation = standoff_m + f64::from(BAND_VOXELS) * s;
    let saturation_sq = saturation * saturation;
    let mut codes = Box::new([0i8; BRICK_CODES]);
    for z in 0..BRICK_EDGE {
        for y in 0..BRICK_EDGE {
            for x in 0..BRICK_EDGE {
                let i = (z * BRICK_EDGE + y) * BRICK_EDGE + x;
                // Wholly outside (inside) a solid and farther than the saturation from every
                // tracked triangle: the code saturates far (deep) whatever the exact distance.
                let saturated = match placed[i] {
                    Placement::Outside => Some(distance::CODE_FAR),
                    Placement::Inside => Some(distance::CODE_DEEP),
                    Placement::OnSurface => None,
                }
                .filter(|_| best[i].nearest_sq() >= saturation_sq);
                codes[i] = saturated.unwrap_or_else(|| {
                    let p = DVec3::new(centre(x, 0), centre(y, 1), centre(z, 2));
                    let d = best[i].signed_distance(scene, p, placed[i], reach);
                    distance::code_of(d - standoff_m, s)
                });
            }
        }
    }
    CubeCodes::from_codes(codes)
}

/// A triangle listed for a cube.
struct Listed {
    t: u32,
    component: u32,
    /// The triangle prepared for rows of samples.
    row: RowTriangle,
    /// The triangle's box (m).
    lo: DVec3,
    hi: DVec3,
}

impl Listed {
    fn new(scene: &ExactScene, t: u32) -> Listed {
        let tri = scene.triangle(t);
        let (lo, hi) = triangle_box(&tri);
        Listed {
            t,
            component: scene.component_of(t),
            row: RowTriangle::new(tri),
            lo,
            hi,
        }
    }

    /// Squared distance (m²) from `p` to the triangle's box.
    fn box_distance_sq(&self, p: DVec3) -> f64 {
        box_distance_sq(self.lo, self.hi, p)
    }
}

/// Squared distance (m²) from `p` to the box `lo..=hi` (m).
fn box_distance_sq(lo: DVec3, hi: DVec3, p: DVec3) -> f64 {
    ((lo - p).max(DVec3::ZERO) + (p - hi).max(DVec3::ZERO)).length_squared()
}

/// Components tracked per sample; a sample near more distinct components than this keeps the
/// nearest ones.
const COMPONENTS_PER_SAMPLE: usize = 4;

/// The nearest triangle of each of up to [`COMPONENTS_PER_SAMPLE`] components near one sample;
/// unused entries have `u32::MAX` as component.
#[derive(Clone, Copy)]
struct Nearest {
    entries: [Entry; COMPONENTS_PER_SAMPLE],
}

/// One component's nearest triangle offered to a sample.
#[derive(Clone, Copy)]
struct Entry {
    /// Squared distance (m²); infinite when unused.
    d_sq: f64,
    component: u32,
    triangle: u32,
}

impl Entry {
    const UNUSED: Entry = Entry {
        d_sq: f64::INFINITY,
        component: u32::MAX,
        triangle: u32::MAX,
    };
}

impl Default for Nearest {
    fn default() -> Self {
        Nearest {
            entries: [Entry::UNUSED; COMPONENTS_PER_SAMPLE],
        }
    }
}

impl Nearest {
    /// The squared distance (m²) of the nearest triangle offered, of any component (infinite when
    /// none was).
    fn nearest_sq(&self) -> f64 {
        self.entries
            .iter()
            .map(|e| e.d_sq)
            .fold(f64::INFINITY, f64::min)
    }

    /// The squared distance a triangle of `component` must be below for [`Nearest::offer`] to
    /// keep it: the component's nearest so far, else (a new component) the farthest entry's (an
    /// unused entry is infinitely far).
    fn improves_below(&self, component: u32) -> f64 {
        match self.entries.iter().find(|e| e.component == component) {
            Some(e) => e.d_sq,
            None => self
                .entries
                .iter()
                .map(|e| e.d_sq)
                .fold(f64::NEG_INFINITY, f64::max),
        }
    }

    /// Triangle `t` of `component` at squared distance `d_sq`. For one component the result does
    /// not depend on the order of the offers.
    fn offer(&mut self, component: u32, d_sq: f64, t: u32) {
        let entry = Entry {
            d_sq,
            component,
            triangle: t,
        };
        if let Some(e) = self.entries.iter_mut().find(|e| e.component == component) {
            // At equal distance the lower-numbered triangle, whatever the order of the offers.
            if d_sq < e.d_sq || (d_sq == e.d_sq && t < e.triangle) {
                *e = entry;
            }
            return;
        }
        // A new component replaces the farthest entry (an unused one is infinitely far).
        if let Some(e) = self
            .entries
            .iter_mut()
            .max_by(|a, b| a.d_sq.total_cmp(&b.d_sq))
            .filter(|e| d_sq < e.d_sq)
        {
            *e = entry;
        }
    }

    /// The signed distance (m) of sample `p`, within `±reach`: the minimum over the tracked
    /// components of the signed distance to each one's nearest triangle (negative inside a closed
    /// component, unsigned for an open one). A sample the inside map calls `interior` is negative
    /// whatever: an open component's distance is negated (the flood fill closed it), and when every
    /// tracked component has it outside, the solid enclosing it has its surface beyond the reach
    /// (`−reach`; e.g. deep in a box, near a ball sunk into the box). Nothing tracked: `±reach`.
    fn signed_distance(&self, scene: &ExactScene, p: DVec3, placed: Placement, reach: f64) -> f64 {
        let tracked = self.entries.iter().filter(|e| e.component != u32::MAX);
        if placed == Placement::Outside {
            // Positive for every component: the nearest triangle's distance (its entry alone was
            // kept up to date, the others may be stale).
            return tracked
                .min_by(|a, b| a.d_sq.total_cmp(&b.d_sq).then(a.triangle.cmp(&b.triangle)))
                .map_or(reach, |e| scene.signed_distance_to_triangle(p, e.triangle));
        }
        let interior = placed == Placement::Inside;
        let (mut nearest, mut nearest_open) = (f64::INFINITY, f64::INFINITY);
        for e in tracked {
            let d = scene.signed_distance_to_triangle(p, e.triangle);
            nearest = nearest.min(d);
            if !scene.is_closed(e.component) {
                nearest_open = nearest_open.min(d);
            }
        }
        match (interior, nearest.is_finite()) {
            (false, true) => nearest,
            (false, false) => reach,
            (true, _) if nearest < 0.0 => nearest,
            (true, _) if nearest_open.is_finite() => -nearest_open,
            (true, _) => -reach,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{voxelize_tree, VoxelizeOptions};
    use vps_voxmap::{TreeConfig, VoxelWidth};

    /// Every sample's code against the exact scene's own signed distance
    /// ([`ExactScene::signed_distance`]: a bounding-volume search per point, not the builder's
    /// triangle-driven visit, and inside or out at any depth), on maps whose own kinds say little
    /// of it: 2-bit with the force layer offset 2 voxels outward (Interior outside the surface) and
    /// 4-bit (Surface depth layers deep inside). A box, a ball 15 mm above it and a tube beside
    /// it, at two stand-offs. (Overlapping solids are not compared: where a solid's surface lies
    /// inside another solid, the band holds the distance to that inner surface when the enclosing
    /// solid's surface is beyond the reach, not the union's depth.) Cubes not stored must be uniform far or deep
    /// as the exact distance says at every sample.
    #[test]
    fn every_sample_is_the_exact_signed_distance_quantised() {
        let meshes = box_ball_tube();
        let scene = ExactScene::new(&meshes).unwrap();
        let s = 0.004;
        for width in [VoxelWidth::Two, VoxelWidth::Four] {
            let opts = VoxelizeOptions {
                voxel_size: s,
                width,
                offset_layers: 2,
                ..VoxelizeOptions::default()
            };
            let (tree, _) = voxelize_tree(&meshes, &opts, TreeConfig::default()).unwrap();
            let spec = *tree.spec();
            for standoff in [0.5 * s, 0.125 * s] {
                let band = distance_band(&tree, &meshes, standoff, 1 << 30).unwrap();
                let reach = standoff + (f64::from(BAND_VOXELS) + 1.0 / 128.0) * s;
                let [nx, ny, nz] = band.cube_dims();
                let (mut samples, mut off_by_one) = (0usize, 0usize);
                for c in
                    (0..nz).flat_map(|z| (0..ny).flat_map(move |y| (0..nx).map(move |x| [x, y, z])))
                {
                    let c = c.map(|v| (v * CUBE_EDGE) as i32);
                    let slot = band.slot_of_cell(c);
                    for k in 0..BRICK_CODES {
                        let l = [
                            k % BRICK_EDGE,
                            k / BRICK_EDGE % BRICK_EDGE,
                            k / (BRICK_EDGE * BRICK_EDGE),
                        ];
                        let ijk = glam::IVec3::from_array([0, 1, 2].map(|a| c[a] + l[a] as i32));
                        if (0..3).any(|a| ijk[a] >= spec.dims[a] as i32) {
                            continue;
                        }
                        let p = spec.origin + (ijk.as_dvec3() + DVec3::splat(0.5)) * s;
                        let d = scene.signed_distance(p).distance_m.clamp(-reach, reach);
                        let expected = distance::code_of(d - standoff, s);
                        let code = sample_code(&band, slot, c, k);
                        let gap = (i32::from(code) - i32::from(expected)).abs();
                        assert!(
                            gap <= 1,
                            "{width:?}, stand-off {standoff}: sample {ijk} at {p}: code {code}, \
                             exact {expected} (d {d} m)"
                        );
                        samples += 1;
                        off_by_one += usize::from(gap == 1);
                    }
                }
                assert!(samples > 100_000, "{samples} samples");
                // A code one off: two square roots of the same distance rounded to either side
                // of a code boundary.
                assert!(
                    off_by_one * 10_000 <= samples,
                    "{off_by_one} of {samples} one code off"
                );
            }
        }
    }

    /// The inside map a voxelization keeps is the offset-free 2-bit classification of every
    /// voxel (and Free beyond the grid), whatever the map's own width and offset; the band built
    /// from it is the band built with its own; the tree is the one `voxelize_tree` makes; a map
    /// of another grid is refused. A box, a ball above it, a tube beside it, and a box with one
    /// triangle missing (open: the winding number closes it).
    #[test]
    fn the_kept_inside_map_gives_the_same_band() {
        let mut open = vps_mesh::builtin::by_name("box").unwrap().transformed(
            0.5,
            glam::DQuat::IDENTITY,
            DVec3::new(-0.1, 0.0, 0.0),
        );
        open.triangles.pop();
        let meshes: Vec<TriMesh> = box_ball_tube().into_iter().chain([open]).collect();
        let s = 0.004;
        for (width, offset_layers) in [(VoxelWidth::Two, 2), (VoxelWidth::Four, 1)] {
            let opts = VoxelizeOptions {
                voxel_size: s,
                width,
                offset_layers,
                ..VoxelizeOptions::default()
            };
            let (tree, _, inside) =
                crate::voxelize_tree_keeping_inside(&meshes, &opts, TreeConfig::default()).unwrap();
            let (plain, _) = voxelize_tree(&meshes, &opts, TreeConfig::default()).unwrap();
            assert_eq!(tree.content_hash(), plain.content_hash(), "{width:?}");
            let kinds = placements_against_offset_free(&meshes, &inside, 1);
            assert!(kinds.iter().all(|&k| k > 1000), "{width:?}: {kinds:?}");
            let standoff = 0.5 * s;
            let own = distance_band(&tree, &meshes, standoff, 1 << 30).unwrap();
            let (kept, phases) =
                distance_band_with_inside(&tree, &inside, &meshes, standoff, 1 << 30).unwrap();
            assert_eq!(phases.inside_map_ms, 0.0);
            assert_eq!(kept.directory(), own.directory(), "{width:?}");
            assert_eq!(kept.slot_codes(), own.slot_codes(), "{width:?}");
        }
        // A box wide enough to hold whole chunks of interior (64³ voxels): the map's uniform
        // chunks.
        let big = [vps_mesh::builtin::by_name("box").unwrap().transformed(
            7.0,
            glam::DQuat::IDENTITY,
            DVec3::ZERO,
        )];
        let opts = VoxelizeOptions {
            voxel_size: 0.005,
            offset_layers: 1,
            ..VoxelizeOptions::default()
        };
        let (_, _, inside) =
            crate::voxelize_tree_keeping_inside(&big, &opts, TreeConfig::default()).unwrap();
        let kinds = placements_against_offset_free(&big, &inside, 3);
        assert!(
            kinds[Placement::Inside as usize] > 64 * 64 * 64 / 3,
            "{kinds:?}"
        );
        // A map of another grid.
        let coarse = VoxelizeOptions {
            voxel_size: 2.0 * s,
            ..VoxelizeOptions::default()
        };
        let (_, _, other) =
            crate::voxelize_tree_keeping_inside(&meshes, &coarse, TreeConfig::default()).unwrap();
        let fine = VoxelizeOptions {
            voxel_size: s,
            ..VoxelizeOptions::default()
        };
        let (tree, _) = voxelize_tree(&meshes, &fine, TreeConfig::default()).unwrap();
        assert!(matches!(
            distance_band_with_inside(&tree, &other, &meshes, 0.5 * s, 1 << 30),
            Err(BandBuildError::InsideGrid)
        ));
    }

    /// The phases are parts of the build, none counted twice: each within the whole, the two run
    /// side by side within their joint time, and the serial ones with that joint time within
    /// the build's wall time.
    #[test]
    fn the_build_phases_are_parts_of_the_build() {
        let meshes = [vps_mesh::builtin::by_name("box").unwrap()];
        let opts = VoxelizeOptions {
            voxel_size: 0.004,
            width: VoxelWidth::Four,
            ..VoxelizeOptions::default()
        };
        let (tree, _) = voxelize_tree(&meshes, &opts, TreeConfig::default()).unwrap();
        let started = Instant::now();
        let (band, p) = distance_band_timed(&tree, &meshes, 0.002, 1 << 30).unwrap();
        let wall_ms = started.elapsed().as_secs_f64() * 1e3;
        assert!(band.brick_count() > 0);
        let phases = [
            p.lists_ms,
            p.exact_scene_ms,
            p.inside_map_ms,
            p.scene_and_inside_ms,
            p.samples_ms,
            p.assemble_ms,
        ];
        assert!(phases.iter().all(|&ms| ms > 0.0 && ms <= wall_ms), "{p:?}");
        assert!(
            p.exact_scene_ms.max(p.inside_map_ms) <= p.scene_and_inside_ms,
            "{p:?}"
        );
        let serial = p.lists_ms + p.scene_and_inside_ms + p.samples_ms + p.assemble_ms;
        assert!(serial <= wall_ms, "{p:?}, wall {wall_ms} ms");
    }

    /// A box, a ball 15 mm above it and a tube beside it.
    fn box_ball_tube() -> [TriMesh; 3] {
        let ball = vps_mesh::builtin::uv_sphere(0.03, 24, 12).transformed(
            1.0,
            glam::DQuat::IDENTITY,
            DVec3::new(0.0, 0.0, 0.095),
        );
        let tube = vps_mesh::builtin::cylinder(0.02, 0.04, 24).transformed(
            1.0,
            glam::DQuat::IDENTITY,
            DVec3::new(0.1, 0.0, 0.0),
        );
        [vps_mesh::builtin::by_name("box").unwrap(), ball, tube]
    }

    /// Asserts that `inside` places every voxel of its grid and of one ring beyond it (every
    /// `z_step`-th plane) as a 2-bit map of `meshes` with no offset on that grid does; counts of
    /// the placements, indexed by [`Placement`].
    fn placements_against_offset_free(
        meshes: &[TriMesh],
        inside: &InsideMap,
        z_step: usize,
    ) -> [usize; 3] {
        let spec = *inside.spec();
        let opts = VoxelizeOptions {
            voxel_size: spec.voxel_size,
            width: VoxelWidth::Two,
            offset_layers: 0,
            ..VoxelizeOptions::default()
        };
        let (reference, _) =
            crate::voxelize_tree_in(meshes, spec, &opts, TreeConfig::default()).unwrap();
        let d = spec.dims.map(|v| v as i32);
        let mut kinds = [0usize; 3];
        for z in (-1..=d[2]).step_by(z_step) {
            for y in -1..=d[1] {
                for x in -1..=d[0] {
                    let ijk = glam::IVec3::new(x, y, z);
                    let placed = Placement::of(inside.get(ijk));
                    assert_eq!(placed, Placement::of(reference.get(ijk)), "voxel {ijk}");
                    kinds[placed as usize] += 1;
                }
            }
        }
        kinds
    }

    /// The code of sample `k` (x fastest) of the brick in directory slot `slot` of the cube whose
    /// first voxel is `c`.
    fn sample_code(band: &DistanceBand, slot: u32, c: [i32; 3], k: usize) -> i8 {
        if slot == distance::SLOT_FAR {
            return distance::CODE_FAR;
        }
        if slot == distance::SLOT_DEEP {
            return distance::CODE_DEEP;
        }
        let l = [
            k % BRICK_EDGE,
            k / BRICK_EDGE % BRICK_EDGE,
            k / (BRICK_EDGE * BRICK_EDGE),
        ];
        // The cell whose lower corner is the sample, or (on the apron) the one before it.
        let base = [0, 1, 2].map(|a| c[a] + l[a].min(CUBE_EDGE as usize - 1) as i32);
        let codes = band.cell_codes(slot, base);
        let up = l.map(|v| usize::from(v == CUBE_EDGE as usize));
        codes[up[2]][up[1]][up[0]]
    }
}
