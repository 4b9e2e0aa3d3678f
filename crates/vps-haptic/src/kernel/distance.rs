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
//! Portable lane code; where the CPU has AVX2, full blocks go through [`avx2::sample_blocks`]
//! (one gather of the directory slots and four of the codes per block, the arithmetic in 256-bit
//! registers), and where it also has AVX-512F, AVX-512DQ and POPCNT, blocks of 16 through
//! `avx512::sample_blocks` (the same on sixteen lanes): the same operations in the same order, so
//! the same bits, which a unit test checks. Both run their blocks in batches, software-pipelined:
//! the next batch's directory slots are gathered before this batch's arithmetic and its codes
//! after, so that the reads overlap other work (docs/kernel.md, "The distance model's kernel").
//! No allocation, no locks, no I/O.

#[cfg(target_arch = "x86_64")]
use super::avx512::WIDE_LANES;
use super::{
    add3_fixed, brake_block, load, place, ClassAccumulator, GridFrame, Soa, Widest, CHUNK_BLOCKS,
};
use crate::lanes::{cross, floor_i32, mat_vec, scale, F32s, Vec3s, LANES};
use crate::sums::PartialSums;
use vps_voxmap::distance::{
    DistanceBand, BAND_VOXELS, CODES_PER_VOXEL, CODE_DEEP, CODE_FAR, SLOT_FAR,
};

/// `lerp` and `value_and_gradient` of one SIMD copy of the block, written once for both widths
/// (`__m256` in [`avx2`], `__m512` in `avx512`): the trilinear value and gradient of
/// [`value_and_gradient`] with the same IEEE operations in the same order (two products, then the
/// sum: no fused multiply-add), so every copy gives the same bits. Arguments: the target feature,
/// the f32 vector type, and the broadcast, add, subtract and multiply intrinsics.
#[cfg(target_arch = "x86_64")]
macro_rules! trilinear_ops {
    ($feature:literal, $f:ty, $set1:ident, $add:ident, $sub:ident, $mul:ident) => {
        /// `a · wa + b · wb` per lane (two products, then the sum: no fused multiply-add).
        #[inline]
        #[target_feature(enable = $feature)]
        fn lerp(a: $f, wa: $f, b: $f, wb: $f) -> $f {
            $add($mul(a, wa), $mul(b, wb))
        }

        /// `super::value_and_gradient` in vector registers; `c[z][y][x]` the corner codes.
        #[inline]
        #[target_feature(enable = $feature)]
        fn value_and_gradient(c: &[[[$f; 2]; 2]; 2], f: &[$f; 3]) -> ($f, [$f; 3]) {
            let one = $set1(1.0);
            let (fx, fy, fz) = (f[0], f[1], f[2]);
            let (gx, gy, gz) = ($sub(one, fx), $sub(one, fy), $sub(one, fz));
            let x00 = lerp(c[0][0][0], gx, c[0][0][1], fx);
            let x10 = lerp(c[0][1][0], gx, c[0][1][1], fx);
            let x01 = lerp(c[1][0][0], gx, c[1][0][1], fx);
            let x11 = lerp(c[1][1][0], gx, c[1][1][1], fx);
            let y0 = lerp(x00, gy, x10, fy);
            let y1 = lerp(x01, gy, x11, fy);
            let q = $set1(1.0 / CODES_PER_VOXEL);
            let value = $mul(lerp(y0, gz, y1, fz), q);
            let d00 = $sub(c[0][0][1], c[0][0][0]);
            let d10 = $sub(c[0][1][1], c[0][1][0]);
            let d01 = $sub(c[1][0][1], c[1][0][0]);
            let d11 = $sub(c[1][1][1], c[1][1][0]);
            let dx = lerp(lerp(d00, gy, d10, fy), gz, lerp(d01, gy, d11, fy), fz);
            let dy = lerp($sub(x10, x00), gz, $sub(x11, x01), fz);
            let dz = $sub(y1, y0);
            (value, [$mul(dx, q), $mul(dy, q), $mul(dz, q)])
        }
    };
}

#[cfg(target_arch = "x86_64")]
mod avx512;

/// Shortest gradient (per voxel, 1 for an exact distance field) whose direction is trusted; below
/// it the point's own normal is used.
pub(crate) const MIN_GRADIENT: f32 = 0.25;

/// Braking range beyond the stand-off (voxels): the band's counterpart of a Proximity voxel.
const BRAKE_RANGE_VOXELS: f32 = 1.0;

/// One class sampled against a band: the per-call inputs of the block loop, the same for every
/// block of the class.
#[derive(Clone, Copy)]
pub(super) struct BandClass<'a> {
    /// The map's signed-distance band.
    pub(super) band: &'a DistanceBand,
    /// The band's stand-off (voxels; baked into its codes): `e < −standoff_voxels` is inside the
    /// exact surface.
    pub(super) standoff_voxels: f32,
    /// The pose prepared for the grid.
    pub(super) frame: &'a GridFrame,
    /// The class's body-frame points; the shortest of the six arrays bounds the class.
    pub(super) points: Soa<'a>,
    /// The class's body-frame normals.
    pub(super) normals: Soa<'a>,
}

/// Adds the sums of `class`'s points against its band to `sums`, on the widest copy of the block
/// loop up to `widest` that the CPU runs (the same bits on each).
pub(super) fn accumulate(class: BandClass, sums: &mut PartialSums, widest: Widest) {
    #[cfg(target_arch = "x86_64")]
    if avx2::fits_lanes(class.band) {
        let BandClass {
            band,
            standoff_voxels,
            frame,
            points,
            normals,
        } = class;
        if widest == Widest::Avx512 && super::cpu_has_avx512() {
            // SAFETY: the CPU supports AVX2, AVX-512F, AVX-512DQ and POPCNT, and the band's
            // indices fit 32-bit lanes (both checked just above).
            return unsafe {
                accumulate_avx512(band, standoff_voxels, frame, points, normals, sums)
            };
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports AVX2 and the band's indices fit 32-bit lanes (checked
            // just above).
            return unsafe { accumulate_avx2(band, standoff_voxels, frame, points, normals, sums) };
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = widest;
    accumulate_any::<false, false>(class, sums)
}

/// [`accumulate_any`] compiled with AVX2 enabled, full blocks through [`avx2::sample_blocks`].
/// The class comes as separate arguments, so that LLVM knows the frame and the band alias nothing
/// the loop writes: read through references held in a [`BandClass`] in memory, they were read
/// again for every block (`kernel_ir` example, `distance-free` mode: 33 % more instructions).
///
/// # Safety
/// The CPU must support AVX2 and [`avx2::fits_lanes`] must hold for `band`.
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
    let class = BandClass {
        band,
        standoff_voxels,
        frame,
        points,
        normals,
    };
    accumulate_any::<true, false>(class, sums)
}

/// The AVX-512 copy: [`accumulate_avx2`] with full blocks of 16 points through
/// [`avx512::sample_blocks`] (a last block of 8 through the AVX2 one). The same bits.
///
/// # Safety
/// The CPU must support AVX2, AVX-512F, AVX-512DQ and POPCNT, and [`avx2::fits_lanes`] must hold
/// for `band`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512dq,popcnt")]
unsafe fn accumulate_avx512(
    band: &DistanceBand,
    standoff_voxels: f32,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    let class = BandClass {
        band,
        standoff_voxels,
        frame,
        points,
        normals,
    };
    accumulate_any::<true, true>(class, sums)
}

/// `AVX2`: full blocks through [`avx2::sample_blocks`] (only from [`accumulate_avx2`] and
/// [`accumulate_avx512`]); `AVX512`: full blocks of 16 through [`avx512::sample_blocks`] first
/// (only from [`accumulate_avx512`]).
#[inline(always)]
fn accumulate_any<const AVX2: bool, const AVX512: bool>(class: BandClass, sums: &mut PartialSums) {
    if class.frame.needs_clamp {
        accumulate_lanes::<true, AVX2, AVX512>(class, sums)
    } else {
        accumulate_lanes::<false, AVX2, AVX512>(class, sums)
    }
}

#[inline(always)]
fn accumulate_lanes<const CLAMP: bool, const AVX2: bool, const AVX512: bool>(
    class: BandClass,
    sums: &mut PartialSums,
) {
    let mut acc = ClassAccumulator::default();
    let n = class
        .points
        .iter()
        .chain(class.normals.iter())
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
        #[cfg(target_arch = "x86_64")]
        if AVX2 {
            let mut begin_8 = begin;
            if AVX512 {
                let wide_end = begin + (end - begin) / WIDE_LANES * WIDE_LANES;
                // SAFETY: `AVX512` is only set by `accumulate_avx512` (the CPU has AVX-512F and
                // DQ, the band passed `fits_lanes`); `wide_end ≤ end ≤ n`, the shortest array.
                unsafe { avx512::sample_blocks::<CLAMP>(&class, begin, wide_end, &mut acc) };
                begin_8 = wide_end;
            }
            // SAFETY: `AVX2` is only set by `accumulate_avx2` and `accumulate_avx512` (the CPU
            // has AVX2, the band passed `fits_lanes`); `end ≤ full ≤ n`, the shortest array, and
            // `end − begin_8` is a multiple of `LANES`.
            unsafe { avx2::sample_blocks::<CLAMP>(&class, begin_8, end, &mut acc) };
            acc.flush(sums);
            begin = end;
            continue;
        }
        for start in (begin..end).step_by(LANES) {
            sample_block::<CLAMP>(&class, start, LANES, &mut acc);
        }
        acc.flush(sums);
        begin = end;
    }
    if full < n {
        sample_block::<CLAMP>(&class, full, n - full, &mut acc);
    }
    acc.finish_into(sums);
}

/// Codes of one trilinear cell per lane: `corners[z][y][x][lane]`.
type Corners = [[[F32s; 2]; 2]; 2];

/// One block of `valid ≤ LANES` points: transform, cell lookup per lane, then the band arithmetic
/// for all lanes at once (lane loops the compiler vectorises; lanes outside the band masked to
/// zero by selection, never by multiplication, so a non-finite value in a masked lane cannot
/// reach the sums).
#[inline(always)]
fn sample_block<const CLAMP: bool>(
    class: &BandClass,
    start: usize,
    valid: usize,
    acc: &mut ClassAccumulator,
) {
    let (lever, grid) = place(class.frame, class.points, start, valid);
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
    let [nx, ny, nz] = class.band.cube_dims();
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
    let directory = class.band.directory();
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
    // Every slot names a brick in memory (far and deep slots their constant bricks), so far and
    // deep lanes read codes like any other and need no case of their own.
    let mut corners: Corners = [[[[f32::from(CODE_FAR); LANES]; 2]; 2]; 2];
    for l in 0..LANES {
        if slots[l] != SLOT_FAR {
            let codes = class
                .band
                .cell_codes(slots[l], [base[0][l], base[1][l], base[2][l]]);
            for (z, plane) in codes.iter().enumerate() {
                for (y, row) in plane.iter().enumerate() {
                    for (x, &c) in row.iter().enumerate() {
                        corners[z][y][x][l] = f32::from(c);
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
    let part_normal = mat_vec(&class.frame.rotation, &load(class.normals, start, valid));
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
        // A deep slot's constant brick reads all CODE_DEEP.
        let deep = hi <= deep_code;
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
            -e[l] * class.frame.voxel_q
        } else if deep {
            BAND_VOXELS * class.frame.voxel_q
        } else {
            0.0
        };
        // Inside the exact surface (d < 0) counts as Interior, as a point in an Interior voxel
        // does for the tangent-plane model: the session's "penetrating".
        let inside = contact && e[l] < -class.standoff_voxels;
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
        brake_block::<CLAMP>(class.frame, &lever, &direction, &braking, acc);
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

/// The full-block path of the AVX2 copy, written with AVX2 intrinsics: the cell's eight codes come
/// from four gathers of 4 bytes per lane (each reads a corner and its +x neighbour, adjacent in the
/// brick) after one gather of the directory slots, and every lane goes through the same instructions
/// (far and deep lanes read their constant bricks, out-of-grid lanes the far one). Each operation
/// is the portable [`super::sample_block`]'s (same operands, same order, no fused multiply-add), so a
/// block gives the same bits either way (a unit test checks it).
#[cfg(target_arch = "x86_64")]
pub(super) mod avx2 {
    use super::super::avx2::{
        add3_fixed, brake_lanes, count_positive, cross, dot, load, mat_vec, scale, V3,
    };
    use super::super::ClassAccumulator;
    use super::{BandClass, BRAKE_RANGE_VOXELS, LANES, MIN_GRADIENT};
    use std::arch::x86_64::*;
    use std::mem::MaybeUninit;
    use vps_voxmap::distance::{
        DistanceBand, BAND_VOXELS, BRICK_CODES, BRICK_EDGE, CODES_PER_VOXEL, CODE_DEEP, CODE_FAR,
    };

    /// Whether the lane arithmetic can address `band`: every directory index and every byte
    /// offset of its codes fits an `i32`, and the grid has at least one cube per axis.
    pub(in crate::kernel) fn fits_lanes(band: &DistanceBand) -> bool {
        let limit = i32::MAX as usize;
        band.directory().len() <= limit
            && band.slot_codes().len() <= limit
            && band.cube_dims().iter().all(|&d| d > 0)
    }

    /// One byte of each 32-bit lane as a signed code, converted to f32 (exact): `LEFT` = 24 gives
    /// the lowest byte, 16 the next.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn code<const LEFT: i32>(v: __m256i) -> __m256 {
        _mm256_cvtepi32_ps(_mm256_srai_epi32::<24>(_mm256_slli_epi32::<LEFT>(v)))
    }

    /// The 4 bytes at `bytes + at` per lane (a corner's code and its +x neighbour's in the lowest
    /// two).
    ///
    /// # Safety
    /// Every lane's 4 bytes must be within the allocation `bytes` points into.
    #[inline]
    #[target_feature(enable = "avx2")]
    unsafe fn code_row(bytes: *const i8, at: __m256i) -> __m256i {
        // SAFETY: the caller's.
        unsafe { _mm256_i32gather_epi32::<1>(bytes.cast(), at) }
    }

    /// `a < b` per lane as an all-ones mask (ordered: false where either is NaN).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn less(a: __m256, b: __m256) -> __m256 {
        _mm256_cmp_ps::<_CMP_LT_OQ>(a, b)
    }

    /// Every bit set.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn all_ones() -> __m256 {
        _mm256_castsi256_ps(_mm256_set1_epi32(-1))
    }

    /// Lanes set in `mask`, counted.
    #[inline]
    #[target_feature(enable = "avx2")]
    fn count(mask: __m256) -> u64 {
        u64::from(_mm256_movemask_ps(mask).count_ones())
    }

    trilinear_ops!(
        "avx2",
        __m256,
        _mm256_set1_ps,
        _mm256_add_ps,
        _mm256_sub_ps,
        _mm256_mul_ps
    );

    /// Blocks per batch of [`sample_blocks`]' pipeline: their memory reads (a directory gather,
    /// then four code gathers that depend on it) are in flight together instead of each block
    /// waiting for its own before its arithmetic (`kernel_ir` example, `distance` mode,
    /// alternated with the block-at-a-time loop: 9.0 → 6.8 ns a point in contact, free space
    /// unchanged; 4 or 16 blocks gave the same).
    const BATCH: usize = 8;

    /// What [`finish_block`] needs of a block, read by [`read_rows`].
    #[derive(Clone, Copy)]
    struct Fetched {
        /// The block's first point.
        start: usize,
        /// Lever arms (m·2^-k, the frame's lever scale) of the block's points.
        lever: V3,
        /// Each lane's position in its trilinear cell, 0..1 per axis.
        f: V3,
        /// The cell's four rows of two codes (`code::<24>` and `code::<16>` of each lane).
        rows: [__m256i; 4],
    }

    /// The blocks of `begin..end` (a multiple of [`LANES`] points) in batches of [`BATCH`],
    /// software-pipelined ([`locate`] for the next batch, [`finish_block`] for this one,
    /// [`read_rows`] for the next); those in the band are finished in order: the same operations
    /// on each block, and the same order of additions to `acc`, as block after block.
    ///
    /// # Safety
    /// The CPU must support AVX2; [`fits_lanes`] must hold for the class's band; `end` must be
    /// within every array (bounds are checked anyway).
    #[inline(always)]
    pub(in crate::kernel) unsafe fn sample_blocks<const CLAMP: bool>(
        class: &BandClass,
        begin: usize,
        end: usize,
        acc: &mut ClassAccumulator,
    ) {
        // Software-pipelined by batches: batch k + 1's slots are gathered before batch k's
        // arithmetic, and its codes after it, so that each batch's reads overlap other work.
        // Loops, not `array::from_fn`: a closure does not inherit the caller's target features,
        // and its intrinsics would become calls.
        let mut located = [MaybeUninit::<Located>::uninit(); BATCH];
        let mut fetched = [MaybeUninit::<Fetched>::uninit(); BATCH];
        let mut ready = 0;
        let mut start = begin;
        loop {
            let batch_end = (start + BATCH * LANES).min(end);
            let mut count = 0;
            while start < batch_end {
                // SAFETY: as this function's; `start + LANES ≤ end`.
                if let Some(block) = unsafe { locate(class, start) } {
                    located[count].write(block);
                    count += 1;
                }
                start += LANES;
            }
            for block in &fetched[..ready] {
                // SAFETY: the first `ready` were written in the previous round; the block's own
                // safety conditions are this function's.
                unsafe { finish_block::<CLAMP>(class, block.assume_init_ref(), acc) };
            }
            if count == 0 && start >= end {
                return;
            }
            for (block, out) in located[..count].iter().zip(&mut fetched) {
                // SAFETY: the first `count` were written just above; the rest as this function's.
                out.write(unsafe { read_rows(class, block.assume_init_ref()) });
            }
            ready = count;
        }
    }

    /// A block placed and its directory slots read ([`locate`]), its codes not yet.
    #[derive(Clone, Copy)]
    struct Located {
        /// The block's first point.
        start: usize,
        /// Lever arms (m·2^-k, the frame's lever scale) of the block's points.
        lever: V3,
        /// `g − ½` per axis (voxels).
        t: V3,
        /// `floor(t)`.
        base: [__m256i; 3],
        /// Each lane's directory slot (0, the far brick, outside the grid).
        slots: __m256i,
    }

    /// The first reads of `super::sample_block` for a full block at `start`: the transform, the
    /// cell of each lane and its directory slot; `None` when every lane is far. Not compiled for
    /// a target feature itself: always inlined into `accumulate_avx2`, whose features its
    /// intrinsics then use.
    ///
    /// # Safety
    /// As [`sample_blocks`], with `start + LANES` within every array.
    #[inline(always)]
    unsafe fn locate(class: &BandClass, start: usize) -> Option<Located> {
        unsafe {
            let lever = mat_vec(
                &class.frame.rotation_lever,
                &load::<false>(class.points, start),
            );
            let inv = _mm256_set1_ps(class.frame.inv_voxel_lever);
            let half = _mm256_set1_ps(0.5);
            // Samples sit at voxel centres: the cell's lower corner is floor(g − 1/2), floored
            // as `lanes::floor_i32` does (truncate, then −1 where truncation rounded up).
            let mut t: V3 = [_mm256_setzero_ps(); 3];
            let mut base = [_mm256_setzero_si256(); 3];
            for r in 0..3 {
                let grid = _mm256_add_ps(
                    _mm256_mul_ps(lever[r], inv),
                    _mm256_set1_ps(class.frame.translation_grid[r]),
                );
                t[r] = _mm256_sub_ps(grid, half);
                let truncated = _mm256_cvttps_epi32(t[r]);
                let up = _mm256_cmp_ps::<_CMP_LT_OQ>(t[r], _mm256_cvtepi32_ps(truncated));
                base[r] = _mm256_add_epi32(truncated, _mm256_castps_si256(up));
            }
            // The directory slot of each lane's cube; lanes outside the grid read slot 0 (far).
            let dims = class.band.cube_dims();
            let mut cube = [_mm256_setzero_si256(); 3];
            let mut inside = _mm256_set1_epi32(-1);
            for r in 0..3 {
                cube[r] = _mm256_srai_epi32::<3>(base[r]);
                // Unsigned `cube < dims`: negative cubes are huge unsigned.
                let last = _mm256_set1_epi32((dims[r] - 1) as i32);
                let within = _mm256_cmpeq_epi32(_mm256_min_epu32(cube[r], last), cube[r]);
                inside = _mm256_and_si256(inside, within);
            }
            let index = _mm256_add_epi32(
                _mm256_mullo_epi32(
                    _mm256_add_epi32(
                        _mm256_mullo_epi32(cube[2], _mm256_set1_epi32(dims[1] as i32)),
                        cube[1],
                    ),
                    _mm256_set1_epi32(dims[0] as i32),
                ),
                cube[0],
            );
            // One gather of the eight directory slots (lanes outside the grid: slot 0, far); a
            // block with every lane far (free space) ends here, before any code is loaded.
            // SAFETY: lanes in `inside` index the directory (`index < nx·ny·nz = len ≤ i32::MAX`,
            // `fits_lanes`); the others are not read.
            let slot_lanes = _mm256_mask_i32gather_epi32::<4>(
                _mm256_setzero_si256(),
                class.band.directory().as_ptr().cast(),
                index,
                inside,
            );
            if _mm256_testz_si256(slot_lanes, slot_lanes) != 0 {
                return None;
            }
            Some(Located {
                start,
                lever,
                t,
                base,
                slots: slot_lanes,
            })
        }
    }

    /// The eight codes of each lane's cell of a located block.
    ///
    /// # Safety
    /// As [`sample_blocks`].
    #[inline(always)]
    unsafe fn read_rows(class: &BandClass, located: &Located) -> Fetched {
        unsafe {
            let Located {
                start,
                lever,
                t,
                base,
                slots: slot_lanes,
            } = *located;
            // The four rows of the cell (each a corner and its +x neighbour in its lowest two
            // bytes) at `slot · 729 + in_brick + (dz · 9 + dy) · 9`, gathered: with the blocks
            // fetched in batches, gathers beat 32 scalar loads put together into vectors (6.8
            // against 7.6 ns a point, `kernel_ir`'s `distance` mode alternated; block at a time,
            // the loads had won). The slots themselves are gathered, which in free space beat
            // eight loads (2.0 → 1.1 ns a point, `vps bench kernel`).
            let bytes = class.band.slot_codes().as_ptr();
            // The cell's lower corner in its brick (`slot · 729` added per lane below).
            let seven = _mm256_set1_epi32(7);
            let edge = _mm256_set1_epi32(BRICK_EDGE as i32);
            let local = [
                _mm256_and_si256(base[0], seven),
                _mm256_and_si256(base[1], seven),
                _mm256_and_si256(base[2], seven),
            ];
            let in_brick = _mm256_add_epi32(
                _mm256_mullo_epi32(
                    _mm256_add_epi32(_mm256_mullo_epi32(local[2], edge), local[1]),
                    edge,
                ),
                local[0],
            );
            let at = _mm256_add_epi32(
                _mm256_mullo_epi32(slot_lanes, _mm256_set1_epi32(BRICK_CODES as i32)),
                in_brick,
            );
            // SAFETY (each row): the slot names a brick in memory (`slot_codes`: `(slot + 1) · 729
            // + CODES_PADDING ≤ len ≤ i32::MAX`, `fits_lanes`), `in_brick ≤ 7 + 7·9 + 7·81 = 637`,
            // and the farthest row's 4 bytes end at 637 + 90 + 4 = 731 ≤ 729 + CODES_PADDING.
            let step = |s: usize| _mm256_add_epi32(at, _mm256_set1_epi32(s as i32));
            let rows = [
                code_row(bytes, at),
                code_row(bytes, step(BRICK_EDGE)),
                code_row(bytes, step(BRICK_EDGE * BRICK_EDGE)),
                code_row(bytes, step(BRICK_EDGE * BRICK_EDGE + BRICK_EDGE)),
            ];
            Fetched {
                start,
                lever,
                f: [
                    _mm256_sub_ps(t[0], _mm256_cvtepi32_ps(base[0])),
                    _mm256_sub_ps(t[1], _mm256_cvtepi32_ps(base[1])),
                    _mm256_sub_ps(t[2], _mm256_cvtepi32_ps(base[2])),
                ],
                rows,
            }
        }
    }

    /// The arithmetic of `super::sample_block` for the block at `start` fetched as `block`: the
    /// trilinear value and gradient, the contact, deep and braking lanes, their sums into `acc`.
    ///
    /// # Safety
    /// As [`sample_blocks`].
    #[inline(always)]
    unsafe fn finish_block<const CLAMP: bool>(
        class: &BandClass,
        block: &Fetched,
        acc: &mut ClassAccumulator,
    ) {
        unsafe {
            let Fetched {
                start,
                lever,
                f,
                rows,
            } = *block;
            let [r00, r10, r01, r11] = rows;
            let corners = [
                [
                    [code::<24>(r00), code::<16>(r00)],
                    [code::<24>(r10), code::<16>(r10)],
                ],
                [
                    [code::<24>(r01), code::<16>(r01)],
                    [code::<24>(r11), code::<16>(r11)],
                ],
            ];
            let (e, gradient) = value_and_gradient(&corners, &f);
            let (mut lo, mut hi) = (corners[0][0][0], corners[0][0][0]);
            for plane in &corners {
                for row in plane {
                    for &corner in row {
                        lo = _mm256_min_ps(lo, corner);
                        hi = _mm256_max_ps(hi, corner);
                    }
                }
            }
            let zero = _mm256_setzero_ps();
            let deep = _mm256_cmp_ps::<_CMP_LE_OQ>(hi, _mm256_set1_ps(f32::from(CODE_DEEP)));
            let in_band = _mm256_andnot_ps(
                deep,
                _mm256_and_ps(
                    less(lo, _mm256_set1_ps(f32::from(CODE_FAR))),
                    less(e, _mm256_set1_ps(BAND_VOXELS)),
                ),
            );
            let len_sq = dot(&gradient, &gradient);
            let trusted =
                _mm256_cmp_ps::<_CMP_GE_OQ>(len_sq, _mm256_set1_ps(MIN_GRADIENT * MIN_GRADIENT));
            let inv_len = _mm256_div_ps(_mm256_set1_ps(1.0), _mm256_sqrt_ps(len_sq));
            let contact = _mm256_and_ps(in_band, less(e, zero));
            let braking = _mm256_and_ps(
                _mm256_andnot_ps(less(e, zero), in_band),
                less(e, _mm256_set1_ps(BRAKE_RANGE_VOXELS)),
            );
            let own = _mm256_or_ps(_mm256_andnot_ps(trusted, all_ones()), deep);
            let pushing = _mm256_or_ps(_mm256_or_ps(contact, braking), deep);
            let mut direction: V3 = [zero; 3];
            for a in 0..3 {
                direction[a] = _mm256_and_ps(pushing, _mm256_mul_ps(gradient[a], inv_len));
            }
            // The point's own normal where a pushing lane has no trusted scene normal (deep, or
            // a short gradient): rotated only then (in contact, rarely).
            let own_pushing = _mm256_and_ps(own, pushing);
            if _mm256_movemask_ps(own_pushing) != 0 {
                let part_normal =
                    mat_vec(&class.frame.rotation, &load::<false>(class.normals, start));
                for a in 0..3 {
                    direction[a] = _mm256_blendv_ps(direction[a], part_normal[a], own_pushing);
                }
            }
            let voxel_q = _mm256_set1_ps(class.frame.voxel_q);
            let depth = _mm256_blendv_ps(
                _mm256_and_ps(deep, _mm256_set1_ps(BAND_VOXELS * class.frame.voxel_q)),
                _mm256_mul_ps(_mm256_sub_ps(zero, e), voxel_q),
                contact,
            );
            // Inside the exact surface (d < 0) counts as Interior.
            let inside_surface =
                _mm256_and_ps(contact, less(e, _mm256_set1_ps(-class.standoff_voxels)));
            let surface = count(_mm256_andnot_ps(inside_surface, contact));
            let interior = count(_mm256_or_ps(deep, inside_surface));
            acc.surface += surface;
            acc.interior += interior;
            acc.non_free += count(_mm256_or_ps(in_band, deep));
            if surface + interior > 0 {
                acc.contacts += count_positive(depth);
                let force_dir = scale(&direction, depth);
                add3_fixed::<CLAMP, false>(&mut acc.depth_normal, &force_dir);
                add3_fixed::<CLAMP, false>(&mut acc.depth_torque, &cross(&lever, &force_dir));
                acc.depth_blocks += 1;
            }
            if _mm256_movemask_ps(braking) != 0 {
                brake_lanes::<CLAMP, false>(class.frame, &lever, &direction, braking, acc);
            }
        }
    }
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

    /// The AVX2 block, the AVX-512 wide block (where the CPU has it) and the portable block give
    /// the same sums bit for bit, on a band
    /// of far, deep and random bricks, with points inside, across the edge of and outside the
    /// grid, moving and spinning (braking lanes); also for any split of the shell.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_avx2_and_avx512_blocks_give_the_portable_bits() {
        use crate::KernelPose;
        use glam::{DVec3, Mat3, Vec3};
        use vps_voxmap::distance::{assemble, CubeCodes, BRICK_CODES};
        use vps_voxmap::{DenseGrid, GridSpec};
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let spec = GridSpec {
            origin: DVec3::splat(-0.1),
            voxel_size: 0.01,
            dims: [20, 17, 23],
        };
        let band = assemble(&spec, 0.004, |_| match rng.gen_range(0..4) {
            0 => CubeCodes::Far,
            1 => CubeCodes::Deep,
            _ => {
                let mut codes = Box::new([0i8; BRICK_CODES]);
                for c in codes.iter_mut() {
                    *c = rng.gen_range(-127i8..=127);
                }
                CubeCodes::Brick(codes)
            }
        })
        .unwrap();
        assert!(avx2::fits_lanes(&band));
        let grid = DenseGrid::new(spec);
        let n = 2003;
        let soa: [Vec<f32>; 6] = std::array::from_fn(|k| {
            (0..n)
                .map(|_| {
                    if k < 3 {
                        rng.gen_range(-0.14f32..0.14)
                    } else {
                        rng.gen_range(-1.0f32..1.0)
                    }
                })
                .collect()
        });
        let pose = KernelPose {
            rotation: Mat3::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.9),
            translation: Vec3::new(0.011, -0.017, 0.006),
            linear_velocity: Vec3::new(0.4, -0.6, 0.3),
            angular_velocity: Vec3::new(-3.0, 2.0, 6.0),
        };
        let shell = super::super::soa_shell(&soa, n, spec.voxel_size, 0.25);
        let standoff = (band.standoff_m() / spec.voxel_size) as f32;
        for needs_clamp in [false, true] {
            let frame = GridFrame {
                needs_clamp,
                ..GridFrame::new(&grid, &pose, &shell)
            };
            let class = BandClass {
                band: &band,
                standoff_voxels: standoff,
                frame: &frame,
                points: [&soa[0][..], &soa[1][..], &soa[2][..]],
                normals: [&soa[3][..], &soa[4][..], &soa[5][..]],
            };
            let mut portable = PartialSums::default();
            accumulate_any::<false, false>(class, &mut portable);
            let mut avx2 = PartialSums::default();
            // SAFETY: AVX2 was detected and `fits_lanes` holds (asserted) above.
            unsafe {
                accumulate_avx2(
                    &band,
                    standoff,
                    &frame,
                    class.points,
                    class.normals,
                    &mut avx2,
                )
            };
            assert_eq!(avx2, portable, "needs_clamp {needs_clamp}");
            if super::super::cpu_has_avx512() {
                let mut avx512 = PartialSums::default();
                // SAFETY: AVX2, AVX-512F, AVX-512DQ and POPCNT were detected; `fits_lanes`
                // holds (asserted above).
                unsafe {
                    accumulate_avx512(
                        &band,
                        standoff,
                        &frame,
                        class.points,
                        class.normals,
                        &mut avx512,
                    )
                };
                assert_eq!(avx512, portable, "AVX-512, needs_clamp {needs_clamp}");
                // Shells of every length up to three wide blocks and a tail (wide blocks, a
                // last 8-lane block, the tail in every combination).
                for len in 1..=56 {
                    let part = BandClass {
                        points: [&soa[0][..len], &soa[1][..len], &soa[2][..len]],
                        normals: [&soa[3][..len], &soa[4][..len], &soa[5][..len]],
                        ..class
                    };
                    let mut expected = PartialSums::default();
                    accumulate_any::<false, false>(part, &mut expected);
                    let mut wide = PartialSums::default();
                    // SAFETY: as above.
                    unsafe {
                        accumulate_avx512(
                            &band,
                            standoff,
                            &frame,
                            part.points,
                            part.normals,
                            &mut wide,
                        )
                    };
                    assert_eq!(wide, expected, "AVX-512, {len} points");
                }
            }
            // Point by point (every point a tail block of one): the same sums.
            let mut single = PartialSums::default();
            for i in 0..n {
                let point = BandClass {
                    points: [&soa[0][i..=i], &soa[1][i..=i], &soa[2][i..=i]],
                    normals: [&soa[3][i..=i], &soa[4][i..=i], &soa[5][i..=i]],
                    ..class
                };
                accumulate_any::<false, false>(point, &mut single);
            }
            assert_eq!(single, portable);
        }
    }
}
