//! `vps bench loop`: the end-to-end 1 kHz loop over many frames with a large point shell: missed
//! deadlines and compute/period percentiles, recorded against the scheduled tick.
//!
//! Scene: the aircraft bay at `--voxel-size`. Part: the teapot's shell sampled at the voxel size
//! that gives about `--points` points (the shell may be finer than the voxmap; the kernel does not
//! care, and this is how a user buys point count independently of scene memory). Motion: the
//! standard scripted session, back and forth along the corridor.

use super::output::print_json;
use crate::session::{builtin_scene, classed, laps_script};
use anyhow::Result;
use serde::Serialize;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use vps_device::{HandParams, SimulatedHand};
use vps_haptic::{HapticParams, PartState};
use vps_runtime::{run_loop, LoopConfig, RtGrant, SessionSetup, StatsSummary};
use vps_voxelize::{point_shell, ShellMethod};

#[derive(Serialize)]
struct LoopBench {
    scene_triangles: usize,
    voxel_size_m: f64,
    shell_voxel_size_m: f64,
    shell_points: usize,
    threads: usize,
    frames_requested: u64,
    rt: RtGrant,
    host_idle: super::host_idle::HostIdle,
    stats: StatsSummary,
}

/// Runs the benchmark and prints JSON.
pub fn run(voxel_size: f64, points: usize, frames: u64, threads: usize) -> Result<()> {
    let mut scene = builtin_scene(voxel_size, ShellMethod::VoxelCentres)?;
    // Point count scales as 1/s² for a surface: choose the shell's voxel size for `points`.
    let coarse = scene.shell.len().max(1) as f64;
    let shell_voxel = voxel_size * (coarse / points.max(1) as f64).sqrt();
    scene.shell = point_shell(
        &vps_mesh::builtin::teapot(),
        shell_voxel,
        ShellMethod::VoxelCentres,
    )?;
    let params = HapticParams::default().with_scene(voxel_size, scene.shell.max_radius())?;
    let laps = 1 + (frames as f64 * params.dt / 30.0).ceil() as usize;
    let script = laps_script(&scene.tree, &scene.corridor, 0.8, laps)?;
    let (start, orientation) = script.sample(0.0);
    let config = LoopConfig {
        frames: Some(frames),
        threads,
        realtime: true,
        ..LoopConfig::default()
    };
    let report = run_loop(
        scene.tree.clone(),
        classed(&scene.shell),
        SessionSetup {
            params,
            device: Box::new(SimulatedHand::new(script, HandParams::default())?),
            initial: PartState::at_rest(start, orientation),
            config,
            feed: None,
            stop: Arc::new(AtomicBool::new(false)),
        },
    )?;
    print_json(&LoopBench {
        scene_triangles: scene.scene_triangles,
        voxel_size_m: voxel_size,
        shell_voxel_size_m: shell_voxel,
        shell_points: scene.shell.len(),
        threads,
        frames_requested: frames,
        rt: report.rt,
        host_idle: super::host_idle::HostIdle::read(),
        stats: report.stats,
    })
}
