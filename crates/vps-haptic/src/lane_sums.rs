//! How the sampling kernel adds up a class's per-point contributions ([`LaneSums`]):
//! [`FixedLanes`], the kernel's (each point's contact contribution quantised to an integer as it
//! is computed, integers summed: the same bits in any split of the shell), and
//! [`CanonicalF64Lanes`], the previous kernel's (f64 sums per lane in a canonical order, quantised
//! once per class: the same bits in any grouping of a fixed class count), kept so that
//! `vps bench kernel` can measure both. The braking sums use the f64 lanes in both (see
//! [`crate::quanta`] for why).

use crate::lanes::{
    add3_f64, add3_quantised, add_f64, reduce, total_i128, F32s, F64s, I64s, Vec3s, LANES,
};
use crate::quanta::{Quanta, Quantum, POINT_LIMIT};
use crate::sums::{PartialSums, AREA_SCALE, LENGTH_SCALE};

/// Per-lane running sums of one class's contact and braking contributions. The kernel adds whole
/// blocks (lanes that do not contribute hold 0) and turns the result into [`PartialSums`] once
/// per class. No allocation.
pub(crate) trait LaneSums: Sized {
    /// Empty sums for a class sampled with `quanta`.
    fn new(quanta: &Quanta) -> Self;
    /// Adds a block's `d N` (m) and `(P − x) × d N` (m²).
    fn add_contact(&mut self, force_dir: &Vec3s, torque: &Vec3s);
    /// Adds a block's `a²` (m²/s²), `a N` (m/s) and `(P − x) × a N` (m²/s).
    fn add_brake(&mut self, a_sq: &F32s, brake_dir: &Vec3s, torque: &Vec3s);
    /// Adds the contact totals to `sums`.
    fn contact_into(&self, sums: &mut PartialSums);
    /// Adds the braking totals to `sums`.
    fn brake_into(&self, sums: &mut PartialSums);
}

/// The kernel's sums: every contact contribution rounded to its quantum ([`crate::quanta`]) and
/// added as an integer in i64 lanes, so the contact totals do not depend on how the points are
/// grouped; the braking sums as [`CanonicalF64Lanes`].
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct FixedLanes {
    quanta: Quanta,
    depth_normal: [I64s; 3],
    depth_torque: [I64s; 3],
    brake: CanonicalF64Lanes,
}

/// `Σ lanes · 2^shift` per component, added to `acc`.
#[inline]
fn add_totals(acc: &mut [i128; 3], lanes: &[I64s; 3], quantum: Quantum) {
    for (a, l) in acc.iter_mut().zip(lanes) {
        *a = a.wrapping_add(total_i128(l) << quantum.shift);
    }
}

impl LaneSums for FixedLanes {
    #[inline(always)]
    fn new(quanta: &Quanta) -> Self {
        FixedLanes {
            quanta: *quanta,
            depth_normal: [[0; LANES]; 3],
            depth_torque: [[0; LANES]; 3],
            brake: CanonicalF64Lanes::default(),
        }
    }

    #[inline(always)]
    fn add_contact(&mut self, force_dir: &Vec3s, torque: &Vec3s) {
        let q = self.quanta;
        add3_quantised(
            &mut self.depth_normal,
            force_dir,
            q.depth_normal.scale,
            POINT_LIMIT,
        );
        add3_quantised(
            &mut self.depth_torque,
            torque,
            q.depth_torque.scale,
            POINT_LIMIT,
        );
    }

    #[inline(always)]
    fn add_brake(&mut self, a_sq: &F32s, brake_dir: &Vec3s, torque: &Vec3s) {
        self.brake.add_brake(a_sq, brake_dir, torque);
    }

    fn contact_into(&self, sums: &mut PartialSums) {
        let q = self.quanta;
        add_totals(&mut sums.depth_normal, &self.depth_normal, q.depth_normal);
        add_totals(&mut sums.depth_torque, &self.depth_torque, q.depth_torque);
    }

    fn brake_into(&self, sums: &mut PartialSums) {
        self.brake.brake_into(sums);
    }
}

/// The previous kernel's sums: per-lane f64 sums (lane `l` holds the points `l, l + 8, …` of the
/// class, in ascending order), lanes combined in a fixed tree and quantised once per class
/// (`value · 2^40` or `2^48`, truncated toward zero, saturating). Exact for any grouping of a
/// fixed class count; a different class count rounds differently.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct CanonicalF64Lanes {
    depth_normal: [F64s; 3],
    depth_torque: [F64s; 3],
    brake_sq: F64s,
    brake_force: [F64s; 3],
    brake_torque: [F64s; 3],
}

/// `value · scale` truncated toward zero, saturating (NaN → 0). `scale` is a power of two, so the
/// product is exact unless it overflows.
#[inline(always)]
fn quantise(value: f64, scale: f64) -> i128 {
    (value * scale) as i128
}

/// The lanes' rounded totals, added to `acc`.
fn add_rounded(acc: &mut [i128; 3], lanes: &[F64s; 3], scale: f64) {
    for (a, l) in acc.iter_mut().zip(lanes) {
        *a = a.wrapping_add(quantise(reduce(l), scale));
    }
}

impl LaneSums for CanonicalF64Lanes {
    #[inline(always)]
    fn new(_: &Quanta) -> Self {
        CanonicalF64Lanes::default()
    }

    #[inline(always)]
    fn add_contact(&mut self, force_dir: &Vec3s, torque: &Vec3s) {
        add3_f64(&mut self.depth_normal, force_dir);
        add3_f64(&mut self.depth_torque, torque);
    }

    #[inline(always)]
    fn add_brake(&mut self, a_sq: &F32s, brake_dir: &Vec3s, torque: &Vec3s) {
        add_f64(&mut self.brake_sq, a_sq);
        add3_f64(&mut self.brake_force, brake_dir);
        add3_f64(&mut self.brake_torque, torque);
    }

    fn contact_into(&self, sums: &mut PartialSums) {
        add_rounded(&mut sums.depth_normal, &self.depth_normal, LENGTH_SCALE);
        add_rounded(&mut sums.depth_torque, &self.depth_torque, AREA_SCALE);
    }

    fn brake_into(&self, sums: &mut PartialSums) {
        sums.brake_sq = sums
            .brake_sq
            .wrapping_add(quantise(reduce(&self.brake_sq), LENGTH_SCALE));
        add_rounded(&mut sums.brake_force, &self.brake_force, LENGTH_SCALE);
        add_rounded(&mut sums.brake_torque, &self.brake_torque, AREA_SCALE);
    }
}
