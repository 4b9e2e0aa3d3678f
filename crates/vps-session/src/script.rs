//! The simulated hand's scripts: the standard session along a corridor (with detours into
//! contact found in the voxmap itself) and a plain path through given grip positions.
//!
//! The detours march from a waypoint along a direction to the first Surface voxel, so the session
//! presses real obstacles of whatever scene it is given: a rest on the surface below, a slide along
//! it, a press on each side wall, and one fast (1 m/s) collision.

use crate::file::MAX_WAYPOINTS;
use anyhow::{bail, Context, Result};
use glam::{DQuat, DVec3};
use vps_device::script::{Script, ScriptBuilder};
use vps_voxmap::{Voxel, VoxelTree};

/// Marches from `from` along `dir` in half-voxel steps up to `max_distance` (m) and returns the
/// centre of the first Surface voxel met.
pub fn first_surface(
    tree: &VoxelTree,
    from: DVec3,
    dir: DVec3,
    max_distance: f64,
) -> Option<DVec3> {
    let spec = tree.spec();
    let step = spec.voxel_size * 0.5;
    let dir = dir.normalize();
    (0..(max_distance / step) as usize)
        .map(|i| from + dir * (i as f64 * step))
        .find(|p| tree.get(spec.index_of(*p)) == Voxel::Surface)
        .map(|p| spec.center_of(spec.index_of(p)))
}

/// Speeds of the standard session (m/s).
const CRUISE: f64 = 0.25;
const PRESS: f64 = 0.08;
const COLLISION: f64 = 1.0;
/// A detour at every this-many corridor waypoints.
const DETOUR_EVERY: usize = 3;

/// The standard scripted session along `corridor` in `tree`: cruise from waypoint to waypoint; at
/// every third interior waypoint make one detour (cycling through: rest on the surface below and
/// slide, press the wall to the side, press the other side, a 1 m/s collision with the surface
/// below). A detour whose direction finds no surface within `reach` (m) is skipped.
pub fn standard_script(tree: &VoxelTree, corridor: &[DVec3], reach: f64) -> Result<Script> {
    laps_script(tree, corridor, reach, 1)
}

/// [`standard_script`] run `laps` times: forward along the corridor, back, forward, ... Errors when
/// the whole path would exceed [`MAX_WAYPOINTS`] waypoints.
pub fn laps_script(
    tree: &VoxelTree,
    corridor: &[DVec3],
    reach: f64,
    laps: usize,
) -> Result<Script> {
    let laps = laps.max(1);
    if corridor.len().saturating_mul(laps) > MAX_WAYPOINTS {
        bail!(
            "{} waypoints × {laps} laps exceeds the {MAX_WAYPOINTS}-waypoint limit",
            corridor.len()
        );
    }
    let mut path: Vec<DVec3> = corridor.to_vec();
    for lap in 1..laps {
        let mut leg: Vec<DVec3> = corridor.to_vec();
        if lap % 2 == 1 {
            leg.reverse();
        }
        path.extend(leg.into_iter().skip(1));
    }
    let corridor = &path[..];
    let start = *corridor.first().context("the corridor has no waypoints")?;
    let mut b = ScriptBuilder::start(start, DQuat::IDENTITY).hold(0.2);
    let directions = [DVec3::NEG_Z, DVec3::Y, DVec3::NEG_Y, DVec3::NEG_Z];
    for (i, &w) in corridor.iter().enumerate().skip(1) {
        b = b.move_to(w, CRUISE);
        if i + 1 == corridor.len() {
            break;
        }
        if i % DETOUR_EVERY != 0 {
            continue;
        }
        let kind = (i / DETOUR_EVERY - 1) % directions.len();
        let dir = directions[kind];
        let Some(surface) = first_surface(tree, w, dir, reach) else {
            continue;
        };
        // The handle goes to the surface voxel itself: the part (tens of mm across) meets the
        // force layer first and the coupling presses it there, clamped to k_T s / 2.
        b = match kind {
            0 => {
                let along = (corridor[i + 1] - w).normalize_or_zero() * 0.05;
                b.move_to(surface, PRESS)
                    .hold(0.3)
                    .move_to(surface + along, PRESS / 2.0)
                    .hold(0.2)
            }
            3 => b.move_to(surface, COLLISION).hold(0.2),
            _ => b.move_to(surface, PRESS).hold(0.3),
        };
        b = b.move_to(w, CRUISE);
    }
    Ok(b.hold(0.2).build()?)
}

/// A plain path: start at rest at the first waypoint, then visit every waypoint in order at
/// `speed` (m/s), pausing `hold` (s) at each; `laps` times (forward, back, ...). Errors when the
/// whole path would exceed [`MAX_WAYPOINTS`] waypoints.
pub fn path_script(waypoints: &[DVec3], speed: f64, hold: f64, laps: usize) -> Result<Script> {
    let laps = laps.max(1);
    if waypoints.len().saturating_mul(laps) > MAX_WAYPOINTS {
        bail!(
            "{} waypoints × {laps} laps exceeds the {MAX_WAYPOINTS}-waypoint limit",
            waypoints.len()
        );
    }
    let start = *waypoints.first().context("the path has no waypoints")?;
    let mut b = ScriptBuilder::start(start, DQuat::IDENTITY).hold(0.2);
    for lap in 0..laps {
        let leg: Box<dyn Iterator<Item = &DVec3>> = if lap % 2 == 0 {
            Box::new(waypoints.iter().skip(1))
        } else {
            Box::new(waypoints.iter().rev().skip(1))
        };
        for &w in leg {
            b = b.move_to(w, speed);
            if hold > 0.0 {
                b = b.hold(hold);
            }
        }
    }
    Ok(b.hold(0.2).build()?)
}

/// How the simulated hand moves.
#[derive(Clone, Debug, PartialEq)]
pub enum HandPlan {
    /// The standard session along corridor waypoints (m), detours within `reach` (m).
    Corridor {
        /// Waypoints (m).
        waypoints: Vec<DVec3>,
        /// How far a detour looks for a surface (m).
        reach: f64,
        /// Walks along the corridor.
        laps: usize,
    },
    /// Grip positions (m) visited in order at `speed` (m/s), pausing `hold` (s) at each.
    Path {
        /// Waypoints (m).
        waypoints: Vec<DVec3>,
        /// Speed (m/s).
        speed: f64,
        /// Pause at each waypoint (s).
        hold: f64,
    },
}

impl HandPlan {
    /// The first waypoint (m): where the hand, and the part, start. `None` without waypoints.
    pub fn first_waypoint(&self) -> Option<DVec3> {
        match self {
            HandPlan::Corridor { waypoints, .. } | HandPlan::Path { waypoints, .. } => {
                waypoints.first().copied()
            }
        }
    }

    /// The script walked `laps` times (a corridor's detours are found in `tree`).
    pub fn script_laps(&self, tree: &VoxelTree, laps: usize) -> Result<Script> {
        match self {
            HandPlan::Corridor {
                waypoints, reach, ..
            } => laps_script(tree, waypoints, *reach, laps),
            HandPlan::Path {
                waypoints,
                speed,
                hold,
            } => path_script(waypoints, *speed, *hold, laps),
        }
    }

    /// The script as the scene declares it (a corridor's `laps`, a path once).
    pub fn script(&self, tree: &VoxelTree) -> Result<Script> {
        let laps = match self {
            HandPlan::Corridor { laps, .. } => *laps,
            HandPlan::Path { .. } => 1,
        };
        self.script_laps(tree, laps)
    }

    /// The scene's script, its laps doubled until it lasts at least `seconds` (or the waypoint
    /// limit is reached).
    pub fn script_covering(&self, tree: &VoxelTree, seconds: f64) -> Result<Script> {
        let (mut laps, count) = match self {
            HandPlan::Corridor {
                laps, waypoints, ..
            } => (*laps, waypoints.len()),
            HandPlan::Path { waypoints, .. } => (1, waypoints.len()),
        };
        let mut script = self.script_laps(tree, laps)?;
        while script.duration() < seconds
            && count.saturating_mul(laps * 2) <= crate::file::MAX_WAYPOINTS
        {
            laps *= 2;
            script = self.script_laps(tree, laps)?;
        }
        Ok(script)
    }
}
