//! `vps bench cluster`: a paced 1 kHz session over a single-host multi-process cluster (W local
//! `vps worker` processes on loopback, QUIC with pinned mutual TLS) with an N-point shell: missed
//! deadlines, frame time percentiles, shares recomputed locally, per-worker metrics.
//!
//! Scene and motion as `vps bench loop` (the scene, default the built-in bay, its part's shell
//! resampled to about `--points` points, the scene's script repeated), so the two are comparable. The loop
//! runs with its defaults: 1 ms period, 800 µs watchdog, replies awaited until 400 µs into the
//! frame, real-time scheduling when granted.

use anyhow::Result;
use serde::Serialize;
use vps_app::output::print_report;
use vps_app::SceneRequest;
use vps_app::{ClusterBackend, Prepared, SessionRequest, Workers};
use vps_cluster::GatherConfig;
use vps_runtime::{LoopConfig, StatsSummary};
use vps_session::{DeviceChoice, SessionAssets};
use vps_voxelize::ShellMethod;

/// What `vps bench cluster` measures.
#[derive(Clone, Debug)]
pub struct ClusterBench {
    /// The scene.
    pub scene: SceneRequest,
    /// Voxel size instead of the scene's (m).
    pub voxel_size: Option<f64>,
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
    pub gather: GatherConfig,
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
    host_idle: crate::machine::HostIdle,
    stats: StatsSummary,
    /// Per-worker figures and `placement` (`CoordinatedRun::cluster_json`).
    cluster: serde_json::Value,
}

/// Runs the benchmark and prints JSON.
pub fn run(bench: ClusterBench, json: bool) -> Result<()> {
    let mut assets = SessionAssets::open(
        &bench.scene.scene,
        &bench.scene.build_options(bench.voxel_size),
    )?;
    let shell_voxel = assets.resample_shell(bench.points, ShellMethod::VoxelCentres)?;
    let script = assets.script_for_frames(bench.frames)?;
    let config = LoopConfig {
        frames: Some(bench.frames),
        realtime: true,
        ..LoopConfig::default()
    };
    let shell_points = assets.shell.len();
    let plan = assets.plan(&DeviceChoice::Simulated, script, config)?;
    let session = SessionRequest {
        threads: bench.local_threads,
        ..SessionRequest::default()
    };
    let prepared = Prepared::from_plan(assets, plan, DeviceChoice::Simulated, session)?;
    let run = prepared.run_coordinated(ClusterBackend {
        workers: Workers::Local {
            count: bench.workers,
            threads: bench.worker_threads,
        },
        gather: bench.gather,
    })?;
    vps_app::exit::require_complete(&run.report.end, Some(&run.signals))?;
    let cluster = run.cluster_json()?;
    print_report(
        "bench cluster: a paced session over local worker processes",
        &ClusterBenchReport {
        command: format!(
            "vps bench cluster --scene {} --points {} --frames {} --workers {} --worker-threads {} --threads {} \
             --spin-us {} --max-stale-frames {}{}",
            bench.scene.scene,
            bench.points,
            bench.frames,
            bench.workers,
            bench.worker_threads,
            bench.local_threads,
            bench.gather.spin_margin.as_micros(),
            bench.gather.stale.max_age_frames,
            if !bench.gather.adaptive_shares {
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
        host_idle: crate::machine::HostIdle::read(),
        stats: run.report.stats,
        cluster,
        },
        json,
    )
}
