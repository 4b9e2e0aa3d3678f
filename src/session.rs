//! The standard session: a static scene voxelized into a tree, a part's point shell, and a scripted
//! simulated hand that threads the part along the scene's corridor with detours into contact.
//!
//! The detours are found in the voxmap itself (a march along a direction until the first Surface
//! voxel), so the session presses real obstacles of whatever scene it is given: a rest on the
//! surface below, a slide along it, a press on each side wall, and one fast (1 m/s) collision.

use anyhow::{Context, Result};
use glam::{DQuat, DVec3};
use std::sync::Arc;
use std::time::Instant;
use vps_device::script::{Script, ScriptBuilder};
use vps_haptic::ClassedShell;
use vps_voxelize::{point_shell, voxelize_tree, ShellMethod, VoxelizeOptions};
use vps_voxmap::{PointShell, TreeConfig, Voxel, VoxelTree};

/// Everything a session needs, built once.
pub struct SessionScene {
    /// The static scene's voxmap.
    pub tree: Arc<VoxelTree>,
    /// The part's point shell.
    pub shell: PointShell,
    /// Corridor waypoints (m) the part is threaded along.
    pub corridor: Vec<DVec3>,
    /// Triangles in the static scene.
    pub scene_triangles: usize,
    /// Voxelization wall time (ms).
    pub voxelize_ms: f64,
}

/// Builds the built-in scene: the aircraft bay voxelized at `voxel_size` (m), the teapot's shell.
pub fn builtin_scene(voxel_size: f64, method: ShellMethod) -> Result<SessionScene> {
    let bay = vps_mesh::builtin::aircraft_bay();
    let part = vps_mesh::builtin::teapot();
    let t = Instant::now();
    let opts = VoxelizeOptions {
        voxel_size,
        progress: true,
        ..VoxelizeOptions::default()
    };
    // The sparse pipeline: memory follows the bay's surface, not its bounding box (the same
    // tree as the dense pipeline, bit for bit; docs/sparse-voxelize.md).
    let (tree, _) = voxelize_tree(std::slice::from_ref(&bay), &opts, TreeConfig::default())
        .context("voxelizing the aircraft bay")?;
    let voxelize_ms = t.elapsed().as_secs_f64() * 1e3;
    let shell =
        point_shell(&part, voxel_size, method).context("building the teapot's point shell")?;
    Ok(SessionScene {
        tree: Arc::new(tree),
        shell,
        corridor: vps_mesh::builtin::bay_corridor(),
        scene_triangles: bay.triangle_count(),
        voxelize_ms,
    })
}

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
/// every third interior waypoint make one detour (cycling through: rest on the surface below and slide,
/// press the wall to the side, press the other side, a 1 m/s collision with the surface below).
/// A detour whose direction finds no surface within `reach` (m) is skipped.
pub fn standard_script(tree: &VoxelTree, corridor: &[DVec3], reach: f64) -> Result<Script> {
    laps_script(tree, corridor, reach, 1)
}

/// [`standard_script`] run `laps` times: forward along the corridor, back, forward, ...
pub fn laps_script(
    tree: &VoxelTree,
    corridor: &[DVec3],
    reach: f64,
    laps: usize,
) -> Result<Script> {
    let mut path: Vec<DVec3> = corridor.to_vec();
    for lap in 1..laps.max(1) {
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

/// Classes the shell is split into (DESIGN §4). Fixed, independent of the thread count: a class
/// is the unit of work and of exact summation, so the same class count gives a bit-identical
/// wrench however the classes are spread over threads (or, later, worker processes).
pub const CLASS_COUNT: u32 = 64;

/// The shell split into [`CLASS_COUNT`] classes.
pub fn classed(shell: &PointShell) -> Arc<ClassedShell> {
    Arc::new(ClassedShell::new(shell, CLASS_COUNT))
}
