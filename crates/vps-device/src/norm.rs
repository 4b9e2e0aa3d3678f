//! Vector lengths against a limit, without rounding up: what [`crate::DeviceLimits::saturate`]
//! relies on so that no wrench it returns is longer than its limit,
//! in exact arithmetic, by even one ulp.
//!
//! `v * (max / |v|)` is not enough: the division, the square root and the products each round to
//! nearest, so about 40 % of clamped vectors came out 1 to 2 ulps longer than `max`
//! (`max_force = 0.3` gave |F| = 0.30000000000000004). [`clamp_length`] scales, then steps the
//! scale down an ulp at a time ([`f64::next_down`]) until [`length_within`] holds; that test is
//! conservative (its margin covers every rounding of the f64 sum of squares), so what it accepts
//! is within the limit for the exact Euclidean length, and for any client computing the length in
//! f64, naively (`sqrt(x*x + y*y + z*z)`) or with `hypot`.
//! [`exceeds_exactly`] decides the same question without rounding at all (expansion arithmetic),
//! for tests and tools that check what was sent.

use glam::DVec3;

/// The most ulp steps [`clamp_length`] takes below `max / |v|`. The first candidate is at most a
/// few ulps too long and [`length_within`] keeps a margin of about 8 ulps, so about 10 steps are
/// needed; past this bound the zero vector is returned (never reached in the tests' 10^6 vectors).
pub const MAX_STEPS: u32 = 128;

/// `2^k` for `k` in the normal exponent range (-1022..=1023).
fn pow2(k: i32) -> f64 {
    debug_assert!((-1022..=1023).contains(&k));
    f64::from_bits(((k + 1023) as u64) << 52)
}

/// `x · 2^k`, exact unless the result overflows or falls below the normal range.
fn mul_pow2(mut x: f64, mut k: i32) -> f64 {
    while k > 1000 {
        x *= pow2(1000);
        k -= 1000;
    }
    while k < -1000 {
        x *= pow2(-1000);
        k += 1000;
    }
    x * pow2(k)
}

/// `floor(log2(x))` of a finite `x > 0` (subnormals included).
fn exponent(x: f64) -> i32 {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    if biased == 0 {
        let mantissa = bits & ((1u64 << 52) - 1);
        -1074 + (63 - mantissa.leading_zeros() as i32)
    } else {
        biased - 1023
    }
}

/// True only when the exact Euclidean length of `v` is at most `max` (finite, > 0); false for a
/// non-finite `v`. Conservative: it may say false for a vector within about 8 ulps below `max`,
/// never true for a longer one. Both are scaled by the power of two that puts `max` in [1, 2)
/// (exact), the sum of squares is taken in f64 and compared with `max²` less a margin of 16 units
/// of rounding (2^-49 relative), which covers the five roundings of the sum and the two of the
/// bound. No allocation, a dozen flops.
pub fn length_within(v: DVec3, max: f64) -> bool {
    if !(v.is_finite() && max.is_finite() && max > 0.0) {
        return false;
    }
    let e = exponent(max);
    let m = mul_pow2(max, -e);
    let [x, y, z] = v.to_array().map(|c| mul_pow2(c, -e));
    // Components scaled below 2^-1022 lose bits, by at most 2^-1075 each: their squares are under
    // 2^-2000, far inside the margin (m² ≥ 1).
    let sum = x * x + y * y + z * z;
    sum <= (m * m) * (1.0 - pow2(-49))
}

/// `v` itself when [`length_within`]`(v, max)`, else `v` scaled down, direction kept to within a
/// few ulps, to the longest length found within `max` by stepping the scale down from
/// `max / |v|` one ulp at a time ([`MAX_STEPS`] at most; the zero vector beyond). A non-finite
/// `v` gives the zero vector. `max` must be finite and > 0. No allocation.
pub fn clamp_length(v: DVec3, max: f64) -> DVec3 {
    if !(v.is_finite() && max.is_finite() && max > 0.0) {
        return DVec3::ZERO;
    }
    if length_within(v, max) {
        return v;
    }
    // Divide by the largest component first: the length of `u` is in [1, √3], never overflows
    // (|v| can exceed f64::MAX for finite components) and never underflows.
    let big = v.abs().max_element();
    let u = v / big;
    let mut scale = max / u.length();
    for _ in 0..MAX_STEPS {
        let out = u * scale;
        if length_within(out, max) {
            return out;
        }
        scale = scale.next_down();
    }
    DVec3::ZERO
}

/// Error-free sum: `a + b = s + e` exactly (Knuth's two-sum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// Error-free product: `a · b = p + e` exactly (fused multiply-add), barring underflow.
fn two_product(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

/// True when the exact Euclidean length of `v` exceeds `max`, decided without rounding: the
/// squares and `max²` are split into exact pairs and summed as a nonoverlapping expansion
/// (Shewchuk 1997), whose sign is that of its largest nonzero term. Exact while no square
/// underflows (components and `max` above about 1e-150) or overflows (below about 1e150); a
/// non-finite `v` exceeds any limit. Slower than [`length_within`]: for checking what was sent.
pub fn exceeds_exactly(v: DVec3, max: f64) -> bool {
    if !v.is_finite() {
        return true;
    }
    let mut terms = [0.0; 8];
    for (i, c) in v.to_array().into_iter().enumerate() {
        let (p, e) = two_product(c, c);
        terms[2 * i] = p;
        terms[2 * i + 1] = e;
    }
    let (p, e) = two_product(max, max);
    terms[6] = -p;
    terms[7] = -e;
    // Grow the expansion one term at a time; each two_sum is exact, so the components always sum
    // to the exact total, in increasing magnitude without overlap.
    let mut expansion = [0.0; 8];
    for (n, &t) in terms.iter().enumerate() {
        let mut q = t;
        for c in expansion.iter_mut().take(n) {
            let (s, err) = two_sum(q, *c);
            *c = err;
            q = s;
        }
        expansion[n] = q;
    }
    expansion
        .iter()
        .rev()
        .find(|c| **c != 0.0)
        .is_some_and(|c| *c > 0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// SplitMix64: a seeded stream of u64, so every run tests the same vectors.
    struct SplitMix(u64);

    impl SplitMix {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        }

        /// Uniform in [0, 1).
        fn unit(&mut self) -> f64 {
            (self.next() >> 11) as f64 / (1u64 << 53) as f64
        }

        /// ± 10^[lo, hi), log-uniform.
        fn signed_log(&mut self, lo: f64, hi: f64) -> f64 {
            let sign = if self.next() & 1 == 0 { 1.0 } else { -1.0 };
            sign * 10f64.powf(lo + (hi - lo) * self.unit())
        }
    }

    /// The case of the issue: with `max_force = 0.3` the old clamp (`clamp_length_max`) sent
    /// |F| = 0.30000000000000004. Found among this stream's vectors; each one below is one the
    /// old clamp left over the limit, and the new one does not.
    #[test]
    fn the_old_clamp_overshoots_and_the_new_one_does_not() {
        for max in [0.3, 15.0, 0.1] {
            let mut rng = SplitMix(36);
            let mut over_before = 0;
            for _ in 0..1000 {
                let v = DVec3::new(
                    rng.signed_log(-1.0, 2.0),
                    rng.signed_log(-1.0, 2.0),
                    rng.signed_log(-1.0, 2.0),
                );
                let old = v.clamp_length_max(max);
                if exceeds_exactly(old, max) {
                    over_before += 1;
                }
                let new = clamp_length(v, max);
                assert!(!exceeds_exactly(new, max), "{v:?} → {new:?} over {max}");
                assert!(new.length() <= max, "{v:?} → {new:?}");
                assert!(new.x.hypot(new.y).hypot(new.z) <= max, "{v:?} → {new:?}");
            }
            assert!(
                over_before > 100,
                "the old clamp overshot {max} for only {over_before} of 1000"
            );
        }
    }

    /// The issue's figures: this vector clamped by the old `clamp_length_max` had
    /// |F| = 0.30000000000000004 at 0.3 N and 15.000000000000002 at 15 N (in f64, naively).
    #[test]
    fn the_issue_figures_are_within_the_limit() {
        let v = DVec3::new(2.15741445250917, -17.383227521030502, 13.589044385907556);
        assert_eq!(v.clamp_length_max(0.3).length(), 0.30000000000000004);
        assert_eq!(v.clamp_length_max(15.0).length(), 15.000000000000002);
        for max in [0.3, 15.0, 0.1] {
            let c = clamp_length(v, max);
            assert!(!exceeds_exactly(c, max), "{c:?}");
            assert!(
                c.length() <= max && c.length() > max * (1.0 - 1e-14),
                "{c:?}"
            );
        }
        assert_eq!(clamp_length(v, 0.3).length(), 0.2999999999999997);
    }

    /// 10^6 random vectors and limits over 24 decades: the clamped vector never exceeds the limit
    /// (exactly, and in f64 naively and with hypot), keeps the direction, loses at most 1e-14 of
    /// the limit, and a vector within the limit is returned unchanged.
    #[test]
    fn no_clamped_vector_exceeds_its_limit() {
        let mut rng = SplitMix(0x5a7);
        for i in 0..1_000_000 {
            let max = rng.signed_log(-6.0, 4.0).abs();
            let mut v = DVec3::new(
                rng.signed_log(-8.0, 8.0),
                rng.signed_log(-8.0, 8.0),
                rng.signed_log(-8.0, 8.0),
            );
            if i % 7 == 0 {
                v.y = 0.0;
            }
            if i % 11 == 0 {
                // Lengths near the limit: within a few ulps of max on either side.
                v = v.normalize() * max * (1.0 + (rng.unit() - 0.5) * 1e-15);
            }
            let c = clamp_length(v, max);
            assert!(!exceeds_exactly(c, max), "{i}: {v:?} → {c:?} over {max}");
            assert!(c.length() <= max, "{i}: {v:?} → {c:?}");
            assert!(c.x.hypot(c.y).hypot(c.z) <= max, "{i}: {v:?} → {c:?}");
            if exceeds_exactly(v, max) {
                assert!(c.length() >= max * (1.0 - 1e-14), "{i}: {v:?} → {c:?}");
                let cos = c.dot(v) / (c.length() * v.length());
                assert!(cos > 1.0 - 1e-14, "{i}: direction {v:?} → {c:?}");
            } else if v.length() < max * (1.0 - 1e-14) {
                assert_eq!(c, v, "{i}");
            }
        }
    }

    #[test]
    fn extreme_vectors_are_clamped_or_zeroed() {
        for max in [0.3, 15.0, 1e4, f64::MIN_POSITIVE, 5e-324] {
            for v in [
                DVec3::splat(f64::MAX),
                DVec3::new(f64::MAX, -f64::MAX, 1.0),
                DVec3::new(1e300, 0.0, 0.0),
                DVec3::new(5e-324, 5e-324, 0.0),
            ] {
                let c = clamp_length(v, max);
                assert!(length_within(c, max), "{v:?} at {max}: {c:?}");
                assert!(c.length() <= max, "{v:?} at {max}: {c:?}");
            }
            for v in [
                DVec3::new(f64::NAN, 0.0, 0.0),
                DVec3::new(0.0, f64::INFINITY, 0.0),
            ] {
                assert_eq!(clamp_length(v, max), DVec3::ZERO);
                assert!(!length_within(v, max));
            }
        }
        // A huge vector keeps its direction.
        let c = clamp_length(DVec3::new(1e300, 1e300, 0.0), 15.0);
        assert!((c.x - c.y).abs() <= 1e-15 && c.z == 0.0, "{c:?}");
        assert!(c.length() > 15.0 * (1.0 - 1e-14), "{c:?}");
    }

    #[test]
    fn exceeds_exactly_decides_at_the_ulp() {
        assert!(!exceeds_exactly(DVec3::new(0.3, 0.0, 0.0), 0.3));
        assert!(exceeds_exactly(DVec3::new(0.3f64.next_up(), 0.0, 0.0), 0.3));
        assert!(!exceeds_exactly(DVec3::new(3.0, 4.0, 0.0), 5.0));
        assert!(exceeds_exactly(DVec3::new(3.0, 4.0f64.next_up(), 0.0), 5.0));
        assert!(exceeds_exactly(DVec3::new(f64::NAN, 0.0, 0.0), 5.0));
    }
}
