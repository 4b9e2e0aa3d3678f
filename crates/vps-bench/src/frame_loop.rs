//! `vps bench loop`: the end-to-end 1 kHz loop over many frames with a large point shell: missed
//! deadlines and compute/period percentiles, recorded against the scheduled tick.
//!
//! Scene: `--scene` (default the built-in bay) at its voxel size or `--voxel-size`. Part: the
//! scene's part's shell sampled at the voxel size that gives about `--points` points (the shell may
//! be finer than the voxmap; the kernel does not care, and this is how a user buys point count
//! independently of scene memory). Motion: the scene's script, its laps repeated to cover the run.

use anyhow::Result;
use serde::Serialize;
use vps_app::output::print_report;
use vps_app::SceneRequest;
use vps_runtime::{run_loop, LoopConfig, RtGrant, StatsSummary};
use vps_session::{DeviceChoice, SessionAssets};
use vps_voxelize::ShellMethod;

#[derive(Serialize)]
struct LoopBench {
    scene: String,
    scene_triangles: usize,
    voxel_size_m: f64,
    shell_voxel_size_m: f64,
    shell_points: usize,
    threads: usize,
    frames_requested: u64,
    rt: RtGrant,
    host_idle: crate::machine::HostIdle,
    stats: StatsSummary,
}

/// Runs the benchmark and prints JSON.
pub fn run(
    scene: &SceneRequest,
    voxel_size: Option<f64>,
    points: usize,
    frames: u64,
    threads: usize,
    json: bool,
) -> Result<()> {
    let mut assets = SessionAssets::open(&scene.scene, &scene.build_options(voxel_size))?;
    let shell_voxel = assets.resample_shell(points, ShellMethod::VoxelCentres)?;
    let script = assets.script_for_frames(frames)?;
    let config = LoopConfig {
        frames: Some(frames),
        threads,
        realtime: true,
        ..LoopConfig::default()
    };
    let plan = assets.plan(&DeviceChoice::Simulated, script, config)?;
    let (setup, signals) = plan.into_live_setup(None)?;
    let report = run_loop(assets.tree.clone(), assets.classed_shell(), setup)?;
    vps_app::exit::require_complete(&report.end, Some(&signals))?;
    print_report(
        "bench loop: the 1 kHz loop over many frames",
        &LoopBench {
            scene: assets.label.clone(),
            scene_triangles: assets.scene_triangles,
            voxel_size_m: assets.voxel_size,
            shell_voxel_size_m: shell_voxel,
            shell_points: assets.shell.len(),
            threads,
            frames_requested: frames,
            rt: report.rt,
            host_idle: crate::machine::HostIdle::read(),
            stats: report.stats,
        },
        json,
    )
}
