//! The signed-distance band of a voxmap ([`vps_voxmap::distance`]), computed from the exact
//! triangles: the `distance` force model's input.
//!
//! 1. **Cubes to store.** Every 8³ cube whose samples (voxel centres, with the one-sample apron)
//!    could lie within the band's reach of a triangle is marked: each triangle's box grown by the
//!    reach `standoff + 127/64 s` (plus half a voxel) marks the cubes it overlaps.
//! 2. **Samples.** In each marked cube (parallel, rayon), every sample gets the exact distance to
//!    the nearest triangle through the bounding-volume hierarchy of [`vps_reference::ExactScene`],
//!    with its sign: negative inside a closed solid (angle-weighted pseudo-normals), and negative
//!    wherever the voxmap's own classification says Interior (so an open mesh that the flood fill
//!    closed is inside here too). `e = d − standoff` is quantised to `s / 64` and saturated.
//! 3. **Unmarked cubes** lie farther than the reach from every triangle, so they hold no surface:
//!    the voxmap's voxel at the cube's centre says whether the cube is deep inside (Interior) or far
//!    outside.
//!
//! Cost: one exact distance query per stored sample (about 729 per cube near the surface); memory
//! 4 bytes per cube of the grid plus 729 bytes per stored cube, checked against the budget before
//! any sample is computed.

use rayon::prelude::*;
use vps_mesh::TriMesh;
use vps_reference::ExactScene;
use vps_voxmap::distance::{
    self, CubeCodes, DistanceBand, BAND_VOXELS, BRICK_CODES, BRICK_EDGE, CODE_DEEP, CODE_FAR,
    CUBE_EDGE, MAX_STANDOFF_VOXELS,
};
use vps_voxmap::{GridSpec, Voxel, VoxelTree};

/// Largest directory the band builds (cubes): 2^24, as the tree's leaf directory
/// ([`vps_voxmap::DIRECTORY_MAX_BYTES`]).
pub const MAX_BAND_CUBES: u64 = 1 << 24;

/// Why a band could not be built.
#[derive(Debug, thiserror::Error)]
pub enum BandBuildError {
    /// The stand-off is negative, not finite or more than half a voxel.
    #[error("standoff {standoff_m} m: must be within 0..={max_m} m (half the voxel size {voxel_size} m); for a larger margin use a larger voxel_size")]
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
        /// Cubes to store.
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
/// `0..=` half a voxel) baked in, within `max_memory_bytes`. Blocking, parallel (rayon),
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
    let reach = standoff_m + f64::from(BAND_VOXELS) * s + 0.5 * s;
    let marked = mark_cubes(&spec, cube_dims, meshes, reach);
    let bricks = marked.iter().filter(|&&m| m).count() as u64;
    let bytes = 4 * cubes + bricks * BRICK_CODES as u64;
    if bytes > max_memory_bytes {
        return Err(BandBuildError::OverBudget {
            bytes,
            bricks,
            budget: max_memory_bytes,
        });
    }
    let scene = ExactScene::new(meshes)?;
    let [nx, ny, _] = cube_dims;
    let index = |c: [u32; 3]| (c[2] as usize * ny as usize + c[1] as usize) * nx as usize + c[0] as usize;
    let stored: Vec<(usize, CubeCodes)> = marked
        .par_iter()
        .enumerate()
        .filter(|(_, &m)| m)
        .map(|(i, _)| {
            let c = [
                (i % nx as usize) as u32,
                (i / nx as usize % ny as usize) as u32,
                (i / (nx as usize * ny as usize)) as u32,
            ];
            (i, sample_cube(tree, &scene, c, standoff_m, reach))
        })
        .collect();
    let mut stored = stored.into_iter().peekable();
    Ok(distance::assemble(&spec, standoff_m, |c| {
        let i = index(c);
        if stored.peek().is_some_and(|(j, _)| *j == i) {
            return stored.next().map(|(_, codes)| codes).unwrap_or(CubeCodes::Far);
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

/// Cubes whose samples (apron included) may lie within `reach` (m) of a triangle.
fn mark_cubes(spec: &GridSpec, cube_dims: [u32; 3], meshes: &[TriMesh], reach: f64) -> Vec<bool> {
    let [nx, ny, nz] = cube_dims;
    let mut marked = vec![false; nx as usize * ny as usize * nz as usize];
    let edge = f64::from(CUBE_EDGE);
    for mesh in meshes {
        for t in &mesh.triangles {
            let Some(v) = t
                .iter()
                .map(|&i| mesh.vertices.get(i as usize).copied())
                .collect::<Option<Vec<_>>>()
            else {
                continue;
            };
            let lo = v[0].min(v[1]).min(v[2]) - glam::DVec3::splat(reach);
            let hi = v[0].max(v[1]).max(v[2]) + glam::DVec3::splat(reach);
            // Sample index range (sample i at (i + 0.5) s), then the cubes holding those samples
            // as their own or as the apron of the cube before.
            let range = |a: usize| {
                let to = |x: f64| (x - spec.origin[a]) / spec.voxel_size - 0.5;
                let first = to(lo[a]).ceil();
                let last = to(hi[a]).floor();
                let c0 = ((first - 1.0) / edge).floor().max(0.0);
                let c1 = (last / edge).floor().min(f64::from(cube_dims[a]) - 1.0);
                (c0 as i64, c1 as i64)
            };
            let (x0, x1) = range(0);
            let (y0, y1) = range(1);
            let (z0, z1) = range(2);
            for z in z0..=z1 {
                for y in y0..=y1 {
                    for x in x0..=x1 {
                        marked[(z as usize * ny as usize + y as usize) * nx as usize + x as usize] =
                            true;
                    }
                }
            }
        }
    }
    marked
}

/// The 729 codes of cube `c`, or its uniform kind when every code saturates the same way.
fn sample_cube(
    tree: &VoxelTree,
    scene: &ExactScene,
    c: [u32; 3],
    standoff_m: f64,
    reach: f64,
) -> CubeCodes {
    let spec = tree.spec();
    let s = spec.voxel_size;
    let mut codes = Box::new([0i8; BRICK_CODES]);
    let (mut far, mut deep) = (true, true);
    for z in 0..BRICK_EDGE {
        for y in 0..BRICK_EDGE {
            for x in 0..BRICK_EDGE {
                let ijk = glam::IVec3::new(
                    (c[0] * CUBE_EDGE) as i32 + x as i32,
                    (c[1] * CUBE_EDGE) as i32 + y as i32,
                    (c[2] * CUBE_EDGE) as i32 + z as i32,
                );
                let p = spec.origin + (ijk.as_dvec3() + glam::DVec3::splat(0.5)) * s;
                let interior = tree.get(ijk) == Voxel::Interior;
                let d = match scene.signed_distance_within(p, reach) {
                    Some(sd) if interior => -sd.distance_m.abs(),
                    Some(sd) => sd.distance_m,
                    None if interior => -reach,
                    None => reach,
                };
                let code = distance::code_of(d - standoff_m, s);
                far &= code == CODE_FAR;
                deep &= code == CODE_DEEP;
                codes[(z * BRICK_EDGE + y) * BRICK_EDGE + x] = code;
            }
        }
    }
    if far {
        CubeCodes::Far
    } else if deep {
        CubeCodes::Deep
    } else {
        CubeCodes::Brick(codes)
    }
}
