//! The `distance` force model's block loop: each point is sampled against the map's
//! signed-distance band ([`vps_voxmap::distance`]) instead of its voxel kinds.
//!
//! Per point `P` (grid coordinates `g`): the band's trilinear cell around `g` gives
//! `e = d − standoff` (voxels; `d` the signed distance to the scene's exact surface, the stand-off
//! baked into the band) and its gradient, whose direction `n` is the scene's outward normal.
//! - `e < 0`: a contact; pushes with depth `−e · s` along `n` (counted as Surface, or as Interior
//!   when `d < 0`, i.e. the point is inside the exact surface: `e < −standoff`).
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
//! Portable lane code, compiled a second time with AVX2 enabled where the CPU has it (the same
//! operations, so the same bits). No allocation, no locks, no I/O.

use super::{add3_fixed, brake_block, load, ClassAccumulator, GridFrame, Soa, CHUNK_BLOCKS};
use crate::lanes::{cross, floor_i32, mat_vec, scale, scale_add, F32s, Vec3s, LANES};
use crate::sums::PartialSums;
use vps_voxmap::distance::{
    DistanceBand, BAND_VOXELS, CODES_PER_VOXEL, CODE_DEEP, CODE_FAR, SLOT_DEEP, SLOT_FAR,
};

/// Shortest gradient (per voxel, 1 for an exact distance field) whose direction is trusted; below
/// it the point's own normal is used.
pub(crate) const MIN_GRADIENT: f32 = 0.25;

/// Braking range beyond the stand-off (voxels): the band's counterpart of a Proximity voxel.
const BRAKE_RANGE_VOXELS: f32 = 1.0;

/// Adds the sums of one class's points against `band` to `sums`.
pub(super) fn accumulate(
    band: &DistanceBand,
    standoff_voxels: f32,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { accumulate_avx2(band, standoff_voxels, frame, points, normals, sums) };
    }
    accumulate_any(band, standoff_voxels, frame, points, normals, sums)
}

/// [`accumulate_any`] compiled with AVX2 enabled (wider lane loops; the same IEEE operations, so
/// the same bits).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2(
    band: &DistanceBand,
    standoff_voxels: f32,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    accumulate_any(band, standoff_voxels, frame, points, normals, sums)
}

#[inline(always)]
fn accumulate_any(
    band: &DistanceBand,
    standoff_voxels: f32,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    if frame.needs_clamp {
        accumulate_lanes::<true>(band, standoff_voxels, frame, points, normals, sums)
    } else {
        accumulate_lanes::<false>(band, standoff_voxels, frame, points, normals, sums)
    }
}

#[inline(always)]
fn accumulate_lanes<const CLAMP: bool>(
    band: &DistanceBand,
    standoff_voxels: f32,
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
    // Full blocks with the block length a constant (so that loading a block is a fixed-size
    // copy), flushed every chunk; then the zero-padded tail block.
    let full = n - n % LANES;
    let chunk = CHUNK_BLOCKS * LANES;
    let mut begin = 0;
    while begin < full {
        let end = (begin + chunk).min(full);
        for start in (begin..end).step_by(LANES) {
            sample_block::<CLAMP>(
                band,
                standoff_voxels,
                frame,
                points,
                normals,
                start,
                LANES,
                &mut acc,
            );
        }
        acc.flush(sums);
        begin = end;
    }
    if full < n {
        sample_block::<CLAMP>(
            band,
            standoff_voxels,
            frame,
            points,
            normals,
            full,
            n - full,
            &mut acc,
        );
    }
    acc.finish_into(sums);
}

/// Codes of one trilinear cell per lane: `corners[z][y][x][lane]`.
type Corners = [[[F32s; 2]; 2]; 2];

/// One block of `valid ≤ LANES` points: transform, cell lookup per lane, then the band arithmetic
/// for all lanes at once (lane loops the compiler vectorises; lanes outside the band masked to
/// zero by selection, never by multiplication, so a non-finite value in a masked lane cannot
/// reach the sums).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sample_block<const CLAMP: bool>(
    band: &DistanceBand,
    standoff_voxels: f32,
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
    // The directory slot of each lane's cube (lanes past `valid` and outside the grid: far):
    // cube indices and the range test as lane arithmetic, then one load per lane in range.
    let [nx, ny, nz] = band.cube_dims();
    let mut index = [0u32; LANES];
    let mut inside = [false; LANES];
    for l in 0..LANES {
        let c = [base[0][l] >> 3, base[1][l] >> 3, base[2][l] >> 3];
        inside[l] = l < valid && (c[0] as u32) < nx && (c[1] as u32) < ny && (c[2] as u32) < nz;
        index[l] = ((c[2] as u32).wrapping_mul(ny).wrapping_add(c[1] as u32))
            .wrapping_mul(nx)
            .wrapping_add(c[0] as u32);
    }
    if !inside.iter().any(|&i| i) {
        return;
    }
    let directory = band.directory();
    let slots: [u32; LANES] = std::array::from_fn(|l| {
        if inside[l] {
            directory
                .get(index[l] as usize)
                .copied()
                .unwrap_or(SLOT_FAR)
        } else {
            SLOT_FAR
        }
    });
    if slots.iter().all(|&s| s == SLOT_FAR) {
        return;
    }
    let mut corners: Corners = [[[[f32::from(CODE_FAR); LANES]; 2]; 2]; 2];
    let mut deep_slot = [false; LANES];
    for l in 0..LANES {
        match slots[l] {
            SLOT_FAR => {}
            SLOT_DEEP => deep_slot[l] = true,
            slot => {
                let codes = band.cell_codes(slot, [base[0][l], base[1][l], base[2][l]]);
                for (z, plane) in codes.iter().enumerate() {
                    for (y, row) in plane.iter().enumerate() {
                        for (x, &c) in row.iter().enumerate() {
                            corners[z][y][x][l] = f32::from(c);
                        }
                    }
                }
            }
        }
    }
    let mut f = [[0.0f32; LANES]; 3];
    for a in 0..3 {
        for l in 0..LANES {
            f[a][l] = t[a][l] - base[a][l] as f32;
        }
    }
    let (e, gradient) = value_and_gradient(&corners, &f);
    let far_code = f32::from(CODE_FAR);
    let deep_code = f32::from(CODE_DEEP);
    let part_normal = mat_vec(&frame.rotation, &load(normals, start, valid));
    let mut direction: Vec3s = [[0.0; LANES]; 3];
    let mut depth: F32s = [0.0; LANES];
    let mut braking = [false; LANES];
    let (mut surface, mut interior, mut near) = (0u64, 0u64, 0u64);
    for l in 0..LANES {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for plane in &corners {
            for row in plane {
                for corner in row {
                    lo = lo.min(corner[l]);
                    hi = hi.max(corner[l]);
                }
            }
        }
        let deep = deep_slot[l] || hi <= deep_code;
        let in_band = !deep && lo < far_code && e[l] < BAND_VOXELS;
        let len_sq = (gradient[0][l] * gradient[0][l] + gradient[1][l] * gradient[1][l])
            + gradient[2][l] * gradient[2][l];
        let trusted = len_sq >= MIN_GRADIENT * MIN_GRADIENT;
        let inv = 1.0 / len_sq.sqrt();
        let contact = in_band && e[l] < 0.0;
        braking[l] = in_band && e[l] >= 0.0 && e[l] < BRAKE_RANGE_VOXELS;
        let own = !trusted || deep;
        for a in 0..3 {
            let scene = gradient[a][l] * inv;
            let d = if own { part_normal[a][l] } else { scene };
            direction[a][l] = if contact || braking[l] || deep {
                d
            } else {
                0.0
            };
        }
        depth[l] = if contact {
            -e[l] * frame.voxel_q
        } else if deep {
            BAND_VOXELS * frame.voxel_q
        } else {
            0.0
        };
        // Inside the exact surface (d < 0) counts as Interior, as a point in an Interior voxel
        // does for the tangent-plane model: the session's "penetrating".
        let inside = contact && e[l] < -standoff_voxels;
        surface += u64::from(contact && !inside);
        interior += u64::from(deep || inside);
        near += u64::from(in_band || deep);
    }
    acc.surface += surface;
    acc.interior += interior;
    acc.non_free += near;
    if surface + interior > 0 {
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

/// `e` (voxels) and its gradient per lane: the trilinear interpolation of
/// [`vps_voxmap::distance::BandCell::value_and_gradient`], lane by lane, with the same operations
/// in the same order.
#[inline(always)]
fn value_and_gradient(c: &Corners, f: &Vec3s) -> (F32s, Vec3s) {
    let mut value = [0.0; LANES];
    let mut gradient = [[0.0; LANES]; 3];
    let q = 1.0 / CODES_PER_VOXEL;
    for l in 0..LANES {
        let (fx, fy, fz) = (f[0][l], f[1][l], f[2][l]);
        let (gx, gy, gz) = (1.0 - fx, 1.0 - fy, 1.0 - fz);
        let x00 = c[0][0][0][l] * gx + c[0][0][1][l] * fx;
        let x10 = c[0][1][0][l] * gx + c[0][1][1][l] * fx;
        let x01 = c[1][0][0][l] * gx + c[1][0][1][l] * fx;
        let x11 = c[1][1][0][l] * gx + c[1][1][1][l] * fx;
        let y0 = x00 * gy + x10 * fy;
        let y1 = x01 * gy + x11 * fy;
        value[l] = (y0 * gz + y1 * fz) * q;
        let d00 = c[0][0][1][l] - c[0][0][0][l];
        let d10 = c[0][1][1][l] - c[0][1][0][l];
        let d01 = c[1][0][1][l] - c[1][0][0][l];
        let d11 = c[1][1][1][l] - c[1][1][0][l];
        gradient[0][l] = ((d00 * gy + d10 * fy) * gz + (d01 * gy + d11 * fy) * fz) * q;
        gradient[1][l] = ((x10 - x00) * gz + (x11 - x01) * fz) * q;
        gradient[2][l] = (y1 - y0) * q;
    }
    (value, gradient)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use vps_voxmap::distance::BandCell;

    /// The lane form of the trilinear value and gradient gives the bits of the scalar form that
    /// `vps inspect`, the tests and `DistanceBand::standoff_distance_at` use, for every lane.
    #[test]
    fn the_lane_interpolation_is_the_scalar_one_bit_for_bit() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        for _ in 0..1000 {
            let mut corners: Corners = [[[[0.0; LANES]; 2]; 2]; 2];
            let mut f: Vec3s = [[0.0; LANES]; 3];
            for plane in &mut corners {
                for row in plane.iter_mut() {
                    for corner in row.iter_mut() {
                        for c in corner.iter_mut() {
                            *c = f32::from(rng.gen_range(-127i8..=127));
                        }
                    }
                }
            }
            for axis in &mut f {
                for x in axis.iter_mut() {
                    *x = rng.gen::<f32>();
                }
            }
            let (value, gradient) = value_and_gradient(&corners, &f);
            for l in 0..LANES {
                let cell = BandCell {
                    corners: corners.map(|plane| plane.map(|row| row.map(|c| c[l]))),
                };
                let (v, g) = cell.value_and_gradient([f[0][l], f[1][l], f[2][l]]);
                assert_eq!(v.to_bits(), value[l].to_bits());
                for a in 0..3 {
                    assert_eq!(g[a].to_bits(), gradient[a][l].to_bits());
                }
            }
        }
    }
}
