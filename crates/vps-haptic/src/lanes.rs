//! Eight-lane f32 arithmetic for the sampling kernel: a block of [`LANES`] points is processed as
//! structure-of-arrays, one array element per point, in plain loops over fixed-size arrays that the
//! compiler turns into SIMD (two SSE2 registers per array on baseline x86-64, one AVX2 register
//! where the kernel's AVX2 copy runs).
//!
//! Every operation here is an IEEE basic operation (add, subtract, multiply, compare, convert) in
//! a fixed order per lane, never a fused multiply-add, so a lane gives the same bits whatever
//! instructions compute it: scalar, SSE2 or AVX2. The kernel's exactness rests on this.

use glam::Mat3;

/// Points per block, and the number of accumulator lanes.
pub(crate) const LANES: usize = vps_voxmap::BLOCK_LANES;

/// One f32 value per lane.
pub(crate) type F32s = [f32; LANES];
/// One 3-vector per lane, as three component arrays.
pub(crate) type Vec3s = [F32s; 3];

/// `m · v` per lane: `(c0 v.x + c1 v.y) + c2 v.z` with `c` the matrix columns (glam's order).
#[inline(always)]
pub(crate) fn mat_vec(m: &Mat3, v: &Vec3s) -> Vec3s {
    let cols = [m.x_axis, m.y_axis, m.z_axis];
    let mut out = [[0.0; LANES]; 3];
    for (r, o) in out.iter_mut().enumerate() {
        let (a, b, c) = (cols[0][r], cols[1][r], cols[2][r]);
        for l in 0..LANES {
            o[l] = a * v[0][l] + b * v[1][l] + c * v[2][l];
        }
    }
    out
}

/// `v · scale + offset` per lane.
#[inline(always)]
pub(crate) fn scale_add(v: &Vec3s, scale: f32, offset: [f32; 3]) -> Vec3s {
    let mut out = *v;
    for (o, off) in out.iter_mut().zip(offset) {
        for x in o.iter_mut() {
            *x = *x * scale + off;
        }
    }
    out
}

/// `a · b` per lane: `(a.x b.x + a.y b.y) + a.z b.z` (glam's order).
#[inline(always)]
pub(crate) fn dot(a: &Vec3s, b: &Vec3s) -> F32s {
    let mut out = [0.0; LANES];
    for (l, o) in out.iter_mut().enumerate() {
        *o = a[0][l] * b[0][l] + a[1][l] * b[1][l] + a[2][l] * b[2][l];
    }
    out
}

/// `a × b` per lane (glam's formula: `(a.y b.z − b.y a.z, a.z b.x − b.z a.x, a.x b.y − b.x a.y)`).
#[inline(always)]
pub(crate) fn cross(a: &Vec3s, b: &Vec3s) -> Vec3s {
    let mut out = [[0.0; LANES]; 3];
    for (r, o) in out.iter_mut().enumerate() {
        let (i, j) = ((r + 1) % 3, (r + 2) % 3);
        for l in 0..LANES {
            o[l] = a[i][l] * b[j][l] - b[i][l] * a[j][l];
        }
    }
    out
}

/// `v · s` per lane, `s` per lane.
#[inline(always)]
pub(crate) fn scale(v: &Vec3s, s: &F32s) -> Vec3s {
    let mut out = *v;
    for o in out.iter_mut() {
        for l in 0..LANES {
            o[l] *= s[l];
        }
    }
    out
}

/// `u + w × v` for one vector `u`, `w` and per-lane `v` (a point's velocity from the part's linear
/// velocity `u`, angular velocity `w` and lever `v`), with glam's cross formula.
#[inline(always)]
pub(crate) fn add_cross_uniform(u: [f32; 3], w: [f32; 3], v: &Vec3s) -> Vec3s {
    let mut out = [[0.0; LANES]; 3];
    for (r, o) in out.iter_mut().enumerate() {
        let (i, j) = ((r + 1) % 3, (r + 2) % 3);
        for l in 0..LANES {
            o[l] = u[r] + (w[i] * v[j][l] - v[i][l] * w[j]);
        }
    }
    out
}

/// `floor(v)` per lane as an integer. A value beyond the i32 range, or NaN, gives `i32::MIN` or
/// `i32::MAX`, which lies outside any grid (dims are at most `i32::MAX`): read as Free.
///
/// On x86-64: truncate with `cvttps2dq` (gives `i32::MIN` for every out-of-range or NaN lane in
/// one instruction; the scalar `as i32` saturates and checks NaN per value), then step down where
/// truncation rounded a negative value up. No libm call: baseline x86-64 has no SSE4.1 `roundps`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn floor_i32(v: &F32s) -> [i32; LANES] {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi32, _mm_castps_si128, _mm_cmplt_ps, _mm_cvtepi32_ps, _mm_cvttps_epi32,
        _mm_loadu_ps, _mm_storeu_si128,
    };
    let mut out = [0i32; LANES];
    for q in 0..LANES / 4 {
        // SAFETY: SSE and SSE2 are part of the x86-64 baseline; `v[4q..4q + 4]` and
        // `out[4q..4q + 4]` are 16 readable / writable bytes (q < LANES / 4), and the unaligned
        // load and store have no alignment requirement.
        unsafe {
            let x = _mm_loadu_ps(v.as_ptr().add(4 * q));
            let truncated = _mm_cvttps_epi32(x);
            // All ones (−1) where truncation rounded up, i.e. `x < trunc(x)`.
            let rounded_up = _mm_castps_si128(_mm_cmplt_ps(x, _mm_cvtepi32_ps(truncated)));
            let floored = _mm_add_epi32(truncated, rounded_up);
            _mm_storeu_si128(out.as_mut_ptr().add(4 * q).cast::<__m128i>(), floored);
        }
    }
    out
}

/// Portable form of the x86-64 [`floor_i32`]: the same results (out-of-range values saturate,
/// outside any grid).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(crate) fn floor_i32(v: &F32s) -> [i32; LANES] {
    std::array::from_fn(|l| {
        let t = v[l] as i32;
        t - (v[l] < t as f32) as i32
    })
}

/// Bit `l` set where lane `l`'s cell differs from lane `l − 1`'s (lane 0: from `first_prev`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn differs_from_previous(cell: &[[i32; LANES]; 3], first_prev: [i32; 3]) -> u32 {
    use std::arch::x86_64::{
        _mm_and_si128, _mm_castsi128_ps, _mm_cmpeq_epi32, _mm_loadu_si128, _mm_movemask_ps,
        _mm_set1_epi32,
    };
    let mut mask = 0u32;
    for q in 0..LANES / 4 {
        // SAFETY: SSE2 is part of the x86-64 baseline; every load reads 16 bytes inside a
        // `[i32; LANES]` array (offset 4q, q < LANES / 4), with no alignment requirement.
        unsafe {
            let mut same = _mm_set1_epi32(-1);
            for r in 0..3 {
                let mut prev = [0i32; LANES];
                prev[0] = first_prev[r];
                prev[1..].copy_from_slice(&cell[r][..LANES - 1]);
                let a = _mm_loadu_si128(cell[r].as_ptr().add(4 * q).cast());
                let b = _mm_loadu_si128(prev.as_ptr().add(4 * q).cast());
                same = _mm_and_si128(same, _mm_cmpeq_epi32(a, b));
            }
            mask |= (_mm_movemask_ps(_mm_castsi128_ps(same)) as u32) << (4 * q);
        }
    }
    !mask & ((1 << LANES) - 1)
}

/// Portable form of the x86-64 [`differs_from_previous`].
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
pub(crate) fn differs_from_previous(cell: &[[i32; LANES]; 3], first_prev: [i32; 3]) -> u32 {
    let mut mask = 0u32;
    for l in 0..LANES {
        let prev = |r: usize| {
            if l == 0 {
                first_prev[r]
            } else {
                cell[r][l - 1]
            }
        };
        let differs = (cell[0][l] != prev(0)) | (cell[1][l] != prev(1)) | (cell[2][l] != prev(2));
        mask |= u32::from(differs) << l;
    }
    mask
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn floor_matches_f32_floor_and_sends_huge_values_outside_any_grid() {
        let xs = [0.0f32, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999_999, -2.000_001];
        let got = floor_i32(&xs);
        for (g, x) in got.iter().zip(xs) {
            assert_eq!(*g, x.floor() as i32, "x = {x}");
        }
        let big = [
            16_777_215.0f32,
            -16_777_215.0,
            3e9,
            -3e9,
            f32::NAN,
            1e30,
            -1e30,
            0.0,
        ];
        let got = floor_i32(&big);
        assert_eq!(&got[..2], &[16_777_215, -16_777_215]);
        for &c in &got[2..7] {
            assert!(c < 0 || c == i32::MAX, "gave {c}");
        }
    }

    #[test]
    fn lane_formulas_match_glam() {
        let m = Mat3::from_euler(glam::EulerRot::XYZ, 0.3, -1.2, 2.1);
        let pts: Vec<Vec3> = (0..LANES)
            .map(|i| Vec3::new(i as f32 * 0.37 - 1.0, 0.2 - i as f32, (i * i) as f32 * 0.01))
            .collect();
        let soa: Vec3s = std::array::from_fn(|r| std::array::from_fn(|l| pts[l][r]));
        let (mv, cr, dt) = (
            mat_vec(&m, &soa),
            cross(&soa, &mat_vec(&m, &soa)),
            dot(&soa, &soa),
        );
        let u = Vec3::new(0.1, -0.2, 0.3);
        let w = Vec3::new(-2.0, 0.5, 4.0);
        let vel = add_cross_uniform(u.to_array(), w.to_array(), &soa);
        for (l, p) in pts.iter().enumerate() {
            let lane = |v: &Vec3s| Vec3::new(v[0][l], v[1][l], v[2][l]);
            assert_eq!(lane(&mv), m * *p);
            assert_eq!(lane(&cr), p.cross(m * *p));
            assert_eq!(dt[l], p.dot(*p));
            assert_eq!(lane(&vel), u + w.cross(*p));
        }
    }

    #[test]
    fn differs_from_previous_marks_lanes_that_change_cell() {
        let mut cell = [[7i32; LANES]; 3];
        cell[0][3] = 8; // lanes 3 and 4 in another cell
        cell[0][4] = 8; // lane 5 back to x = 7
        cell[2][6] = -1; // lane 6 alone, lane 7 back
        assert_eq!(differs_from_previous(&cell, [7; 3]), 0b1110_1000);
        assert_eq!(differs_from_previous(&cell, [7, 7, 6]), 0b1110_1001);
        assert_eq!(differs_from_previous(&cell, [i32::MIN; 3]) & 1, 1);
    }
}
