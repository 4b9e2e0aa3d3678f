//! Where the part starts: a session begins with the part at the script's first pose (the first
//! hand waypoint, or a corridor's `from`), whatever the device. A part placed there inside a
//! static object is held inside it for the whole session (every frame penetrates and the force
//! cannot push it out), so sessions say so before they run.

use crate::scene::SessionAssets;
use glam::DVec3;
use vps_device::script::Script;
use vps_voxmap::{PointShell, Voxel, VoxelTree};

/// How many of the shell's points lie inside static objects at the session's first pose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StartOverlap {
    /// The grip's position at frame 0 (m, scene coordinates).
    pub position: DVec3,
    /// Shell points in Interior voxels (inside a static object, past its force layer).
    pub interior_points: usize,
    /// All shell points.
    pub points: usize,
}

impl StartOverlap {
    /// Counts the points of `shell` (grip frame) in Interior voxels of `tree` with the grip at the
    /// first pose of `script`. Setup-time only: one lookup per point.
    pub fn of(tree: &VoxelTree, shell: &PointShell, script: &Script) -> StartOverlap {
        let (position, orientation) = script.sample(0.0);
        let spec = tree.spec();
        let interior_points = shell
            .points
            .iter()
            .map(|p| position + orientation * p.as_dvec3())
            .filter(|p| tree.get(spec.index_of(*p)) == Voxel::Interior)
            .count();
        StartOverlap {
            position,
            interior_points,
            points: shell.points.len(),
        }
    }

    /// A warning for a user when any point starts inside a static object, naming the first
    /// waypoint and what to do; `None` when the part starts clear.
    pub fn warning(&self) -> Option<String> {
        if self.interior_points == 0 {
            return None;
        }
        let [x, y, z] = self.position.to_array().map(|c| format!("{c:.4}"));
        Some(format!(
            "the part starts inside a static object: with the grip at the first hand waypoint \
             [{x}, {y}, {z}] m, {} of its {} shell points lie inside static geometry, so it is held \
             there and every frame penetrates; move the first waypoint (`hand.waypoints[0]` or \
             `corridor.from`) into free space",
            self.interior_points, self.points
        ))
    }
}

impl SessionAssets {
    /// [`StartOverlap::of`] for this scene's voxmap and shell and the session's `script`.
    pub fn start_overlap(&self, script: &Script) -> StartOverlap {
        StartOverlap::of(&self.tree, self.shell.points(), script)
    }
}
