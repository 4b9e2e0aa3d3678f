//! What `vps sweep` and `vps tune` share: what one setting's scripted session runs with on a built
//! voxmap ([`SweepSession`], [`session_on`]), running it on the runtime's 1 kHz loop with the command's
//! signal handlers ([`run_sweep_session`]), and the row of the sweep table ([`SweepRow`], the JSON
//! `vps sweep` writes and `vps tune` reads). Not a subcommand.

use anyhow::{bail, Result};
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use vps_device::script::Script;
use vps_haptic::HapticParams;
use vps_runtime::{run_loop, LoopConfig, SignalStop};
use vps_session::file::{ForceModelName, ShellMethodName};
use vps_session::scene::BuiltVoxmap;
use vps_session::{DeviceChoice, LoadedScene, PartShell, SessionPlan};
use vps_voxmap::VoxelTree;

/// What one setting's session runs with (its setup, not the run: [`run_sweep_session`] runs it): a
/// voxmap, the part's shell on it, the parameters and the script.
pub struct SweepSession {
    /// The voxmap.
    pub tree: Arc<VoxelTree>,
    /// Voxelization wall time (ms).
    pub voxelize_ms: f64,
    /// The part's shell and its classes (built once for the setting's session and accuracy
    /// pass).
    pub shell: PartShell,
    /// Parameters for this voxmap and shell.
    pub params: HapticParams,
    /// The scene's script on this voxmap, its laps repeated to last at least the session asked for.
    pub script: Script,
}

/// The setup of a session on an already built `map`: the part's shell of `method` at `voxel_size` (m), the
/// scene's parameters and its script lasting at least `seconds` (s). Allocates; setup only.
pub fn session_on(
    scene: &LoadedScene,
    map: &BuiltVoxmap,
    voxel_size: f64,
    method: ShellMethodName,
    seconds: f64,
) -> Result<SweepSession> {
    let shell = scene.build_shell(voxel_size, method.method())?;
    let params = scene.params_for(voxel_size, &shell)?;
    let script = scene.hand().script_covering(&map.tree, seconds)?;
    Ok(SweepSession {
        tree: map.tree.clone(),
        voxelize_ms: map.voxelize_ms,
        shell: PartShell::new(shell),
        params,
        script,
    })
}

/// Runs `frames` frames of `session` on the runtime's loop, one thread, free-running or paced,
/// with the simulated hand as the device. The loop stops when `signals` (the command's SIGINT,
/// SIGTERM and SIGHUP handlers, installed once) fire: the device is then written the exact zero
/// wrench and the report's `end` is `Stopped`. Blocks for the session.
pub fn run_sweep_session(
    session: &SweepSession,
    frames: u64,
    paced: bool,
    signals: &SignalStop,
) -> Result<vps_runtime::LoopReport> {
    let device = DeviceChoice::Simulated.open(session.script.clone(), &Default::default())?;
    let config = LoopConfig {
        frames: Some(frames),
        threads: 1,
        realtime: paced,
        free_running: !paced,
        ..LoopConfig::default()
    };
    let plan = SessionPlan::new(session.params, device, config);
    let report = run_loop(
        session.tree.clone(),
        session.shell.classed(),
        plan.into_stopped_setup(None, signals),
    )?;
    if let Some(err) = &report.device_error {
        bail!("the simulated hand failed: {err}");
    }
    Ok(report)
}

/// The sweep table as written to `--json`: its rows and whether the sweep ran to its end.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SweepTable {
    /// False when the sweep was stopped before its last row (the rows cover the settings done).
    pub complete: bool,
    /// Why the sweep ended: "all rows done", or "stopped by SIGINT during ..." (that row is left
    /// out).
    pub end: String,
    /// One row per scene × voxel size × voxel width × shell method, in the order run.
    pub rows: Vec<SweepRow>,
}

/// The force model of a row from a table written before the sweep had that axis.
fn tangent_plane() -> ForceModelName {
    ForceModelName::TangentPlane
}

/// One row of the table: one scene × force model × voxel size × voxel width × shell method.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SweepRow {
    /// Scene name.
    pub scene: String,
    /// Shell method.
    pub method: ShellMethodName,
    /// Voxel edge (mm).
    pub voxel_size_mm: f64,
    /// Bits per voxel of the voxmap: 2 (kinds only), 4 or 8 (kinds plus distance layers).
    pub voxel_width: u32,
    /// The force model (`tangent-plane` in tables written before the sweep had this axis).
    #[serde(default = "tangent_plane")]
    pub force_model: ForceModelName,
    /// True when this row's voxel width, shell method and force model are its scene file's own
    /// (`voxels.voxel_width`, `voxels.shell_method`, `voxels.force_model`): the rows a session on
    /// that scene runs with at each voxel size.
    pub default: bool,
    /// True when this row's voxel size is also the scene file's own `voxels.voxel_size` (with
    /// `default`: the setting a session on the scene runs with).
    pub default_size: bool,
    /// What was voxelized: `scene` or `workspace`.
    pub voxelized: String,
    /// Shell points.
    pub shell_points: usize,
    /// Voxmap (tree) memory (bytes).
    pub voxmap_bytes: usize,
    /// Voxelization and tree build (ms).
    pub voxelize_ms: f64,
    /// Frames in the session.
    pub frames: u64,
    /// Frame compute p50 (µs), free-running loop, one thread.
    pub compute_p50_us: f64,
    /// Frame compute p99.9 (µs).
    pub compute_p999_us: f64,
    /// Frames with a point in Interior over frames with a point in Surface or Interior, over the
    /// deterministic replay of the session (the accuracy pass).
    pub penetration_ratio: Option<f64>,
    /// Touching frames where the reference was computed.
    pub compared_frames: u64,
    /// Compared frames where both the voxel force and the reference force are non-zero.
    pub both_force_frames: u64,
    /// Compared frames with a voxel force but no reference force.
    pub voxel_only_frames: u64,
    /// Compared frames with a reference force but no voxel force.
    pub reference_only_frames: u64,
    /// Angle between voxel and reference force (degrees): median over `both_force_frames`.
    pub direction_error_deg_p50: Option<f64>,
    /// The same, 95th percentile.
    pub direction_error_deg_p95: Option<f64>,
    /// |(|F_vox| − |F_ref|) / |F_ref||, median over `both_force_frames`.
    pub magnitude_error_p50: Option<f64>,
    /// |F_vox| / |F_ref|, median (below 1: the voxel field is softer than the reference).
    pub magnitude_ratio_p50: Option<f64>,
    /// Smallest exact signed distance of any shell point over the compared frames (mm; negative =
    /// the exact surface was penetrated).
    pub min_separation_mm: Option<f64>,
}
