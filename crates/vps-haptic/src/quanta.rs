//! Per-point fixed-point quanta of the sampling kernel: each point's contribution is rounded to an
//! integer multiple of a power-of-two quantum as soon as it is computed, and integers add exactly
//! in any order, so a frame's sums are the same bits however its points are split into classes,
//! shares and threads.
//!
//! This applies to the contact sums. A quantum `2^-e` (SI units) is chosen per sum from a bound on
//! what one point can contribute, so that a point's value fits `|q| ≤ 2^30` in an `i32` lane:
//!
//! | sum | per-point bound |
//! |---|---|
//! | `depth_normal` (m) | `D = (√3/2 + 255) s`: depth of the deepest layer an 8-bit map holds |
//! | `depth_torque` (m²) | `r_max D` |
//!
//! with `s` the voxel size and `r_max` the shell's largest point radius. (The braking sums stay on
//! per-class f64 sums rounded once, see `lane_sums`: their plausibility check, `|S_f| ≤ √(n S_q)`,
//! needs `S_q` and `S_f` rounded at one fine resolution, which a per-point `i32` quantum sized for
//! the fastest point cannot give to slowly approaching points.) `e` is the largest integer with `bound · 2^e ≤ 2^30`, capped at the exponent of the
//! sums' LSB ([`crate::sums`]: 40 for length-like, 48 for area-like sums) so that a quantum is never
//! finer than the sums' LSB and turning a total into LSBs is an exact left shift by
//! `LSB exponent − e ≥ 0`; and floored 64 below it so the shift stays ≤ 64. For the 5 mm voxels of
//! the demo: depth quantum 2^-29 m ≈ 1.9 nm (K_ff of a few kN/m makes that µN per point);
//! torque quantum for a 0.1 m part 2^-32 m² ≈ 2.3e-10 m².
//!
//! Range: every point's integer is clamped to `±2^30` before it is added (the bounds above hold for
//! unit normals and an orthonormal rotation; the clamp makes them hold for any input), so an `i64`
//! lane of the kernel cannot overflow before `2^33` points, and a class's total over eight lanes
//! (at most `2^32 · 2^30 = 2^62` for a class of up to `2^32` points) shifted left by at most 64
//! stays below `2^126`: exact in `i128`. (Proved for the extreme cases in this module's tests.)
//!
//! The quanta depend only on the voxel size and the shell's `r_max`, which every share of a frame
//! has in common, and are computed from exact f64 bit patterns (no `log2` from libm), so
//! every worker picks the same quanta.

use crate::sums::{AREA_SCALE, LENGTH_SCALE};

/// Largest magnitude of one point's quantised value.
pub(crate) const POINT_LIMIT: f32 = (1u32 << 30) as f32;

/// Exponent of the sums' LSB for length-like sums (2^-40).
const LENGTH_EXP: i32 = 40;
/// Exponent of the sums' LSB for area-like sums (2^-48).
const AREA_EXP: i32 = 48;

// The exponents above are the sums' scales.
const _: () = assert!(LENGTH_SCALE == (1u64 << LENGTH_EXP) as f64);
const _: () = assert!(AREA_SCALE == (1u64 << AREA_EXP) as f64);

/// Deepest Surface layer any voxmap reports (layers are `u8`).
const MAX_LAYER: f64 = 255.0;

/// One sum's quantum: points are multiplied by `scale = 2^e` and rounded to integers; totals are
/// shifted left by `shift = LSB exponent − e` into the sums' LSBs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Quantum {
    pub(crate) scale: f32,
    pub(crate) shift: u32,
}

impl Quantum {
    /// The quantum for per-point values of magnitude at most `bound` in a sum whose LSB is
    /// `2^-lsb_exp` (see the module docs). A bound that is 0, subnormal or not finite gets the
    /// finest quantum (the LSB) or, if infinite, the coarsest.
    fn for_bound(bound: f64, lsb_exp: i32) -> Quantum {
        let bits = bound.to_bits();
        let biased = ((bits >> 52) & 0x7ff) as i32;
        let e = if biased == 0x7ff {
            lsb_exp - 64
        } else if biased == 0 {
            lsb_exp
        } else {
            // bound < 2^(k + 1) with k = biased − 1023, so bound · 2^(29 − k) < 2^30.
            (29 - (biased - 1023)).clamp(lsb_exp - 64, lsb_exp)
        };
        // 2^e from its bits: e is within [−24, 48], a normal f32 exponent.
        Quantum {
            scale: f32::from_bits(((e + 127) as u32) << 23),
            shift: (lsb_exp - e) as u32,
        }
    }
}

/// The quanta of the two contact sums.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Quanta {
    pub(crate) depth_normal: Quantum,
    pub(crate) depth_torque: Quantum,
}

impl Quanta {
    /// The quanta for voxel size `voxel_size` (m) and a shell of largest point radius
    /// `max_radius` (m) (see the module docs for the bounds).
    pub(crate) fn new(voxel_size: f64, max_radius: f64) -> Quanta {
        let depth = (0.5 * 3f64.sqrt() + MAX_LAYER) * voxel_size;
        Quanta {
            depth_normal: Quantum::for_bound(depth, LENGTH_EXP),
            depth_torque: Quantum::for_bound(max_radius * depth, AREA_EXP),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_bounded_value_fits_the_point_limit_at_the_finest_allowed_quantum() {
        for bound in [1e-9, 4.3e-3, 0.005 * 256.0, 1.0, 3.7, 1e3, 1.7e6] {
            let q = Quantum::for_bound(bound, LENGTH_EXP);
            let scaled = bound * f64::from(q.scale);
            assert!(scaled <= f64::from(POINT_LIMIT), "{bound}: {scaled}");
            // Not needlessly coarse: within a factor of two of the limit, unless capped at the LSB.
            assert!(
                q.shift == 0 || 2.0 * scaled >= f64::from(POINT_LIMIT),
                "{bound}"
            );
            assert!(q.shift <= 64);
        }
        // The demo's 5 mm voxels: depth quantum 2^-29 m; a 0.1 m part: torque quantum 2^-32 m².
        let quanta = Quanta::new(0.005, 0.1);
        assert_eq!(quanta.depth_normal.scale, (1u32 << 29) as f32);
        assert_eq!(quanta.depth_normal.shift, 11);
        assert_eq!(quanta.depth_torque.shift, 16);
        // A shell of one point at the origin: no torque, finest quantum.
        assert_eq!(Quanta::new(0.005, 0.0).depth_torque.shift, 0);
    }

    #[test]
    fn degenerate_bounds_stay_within_the_shift_range() {
        for bound in [
            0.0,
            f64::MIN_POSITIVE / 4.0,
            f64::INFINITY,
            f64::NAN,
            f64::MAX,
        ] {
            let q = Quantum::for_bound(bound, AREA_EXP);
            assert!(q.shift <= 64, "{bound}");
            assert!(q.scale.is_finite() && q.scale > 0.0);
        }
    }

    /// The overflow argument of the module docs, at its extremes: a class of 2^32 points each at
    /// the clamp, in eight i64 lanes, shifted by the largest shift, fits an i128.
    #[test]
    fn extreme_class_totals_fit_i128() {
        let per_lane_points = (1i64 << 32) / 8;
        let lane = per_lane_points.checked_mul(1 << 30).expect("lane fits i64");
        let total = (0..8).try_fold(0i128, |acc, _| acc.checked_add(i128::from(lane)));
        let total = total.expect("class total fits");
        assert!(total.checked_mul(1i128 << 64).is_some());
        assert_eq!(total, 1i128 << 62);
    }
}
