//! Integer fixed-point partial sums (docs/architecture.md#exact-sums-and-the-cluster): what one class, one share or the whole shell
//! contributes to a frame. Integer addition is associative and commutative, so sums merged in any
//! grouping and any order are bit-identical.
//!
//! Quantisation: the kernel computes each point's contribution in f32 (IEEE basic operations only,
//! so the same bits on every machine and instruction set) and rounds it at once to the nearest
//! integer multiple of the sum's LSB (ties to even); the integers are added. Every point is
//! rounded on its own, so the sums do not depend on how the shell is split, grouped or ordered.
//! The scales:
//!
//! | sum | unit | LSB |
//! |---|---|---|
//! | `depth_normal` = Σ d_i N_i | m | 2^-40 m ≈ 9.1e-13 m |
//! | `depth_torque` = Σ (P_i − x) × d_i N_i | m² | 2^-48 m² ≈ 3.6e-15 m² |
//! | `brake_sq` = S_q = Σ (V_i·N_i)² | m²/s² | 2^-40 m²/s² |
//! | `brake_force` = S_f = Σ (V_i·N_i) N_i | m/s | 2^-40 m/s |
//! | `brake_torque` = S_t = Σ (P_i − x) × (V_i·N_i) N_i | m²/s | 2^-48 m²/s |
//!
//! These LSBs are finer than the f32 rounding of the values they hold (a 5 mm depth is an f32 with
//! a 3e-10 m step; the LSB is 9.1e-13 m), so rounding adds no visible error: a sum is within half
//! an LSB per point of the exact sum of the f32 contributions. In force: one LSB of Σ d N is
//! `K_ff · 2^-40 m` before averaging (9.1e-10 N at K_ff = 1000 N/m), and the averaging
//! (`threshold / N` for N ≥ 10 contacts) keeps the whole rounding error of the contact force
//! below `5 · K_ff · 2^-40 m`, whatever the point count.
//!
//! Overflow bound: each point's rounded contribution is at most 2^50 LSB in magnitude (the kernel
//! clamps it there, `|d N| ≤ 1024 m`, `|(P − x) × d N| ≤ 4 m²`, `(V·N)² ≤ 1024 m²/s²`,
//! `|(P − x) × (V·N) N| ≤ 4 m²/s`, in frames whose speeds or sizes could exceed that; see
//! `crate::kernel`). The
//! kernel's `i64` lanes add at most 2^11 such values (< 2^61) before they move into these `i128`
//! totals, so a frame's sums cannot overflow below 2^77 points, far beyond any shell that fits in
//! memory. Counters are `u64`.

use glam::DVec3;

/// Scale of length-like sums (`depth_normal`, `brake_force`, `brake_sq`): 2^40 per SI unit.
pub const LENGTH_SCALE: f64 = (1u64 << 40) as f64;
/// Scale of area-like sums (`depth_torque`, `brake_torque`): 2^48 per SI unit.
pub const AREA_SCALE: f64 = (1u64 << 48) as f64;

/// The sums a worker or a local thread returns for a set of classes. All-zero (`Default`) is the
/// empty sum. Plain data: `Copy`, serde-serialisable, no allocation.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize,
)]
pub struct PartialSums {
    /// Σ d_i N_i over Surface points, LSB 2^-40 m per component.
    pub depth_normal: [i128; 3],
    /// Σ (P_i − x) × d_i N_i over Surface points, LSB 2^-48 m² per component.
    pub depth_torque: [i128; 3],
    /// Number of pushing points (Surface, or Interior pushing as layer 1) with d_i > 0 (the paper's N).
    pub contacts: u64,
    /// S_q = Σ (V_i·N_i)² over approaching Proximity points, LSB 2^-40 m²/s².
    pub brake_sq: i128,
    /// S_f = Σ (V_i·N_i) N_i over approaching Proximity points, LSB 2^-40 m/s per component.
    pub brake_force: [i128; 3],
    /// S_t = Σ (P_i − x) × (V_i·N_i) N_i over approaching Proximity points, LSB 2^-48 m²/s.
    pub brake_torque: [i128; 3],
    /// Number of approaching Proximity points (V_i·N_i < 0).
    pub approaching: u64,
    /// Number of points in Surface voxels.
    pub surface: u64,
    /// Number of points in Interior voxels.
    pub interior: u64,
    /// Number of points in any voxel that is not Free (Surface, Interior, Proximity).
    pub non_free: u64,
    /// Number of points sampled.
    pub sampled: u64,
}

impl PartialSums {
    /// Adds `other` into `self`: integer addition, exact in any grouping and order. Does not
    /// allocate. Wrapping is impossible for fewer than 2^64 points (see the module docs).
    #[inline]
    pub fn merge(&mut self, other: &PartialSums) {
        add3(&mut self.depth_normal, &other.depth_normal);
        add3(&mut self.depth_torque, &other.depth_torque);
        add3(&mut self.brake_force, &other.brake_force);
        add3(&mut self.brake_torque, &other.brake_torque);
        self.brake_sq = self.brake_sq.wrapping_add(other.brake_sq);
        self.contacts = self.contacts.wrapping_add(other.contacts);
        self.approaching = self.approaching.wrapping_add(other.approaching);
        self.surface = self.surface.wrapping_add(other.surface);
        self.interior = self.interior.wrapping_add(other.interior);
        self.non_free = self.non_free.wrapping_add(other.non_free);
        self.sampled = self.sampled.wrapping_add(other.sampled);
    }

    /// The deepest tangent-plane depth one pushing point can report (m) in a voxmap of voxel size
    /// `voxel_size` (m) whose Surface codes hold `surface_layers` layers (1 for a 2-bit map): a
    /// voxel's half diagonal plus one voxel per layer below the outermost Surface layer, and at
    /// least one layer, because an Interior point pushes as layer 1 (see `crate::kernel`):
    /// `(√3/2 + max(surface_layers − 1, 1)) · s`. `surface_layers` of 0 is read as 1.
    pub fn max_contact_depth(voxel_size: f64, surface_layers: u8) -> f64 {
        (0.5 * 3f64.sqrt() + f64::from(surface_layers.max(2) - 1)) * voxel_size
    }

    /// Consistency checks for a reply that claims to cover `points_in_share` points, where no
    /// Surface point can be deeper than `max_depth` (m; see [`PartialSums::max_contact_depth`]). True when: `sampled == points_in_share`;
    /// `contacts ≤ surface + interior` (Interior points push too); `surface + interior + approaching ≤ non_free ≤ sampled`; every
    /// component of Σ d N at most `contacts · max_depth`;
    /// depth sums zero without contacts; `S_q ≥ 0`; braking sums zero without approaching points and
    /// `|S_f component| ≤ √(approaching · S_q)` (Cauchy–Schwarz), each with one LSB per point of
    /// rounding slack (on `S_q` too: a class whose `S_q` rounds to 0 may still carry an `S_f`).
    /// Torque sums need the part's radius: see [`PartialSums::torque_within`]. Arithmetic only
    /// (the cluster checks every reply with it on the frame thread); does not allocate or block.
    pub fn is_plausible(&self, points_in_share: u64, max_depth: f64) -> bool {
        let counts_ok = self.sampled == points_in_share
            && self
                .surface
                .checked_add(self.interior)
                .is_some_and(|pushing| self.contacts <= pushing)
            && self
                .surface
                .checked_add(self.interior)
                .and_then(|x| x.checked_add(self.approaching))
                .is_some_and(|x| x <= self.non_free)
            && self.non_free <= self.sampled;
        let bound_ok = max_depth.is_finite() && max_depth > 0.0;
        if !counts_ok || !bound_ok {
            return false;
        }
        let slack = self.sampled as f64;
        let depth_bound = self.contacts as f64 * max_depth * LENGTH_SCALE;
        let depth_ok = self
            .depth_normal
            .iter()
            .all(|&c| (c as f64).abs() <= depth_bound + slack);
        let no_contact_ok =
            self.contacts > 0 || (self.depth_normal == [0; 3] && self.depth_torque == [0; 3]);
        let brake_bound =
            (self.approaching as f64 * (self.brake_sq as f64 + slack) * LENGTH_SCALE).sqrt();
        let brake_ok = self.brake_sq >= 0
            && self
                .brake_force
                .iter()
                .all(|&c| (c as f64).abs() <= brake_bound + slack);
        let no_brake_ok = self.approaching > 0
            || (self.brake_sq == 0 && self.brake_force == [0; 3] && self.brake_torque == [0; 3]);
        depth_ok && no_contact_ok && brake_ok && no_brake_ok
    }

    /// True when the torque sums are consistent with levers no longer than `max_radius` (m) and
    /// contact depths of at most `max_depth` (m; see [`PartialSums::max_contact_depth`]):
    /// `|Σ (P−x) × d N|_c ≤ r_max · contacts · max_depth` and
    /// `|S_t|_c ≤ r_max · √(approaching · S_q)`, with one LSB per point of slack. Arithmetic
    /// only; does not allocate or block.
    pub fn torque_within(&self, max_radius: f64, max_depth: f64) -> bool {
        if !(max_radius.is_finite() && max_radius >= 0.0 && max_depth.is_finite()) {
            return false;
        }
        let slack = self.sampled as f64;
        let ratio = AREA_SCALE / LENGTH_SCALE;
        // |r × a|_c ≤ |r| |a| ≤ r_max · max_depth per contact, summed over contacts.
        let depth_bound = self.contacts as f64 * max_radius * max_depth * AREA_SCALE;
        // |r × (V·N) N|_c ≤ r_max |V·N|, and Σ|V·N| ≤ √(n S_q).
        let brake_bound = max_radius
            * (self.approaching as f64 * (self.brake_sq as f64 + slack) * LENGTH_SCALE).sqrt()
            * ratio;
        self.depth_torque
            .iter()
            .all(|&c| (c as f64).abs() <= depth_bound + slack)
            && self
                .brake_torque
                .iter()
                .all(|&c| (c as f64).abs() <= brake_bound + slack)
    }
}

#[inline]
fn add3(a: &mut [i128; 3], b: &[i128; 3]) {
    for (x, y) in a.iter_mut().zip(b) {
        *x = x.wrapping_add(*y);
    }
}

/// The sums in SI units (f64), for the force model.
impl PartialSums {
    /// Σ d_i N_i (m).
    pub fn depth_normal_si(&self) -> DVec3 {
        to_dvec3(&self.depth_normal, LENGTH_SCALE)
    }

    /// Σ (P_i − x) × d_i N_i (m²).
    pub fn depth_torque_si(&self) -> DVec3 {
        to_dvec3(&self.depth_torque, AREA_SCALE)
    }

    /// S_q = Σ (V_i·N_i)² (m²/s²).
    pub fn brake_sq_si(&self) -> f64 {
        self.brake_sq as f64 / LENGTH_SCALE
    }

    /// S_f = Σ (V_i·N_i) N_i (m/s).
    pub fn brake_force_si(&self) -> DVec3 {
        to_dvec3(&self.brake_force, LENGTH_SCALE)
    }

    /// S_t = Σ (P_i − x) × (V_i·N_i) N_i (m²/s).
    pub fn brake_torque_si(&self) -> DVec3 {
        to_dvec3(&self.brake_torque, AREA_SCALE)
    }
}

fn to_dvec3(v: &[i128; 3], scale: f64) -> DVec3 {
    DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64) / scale
}

#[cfg(test)]
mod plausibility_tests {
    use super::*;

    const S: f64 = 0.005;

    /// One approaching point whose `S_q` rounded to 0 while `S_f` kept a few LSBs: genuine, kept.
    #[test]
    fn braking_sums_with_rounded_away_sq_are_plausible() {
        let sums = PartialSums {
            sampled: 1,
            non_free: 1,
            approaching: 1,
            brake_sq: 0,
            brake_force: [5, 0, 0],
            ..PartialSums::default()
        };
        assert!(sums.is_plausible(1, PartialSums::max_contact_depth(S, 1)));
        let mut absurd = sums;
        absurd.brake_force = [1 << 30, 0, 0];
        assert!(!absurd.is_plausible(1, PartialSums::max_contact_depth(S, 1)));
    }

    /// A contact 2.5 voxels deep is impossible in a 2-bit map and fine with 4 Surface layers.
    #[test]
    fn depth_bound_follows_the_surface_layers() {
        let depth = 2.5 * S;
        let sums = PartialSums {
            sampled: 1,
            non_free: 1,
            surface: 1,
            contacts: 1,
            depth_normal: [(depth * LENGTH_SCALE) as i128, 0, 0],
            depth_torque: [0, 0, (0.01 * depth * AREA_SCALE) as i128],
            ..PartialSums::default()
        };
        assert!(!sums.is_plausible(1, PartialSums::max_contact_depth(S, 1)));
        assert!(sums.is_plausible(1, PartialSums::max_contact_depth(S, 4)));
        assert!(!sums.torque_within(0.01, PartialSums::max_contact_depth(S, 1)));
        assert!(sums.torque_within(0.01, PartialSums::max_contact_depth(S, 4)));
        assert_eq!(
            PartialSums::max_contact_depth(S, 0),
            PartialSums::max_contact_depth(S, 1)
        );
    }
}
