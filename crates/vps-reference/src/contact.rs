//! The reference contact of a part pose: every shell point measured against the exact meshes.

use crate::scene::ExactScene;
use glam::{DQuat, DVec3, Vec3};
use rayon::prelude::*;

/// The exact contact geometry of one part pose (world frame, SI units).
///
/// With `φ_i` the signed distance of shell point `P_i` (positive outside), `n_i` the outward
/// normal at its nearest surface point, `x` the part's centre of mass and `δ` the offset:
/// depth `e_i = max(0, δ − φ_i)`; the reference force is `K_ff Σ e_i n_i`, the same law as the
/// voxel field (`K_ff Σ d_i N_i`) but with exact depths measured from the surface offset by `δ`.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ReferenceContact {
    /// Points measured.
    pub points: usize,
    /// Points within the query reach (the others are farther than `reach_m` outside).
    pub resolved_points: usize,
    /// The offset `δ` depths are measured from (m).
    pub offset_m: f64,
    /// Smallest signed distance of any point (m; negative = penetration); `None` when every point
    /// is farther than the reach.
    pub min_separation_m: Option<f64>,
    /// Deepest penetration of the exact surface, `max(0, −min φ)` (m).
    pub max_penetration_m: f64,
    /// Points inside a solid (`φ < 0`).
    pub penetrating_points: usize,
    /// Points closer than the offset (`φ < δ`): the reference contacts.
    pub contact_points: usize,
    /// `Σ e_i` (m).
    pub depth_sum_m: f64,
    /// `Σ e_i n_i` (m): the reference force over `K_ff`.
    pub depth_normal_sum_m: DVec3,
    /// `Σ (P_i − x) × e_i n_i` (m²): the reference torque over `K_ff`.
    pub depth_torque_sum_m2: DVec3,
}

impl ReferenceContact {
    /// Unit direction of the reference force, `None` when no point is within the offset (or the
    /// contributions cancel exactly).
    pub fn force_direction(&self) -> Option<DVec3> {
        self.depth_normal_sum_m.try_normalize()
    }

    /// Deepest penetration of the exact surface (m), 0 when nothing penetrates.
    pub fn penetration_depth_m(&self) -> f64 {
        self.max_penetration_m
    }
}

/// The reference contact of a part's shell points (`body_points`, body frame with the origin at
/// the centre of mass, as in `vps_voxmap::PointShell::points`) at pose (`position` of the centre of mass, `orientation`),
/// depths measured from the surface offset by `offset_m` (0 for plain penetration). Points more than
/// `reach_m` (≥ `offset_m`) outside are not resolved: they cannot contribute, and a reach beyond the
/// offset also yields the minimum separation of near misses. Parallel (rayon), blocking,
/// allocates; the result does not depend on the thread count.
pub fn reference_contact(
    scene: &ExactScene,
    body_points: &[Vec3],
    position: DVec3,
    orientation: DQuat,
    offset_m: f64,
    reach_m: f64,
) -> ReferenceContact {
    let world: Vec<DVec3> = body_points
        .iter()
        .map(|p| orientation * p.as_dvec3() + position)
        .collect();
    reference_contact_points(scene, &world, position, offset_m, reach_m)
}

/// [`reference_contact`] of points already in the world frame (m), torques about `centre` (m).
pub fn reference_contact_points(
    scene: &ExactScene,
    world_points: &[DVec3],
    centre: DVec3,
    offset_m: f64,
    reach_m: f64,
) -> ReferenceContact {
    let reach = reach_m.max(offset_m);
    let measured: Vec<_> = world_points
        .par_iter()
        .map(|&p| scene.signed_distance_within(p, reach).map(|s| (p, s)))
        .collect();
    let mut out = ReferenceContact {
        points: world_points.len(),
        offset_m,
        ..ReferenceContact::default()
    };
    for (p, s) in measured.into_iter().flatten() {
        out.resolved_points += 1;
        let phi = s.distance_m;
        out.min_separation_m = Some(out.min_separation_m.map_or(phi, |m| m.min(phi)));
        if phi < 0.0 {
            out.penetrating_points += 1;
            out.max_penetration_m = out.max_penetration_m.max(-phi);
        }
        let depth = offset_m - phi;
        if depth > 0.0 {
            out.contact_points += 1;
            out.depth_sum_m += depth;
            out.depth_normal_sum_m += s.normal * depth;
            out.depth_torque_sum_m2 += (p - centre).cross(s.normal * depth);
        }
    }
    out
}
