//! The `distance` force model's block loop: each point is sampled against the map's
//! signed-distance band ([`vps_voxmap::distance`]) instead of its voxel kinds.
//!
//! Per point `P` (grid coordinates `g`): the band's trilinear cell around `g` gives
//! `e = d − standoff` (voxels; `d` the signed distance to the scene's exact surface, the stand-off
//! baked into the band) and its gradient, whose direction `n` is the scene's outward normal.
//! - `e < 0`: a contact; pushes with depth `−e · s` along `n` (counted as Surface).
//! - deeper than the band (every corner saturated deep, or a cube stored as deep): pushes with the
//!   band's depth ([`vps_voxmap::distance::BAND_VOXELS`] voxels) along the point's own normal `N`
//!   (no scene normal is stored there; counted as Interior).
//! - `0 ≤ e < 1` voxel and approaching (`V·n < 0`): adds to the braking sums with `n` in place of
//!   the tangent-plane model's `N`.
//! - otherwise (far): nothing.
//!
//! A gradient shorter than [`MIN_GRADIENT`] (a cell whose corners are nearly equal, e.g. on a
//! medial surface inside a thin wall) has no direction of its own: the point's normal `N` is used.
//!
//! The same fixed point and the same accumulator as the tangent-plane loop (module docs of
//! `kernel`): each contribution is computed in f32 with basic IEEE operations in a fixed order and
//! rounded to the sums' LSB at once, so any split of the shell gives the same sums bit for bit.
//! Portable lane code only (no AVX copy yet). No allocation, no locks, no I/O.

use super::{add3_fixed, brake_block, load, ClassAccumulator, GridFrame, Soa, CHUNK_BLOCKS};
use crate::lanes::{cross, floor_i32, mat_vec, scale, scale_add, F32s, Vec3s, LANES};
use crate::sums::PartialSums;
use vps_voxmap::distance::{CellLookup, DistanceBand, BAND_VOXELS};

/// Shortest gradient (per voxel, 1 for an exact distance field) whose direction is trusted; below
/// it the point's own normal is used.
pub(crate) const MIN_GRADIENT: f32 = 0.25;

/// Braking range beyond the stand-off (voxels): the band's counterpart of a Proximity voxel.
const BRAKE_RANGE_VOXELS: f32 = 1.0;

/// Adds the sums of one class's points against `band` to `sums`.
pub(super) fn accumulate(
    band: &DistanceBand,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    if frame.needs_clamp {
        accumulate_lanes::<true>(band, frame, points, normals, sums)
    } else {
        accumulate_lanes::<false>(band, frame, points, normals, sums)
    }
}

fn accumulate_lanes<const CLAMP: bool>(
    band: &DistanceBand,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    let mut acc = ClassAccumulator::default();
    let n = points
        .iter()
        .chain(normals.iter())
        .map(|a| a.len())
        .min()
        .unwrap_or(0);
    let chunk = CHUNK_BLOCKS * LANES;
    let mut begin = 0;
    while begin < n {
        let end = (begin + chunk).min(n);
        for start in (begin..end).step_by(LANES) {
            let valid = (end - start).min(LANES);
            sample_block::<CLAMP>(band, frame, points, normals, start, valid, &mut acc);
        }
        acc.flush(sums);
        begin = end;
    }
    acc.finish_into(sums);
}

/// What one lane found in the band.
#[derive(Clone, Copy, PartialEq)]
enum Found {
    Far,
    Deep,
    /// `e` (voxels) and the gradient.
    Near(f32, [f32; 3]),
}

#[inline(always)]
fn sample_block<const CLAMP: bool>(
    band: &DistanceBand,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    start: usize,
    valid: usize,
    acc: &mut ClassAccumulator,
) {
    let lever = mat_vec(&frame.rotation_lever, &load(points, start, valid));
    let grid = scale_add(&lever, frame.inv_voxel_lever, frame.translation_grid);
    // Samples sit at voxel centres: the cell's lower corner is floor(g − 1/2).
    let mut t = [[0.0f32; LANES]; 3];
    for a in 0..3 {
        for l in 0..LANES {
            t[a][l] = grid[a][l] - 0.5;
        }
    }
    let base = [floor_i32(&t[0]), floor_i32(&t[1]), floor_i32(&t[2])];
    let mut found = [Found::Far; LANES];
    let mut any = false;
    for (l, slot) in found.iter_mut().enumerate().take(valid) {
        let b = [base[0][l], base[1][l], base[2][l]];
        *slot = match band.cell(b) {
            CellLookup::Far => continue,
            CellLookup::Deep => Found::Deep,
            CellLookup::Near(cell) => {
                if cell.all_far() {
                    continue;
                }
                if cell.all_deep() {
                    Found::Deep
                } else {
                    let f = [0, 1, 2].map(|a| t[a][l] - b[a] as f32);
                    let (e, g) = cell.value_and_gradient(f);
                    if e >= BAND_VOXELS {
                        continue;
                    }
                    Found::Near(e, g)
                }
            }
        };
        any = true;
    }
    if !any {
        return;
    }
    let part_normal = mat_vec(&frame.rotation, &load(normals, start, valid));
    // Per lane: the push direction and depth (2^-40 m), and the braking lanes.
    let mut direction: Vec3s = [[0.0; LANES]; 3];
    let mut depth: F32s = [0.0; LANES];
    let mut braking = [false; LANES];
    let mut pushing = false;
    for l in 0..LANES {
        let own = [part_normal[0][l], part_normal[1][l], part_normal[2][l]];
        let (dir, d) = match found[l] {
            Found::Far => continue,
            Found::Deep => {
                acc.non_free += 1;
                acc.interior += 1;
                (own, BAND_VOXELS)
            }
            Found::Near(e, g) => {
                acc.non_free += 1;
                let dir = scene_normal(g).unwrap_or(own);
                if e < 0.0 {
                    acc.surface += 1;
                    (dir, -e)
                } else {
                    braking[l] = e < BRAKE_RANGE_VOXELS;
                    (dir, 0.0)
                }
            }
        };
        for a in 0..3 {
            direction[a][l] = dir[a];
        }
        depth[l] = d * frame.voxel_q;
        pushing |= d > 0.0;
    }
    if pushing {
        acc.contacts += depth.iter().filter(|&&d| d > 0.0).count() as u64;
        let force_dir = scale(&direction, &depth);
        add3_fixed::<CLAMP>(&mut acc.depth_normal, &force_dir);
        add3_fixed::<CLAMP>(&mut acc.depth_torque, &cross(&lever, &force_dir));
        acc.depth_blocks += 1;
    }
    if braking.iter().any(|&b| b) {
        brake_block::<CLAMP>(frame, &lever, &direction, &braking, acc);
    }
}

/// The unit direction of gradient `g`, or `None` when it is shorter than [`MIN_GRADIENT`].
#[inline(always)]
fn scene_normal(g: [f32; 3]) -> Option<[f32; 3]> {
    let len_sq = (g[0] * g[0] + g[1] * g[1]) + g[2] * g[2];
    if len_sq >= MIN_GRADIENT * MIN_GRADIENT {
        let inv = 1.0 / len_sq.sqrt();
        Some([g[0] * inv, g[1] * inv, g[2] * inv])
    } else {
        None
    }
}
