//! `vps bench cluster`: a paced 1 kHz session over a single-host multi-process cluster (W local
//! `vps worker` processes on loopback, QUIC with pinned mutual TLS) with an N-point shell: missed
//! deadlines, frame time percentiles, shares recomputed locally, per-worker metrics.
//!
//! Scene and motion as `vps bench loop` (the aircraft bay, the teapot's shell resampled to about
//! `--points` points, the scripted laps along the corridor), so the two are comparable. The loop
//! runs with its defaults: 1 ms period, 800 µs watchdog, replies awaited until 400 µs into the
//! frame, real-time scheduling when granted.

use super::cluster::run_local_cluster_prepared;
use super::output::print_json;
use super::run::PreparedSession;
use crate::cli::{GatherArgs, RunArgs};
use crate::session::{builtin_scene, laps_script};
use anyhow::Result;
use serde::Serialize;
use vps_cluster::ClusterReport;
use vps_device::{HandParams, SimulatedHand};
use vps_haptic::{HapticParams, PartState};
use vps_runtime::{LoopConfig, StatsSummary};
use vps_voxelize::{point_shell, ShellMethod};

/// What `vps bench cluster` measures.
#[derive(Clone, Copy, Debug)]
pub struct ClusterBench {
    /// Voxel size of the scene (m).
    pub voxel_size: f64,
    /// Approximate shell points.
    pub points: usize,
    /// Frames (1 ms each).
    pub frames: u64,
    /// Worker processes.
    pub workers: usize,
    /// Compute threads per worker process.
    pub worker_threads: usize,
    /// Compute threads of the coordinator (its own share and the fallback).
    pub local_threads: usize,
    /// Share adaptation and reply spinning.
    pub gather: GatherArgs,
}

#[derive(Serialize)]
struct ClusterBenchReport {
    command: String,
    shell_voxel_size_m: f64,
    shell_points: usize,
    workers: usize,
    worker_threads: usize,
    local_threads: usize,
    frames_requested: u64,
    realtime_granted: bool,
    host_idle: super::host_idle::HostIdle,
    stats: StatsSummary,
    cluster: ClusterReport,
}

/// Runs the benchmark and prints JSON.
pub fn run(bench: ClusterBench) -> Result<()> {
    let mut scene = builtin_scene(bench.voxel_size, ShellMethod::VoxelCentres)?;
    // Point count scales as 1/s² for a surface: the shell's voxel size for `points` (as bench loop).
    let coarse = scene.shell.len().max(1) as f64;
    let shell_voxel = bench.voxel_size * (coarse / bench.points.max(1) as f64).sqrt();
    scene.shell = point_shell(
        &vps_mesh::builtin::teapot(),
        shell_voxel,
        ShellMethod::VoxelCentres,
    )?;
    let params = HapticParams::default().with_scene(bench.voxel_size, scene.shell.max_radius())?;
    let laps = 1 + (bench.frames as f64 * params.dt / 30.0).ceil() as usize;
    let script = laps_script(&scene.tree, &scene.corridor, 0.8, laps)?;
    let (start, orientation) = script.sample(0.0);
    let config = LoopConfig {
        frames: Some(bench.frames),
        realtime: true,
        ..LoopConfig::default()
    };
    let shell_points = scene.shell.len();
    let prepared = PreparedSession {
        scene,
        params,
        device: Box::new(SimulatedHand::new(script, HandParams::default())?),
        initial: PartState::at_rest(start, orientation),
        config,
    };
    let session = RunArgs {
        threads: bench.local_threads,
        ..RunArgs::default()
    };
    let run = run_local_cluster_prepared(
        &session,
        prepared,
        bench.workers,
        bench.worker_threads,
        bench.gather,
    )?;
    print_json(&ClusterBenchReport {
        command: format!(
            "vps bench cluster --points {} --frames {} --workers {} --worker-threads {} --threads {} \
             --spin-us {} --max-stale-frames {}{}",
            bench.points,
            bench.frames,
            bench.workers,
            bench.worker_threads,
            bench.local_threads,
            bench.gather.spin_us,
            bench.gather.max_stale_frames,
            if bench.gather.equal_shares {
                " --equal-shares"
            } else {
                ""
            }
        ),
        shell_voxel_size_m: shell_voxel,
        shell_points,
        workers: bench.workers,
        worker_threads: bench.worker_threads,
        local_threads: bench.local_threads,
        frames_requested: bench.frames,
        realtime_granted: run.report.rt.fifo,
        host_idle: super::host_idle::HostIdle::read(),
        stats: run.report.stats,
        cluster: run.cluster,
    })
}
