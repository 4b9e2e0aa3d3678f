//! `vps cert`, `vps worker`, `vps coordinator` and `vps cluster`: the cluster modes over QUIC
//! (docs/architecture.md#exact-sums-and-the-cluster), thin shells over `vps-cluster`.

use super::exit::SessionExit;
use super::run::{finish, prepare, LiveSession, PreparedSession, SessionOutputs};
use crate::cli::{ClusterArgs, CoordinatorArgs, GatherArgs, RunArgs, WorkerArgs};
use anyhow::{Context, Result};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;
use vps_cluster::{
    local_cluster_certs, make_cert, run_coordinator_session, run_worker_service,
    spawn_local_workers, ClusterAssets, ClusterError, ClusterReport, Coordinator,
    CoordinatorConfig, GatherConfig, LocalWorkerArgs, Rejoin, WorkerConfig,
};
use vps_runtime::{LoopConfig, LoopReport, SignalStop};
use vps_session::CLASS_COUNT;

/// How long the coordinator waits for its workers to join before it starts.
const JOIN_TIMEOUT: Duration = Duration::from_secs(20);

/// `vps cert`: a new self-signed certificate and key for a coordinator or worker.
pub fn cert(out: &std::path::Path, name: &str) -> Result<()> {
    let files = make_cert(out, name)?;
    println!("certificate {}", files.cert.display());
    println!(
        "key         {} (keep private; pin the certificate on the other side)",
        files.key.display()
    );
    Ok(())
}

/// Exit status of a worker refused for good (a certificate not pinned on one side, an
/// incompatible protocol): systemd units keep it from restarting (`RestartPreventExitStatus=`).
const EXIT_REFUSED: i32 = 2;

/// `vps worker`: joins a coordinator and answers frame requests; when the coordinator goes away,
/// waits for the next one (unless `--exit-with-coordinator`), until SIGINT or SIGTERM (exit 0).
/// A refusal for good exits with status 2 and says why.
pub fn worker(args: &WorkerArgs) -> Result<()> {
    let mut config = WorkerConfig::from_files(args.coordinator, &args.cert, &args.key, &args.pin)?;
    config.cache_dir = args.cache.clone();
    if let Some(threads) = args.threads {
        config.threads = threads.max(1);
    }
    let stop = Arc::new(AtomicBool::new(false));
    let signals = SignalStop::install(&stop)?;
    let rejoin = Rejoin {
        exit_with_coordinator: args.exit_with_coordinator,
        ..Rejoin::default()
    };
    match run_worker_service(config, stop, rejoin) {
        Ok(service) => {
            let why = signals
                .received()
                .map_or("its coordinator went away", |s| s.name());
            eprintln!(
                "worker stopped ({why}) after {} session(s)",
                service.sessions.len()
            );
            Ok(())
        }
        Err(ClusterError::Refused(reason)) => Err(SessionExit {
            code: EXIT_REFUSED,
            reason: format!("worker refused for good: {reason}"),
        }
        .into()),
        Err(e) => Err(anyhow::Error::new(e).context("worker")),
    }
}

/// What one coordinated session produced.
pub struct CoordinatedRun {
    /// The frame loop's report.
    pub report: LoopReport,
    /// Per-worker figures.
    pub cluster: ClusterReport,
    /// Points in the shell.
    pub shell_points: usize,
    /// The bridge's counters and wrench log, when the device was the UDP bridge.
    pub bridge: Option<vps_input::BridgeMonitor>,
    /// The signal handlers that could stop the session (which one did, if any).
    pub signals: SignalStop,
}

/// Runs one session on a started coordinator once `workers` have joined; `tune` may adjust the
/// loop settings (benchmarks run frames back to back with a longer reply deadline).
#[allow(clippy::too_many_arguments)]
fn coordinate(
    session: &RunArgs,
    listen: SocketAddr,
    cert: &std::path::Path,
    key: &std::path::Path,
    pins: &[PathBuf],
    workers: usize,
    gather: GatherArgs,
    spawn: impl FnOnce(SocketAddr) -> Result<Option<vps_cluster::LocalWorkers>>,
    tune: impl FnOnce(&mut LoopConfig),
) -> Result<CoordinatedRun> {
    let mut prepared = prepare(session)?;
    tune(&mut prepared.plan.config);
    coordinate_prepared(
        session, prepared, listen, cert, key, pins, workers, gather, spawn,
    )
}

/// [`coordinate`] for a session already prepared (benchmarks bring their own scene and device);
/// `session` gives the local threads and the viewer address; `gather` the share adaptation
/// ([`GatherConfig::adaptive_shares`]) and the spin margin ([`GatherConfig::spin_margin`]).
#[allow(clippy::too_many_arguments)]
fn coordinate_prepared(
    session: &RunArgs,
    prepared: PreparedSession,
    listen: SocketAddr,
    cert: &std::path::Path,
    key: &std::path::Path,
    pins: &[PathBuf],
    workers: usize,
    gather: GatherArgs,
    spawn: impl FnOnce(SocketAddr) -> Result<Option<vps_cluster::LocalWorkers>>,
) -> Result<CoordinatedRun> {
    let LiveSession {
        session: scene,
        viewer: _viewer,
        setup,
        bridge,
        signals,
    } = prepared.go_live(session.view)?;
    let cluster_scene = Arc::new(ClusterAssets::new(
        scene.tree.clone(),
        &scene.shell,
        CLASS_COUNT,
    )?);
    let coordinator = Coordinator::start(
        CoordinatorConfig::from_files(listen, cert, key, pins)?,
        cluster_scene,
    )?;
    let addr = coordinator.local_addr()?;
    eprintln!("coordinator listening on {addr}, waiting for {workers} worker(s)");
    let _children = spawn(addr)?;
    coordinator
        .wait_for_workers_until(workers, JOIN_TIMEOUT, &setup.stop)
        .with_context(|| format!("waiting {JOIN_TIMEOUT:?} for {workers} worker(s) to join"))?;
    let gather = GatherConfig {
        local_threads: session.threads.max(1),
        adaptive_shares: !gather.equal_shares,
        predict: gather.predict_split,
        spin_margin: Duration::from_micros(gather.spin_us),
        stale: vps_cluster::fallback::StalePolicy {
            max_age_frames: gather.max_stale_frames,
            ..Default::default()
        },
        ..GatherConfig::default()
    };
    let (report, cluster) = run_coordinator_session(&coordinator, gather, setup)?;
    if let Some(signal) = signals.received() {
        // The device has been written zero; tell the workers this coordinator is going.
        coordinator.close(
            vps_cluster::close::CLOSE_COORDINATOR_STOPPING,
            &format!("coordinator stopping ({})", signal.name()),
        );
    }
    Ok(CoordinatedRun {
        report,
        cluster,
        shell_points: scene.shell.len(),
        bridge,
        signals,
    })
}

/// `vps coordinator`: owns the device loop; workers from the LAN join with pinned certificates.
pub fn coordinator(args: &CoordinatorArgs) -> Result<()> {
    let outputs = SessionOutputs::reserve(&args.session)?;
    let run = coordinate(
        &args.session,
        args.listen,
        &args.cert,
        &args.key,
        &args.pin,
        args.workers,
        args.gather,
        |_| Ok(None),
        |_| {},
    )?;
    finish(
        &args.session,
        outputs,
        &run.signals,
        run.shell_points,
        &run.report,
        run.bridge.as_ref(),
        Some(&run.cluster),
    )
}

/// `vps cluster --local-workers N`: the coordinator plus N worker processes on loopback, with
/// fresh certificates pinned both ways.
pub fn local_cluster(args: &ClusterArgs) -> Result<()> {
    crate::limits::check_thread_total(
        "--local-workers × --worker-threads",
        args.local_workers * args.worker_threads,
    )?;
    let outputs = SessionOutputs::reserve(&args.session)?;
    let run = run_local_cluster(
        &args.session,
        args.local_workers,
        args.worker_threads,
        args.gather,
        |_| {},
    )?;
    finish(
        &args.session,
        outputs,
        &run.signals,
        run.shell_points,
        &run.report,
        run.bridge.as_ref(),
        Some(&run.cluster),
    )
}

/// A session with `workers` local worker processes of `worker_threads` threads each.
pub fn run_local_cluster(
    session: &RunArgs,
    workers: usize,
    worker_threads: usize,
    gather: GatherArgs,
    tune: impl FnOnce(&mut LoopConfig),
) -> Result<CoordinatedRun> {
    let mut prepared = prepare(session)?;
    tune(&mut prepared.plan.config);
    run_local_cluster_prepared(session, prepared, workers, worker_threads, gather)
}

/// [`run_local_cluster`] for a session already prepared (`session`: local threads, viewer).
pub fn run_local_cluster_prepared(
    session: &RunArgs,
    prepared: PreparedSession,
    workers: usize,
    worker_threads: usize,
    gather: GatherArgs,
) -> Result<CoordinatedRun> {
    let dir = std::env::temp_dir().join(format!("vps-cluster-{}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
    let certs = local_cluster_certs(&dir, workers)?;
    let exe = std::env::current_exe().context("locating the vps executable")?;
    let result = coordinate_prepared(
        session,
        prepared,
        "127.0.0.1:0".parse()?,
        &certs.coordinator.cert,
        &certs.coordinator.key,
        &certs.worker_pins(),
        workers,
        gather,
        |addr| {
            // Each worker its own certificate: the coordinator admits one live connection per
            // certificate.
            let spawn_args: Vec<LocalWorkerArgs> = (0..workers)
                .filter_map(|k| certs.worker_args(k, addr, Some(worker_threads)))
                .collect();
            Ok(Some(spawn_local_workers(&exe, &spawn_args)?))
        },
    );
    let _ = std::fs::remove_dir_all(&dir);
    result
}
