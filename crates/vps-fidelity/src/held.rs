//! A part held by a simulated hand, frame by frame: each frame samples the whole shell against the
//! voxmap and steps the part through the virtual coupling (the haptic frame of `vps_haptic::step`,
//! as a session does), then measures the shell points at the part's new pose against the exact
//! meshes. Shared by the [`crate::clearance`] benchmark and the tunnelling test. Blocking,
//! allocating, parallel (the exact measure, rayon).

use glam::{DQuat, DVec3};
use vps_haptic::{
    sample_all, step, ClassedShell, HandleSample, HapticParams, KernelPose, PartState,
};
use vps_reference::{reference_contact, ExactScene, ReferenceContact};
use vps_voxmap::{PointShell, VoxelLookup};

/// A part (its point shell) held by the hand against one scene: its voxmap and its exact meshes.
pub struct HeldPart<'a, L> {
    map: &'a L,
    exact: &'a ExactScene,
    shell: &'a PointShell,
    classed: ClassedShell,
    params: &'a HapticParams,
    state: PartState,
}

impl<'a, L: VoxelLookup> HeldPart<'a, L> {
    /// The part of `shell` at rest with its centre of mass at `position` (m) and at
    /// `orientation`, against `map` and `exact` (the same scene), stepped with `params`.
    pub fn at_rest(
        map: &'a L,
        exact: &'a ExactScene,
        shell: &'a PointShell,
        params: &'a HapticParams,
        position: DVec3,
        orientation: DQuat,
    ) -> Self {
        HeldPart {
            map,
            exact,
            shell,
            classed: ClassedShell::new(shell, 1),
            params,
            state: PartState::at_rest(position, orientation),
        }
    }

    /// One haptic frame with the hand at `handle`: the part's next state, then the exact contact
    /// of its shell points there, depths from the exact surface (no offset), points more than
    /// `reach_m` (m) outside not resolved.
    pub fn frame(&mut self, handle: &HandleSample, reach_m: f64) -> ReferenceContact {
        let sums = sample_all(
            self.map,
            &self.classed,
            &KernelPose::from_state(&self.state),
        );
        self.state = step(self.params, &self.state, handle, &sums).next_state;
        reference_contact(
            self.exact,
            &self.shell.points,
            self.state.position,
            self.state.orientation,
            0.0,
            reach_m,
        )
    }

    /// The shell points in the world frame at the part's current pose (m).
    pub fn world_points(&self) -> impl Iterator<Item = DVec3> + '_ {
        self.shell
            .points
            .iter()
            .map(|p| self.state.orientation * p.as_dvec3() + self.state.position)
    }
}
