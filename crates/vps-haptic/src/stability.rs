//! The fixed-step stability bound behind the default gains.
//!
//! # The bound
//!
//! [`crate::step`] integrates with semi-implicit (symplectic) Euler: `v' = v + dt·a(x, v)`, then
//! `x' = x + dt·v'`. Linearise one axis near a resting contact as `a = −ω² x − c v` (ω² = total
//! stiffness / mass, c = damping / mass). With `u = dt·v` and `h = ω dt`, one step is the matrix
//! `[[1 − c dt, −h²], [1 − c dt, 1 − h²]]` acting on `(u, x)`, whose trace is `2 − c dt − h²` and
//! determinant `1 − c dt`. Both eigenvalues lie inside the unit circle (Jury criterion) iff
//!
//! ```text
//!     0 < c·dt < 2      and      (ω dt)² + 2 c dt < 4.
//! ```
//!
//! We call `((ω dt)² + 2 c dt) / 4` the *stability index* (< 1: stable; [`stability_index`]).
//!
//! # What stiffness the part sees
//!
//! In resting contact the part feels the coupling spring `k_T` and the force field. After the
//! paper's averaging (force × threshold/N once N ≥ threshold, threshold = 10), N points at the same
//! depth give a field stiffness `min(N, 10)·K_ff ≤ 10 K_ff`. The only damping is the coupling's,
//! critically damped: `c = 2 √(k_T/m)`. Rotationally, each contact has a lever at most `r_max`, so
//! the field's rotational stiffness is at most `10 K_ff r_max²`; with the coupling's rotational
//! natural frequency set equal to the translational one (`k_R = k_T I / m`; the default is twice
//! that, [`crate::params::ROTATIONAL_COUPLING_FACTOR`], which raises the rotational index to ≈ 0.57) and
//! `I = 0.4 m r_max²` (solid sphere), the rotational field term is `10 K_ff r_max² / I = 25 K_ff / m`,
//! 2.5 times the translational one. So with `h = √(k_T/m) dt` and `K_ff = k_T / κ`:
//!
//! ```text
//!     translation:  (1 + 10/κ)  h² + 4h < 4
//!     rotation:     (1 + ρ_R)   h² + 4h < 4,    ρ_R = 10 m r_max² / (κ I)  (= 25/κ for a sphere)
//! ```
//!
//! # The defaults
//!
//! * `κ = k_T / K_ff = 1/2` ([`COUPLING_TO_FIELD`]): the paper clamps the spring at its value for a
//!   half-voxel stretch, `k_T s/2`, so that a *single* contact at the deepest half-voxel,
//!   `K_ff s/2`, can hold it; κ = 1/2 holds it at a quarter voxel, leaving margin before the point
//!   crosses into the next voxel (where its depth, and force, drop).
//! * Margin: we take `h` so that the worse of the two indices is [`STABILITY_MARGIN`] = 1/2, i.e.
//!   `(1 + ρ) h² + 4h = 4 · 1/2`, `h = 2 (√(1 + μ(1 + ρ)) − 1) / (1 + ρ)` ([`coupling_step_ratio`]).
//!   For a sphere-inertia part with κ = 1/2: ρ = 50, h ≈ 0.163.
//! * Then `k_T = h² m / dt²`, `K_ff = k_T / κ`, `k_R = k_T I / m`, `b_T = 2 √(k_T m)`,
//!   `b_R = 2 √(k_R I)`. With the paper's m = 12 g and dt = 1 ms: k_T ≈ 318 N/m, K_ff ≈ 635 N/m,
//!   and the clamped coupling force at 5 mm voxels, `k_T s / 2`, is ≈ 0.8 N. Stiffness (and the
//!   holding force) scales with m / dt²: a heavier reflected mass buys a stiffer wall.
//!
//! The bound counts on the coupling damper acting in contact; [`crate::coupling::coupling_wrench`]
//! clamps the spring before adding the damper so that a long stretch cannot mask it.
//!
//! # A pair of moving parts
//!
//! Two parts pressed into each other ([`crate::pair`]), each held by its own coupling: with
//! `x = x_a − x_b`, both samplings see the interpenetration, and the pair force applies a share
//! `s` of each, about `−2 s N K_ff x` on A and its negation on B. The relative motion then sees
//! `ω² = k_T/m + 2 s N K_ff (1/m_a + 1/m_b)`: for two equal parts `4 s` times a wall's field term
//! (rotation likewise, with `r²/I`). [`crate::pair::pair_stability`] evaluates it: with the default
//! gains and two 40 mm cubes, `s = ½` gives indices 0.43 (translation) and 0.90 (rotation),
//! `s = 1` gives 1.57 in rotation: past the bound, which is what the measurement found (two cubes
//! pressed together at full share buzzed for ever at 56 mm/s). Hence [`crate::pair::PAIR_SHARE`]
//! = ½; a heavier partner (a larger reduced mass) lowers the index.
//!
//! Not covered by the linear bound: the force jumps as points cross voxel boundaries and as N
//! changes (the paper's non-passivity). The crate's stability tests measure energy over 60 s of
//! resting contact and sweep K_ff, dt and m (`tests/stability.rs`).

/// The fraction of the stability limit the default gains use (index ≤ this).
pub const STABILITY_MARGIN: f64 = 0.5;

/// Default ratio `κ = k_T / K_ff` of coupling stiffness to per-point field stiffness.
pub const COUPLING_TO_FIELD: f64 = 0.5;

/// Moment of inertia factor of a solid sphere: `I = 0.4 m r²`.
pub const SPHERE_INERTIA_FACTOR: f64 = 0.4;

/// The stability index `((ω dt)² + 2 c dt) / 4` of symplectic Euler on `a = −ω² x − c v`, where
/// `omega_dt = ω·dt` and `damping_dt = c·dt`; stable iff index < 1 and `c·dt < 2`.
pub fn stability_index(omega_dt: f64, damping_dt: f64) -> f64 {
    if damping_dt >= 2.0 {
        return f64::INFINITY;
    }
    (omega_dt * omega_dt + 2.0 * damping_dt) / 4.0
}

/// The coupling step ratio `h = √(k_T/m)·dt` that puts the index of
/// `(1 + ρ) h² + 4h` (critical coupling damping, field stiffness ρ times the coupling's) at
/// `margin` of the limit 4: `h = 2 (√(1 + margin (1 + ρ)) − 1) / (1 + ρ)`.
pub fn coupling_step_ratio(stiffness_ratio: f64, margin: f64) -> f64 {
    let a = 1.0 + stiffness_ratio;
    2.0 * ((1.0 + margin * a).sqrt() - 1.0) / a
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn step_ratio_solves_the_quadratic() {
        for rho in [0.0, 1.0, 20.0, 50.0] {
            for margin in [0.25, 0.5, 1.0] {
                let h = coupling_step_ratio(rho, margin);
                let lhs = (1.0 + rho) * h * h + 4.0 * h;
                assert!(
                    (lhs - 4.0 * margin).abs() < 1e-12,
                    "rho {rho} margin {margin}"
                );
            }
        }
    }

    #[test]
    fn critically_damped_limit_is_two_root_two_minus_two() {
        // Pure coupling (ρ = 0) at margin 1: h² + 4h = 4 → h = 2√2 − 2.
        let h = coupling_step_ratio(0.0, 1.0);
        assert!((h - (2.0 * 2f64.sqrt() - 2.0)).abs() < 1e-12);
        assert!((stability_index(h, 2.0 * h) - 1.0).abs() < 1e-12);
    }
}
