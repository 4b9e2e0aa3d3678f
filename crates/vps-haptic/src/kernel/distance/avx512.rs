//! The AVX-512 copy of the `distance` model's full blocks: [`super::avx2`]'s block on sixteen
//! lanes, one `__m512` per lane array and lane masks in `__mmask16` registers, so that one wide
//! block does two 8-lane blocks' work with the same instructions (one gather of sixteen
//! directory slots, four of sixteen code rows). Every operation is the 8-lane block's (same
//! operands, same order, no fused multiply-add), so a wide block gives the bits of the two 8-lane
//! blocks it covers (a unit test checks it against the portable copy).
//!
//! Sums: each of a sum's sixteen values is rounded to `i64` (`vcvtps2qq`, the tangent-plane
//! AVX-512 copy's [`add3_fixed`]) and both halves are added to the class's eight `i64` lanes; a
//! wide block counts as two blocks for the carried rounding offset.

use super::super::avx512::{
    add3_fixed, brake_lanes, count, cross, dot, load, mat_vec, scale, V3, WIDE_LANES,
};
use super::super::ClassAccumulator;
use super::{BandClass, BRAKE_RANGE_VOXELS, MIN_GRADIENT};
use std::arch::x86_64::*;
use std::mem::MaybeUninit;
use vps_voxmap::distance::{
    BAND_VOXELS, BRICK_CODES, BRICK_EDGE, CODES_PER_VOXEL, CODE_DEEP, CODE_FAR,
};

/// Wide blocks per batch of [`sample_blocks`]' pipeline (as the AVX2 copy's eight blocks of 8:
/// the same 64 points; 2 and 8 measured the same).
const BATCH: usize = 4;

/// What [`finish_block`] needs of a wide block, read by [`read_rows`].
#[derive(Clone, Copy)]
struct Fetched {
    /// The block's first point.
    start: usize,
    /// Lever arms (m·2^-k, the frame's lever scale) of the block's points.
    lever: V3,
    /// Each lane's position in its trilinear cell, 0..1 per axis.
    f: V3,
    /// The cell's four rows of two codes (`code::<24>` and `code::<16>` of each lane).
    rows: [__m512i; 4],
}

/// One byte of each 32-bit lane as a signed code, converted to f32 (exact): `LEFT` = 24 gives the
/// lowest byte, 16 the next.
#[inline]
#[target_feature(enable = "avx512f")]
fn code<const LEFT: u32>(v: __m512i) -> __m512 {
    _mm512_cvtepi32_ps(_mm512_srai_epi32::<24>(_mm512_slli_epi32::<LEFT>(v)))
}

/// `a < b` per lane (ordered: false where either is NaN).
#[inline]
#[target_feature(enable = "avx512f")]
fn less(a: __m512, b: __m512) -> __mmask16 {
    _mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, b)
}

trilinear_ops!(
    "avx512f",
    __m512,
    _mm512_set1_ps,
    _mm512_add_ps,
    _mm512_sub_ps,
    _mm512_mul_ps
);

/// The wide blocks of `begin..end` (a multiple of [`WIDE_LANES`] points) in batches of
/// [`BATCH`], software-pipelined; those in the band are finished in order: the same sums as the
/// 8-lane blocks they cover (the sums are integers).
///
/// # Safety
/// The CPU must support AVX-512F and AVX-512DQ; [`super::avx2::fits_lanes`] must hold for the
/// class's band; `end` must be within every array.
#[inline(always)]
pub(in crate::kernel) unsafe fn sample_blocks<const CLAMP: bool>(
    class: &BandClass,
    begin: usize,
    end: usize,
    acc: &mut ClassAccumulator,
) {
    // Software-pipelined by batches: batch k + 1's slots are gathered before batch k's
    // arithmetic, and its codes after it, so that each batch's reads overlap other work.
    // Loops, not `array::from_fn`: a closure does not inherit the caller's target features.
    let mut located = [MaybeUninit::<Located>::uninit(); BATCH];
    let mut fetched = [MaybeUninit::<Fetched>::uninit(); BATCH];
    let mut ready = 0;
    let mut start = begin;
    loop {
        let batch_end = (start + BATCH * WIDE_LANES).min(end);
        let mut count = 0;
        while start < batch_end {
            // SAFETY: as this function's; `start + WIDE_LANES ≤ end`.
            if let Some(block) = unsafe { locate(class, start) } {
                located[count].write(block);
                count += 1;
            }
            start += WIDE_LANES;
        }
        for block in &fetched[..ready] {
            // SAFETY: the first `ready` were written in the previous round; the rest as this
            // function's.
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

/// A wide block placed and its directory slots read ([`locate`]), its codes not yet.
#[derive(Clone, Copy)]
struct Located {
    /// The block's first point.
    start: usize,
    /// Lever arms (m·2^-k, the frame's lever scale) of the block's points.
    lever: V3,
    /// `g − ½` per axis (voxels).
    t: V3,
    /// `floor(t)`.
    base: [__m512i; 3],
    /// Each lane's directory slot (0, the far brick, outside the grid).
    slots: __m512i,
}

/// The first reads of a wide block at `start`: the transform, each lane's cell and its directory
/// slot (as [`super::avx2`]'s `locate`, sixteen lanes). `None` when every lane is far (its slot is
/// the far brick's, or it is outside the grid).
///
/// # Safety
/// As [`sample_blocks`], with `start + WIDE_LANES` within every array.
#[inline(always)]
unsafe fn locate(class: &BandClass, start: usize) -> Option<Located> {
    unsafe {
        let lever = mat_vec(&class.frame.rotation_lever, &load(class.points, start));
        let inv = _mm512_set1_ps(class.frame.inv_voxel_lever);
        let half = _mm512_set1_ps(0.5);
        // The cell's lower corner is floor(g − 1/2), floored as the other copies do (truncate,
        // then −1 where truncation rounded up).
        let mut t: V3 = [_mm512_setzero_ps(); 3];
        let mut base = [_mm512_setzero_si512(); 3];
        for r in 0..3 {
            let grid = _mm512_add_ps(
                _mm512_mul_ps(lever[r], inv),
                _mm512_set1_ps(class.frame.translation_grid[r]),
            );
            t[r] = _mm512_sub_ps(grid, half);
            let truncated = _mm512_cvttps_epi32(t[r]);
            let up = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t[r], _mm512_cvtepi32_ps(truncated));
            base[r] = _mm512_mask_sub_epi32(truncated, up, truncated, _mm512_set1_epi32(1));
        }
        let dims = class.band.cube_dims();
        let mut cube = [_mm512_setzero_si512(); 3];
        let mut inside: __mmask16 = u16::MAX;
        for r in 0..3 {
            cube[r] = _mm512_srai_epi32::<3>(base[r]);
            // Unsigned `cube < dims`: negative cubes are huge unsigned.
            inside =
                _mm512_mask_cmplt_epu32_mask(inside, cube[r], _mm512_set1_epi32(dims[r] as i32));
        }
        let index = _mm512_add_epi32(
            _mm512_mullo_epi32(
                _mm512_add_epi32(
                    _mm512_mullo_epi32(cube[2], _mm512_set1_epi32(dims[1] as i32)),
                    cube[1],
                ),
                _mm512_set1_epi32(dims[0] as i32),
            ),
            cube[0],
        );
        // SAFETY: lanes in `inside` index the directory (`index < nx·ny·nz = len ≤ i32::MAX`,
        // `fits_lanes`); the others are not read and stay slot 0 (far).
        let slot_lanes = _mm512_mask_i32gather_epi32::<4>(
            _mm512_setzero_si512(),
            inside,
            index,
            class.band.directory().as_ptr().cast(),
        );
        if _mm512_test_epi32_mask(slot_lanes, slot_lanes) == 0 {
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
        let bytes = class.band.slot_codes().as_ptr();
        let seven = _mm512_set1_epi32(7);
        let edge = _mm512_set1_epi32(BRICK_EDGE as i32);
        let local = [
            _mm512_and_si512(base[0], seven),
            _mm512_and_si512(base[1], seven),
            _mm512_and_si512(base[2], seven),
        ];
        let in_brick = _mm512_add_epi32(
            _mm512_mullo_epi32(
                _mm512_add_epi32(_mm512_mullo_epi32(local[2], edge), local[1]),
                edge,
            ),
            local[0],
        );
        let at = _mm512_add_epi32(
            _mm512_mullo_epi32(slot_lanes, _mm512_set1_epi32(BRICK_CODES as i32)),
            in_brick,
        );
        // SAFETY (each row): as the AVX2 copy's: the slot names a brick in memory
        // (`(slot + 1) · 729 + CODES_PADDING ≤ len ≤ i32::MAX`, `fits_lanes`) and the farthest
        // row's 4 bytes end at 637 + 90 + 4 = 731 ≤ 729 + CODES_PADDING.
        let row = |s: usize| {
            _mm512_i32gather_epi32::<1>(
                _mm512_add_epi32(at, _mm512_set1_epi32(s as i32)),
                bytes.cast(),
            )
        };
        let rows = [
            row(0),
            row(BRICK_EDGE),
            row(BRICK_EDGE * BRICK_EDGE),
            row(BRICK_EDGE * BRICK_EDGE + BRICK_EDGE),
        ];
        Fetched {
            start,
            lever,
            f: [
                _mm512_sub_ps(t[0], _mm512_cvtepi32_ps(base[0])),
                _mm512_sub_ps(t[1], _mm512_cvtepi32_ps(base[1])),
                _mm512_sub_ps(t[2], _mm512_cvtepi32_ps(base[2])),
            ],
            rows,
        }
    }
}

/// The arithmetic of a fetched wide block: the trilinear value and gradient, the contact, deep
/// and braking lanes, their sums into `acc` (as [`super::avx2`]'s `finish_block`).
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
                    lo = _mm512_min_ps(lo, corner);
                    hi = _mm512_max_ps(hi, corner);
                }
            }
        }
        let zero = _mm512_setzero_ps();
        let deep = _mm512_cmp_ps_mask::<_CMP_LE_OQ>(hi, _mm512_set1_ps(f32::from(CODE_DEEP)));
        let in_band = !deep
            & less(lo, _mm512_set1_ps(f32::from(CODE_FAR)))
            & less(e, _mm512_set1_ps(BAND_VOXELS));
        let len_sq = dot(&gradient, &gradient);
        let trusted =
            _mm512_cmp_ps_mask::<_CMP_GE_OQ>(len_sq, _mm512_set1_ps(MIN_GRADIENT * MIN_GRADIENT));
        let inv_len = _mm512_div_ps(_mm512_set1_ps(1.0), _mm512_sqrt_ps(len_sq));
        let negative = less(e, zero);
        let contact = in_band & negative;
        let braking = in_band & !negative & less(e, _mm512_set1_ps(BRAKE_RANGE_VOXELS));
        let own = !trusted | deep;
        let pushing = contact | braking | deep;
        let mut direction: V3 = [zero; 3];
        for a in 0..3 {
            direction[a] = _mm512_maskz_mul_ps(pushing, gradient[a], inv_len);
        }
        // The point's own normal where a pushing lane has no trusted scene normal (deep, or a
        // short gradient): rotated only then (in contact, rarely).
        let own_pushing = own & pushing;
        if own_pushing != 0 {
            let part_normal = mat_vec(&class.frame.rotation, &load(class.normals, start));
            for a in 0..3 {
                direction[a] = _mm512_mask_mov_ps(direction[a], own_pushing, part_normal[a]);
            }
        }
        let voxel_q = _mm512_set1_ps(class.frame.voxel_q);
        let depth = _mm512_mask_blend_ps(
            contact,
            _mm512_maskz_mov_ps(deep, _mm512_set1_ps(BAND_VOXELS * class.frame.voxel_q)),
            _mm512_mul_ps(_mm512_sub_ps(zero, e), voxel_q),
        );
        // Inside the exact surface (d < 0) counts as Interior.
        let inside_surface = contact & less(e, _mm512_set1_ps(-class.standoff_voxels));
        let surface = count(contact & !inside_surface);
        let interior = count(deep | inside_surface);
        acc.surface += surface;
        acc.interior += interior;
        acc.non_free += count(in_band | deep);
        if surface + interior > 0 {
            acc.contacts += count(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(depth, zero));
            let force_dir = scale(&direction, depth);
            add3_fixed::<CLAMP>(&mut acc.depth_normal, &force_dir);
            add3_fixed::<CLAMP>(&mut acc.depth_torque, &cross(&lever, &force_dir));
            acc.depth_blocks += 2;
        }
        if braking != 0 {
            brake_lanes::<CLAMP>(class.frame, &lever, &direction, braking, acc);
        }
    }
}
