//! The full-block path of the AVX2 copy, written with AVX2 intrinsics: the portable lane loops
//! leave much of the block arithmetic in 128-bit halves even when compiled for AVX2. Every
//! operation is the portable one (same operands, same order, no fused multiply-add), so a block
//! gives the same bits either way (a unit test checks it).

use super::{
    count_bytes, look_up_fresh, ClassAccumulator, ClassLoop, GridFrame, I64s, KindMasks, Soa,
    LANES, LENGTH_Q, ROUNDER, ROUNDER_BITS, Y_MAX,
};
use glam::Mat3;
use std::arch::x86_64::*;
use vps_voxmap::{Voxel, VoxelLookup};

/// One 256-bit vector per component.
pub(super) type V3 = [__m256; 3];

/// Lanes `start..start + LANES` of the three arrays. `UNCHECKED` (the AVX-512 copy): without
/// bounds checks, which `accumulate_lanes` makes once per class instead.
///
/// # Safety
/// The CPU must support AVX2; with `UNCHECKED`, `start + LANES` must be within every array.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn load<const UNCHECKED: bool>(xs: Soa, start: usize) -> V3 {
    let mut out = [_mm256_setzero_ps(); 3];
    for r in 0..3 {
        let lanes = if UNCHECKED {
            // SAFETY: `start + LANES` is within every array (this function's contract).
            unsafe { xs[r].get_unchecked(start..start + LANES) }
        } else {
            &xs[r][start..start + LANES]
        };
        // SAFETY: `lanes` holds LANES f32 (32 bytes); unaligned load.
        out[r] = unsafe { _mm256_loadu_ps(lanes.as_ptr()) };
    }
    out
}

vec3_ops!(
    "avx2",
    __m256,
    __m256i,
    _mm256_setzero_ps,
    _mm256_set1_ps,
    _mm256_add_ps,
    _mm256_sub_ps,
    _mm256_mul_ps,
    _mm256_cvtepi32_ps
);

/// Number of lanes with `x > 0` (`GT`) or `x < 0`.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn count_positive(x: __m256) -> u64 {
    let m = _mm256_cmp_ps::<_CMP_GT_OQ>(x, _mm256_setzero_ps());
    u64::from(_mm256_movemask_ps(m).count_ones())
}

#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn count_negative(x: __m256) -> u64 {
    let m = _mm256_cmp_ps::<_CMP_LT_OQ>(x, _mm256_setzero_ps());
    u64::from(_mm256_movemask_ps(m).count_ones())
}

/// `super::add_fixed`: `acc += bits(f64(y) + 1.5 · 2^52)` per lane, `y` clamped first with
/// `CLAMP` (`max` then `min`: NaN gives `-Y_MAX` as `f32::max` does). `AVX512`: the AVX-512
/// copy, [`add_rounded_avx512`].
///
/// # Safety
/// The CPU must support AVX2, and AVX-512F and DQ with `AVX512`; inlined only into callers
/// compiled for them.
#[inline(always)]
pub(super) unsafe fn add_fixed<const CLAMP: bool, const AVX512: bool>(acc: &mut I64s, y: __m256) {
    let y = if CLAMP {
        _mm256_min_ps(
            _mm256_max_ps(y, _mm256_set1_ps(-Y_MAX)),
            _mm256_set1_ps(Y_MAX),
        )
    } else {
        y
    };
    if AVX512 {
        // SAFETY: as this function's.
        unsafe { add_rounded_avx512(acc, y) }
    } else {
        // SAFETY: as this function's.
        unsafe { add_rounded_avx2(acc, y) }
    }
}

/// `acc += round(y) + bits(1.5 · 2^52)` per lane (the carried form of `super::add_fixed`):
/// one conversion of the eight f32 lanes to `i64`, to nearest with ties to even, the same
/// integer as `bits(f64(y) + 1.5 · 2^52) − bits(1.5 · 2^52)` for every `|y| < 2^51` (`f64(y)`
/// is exact and both round the exact value to nearest, ties to even). `|y| ≤ Y_MAX` here: the
/// frame's bound or the clamp (see the module docs).
///
/// # Safety
/// The CPU must support AVX-512F and AVX-512DQ.
#[inline]
#[target_feature(enable = "avx512f,avx512dq")]
unsafe fn add_rounded_avx512(acc: &mut I64s, y: __m256) {
    let rounded = _mm512_cvt_roundps_epi64::<{ _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC }>(y);
    let carried = _mm512_add_epi64(rounded, _mm512_set1_epi64(ROUNDER_BITS));
    let p = acc.as_mut_ptr().cast::<__m512i>();
    // SAFETY: `acc` is 8 i64 (64 bytes), loaded and stored unaligned.
    unsafe { _mm512_storeu_si512(p, _mm512_add_epi64(_mm512_loadu_si512(p), carried)) };
}

/// `acc += bits(f64(y) + 1.5 · 2^52)` per lane, in two halves of four.
///
/// # Safety
/// The CPU must support AVX2.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn add_rounded_avx2(acc: &mut I64s, y: __m256) {
    let rounder = _mm256_set1_pd(ROUNDER);
    let lo = _mm256_add_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(y)), rounder);
    let hi = _mm256_add_pd(_mm256_cvtps_pd(_mm256_extractf128_ps::<1>(y)), rounder);
    let p = acc.as_mut_ptr().cast::<__m256i>();
    // SAFETY: `acc` is 8 i64 (64 bytes): two unaligned 32-byte halves.
    unsafe {
        _mm256_storeu_si256(
            p,
            _mm256_add_epi64(_mm256_loadu_si256(p), _mm256_castpd_si256(lo)),
        );
        _mm256_storeu_si256(
            p.add(1),
            _mm256_add_epi64(_mm256_loadu_si256(p.add(1)), _mm256_castpd_si256(hi)),
        );
    }
}

/// [`add_fixed`] per component.
///
/// # Safety
/// As [`add_fixed`]'s.
#[inline(always)]
pub(super) unsafe fn add3_fixed<const CLAMP: bool, const AVX512: bool>(
    acc: &mut [I64s; 3],
    y: &V3,
) {
    for (a, v) in acc.iter_mut().zip(y) {
        // SAFETY: as this function's.
        unsafe { add_fixed::<CLAMP, AVX512>(a, *v) };
    }
}

/// `super::brake_block` in 256-bit registers: `a = V·N` in the lanes of `mask` (all ones or
/// all zeros) that approach (`V·N < 0`), 0 elsewhere; adds `a²`, `a N` and `(P − x) × a N`
/// and counts the approaching lanes. `lever` is `P − x` in 2^-8 m. Shared by the
/// tangent-plane block (Proximity lanes) and the distance block (braking lanes).
///
/// # Safety
/// As [`add_fixed`]'s.
#[inline(always)]
pub(super) unsafe fn brake_lanes<const CLAMP: bool, const AVX512: bool>(
    frame: &GridFrame,
    lever: &V3,
    normal: &V3,
    mask: __m256,
    acc: &mut ClassAccumulator,
) {
    unsafe {
        let velocity =
            add_cross_uniform(frame.linear_velocity, frame.angular_velocity_lever, lever);
        let approach = dot(&velocity, normal);
        let approaching = _mm256_and_ps(
            mask,
            _mm256_cmp_ps::<_CMP_LT_OQ>(approach, _mm256_setzero_ps()),
        );
        let x = _mm256_and_ps(approaching, approach);
        let a = _mm256_mul_ps(x, _mm256_set1_ps(LENGTH_Q));
        let a_sq = _mm256_mul_ps(x, a);
        acc.approaching += count_negative(a);
        add_fixed::<CLAMP, AVX512>(&mut acc.brake_sq, a_sq);
        let brake_dir = scale(normal, a);
        add3_fixed::<CLAMP, AVX512>(&mut acc.brake_force, &brake_dir);
        add3_fixed::<CLAMP, AVX512>(&mut acc.brake_torque, &cross(lever, &brake_dir));
        acc.brake_blocks += 1;
    }
}

/// Lanes of `kinds` equal to `kind`, as 32-bit masks.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn kind_is(kinds: __m256i, kind: Voxel) -> __m256i {
    _mm256_cmpeq_epi32(kinds, _mm256_set1_epi32(i32::from(kind.bits())))
}

/// `ClassAccumulator::count_kinds` in 32-bit lanes, for the AVX-512 copy: the same counts,
/// and the masks with one bit per lane (bit `l`: lane `l`) instead of one byte.
///
/// # Safety
/// The CPU must support AVX2 and POPCNT.
#[inline]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn count_kind_lanes(acc: &mut ClassAccumulator, kinds: &[u8; LANES]) -> Option<KindMasks> {
    // SAFETY: `kinds` is 8 bytes, loaded unaligned.
    let kind = _mm256_cvtepu8_epi32(unsafe { _mm_loadl_epi64(kinds.as_ptr().cast()) });
    let lanes = |k: Voxel| _mm256_movemask_ps(_mm256_castsi256_ps(kind_is(kind, k))) as u64;
    let (surface, proximity, interior) = (
        lanes(Voxel::Surface),
        lanes(Voxel::Proximity),
        lanes(Voxel::Interior),
    );
    let non_free = surface | proximity | interior;
    if non_free == 0 {
        return None;
    }
    acc.non_free += u64::from(non_free.count_ones());
    acc.interior += u64::from(interior.count_ones());
    Some(KindMasks {
        surface,
        proximity,
        interior,
    })
}

/// `super::sample_block` for a full block at `start` (`start + LANES` within every array).
/// Not compiled for a target feature itself: always inlined into `accumulate_avx2` or
/// `accumulate_avx512`, whose features its intrinsics then use. `AVX512`: the AVX-512 rounding
/// ([`add_fixed`]).
///
/// # Safety
/// The CPU must support AVX2, and with `AVX512` AVX-512F and AVX-512DQ.
#[inline(always)]
pub(super) unsafe fn sample_block<L: VoxelLookup, const CLAMP: bool, const AVX512: bool>(
    class: &mut ClassLoop<L>,
    start: usize,
) {
    unsafe {
        // The AVX-512 copy skips the bounds checks: `start + LANES ≤ n`, the shortest of the
        // six arrays (`accumulate_lanes`). The AVX2 copy stays the previous kernel's code.
        let lever = mat_vec(
            &class.frame.rotation_lever,
            &load::<AVX512>(class.points, start),
        );
        let inv = _mm256_set1_ps(class.frame.inv_voxel_lever);
        let mut grid: V3 = [_mm256_setzero_ps(); 3];
        // floor, as `lanes::floor_i32`: truncate, then −1 where truncation rounded up.
        // (`AVX512`: round down, then truncate.)
        let mut cell = [_mm256_setzero_si256(); 3];
        for r in 0..3 {
            grid[r] = _mm256_add_ps(
                _mm256_mul_ps(lever[r], inv),
                _mm256_set1_ps(class.frame.translation_grid[r]),
            );
            cell[r] = if AVX512 {
                // Rounded down first: the same cells wherever `lanes::floor_i32` gives a
                // cell inside an i32 grid (beyond ±2^31 both give cells outside every grid,
                // which read as Free).
                _mm256_cvttps_epi32(_mm256_floor_ps(grid[r]))
            } else {
                let t = _mm256_cvttps_epi32(grid[r]);
                let up = _mm256_cmp_ps::<_CMP_LT_OQ>(grid[r], _mm256_cvtepi32_ps(t));
                _mm256_add_epi32(t, _mm256_castps_si256(up))
            };
        }
        // Lanes whose cell differs from the previous lane's (lane 0: the last voxel's).
        let shift = _mm256_setr_epi32(0, 0, 1, 2, 3, 4, 5, 6);
        let mut same = _mm256_set1_epi32(-1);
        for (c, previous) in cell.iter().zip(class.last.cell) {
            let prev = _mm256_blend_epi32::<1>(
                _mm256_permutevar8x32_epi32(*c, shift),
                _mm256_set1_epi32(previous),
            );
            same = _mm256_and_si256(same, _mm256_cmpeq_epi32(*c, prev));
        }
        let fresh = !(_mm256_movemask_ps(_mm256_castsi256_ps(same)) as u32) & 0xff;
        let mut cells = [[0i32; LANES]; 3];
        for r in 0..3 {
            _mm256_storeu_si256(cells[r].as_mut_ptr().cast(), cell[r]);
        }
        let (kinds, layers) = if AVX512 {
            look_up_fresh::<L, false>(class.map, &cells, LANES, fresh, &mut class.last)
        } else {
            look_up_fresh::<L, true>(class.map, &cells, LANES, fresh, &mut class.last)
        };
        let masks = if AVX512 {
            if u64::from_le_bytes(kinds) == 0 {
                return;
            }
            count_kind_lanes(&mut class.acc, &kinds)
        } else {
            class.acc.count_kinds(kinds)
        };
        let Some(KindMasks {
            surface,
            proximity,
            interior,
        }) = masks
        else {
            return;
        };
        let normal = mat_vec(&class.frame.rotation, &load::<AVX512>(class.normals, start));
        let kind = _mm256_cvtepu8_epi32(_mm_loadl_epi64(kinds.as_ptr().cast()));
        if surface | interior != 0 {
            class.acc.surface += if AVX512 {
                u64::from(surface.count_ones())
            } else {
                count_bytes(surface)
            };
            let is_interior = kind_is(kind, Voxel::Interior);
            let pushing = _mm256_or_si256(is_interior, kind_is(kind, Voxel::Surface));
            // Interior points push as layer 1.
            let layer = _mm256_blendv_epi8(
                _mm256_cvtepu8_epi32(_mm_loadl_epi64(layers.as_ptr().cast())),
                _mm256_set1_epi32(1),
                is_interior,
            );
            let d = _mm256_add_ps(
                dot(&normal, &to_centre(&cell, &grid)),
                _mm256_cvtepi32_ps(layer),
            );
            let keep = _mm256_and_ps(
                _mm256_castsi256_ps(pushing),
                _mm256_cmp_ps::<_CMP_GT_OQ>(d, _mm256_setzero_ps()),
            );
            let depth = _mm256_and_ps(keep, _mm256_mul_ps(d, _mm256_set1_ps(class.frame.voxel_q)));
            class.acc.contacts += count_positive(depth);
            let force_dir = scale(&normal, depth);
            add3_fixed::<CLAMP, AVX512>(&mut class.acc.depth_normal, &force_dir);
            add3_fixed::<CLAMP, AVX512>(&mut class.acc.depth_torque, &cross(&lever, &force_dir));
            class.acc.depth_blocks += 1;
        }
        if proximity != 0 {
            let is_proximity = _mm256_castsi256_ps(kind_is(kind, Voxel::Proximity));
            brake_lanes::<CLAMP, AVX512>(
                class.frame,
                &lever,
                &normal,
                is_proximity,
                &mut class.acc,
            );
        }
    }
}
