//! Contact between two moving parts, sans-IO: the first piece of several parts in one scene.
//!
//! Each moving part has a voxmap of its own mesh in its own body frame (origin at its grip) beside
//! its point shell. For a pair (A, B), A's shell is sampled in B's voxmap at A's pose relative to
//! B ([`pose_in`]), and B's shell in A's voxmap at B's pose relative to A ([`sample_pair`]). Each
//! direction's sums become a contact wrench by the same force model as the static scene
//! ([`crate::contact::contact_wrench`]); [`pair_wrenches`] then applies **one** pair force to
//! both parts: `F = f_ab − f_ba` on A and `f_ba − f_ab = −F` on B, exact negations in `f64`, so the
//! two forces are equal and opposite to the bit (a zero component is a zero on both), whatever
//! the split of the sums (the sums themselves
//! are exact in any grouping, [`crate::sums`]). Torques are about each part's own origin, and the
//! pair's total torque about any point is zero up to `f64` rounding (angular momentum is kept).
//!
//! The frame loop runs it for every pair of a scene's moving parts (`vps_runtime::parts`).
//!
//! **Pre-contact braking between parts** ([`pair_braking`]): the static scene's braking
//! ([`crate::contact::brake_wrench`]) applied to the pair's relative motion: each direction's
//! Proximity points brake the approach of one part's origin towards the other with the pair's
//! reduced mass, at most stopping it in one frame and never reversing it, half of each direction
//! applied (as for contact), one force exactly opposite on the two parts, through each part's
//! origin (no braking torque between parts).
//!
//! [`PairPass`] is one frame's pair work for several parts (the broad phase, both samplings, the
//! wrenches summed per part), as the frame loop runs it.
//!
//! Pure; nothing here blocks, and only [`PairPass::new`] allocates.

use glam::{DQuat, DVec3};

use crate::contact::{brake_viscosity, contact_wrench};
use crate::frame::OtherParts;
use crate::params::{Gains, HapticParams, StabilityIndices};
use crate::stability::stability_index;
use crate::state::{KernelPose, PartState};
use crate::sums::PartialSums;
use crate::{sample_all, ClassedShell, Wrench};
use vps_voxmap::VoxelLookup;

/// Part `a`'s pose and velocities expressed in part `b`'s body frame (where `b`'s voxmap lies):
/// rotation `R_b^T R_a`, position `R_b^T (x_a − x_b)`, linear velocity of `a`'s origin relative
/// to `b`'s moving frame `R_b^T (v_a − v_b − ω_b × (x_a − x_b))`, angular velocity
/// `R_b^T (ω_a − ω_b)`. Computed in `f64`, then made the kernel's `f32` pose.
pub fn pose_in(a: &PartState, b: &PartState) -> KernelPose {
    let to_b = b.orientation.normalize().inverse();
    let offset = a.position - b.position;
    let relative = PartState {
        position: to_b * offset,
        orientation: (to_b * a.orientation.normalize()).normalize(),
        linear_velocity: to_b
            * (a.linear_velocity - b.linear_velocity - b.angular_velocity.cross(offset)),
        angular_velocity: to_b * (a.angular_velocity - b.angular_velocity),
    };
    KernelPose::from_state(&relative)
}

/// Whether two parts' bounding spheres (radius `radius_a`, `radius_b` about their origins, m),
/// grown by `margin` (m, e.g. the force layer and proximity depth), overlap: the broad phase. A
/// pair that may not touch is not sampled and costs nothing.
pub fn may_touch(a: &PartState, radius_a: f64, b: &PartState, radius_b: f64, margin: f64) -> bool {
    let reach = radius_a + radius_b + margin;
    (a.position - b.position).length_squared() <= reach * reach
}

/// The share of each direction's contact wrench a pair applies: ½. Both samplings (A's points in
/// B, B's in A) measure the same interpenetration, so their sum would double the stiffness a part
/// feels against a static wall of the same depth (and the default gains are chosen for that
/// wall, `crate::stability`). A power of two, so the scaling is exact.
pub const PAIR_SHARE: f64 = 0.5;

/// The linearised stability indices of two parts pressed into each other, each held by its own
/// coupling, the pair force applied with `share` of each direction ([`PAIR_SHARE`] in sessions)
/// and the stiffness of `a`'s parameters (the loop's choice: the lower-numbered part's). With
/// `x = x_a − x_b` and `N` points at the averaging threshold, the pair force on A is about
/// `−2 s N K_ff x` and on B its negation, so the relative motion sees
/// `ω² = max(k_T/m) + 2 s N K_ff (1/m_a + 1/m_b)` (the reduced mass) and the larger coupling
/// damping; rotation likewise with `K_ff r_a²/I_a + K_ff r_b²/I_b`. For two equal parts the field
/// term is `4 s` times a wall's: `s = ½` doubles it, `s = 1` quadruples it. Arithmetic only.
pub fn pair_stability(a: &HapticParams, b: &HapticParams, share: f64) -> StabilityIndices {
    let (ga, gb) = (a.gains(), b.gains());
    let n = a.contact_average_threshold as f64;
    let field = 2.0 * share * n * ga.k_ff;
    let dt = a.dt;
    let omega_t2 = (ga.k_t / a.mass).max(gb.k_t / b.mass) + field * (1.0 / a.mass + 1.0 / b.mass);
    let damping_t = (ga.b_t / a.mass).max(gb.b_t / b.mass);
    let lever = |p: &HapticParams, inertia: f64| p.max_radius * p.max_radius / inertia;
    let omega_r2 = (ga.k_r / ga.inertia).max(gb.k_r / gb.inertia)
        + field * (lever(a, ga.inertia) + lever(b, gb.inertia));
    let damping_r = (ga.b_r / ga.inertia).max(gb.b_r / gb.inertia);
    StabilityIndices {
        translational: stability_index(omega_t2.sqrt() * dt, damping_t * dt),
        rotational: stability_index(omega_r2.sqrt() * dt, damping_r * dt),
    }
}

/// A voxmap a part carries in its own body frame, sampled by another part's shell. Blanket
/// implemented for every [`VoxelLookup`] (a `VoxelTree` in sessions, a `DenseGrid` in tests).
pub trait BodyVoxmap: Send + Sync {
    /// The merged sums of every class of `shell` at `pose` (in this voxmap's frame). Does not
    /// allocate or block.
    fn sample(&self, shell: &ClassedShell, pose: &KernelPose) -> PartialSums;
}

impl<L: VoxelLookup + Send + Sync> BodyVoxmap for L {
    fn sample(&self, shell: &ClassedShell, pose: &KernelPose) -> PartialSums {
        sample_all(self, shell, pose)
    }
}

/// One part as the pair pass sees it: its state, parameters, own voxmap and shell (both in its
/// body frame, origin at its grip) and the radius about its origin holding mesh and shell (m).
#[derive(Clone, Copy)]
pub struct PairPart<'a> {
    /// Its state this frame.
    pub state: &'a PartState,
    /// Its haptic parameters.
    pub params: &'a HapticParams,
    /// Its own voxmap.
    pub map: &'a dyn BodyVoxmap,
    /// Its point shell.
    pub shell: &'a ClassedShell,
    /// Its bounding radius (m).
    pub radius: f64,
}

/// The pairs of a session, counted.
#[derive(Clone, Copy, Debug, Default, serde::Serialize)]
pub struct PairCounts {
    /// Pairs sampled (both ways) over the session, after the broad phase.
    pub sampled: u64,
    /// Pairs the broad phase skipped.
    pub skipped: u64,
    /// Frames where some pair had a point in a non-Free voxel.
    pub contact_frames: u64,
}

/// One frame's pair work for several parts: every pair that may touch ([`may_touch`]) sampled both
/// ways ([`BodyVoxmap::sample`]) and its wrenches ([`pair_wrenches`], with the lower-numbered
/// part's parameters) summed per part into an [`OtherParts`] (index 0 the session's first part),
/// written in place, with the session's counts. The loop runs it every frame; a study recomputing
/// a session of several parts must run it the same way.
///
/// In two steps when the sampling happens elsewhere (a cluster's workers):
/// [`PairPass::broad_phase`] lists the pairs to sample, [`PairPass::apply`] takes their sums;
/// [`PairPass::run`] is both with the sampling in between, on the calling thread.
pub struct PairPass {
    /// Per part, this frame's pair wrench sum and nearness.
    pub others: Vec<OtherParts>,
    /// The session's counts.
    pub counts: PairCounts,
    /// Per part, frames in contact with another part.
    pub contact_frames: Vec<u64>,
    /// This frame's pairs that may touch, from [`PairPass::broad_phase`].
    touching: Vec<(usize, usize)>,
    /// Their sums, in the same order (for [`PairPass::run`]).
    sums: Vec<PairSums>,
    /// This frame's pairs in contact, from [`PairPass::apply`].
    near: Vec<(usize, usize)>,
}

impl PairPass {
    /// A pass for `parts` parts. Allocates (the only allocation of the pass); setup-time only.
    pub fn new(parts: usize) -> PairPass {
        let pairs = parts * parts.saturating_sub(1) / 2;
        PairPass {
            others: vec![OtherParts::NONE; parts],
            counts: PairCounts::default(),
            contact_frames: vec![0; parts],
            touching: Vec::with_capacity(pairs),
            sums: Vec::with_capacity(pairs),
            near: Vec::with_capacity(pairs),
        }
    }

    /// The pairs `(i, j)`, `i < j`, in contact in the latest [`PairPass::apply`] (or
    /// [`PairPass::run`]): `i`'s shell reached a non-free voxel of `j`'s voxmap, or `j`'s of
    /// `i`'s. In the broad phase's order. Does not allocate.
    pub fn near_pairs(&self) -> &[(usize, usize)] {
        &self.near
    }

    /// Samples every pair of the `count` parts (`part(k)`; 0 the session's first) that
    /// may touch, and leaves each part's summed pair wrench in `self.others`. Pairs are visited
    /// in the order (0,1), (0,2), …, (1,2), …, so the sums are the same every run. Does not
    /// allocate (for up to the `parts` of [`PairPass::new`]) or block.
    pub fn run<'a>(&mut self, count: usize, part: impl Fn(usize) -> PairPart<'a>, margin: f64) {
        self.broad_phase(count, &part, margin);
        let mut sums = std::mem::take(&mut self.sums);
        sums.clear();
        sums.extend(self.touching.iter().map(|&(i, j)| {
            let (pa, pb) = (part(i), part(j));
            PairSums {
                a_in_b: pb.map.sample(pa.shell, &pose_in(pa.state, pb.state)),
                b_in_a: pa.map.sample(pb.shell, &pose_in(pb.state, pa.state)),
            }
        }));
        self.apply(&part, &sums);
        self.sums = sums;
    }

    /// The broad phase of this frame: the pairs `(i, j)`, `i < j`, of the `count` parts that may
    /// touch, in the order (0,1), (0,2), …, (1,2), …; counts the others as skipped. Does not
    /// allocate (for up to the `parts` of [`PairPass::new`]) or block.
    pub fn broad_phase<'a>(
        &mut self,
        count: usize,
        part: impl Fn(usize) -> PairPart<'a>,
        margin: f64,
    ) -> &[(usize, usize)] {
        self.touching.clear();
        for i in 0..count {
            for j in i + 1..count {
                let (pa, pb) = (part(i), part(j));
                if may_touch(pa.state, pa.radius, pb.state, pb.radius, margin) {
                    self.counts.sampled += 1;
                    self.touching.push((i, j));
                } else {
                    self.counts.skipped += 1;
                }
            }
        }
        &self.touching
    }

    /// Applies the sums of this frame's pairs (`sums[k]` of the `k`-th pair of the latest
    /// [`PairPass::broad_phase`]): each near pair's wrenches and braking summed per part into
    /// `self.others`, the contact counts booked. Does not allocate or block.
    pub fn apply<'a>(&mut self, part: impl Fn(usize) -> PairPart<'a>, sums: &[PairSums]) {
        self.others.iter_mut().for_each(|o| *o = OtherParts::NONE);
        self.near.clear();
        let mut any_contact = false;
        for (&(i, j), sums) in self.touching.iter().zip(sums) {
            let (pa, pb) = (part(i), part(j));
            let (a, b, params) = (pa.state, pb.state, pa.params);
            let near = sums.a_in_b.non_free > 0 || sums.b_in_a.non_free > 0;
            if !near {
                continue;
            }
            any_contact = true;
            self.near.push((i, j));
            let mut w = pair_wrenches(params, &params.gains(), a, b, sums);
            let brake = pair_braking(params, pb.params.mass, a, b, sums);
            // `x + y` and `(−x) + (−y)` are exact negations, so the forces stay opposite.
            w.on_a.force += brake.on_a;
            w.on_b.force += brake.on_b;
            for (k, on) in [(i, w.on_a), (j, w.on_b)] {
                let o = &mut self.others[k];
                o.wrench.force += on.force;
                o.wrench.torque += on.torque;
                o.near = true;
            }
        }
        for (o, frames) in self.others.iter().zip(&mut self.contact_frames) {
            *frames += u64::from(o.near);
        }
        self.counts.contact_frames += u64::from(any_contact);
    }
}

/// The pre-contact braking forces of a pair (world frame, N, through each part's origin).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PairBrake {
    /// On A.
    pub on_a: DVec3,
    /// On B: exactly `−on_a` (a zero component is a zero on both).
    pub on_b: DVec3,
}

/// The pair's pre-contact braking (see the module docs) from its sums, with `params` (the
/// lower-numbered part's: its `braking` flag and `dt`) and the reduced mass of `params.mass` and
/// `mass_b` (kg). With `f_ab` the braking force A's points get in B (world frame) and `f_ba` B's in
/// A, the force on A is `(f_ab − f_ba) / 2` and on B `(f_ba − f_ab) / 2`, its exact negation; each
/// half at most stops its direction's approach, so together they never reverse it. No torque
/// (the force acts through each origin). Zero with braking off. Pure; does not allocate or block.
pub fn pair_braking(
    params: &HapticParams,
    mass_b: f64,
    a: &PartState,
    b: &PartState,
    sums: &PairSums,
) -> PairBrake {
    let mu = params.mass * mass_b / (params.mass + mass_b);
    // Each origin's velocity relative to the other's moving frame, in that frame (as `pose_in`).
    let relative = |x: &PartState, y: &PartState| {
        let to_y = y.orientation.normalize().inverse();
        to_y * (x.linear_velocity
            - y.linear_velocity
            - y.angular_velocity.cross(x.position - y.position))
    };
    // One direction's braking force, in the frame its sums were sampled in: `−b S_f`.
    let brake = |v: DVec3, sums: &PartialSums| {
        brake_viscosity(params, mu, v, sums).map_or(DVec3::ZERO, |b| -b * sums.brake_force_si())
    };
    let f_ab = b.orientation.normalize() * brake(relative(a, b), &sums.a_in_b);
    let f_ba = a.orientation.normalize() * brake(relative(b, a), &sums.b_in_a);
    PairBrake {
        on_a: (f_ab - f_ba) * PAIR_SHARE,
        on_b: (f_ba - f_ab) * PAIR_SHARE,
    }
}

/// One pair's sums, both ways.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PairSums {
    /// A's shell in B's voxmap (B's body frame; torques about A's origin).
    pub a_in_b: PartialSums,
    /// B's shell in A's voxmap (A's body frame; torques about B's origin).
    pub b_in_a: PartialSums,
}

/// Samples the pair both ways: every class of A's shell in B's voxmap at [`pose_in`]`(a, b)`,
/// and every class of B's shell in A's voxmap at [`pose_in`]`(b, a)`. Does not allocate or block.
pub fn sample_pair<LA: VoxelLookup, LB: VoxelLookup>(
    (map_a, shell_a, a): (&LA, &ClassedShell, &PartState),
    (map_b, shell_b, b): (&LB, &ClassedShell, &PartState),
) -> PairSums {
    PairSums {
        a_in_b: sample_all(map_b, shell_a, &pose_in(a, b)),
        b_in_a: sample_all(map_a, shell_b, &pose_in(b, a)),
    }
}

/// The contact wrenches a pair's sums put on each part, in the world frame, torques about each
/// part's origin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PairWrenches {
    /// On A (N, N·m).
    pub on_a: Wrench,
    /// On B: its force is exactly `−on_a.force` (N; a zero component is a zero on both); its
    /// torque is about B's origin (N·m).
    pub on_b: Wrench,
}

/// The pair's wrenches from its sums. With `f_ab` the force A's points feel in B (world frame) and
/// `f_ba` the force B's points feel in A, the pair force on A is `F = f_ab − f_ba` and on B
/// `f_ba − f_ab`, exactly `−F`. Torques: A's points' torque about A's origin, plus the torque about A's origin of `−f_ba`
/// applied where B's points are (`−τ_ba − (x_b − x_a) × f_ba`), and the mirror for B. Naming the
/// parts the other way round gives the same wrenches, swapped, to the bit.
pub fn pair_wrenches(
    params: &HapticParams,
    gains: &Gains,
    a: &PartState,
    b: &PartState,
    sums: &PairSums,
) -> PairWrenches {
    let to_world = |q: DQuat, w: Wrench| (q.normalize() * w.force, q.normalize() * w.torque);
    let (f_ab, tau_ab) = to_world(b.orientation, contact_wrench(params, gains, &sums.a_in_b));
    let (f_ba, tau_ba) = to_world(a.orientation, contact_wrench(params, gains, &sums.b_in_a));
    let force = (f_ab - f_ba) * PAIR_SHARE;
    let lever = |from: DVec3, to: DVec3, f: DVec3| (to - from).cross(f);
    PairWrenches {
        on_a: Wrench {
            force,
            torque: (tau_ab - tau_ba - lever(a.position, b.position, f_ba)) * PAIR_SHARE,
        },
        on_b: Wrench {
            // `f_ba − f_ab`, the exact negation of `force` (IEEE subtraction is antisymmetric for
            // unequal operands; equal ones give zero on both sides), so naming the parts the
            // other way round swaps the wrenches bit for bit.
            force: (f_ba - f_ab) * PAIR_SHARE,
            torque: (tau_ba - tau_ab - lever(b.position, a.position, f_ab)) * PAIR_SHARE,
        },
    }
}
