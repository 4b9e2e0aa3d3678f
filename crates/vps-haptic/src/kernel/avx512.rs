//! The AVX-512 copy's full blocks of [`WIDE_LANES`] points: the 8-lane block of the AVX-512 copy
//! (`super::avx2::sample_block` with `AVX512`) on sixteen lanes, one `__m512` per lane array, so that
//! one block does two 8-lane blocks' independent work (two lookup chains in flight) with the same
//! registers. Every operation is the 8-lane block's (same operands, same order, no fused
//! multiply-add), lane masks in `__mmask16` registers instead of vector masks; a unit test checks
//! the bits against the portable and AVX2 copies.
//!
//! Blocks go in pairs ([`sample_blocks`]): both blocks are placed and looked up ([`locate`]),
//! then both do their arithmetic ([`sample_located`]). A block's arithmetic waits on its lookup's
//! two dependent loads; issued block by block, the next block's lookups queue behind that wait.
//! In pairs they are in flight together: contact about 1.3× faster, free space unchanged
//! (docs/kernel.md).
//!
//! Sums: each of a sum's sixteen values is rounded to `i64` (`vcvtps2qq`, two conversions of eight)
//! and both halves are added to the class's eight `i64` lanes (lane `l` takes points `l` and
//! `l + 8`), so a block adds two carried values per lane; integers add exactly in any grouping.

use super::{
    ClassAccumulator, ClassLoop, GridFrame, I64s, LastVoxel, Soa, LENGTH_Q, ROUNDER_BITS, Y_MAX,
};
use glam::Mat3;
use std::arch::x86_64::*;
use vps_voxmap::{Voxel, VoxelLookup, WIDE_BLOCK_LANES};

/// Points per wide block: one 512-bit register of f32.
pub(super) const WIDE_LANES: usize = WIDE_BLOCK_LANES;

pub(super) type V3 = [__m512; 3];

/// Lanes `start..start + WIDE_LANES` of the three arrays, without bounds checks.
///
/// # Safety
/// The CPU must support AVX-512F; `start + WIDE_LANES` must be within every array.
#[inline]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn load(xs: Soa, start: usize) -> V3 {
    let mut out = [_mm512_setzero_ps(); 3];
    for r in 0..3 {
        // SAFETY: `start + WIDE_LANES` is within every array (this function's contract): 64
        // bytes, loaded unaligned.
        out[r] = unsafe { _mm512_loadu_ps(xs[r].as_ptr().add(start)) };
    }
    out
}

vec3_ops!(
    "avx512f",
    __m512,
    __m512i,
    _mm512_setzero_ps,
    _mm512_set1_ps,
    _mm512_add_ps,
    _mm512_sub_ps,
    _mm512_mul_ps,
    _mm512_cvtepi32_ps
);

/// Number of set lanes of a mask.
#[inline(always)]
pub(super) fn count(mask: __mmask16) -> u64 {
    u64::from(mask.count_ones())
}

/// `acc += round(y) + bits(1.5 · 2^52)` for each half of the sixteen lanes (lanes `l` and `l + 8`
/// into `acc[l]`): `super::avx2`'s AVX-512 rounding (`vcvtps2qq`, to nearest, ties to even, the
/// same integer as the portable copy's) on each half; `y` clamped to `±Y_MAX` first with `CLAMP`
/// (`max` then `min`: NaN gives `-Y_MAX`, as in the other copies).
///
/// # Safety
/// The CPU must support AVX-512F and AVX-512DQ.
#[inline]
#[target_feature(enable = "avx512f,avx512dq")]
unsafe fn add_fixed<const CLAMP: bool>(acc: &mut I64s, y: __m512) {
    let y = if CLAMP {
        _mm512_min_ps(
            _mm512_max_ps(y, _mm512_set1_ps(-Y_MAX)),
            _mm512_set1_ps(Y_MAX),
        )
    } else {
        y
    };
    const NEAREST: i32 = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;
    let lo = _mm512_cvt_roundps_epi64::<NEAREST>(_mm512_castps512_ps256(y));
    let hi = _mm512_cvt_roundps_epi64::<NEAREST>(_mm512_extractf32x8_ps::<1>(y));
    // Two carried values per lane.
    let carried = _mm512_add_epi64(
        _mm512_add_epi64(lo, hi),
        _mm512_set1_epi64(ROUNDER_BITS.wrapping_mul(2)),
    );
    let p = acc.as_mut_ptr().cast::<__m512i>();
    // SAFETY: `acc` is 8 i64 (64 bytes), loaded and stored unaligned.
    unsafe { _mm512_storeu_si512(p, _mm512_add_epi64(_mm512_loadu_si512(p), carried)) };
}

/// [`add_fixed`] per component.
///
/// # Safety
/// As [`add_fixed`]'s.
#[inline(always)]
pub(super) unsafe fn add3_fixed<const CLAMP: bool>(acc: &mut [I64s; 3], y: &V3) {
    for (a, v) in acc.iter_mut().zip(y) {
        // SAFETY: as this function's.
        unsafe { add_fixed::<CLAMP>(a, *v) };
    }
}

/// The kinds (bits) and layers of a wide block's voxels, one 32-bit lane each, looked up at once
/// ([`VoxelLookup::get_wide_block`]); when no lane starts a new voxel (`fresh`, bit `l`: lane `l`
/// is in another voxel than lane `l - 1`, lane 0 than `last`), every lane copies `last` instead.
/// Updates `last` to lane `WIDE_LANES - 1`. Always inlined (into `accumulate_avx512`, whose
/// features its intrinsics use): a call would pass the vectors through memory.
///
/// # Safety
/// The CPU must support AVX-512F.
#[inline(always)]
unsafe fn look_up<L: VoxelLookup>(
    map: &L,
    cells: &[[i32; WIDE_LANES]; 3],
    fresh: __mmask16,
    last: &mut LastVoxel,
) -> (__m512i, __m512i) {
    const END: usize = WIDE_LANES - 1;
    // SAFETY: the CPU supports AVX-512F (this function's contract); the kind and layer arrays are
    // 16 bytes each, loaded unaligned.
    unsafe {
        if fresh == 0 {
            return (
                _mm512_set1_epi32(i32::from(last.voxel.kind.bits())),
                _mm512_set1_epi32(i32::from(last.voxel.layer)),
            );
        }
        let block = map.get_wide_block(cells);
        last.remember_voxel(block.kinds[END], block.layers[END]);
        last.cell = [cells[0][END], cells[1][END], cells[2][END]];
        (
            _mm512_cvtepu8_epi32(_mm_loadu_si128(block.kinds.as_ptr().cast())),
            _mm512_cvtepu8_epi32(_mm_loadu_si128(block.layers.as_ptr().cast())),
        )
    }
}

/// A wide block's voxels after its lookups ([`locate`]), before its arithmetic
/// ([`sample_located`]).
#[derive(Clone, Copy)]
struct LocatedBlock {
    /// The points' placement.
    placed: Placed,
    /// The voxel kinds' bits.
    kind: __m512i,
    /// The voxel layers.
    layer: __m512i,
}

/// A wide block's points placed by the pose.
#[derive(Clone, Copy)]
struct Placed {
    /// `P − x` per lane (2^-8 m).
    lever: V3,
    /// `P` in grid coordinates (voxels).
    grid: V3,
    /// `floor(grid)`.
    cell: [__m512i; 3],
}

/// The points of the full wide block at `start` placed by `frame`.
///
/// # Safety
/// The CPU must support AVX-512F; `start + WIDE_LANES` must be within the three arrays.
#[inline(always)]
unsafe fn place(frame: &GridFrame, points: Soa, start: usize) -> Placed {
    unsafe {
        let lever = mat_vec(&frame.rotation_lever, &load(points, start));
        let inv = _mm512_set1_ps(frame.inv_voxel_lever);
        let mut grid: V3 = [_mm512_setzero_ps(); 3];
        let mut cell = [_mm512_setzero_si512(); 3];
        for r in 0..3 {
            grid[r] = _mm512_add_ps(
                _mm512_mul_ps(lever[r], inv),
                _mm512_set1_ps(frame.translation_grid[r]),
            );
            // Rounded down, then truncated, as the 8-lane AVX-512 block.
            cell[r] = _mm512_cvttps_epi32(_mm512_roundscale_ps::<
                { _MM_FROUND_TO_NEG_INF | _MM_FROUND_NO_EXC },
            >(grid[r]));
        }
        Placed { lever, grid, cell }
    }
}

/// The first half of `super::sample_block` for a full wide block at `start`: place and look up
/// (updating `last`). Inlined into `accumulate_avx512`, whose features its intrinsics use.
///
/// # Safety
/// The CPU must support AVX-512F; `start + WIDE_LANES` must be within the three arrays.
#[inline(always)]
unsafe fn locate<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    start: usize,
    last: &mut LastVoxel,
) -> LocatedBlock {
    unsafe {
        let placed = place(frame, points, start);
        let cell = placed.cell;
        // Lanes whose cell equals the previous lane's (lane 0: the last voxel's).
        let mut same: __mmask16 = u16::MAX;
        for (c, previous) in cell.iter().zip(last.cell) {
            let prev = _mm512_alignr_epi32::<15>(*c, _mm512_set1_epi32(previous));
            same = _mm512_mask_cmpeq_epi32_mask(same, *c, prev);
        }
        let mut cells = [[0i32; WIDE_LANES]; 3];
        for r in 0..3 {
            _mm512_storeu_si512(cells[r].as_mut_ptr().cast(), cell[r]);
        }
        let (kind, layer) = look_up(map, &cells, !same, last);
        LocatedBlock {
            placed,
            kind,
            layer,
        }
    }
}

/// `super::sample_block` for the full wide block at `start`, and with `PAIR` the one after it
/// too (`start + WIDE_LANES`, or `start + 2 · WIDE_LANES` with `PAIR`, within every array): the
/// blocks' lookups ([`locate`], in block order, so `last` evolves as block by block), then their
/// arithmetic ([`sample_located`]). The same sums as block by block: the lookups are the same and
/// the sums are integers. A pair is faster in contact: the second block's lookup chain (slot,
/// then leaf word) is issued before the first block's arithmetic, which would otherwise wait on
/// its own lookup with the second block's lookups queued behind. Inlined into
/// `accumulate_avx512`, whose features its intrinsics use.
///
/// # Safety
/// The CPU must support AVX-512F and AVX-512DQ; the blocks must be within the six arrays.
#[inline(always)]
pub(super) unsafe fn sample_blocks<L: VoxelLookup, const CLAMP: bool, const PAIR: bool>(
    class: &mut ClassLoop<L>,
    start: usize,
) {
    unsafe {
        let first = locate(class.map, class.frame, class.points, start, &mut class.last);
        let second = if PAIR {
            Some(locate(
                class.map,
                class.frame,
                class.points,
                start + WIDE_LANES,
                &mut class.last,
            ))
        } else {
            None
        };
        sample_located::<CLAMP>(class.frame, class.normals, start, &first, &mut class.acc);
        if let Some(second) = second {
            sample_located::<CLAMP>(
                class.frame,
                class.normals,
                start + WIDE_LANES,
                &second,
                &mut class.acc,
            );
        }
    }
}

/// The second half of `super::sample_block` for the located wide block at `start`: the contact
/// and braking arithmetic for the whole block if any lane needs it.
///
/// # Safety
/// The CPU must support AVX-512F and AVX-512DQ; `start + WIDE_LANES` must be within the three
/// normal arrays.
#[inline(always)]
unsafe fn sample_located<const CLAMP: bool>(
    frame: &GridFrame,
    normals: Soa,
    start: usize,
    block: &LocatedBlock,
    acc: &mut ClassAccumulator,
) {
    unsafe {
        let kind = block.kind;
        let non_free = _mm512_test_epi32_mask(kind, kind);
        if non_free == 0 {
            return;
        }
        let kind_is = |k: Voxel| _mm512_cmpeq_epi32_mask(kind, _mm512_set1_epi32(k.bits().into()));
        let (surface, proximity, interior) = (
            kind_is(Voxel::Surface),
            kind_is(Voxel::Proximity),
            kind_is(Voxel::Interior),
        );
        acc.non_free += count(non_free);
        acc.interior += count(interior);
        let Placed { lever, grid, cell } = block.placed;
        let normal = mat_vec(&frame.rotation, &load(normals, start));
        let pushing = surface | interior;
        if pushing != 0 {
            acc.surface += count(surface);
            // Interior points push as layer 1.
            let layer = _mm512_mask_set1_epi32(block.layer, interior, 1);
            let zero = _mm512_setzero_ps();
            let d = _mm512_add_ps(
                dot(&normal, &to_centre(&cell, &grid)),
                _mm512_cvtepi32_ps(layer),
            );
            let keep = _mm512_mask_cmp_ps_mask::<_CMP_GT_OQ>(pushing, d, zero);
            let depth = _mm512_maskz_mul_ps(keep, d, _mm512_set1_ps(frame.voxel_q));
            acc.contacts += count(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(depth, zero));
            let force_dir = scale(&normal, depth);
            add3_fixed::<CLAMP>(&mut acc.depth_normal, &force_dir);
            add3_fixed::<CLAMP>(&mut acc.depth_torque, &cross(&lever, &force_dir));
            acc.depth_blocks += 2;
        }
        if proximity != 0 {
            brake_lanes::<CLAMP>(frame, &lever, &normal, proximity, acc);
        }
    }
}

/// `super::avx2::brake_lanes` on sixteen lanes: `a = V·N` in the lanes of `mask` that approach
/// (`V·N < 0`), 0 elsewhere; adds `a²`, `a N` and `(P − x) × a N` and counts the approaching
/// lanes. `lever` is `P − x` in the frame's lever scale. Shared by the tangent-plane wide block
/// (Proximity lanes) and the distance model's (braking lanes).
///
/// # Safety
/// As [`add_fixed`]'s.
#[inline(always)]
pub(super) unsafe fn brake_lanes<const CLAMP: bool>(
    frame: &GridFrame,
    lever: &V3,
    normal: &V3,
    mask: __mmask16,
    acc: &mut ClassAccumulator,
) {
    unsafe {
        let velocity =
            add_cross_uniform(frame.linear_velocity, frame.angular_velocity_lever, lever);
        let zero = _mm512_setzero_ps();
        let approach = dot(&velocity, normal);
        let approaching = _mm512_mask_cmp_ps_mask::<_CMP_LT_OQ>(mask, approach, zero);
        let x = _mm512_maskz_mov_ps(approaching, approach);
        let a = _mm512_mul_ps(x, _mm512_set1_ps(LENGTH_Q));
        let a_sq = _mm512_mul_ps(x, a);
        acc.approaching += count(_mm512_cmp_ps_mask::<_CMP_LT_OQ>(a, zero));
        add_fixed::<CLAMP>(&mut acc.brake_sq, a_sq);
        let brake_dir = scale(normal, a);
        add3_fixed::<CLAMP>(&mut acc.brake_force, &brake_dir);
        add3_fixed::<CLAMP>(&mut acc.brake_torque, &cross(lever, &brake_dir));
        acc.brake_blocks += 2;
    }
}
