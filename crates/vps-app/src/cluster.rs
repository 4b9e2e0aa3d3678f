//! Coordinated sessions ([`Prepared::run_coordinated`]), shared by `vps coordinator`, `vps
//! cluster` and the cluster benchmarks: a session whose frames are computed by workers over QUIC
//! (docs/architecture.md#exact-sums-and-the-cluster), on a coordinator started here, with the
//! workers on the LAN ([`Workers::Lan`]) or spawned on this host ([`Workers::Local`]).

use crate::finish::finish;
use crate::prepare::Prepared;
use crate::request::SessionRequest;
use crate::session_files::SessionOutputs;
use anyhow::{Context, Result};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use vps_cluster::{
    local_cluster_certs, run_coordinator_session, spawn_local_workers, ClusterAssets,
    ClusterReport, Coordinator, CoordinatorConfig, GatherConfig, LocalWorkerArgs, PeerTls,
};
use vps_runtime::{KeepOffFrameCore, LoopReport, Placement, SignalStop};
use vps_session::SessionAssets;

/// How long a coordinator waits for its workers to join before it gives up, unless told
/// otherwise (`--join-wait`); local workers (`Workers::Local`) always get this long.
pub const DEFAULT_JOIN_WAIT: Duration = Duration::from_secs(20);

/// What one coordinated session produced.
pub struct CoordinatedRun {
    /// The frame loop's report.
    pub report: LoopReport,
    /// Per-worker figures.
    pub cluster: ClusterReport,
    /// The scene's assets the session ran on.
    pub assets: vps_session::SessionAssets,
    /// The bridge's counters and wrench log, when the device was the UDP bridge.
    pub bridge: Option<vps_input::BridgeMonitor>,
    /// The signal handlers that could stop the session (which one did, if any).
    pub signals: SignalStop,
    /// What was kept off the frame thread's core (`None`: nothing, on one core or unpaced).
    pub placement: Option<Placement>,
    /// What was asked for.
    pub request: SessionRequest,
    /// The files the session writes at its end, checked.
    pub outputs: SessionOutputs,
}

/// Where a coordinated session's workers come from.
pub enum Workers {
    /// Workers on the LAN dial a coordinator listening on `listen`, with `tls` (its identity and
    /// the pinned workers' certificates); the session starts once `count` have joined.
    Lan {
        /// The coordinator's UDP address.
        listen: SocketAddr,
        /// The coordinator's identity and the workers it admits.
        tls: PeerTls,
        /// Workers to wait for.
        count: usize,
        /// How long to wait for them ([`DEFAULT_JOIN_WAIT`] unless the user says).
        join_wait: Duration,
    },
    /// `count` worker processes of `threads` threads each, spawned on this host from this
    /// executable, on loopback with fresh certificates pinned both ways.
    Local {
        /// Worker processes.
        count: usize,
        /// Compute threads per worker process.
        threads: usize,
    },
}

/// A coordinated session's workers and how their replies are gathered.
pub struct ClusterBackend {
    /// Where the workers come from.
    pub workers: Workers,
    /// How replies are gathered; its `local_threads` is set from the request's `threads`.
    pub gather: GatherConfig,
}

impl Prepared {
    /// Runs this session with the workers of `cluster`: its frames are split between the
    /// coordinator's own threads and the workers, replies gathered within each frame's budget.
    pub fn run_coordinated(self, cluster: ClusterBackend) -> Result<CoordinatedRun> {
        match cluster.workers {
            Workers::Lan {
                listen,
                tls,
                count,
                join_wait,
            } => coordinate(
                self,
                listen,
                tls,
                count,
                join_wait,
                cluster.gather,
                |_, _| Ok(None),
            ),
            Workers::Local { count, threads } => {
                run_local_cluster(self, count, threads, cluster.gather)
            }
        }
    }
}

impl CoordinatedRun {
    /// The per-worker figures as JSON with, as `placement`, where the threads and worker
    /// processes were placed and which core the OS granted the frame thread.
    pub fn cluster_json(&self) -> Result<serde_json::Value> {
        let mut cluster = serde_json::to_value(&self.cluster)?;
        if let Some(fields) = cluster.as_object_mut() {
            let mut placement = serde_json::to_value(&self.placement)?;
            if let Some(p) = placement.as_object_mut() {
                // What the OS granted the frame thread, beside what was planned for it.
                p.insert(
                    "frame_thread_pinned_core".into(),
                    serde_json::to_value(self.report.rt.pinned_core)?,
                );
            }
            fields.insert("placement".into(), placement);
        }
        Ok(cluster)
    }

    /// [`finish`] for a coordinated session: its report carries [`Self::cluster_json`] as
    /// `cluster`.
    pub fn finish(self) -> Result<()> {
        let cluster = self.cluster_json()?;
        finish(
            &self.request,
            self.outputs,
            &self.signals,
            &self.assets,
            &self.report,
            self.bridge.as_ref(),
            Some(&cluster),
        )
    }
}

/// Runs `prepared` on a coordinator started on `listen` (with `tls`: its identity and the pinned
/// workers' certificates, loaded by the caller) once `workers` have joined; `spawn` starts local workers
/// when asked, given the coordinator's address and what to keep off the frame thread's core
/// (on a machine of more than one core, the coordinator's network and metrics threads are kept
/// off it too). The request gives the local threads and the viewer
/// address; `gather` the share adaptation ([`GatherConfig::adaptive_shares`]) and the spin margin
/// ([`GatherConfig::spin_margin`]).
fn coordinate(
    prepared: Prepared,
    listen: SocketAddr,
    tls: PeerTls,
    workers: usize,
    join_wait: Duration,
    gather: GatherConfig,
    spawn: impl FnOnce(
        SocketAddr,
        Option<&KeepOffFrameCore>,
    ) -> Result<Option<vps_cluster::LocalWorkers>>,
) -> Result<CoordinatedRun> {
    let keep_off = if prepared.plan.setup.config.realtime {
        KeepOffFrameCore::for_frame(prepared.plan.setup.config.core)
    } else {
        None
    };
    // Held whole to the end: its viewer serves the session.
    let live = prepared.go_live()?;
    let cluster_assets = Arc::new(cluster_assets(&live.assets)?);
    let coordinator = Coordinator::start(
        CoordinatorConfig {
            listen,
            tls,
            keep_off: keep_off.clone(),
        },
        cluster_assets,
    )?;
    let addr = coordinator.local_addr()?;
    eprintln!("coordinator listening on {addr}, waiting for {workers} worker(s)");
    let _children = spawn(addr, keep_off.as_ref())?;
    if coordinator
        .wait_for_workers_until(workers, join_wait, &live.setup.stop)
        .is_err()
    {
        // Listening on every address (0.0.0.0): a worker dials one of this host's own.
        let dialled = if addr.ip().is_unspecified() {
            format!("this host's LAN IP, UDP port {}", addr.port())
        } else {
            addr.to_string()
        };
        anyhow::bail!(
            "only {} of {workers} worker(s) joined within {} s ({} refused for an unpinned certificate, logged above): start the workers (each dials {dialled}, its `coordinator`), pin each worker's certificate here and this coordinator's on each worker, or lower `workers` (or wait longer: `join_wait`)",
            coordinator.joined_workers(),
            join_wait.as_secs_f64(),
            coordinator.refused_unpinned()
        );
    }
    let gather = GatherConfig {
        local_threads: live.request.threads.max(1),
        ..gather
    };
    let (report, cluster) = run_coordinator_session(&coordinator, gather, live.setup)?;
    let placement = coordinator.placement();
    if let Some(signal) = live.signals.received() {
        // The device has been written zero; tell the workers this coordinator is going.
        coordinator.close(
            vps_cluster::close::CLOSE_COORDINATOR_STOPPING,
            &format!("coordinator stopping ({})", signal.name()),
        );
    }
    Ok(CoordinatedRun {
        report,
        cluster,
        assets: live.assets,
        bridge: live.bridge,
        signals: live.signals,
        placement,
        request: live.request,
        outputs: live.outputs,
    })
}

/// What the workers of a session of `assets` sample: the static scene's voxmap and the first
/// part's shell and, in a scene of several parts, every part's shell and body voxmap (the workers
/// then take every part's share of the scene and both directions of every pair). Allocates.
fn cluster_assets(assets: &SessionAssets) -> Result<ClusterAssets> {
    let scene = assets.tree.clone();
    let shells: Vec<_> = std::iter::once(&assets.shell)
        .chain(assets.more_parts.iter().map(|p| &p.shell))
        .map(|s| (s.points(), s.classed()))
        .collect();
    let Some(first_body) = assets.part_body.clone() else {
        return Ok(ClusterAssets::of_classed_parts(scene, &shells[..1], &[])?);
    };
    let bodies: Vec<Arc<vps_voxmap::VoxelTree>> = std::iter::once(first_body)
        .chain(assets.more_parts.iter().map(|p| p.body.clone()))
        .collect();
    Ok(ClusterAssets::of_classed_parts(scene, &shells, &bodies)?)
}

/// Runs `prepared` with `workers` local worker processes of `worker_threads` threads each, on
/// loopback with fresh certificates pinned both ways.
fn run_local_cluster(
    prepared: Prepared,
    workers: usize,
    worker_threads: usize,
    gather: GatherConfig,
) -> Result<CoordinatedRun> {
    let dir = std::env::temp_dir().join(format!("vps-cluster-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let certs = local_cluster_certs(&dir, workers)?;
    let exe = std::env::current_exe().context("locating the vps executable")?;
    let result = coordinate(
        prepared,
        "127.0.0.1:0".parse()?,
        PeerTls::load(
            &certs.coordinator.cert,
            &certs.coordinator.key,
            &certs.worker_pins(),
        )?,
        workers,
        DEFAULT_JOIN_WAIT,
        gather,
        |addr, keep_off| {
            // Each worker its own certificate: the coordinator admits one live connection per
            // certificate.
            let spawn_args: Vec<LocalWorkerArgs> = (0..workers)
                .filter_map(|k| certs.worker_args(k, addr, Some(worker_threads)))
                .collect();
            Ok(Some(spawn_local_workers(&exe, &spawn_args, keep_off)?))
        },
    );
    let _ = std::fs::remove_dir_all(&dir);
    result
}
