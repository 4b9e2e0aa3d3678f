//! `vps worker`: dials the coordinator, joins (receiving the voxmap and shell files unless cached), then answers
//! frame datagrams with the partial sums of the classes each one asks for.
//!
//! Threads: one tokio current-thread runtime for the network, which also computes each share on
//! the local class pool (`vps_runtime::ClassPool`, the loop's own sampler): alone with one compute
//! thread (a request is answered without any thread hand-off), else with the pool's `threads − 1`
//! threads. It always answers the newest queued request and
//! drops older ones (the coordinator has given up on them anyway). Malformed datagrams are counted
//! and ignored.
//!
//! As a service ([`run_worker_service`]) a worker outlives its coordinators: when one goes away
//! (closed, stopped by a signal, silent past the idle timeout, not there yet) it waits
//! ([`Rejoin`]: 100 ms doubling to 5 s, with jitter) and joins the next one at the same address,
//! until its stop flag is set. A refusal for good ([`ClusterError::Refused`]: a certificate not
//! pinned on either side, an incompatible protocol) ends it with that error instead.

use crate::assets::{check_sizes, AssetData, AssetsCache, ClusterAssets, MAX_ASSET_FILE};
use crate::protocol::{
    read_frame, read_join, write_join, FrameReply, FrameRequest, JoinMessage, PROTOCOL_VERSION,
    REPLY_LEN,
};
use crate::tls::{client_config, PeerTls, SERVER_NAME};
use crate::{close, ClusterError};
use std::future::Future;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use vps_haptic::job::MAX_JOBS;
use vps_haptic::PartialSums;
use vps_runtime::ClassPool;
use vps_voxmap::VoxelTree;

/// How a worker runs.
#[derive(Clone, Debug)]
pub struct WorkerConfig {
    /// The coordinator's UDP address.
    pub coordinator: SocketAddr,
    /// This worker's certificate and key, and the coordinator certificates it accepts.
    pub tls: PeerTls,
    /// Where received voxmap and shell files are kept (`None`: no cache).
    pub cache_dir: Option<PathBuf>,
    /// Compute threads (≥ 1).
    pub threads: usize,
}

impl WorkerConfig {
    /// A config for joining `coordinator` with `tls` (e.g. [`PeerTls::load`] from PEM files):
    /// one compute thread per available core, no cache.
    pub fn new(coordinator: SocketAddr, tls: PeerTls) -> WorkerConfig {
        WorkerConfig {
            coordinator,
            tls,
            cache_dir: None,
            threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        }
    }
}

/// What a worker did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WorkerReport {
    /// The id the coordinator gave it.
    pub worker_id: u32,
    /// An asset file (a voxmap or a shell) was transferred (not found in the cache). Named like the
    /// coordinator's `PeerReport::scene_sent`, a key of the session report.
    pub scene_transferred: bool,
    /// Valid frame requests received.
    pub requests: u64,
    /// Replies sent.
    pub replies: u64,
    /// Requests dropped because a request of a newer frame was queued.
    pub superseded: u64,
    /// Datagrams that failed to decode (garbage, truncated, wrong version) or named a job its
    /// assets cannot sample.
    pub invalid_datagrams: u64,
    /// UDP datagrams on its socket that cannot be QUIC packets by their shape (raw garbage; see
    /// [`crate::udp_count`]).
    pub udp_not_quic: u64,
    /// UDP datagrams on its socket shaped like QUIC that none of its connections can own (an
    /// unknown version or connection ID; see [`crate::udp_count`]).
    pub udp_foreign: u64,
    /// How the connection ended ("stopped", or the coordinator's close as quinn reports it).
    pub ended: String,
    /// The coordinator closed the connection itself because its session ended or it was stopped
    /// (close codes [`close::CLOSE_SESSION_DONE`], [`close::CLOSE_COORDINATOR_STOPPING`]): the
    /// expected end of a session, not a loss.
    pub coordinator_closed: bool,
}

/// Runs a worker until the coordinator closes the connection or goes silent (idle timeout).
/// Blocking.
pub fn run_worker(config: WorkerConfig) -> Result<WorkerReport, ClusterError> {
    run_worker_until(config, Arc::new(AtomicBool::new(false)))
}

/// [`run_worker`], also ending (closing its connection) within about 20 ms of `stop` being set;
/// set while it is still connecting or joining, it ends as soon with
/// [`ClusterError::Network`] ("stopped before joining").
pub fn run_worker_until(
    config: WorkerConfig,
    stop: Arc<AtomicBool>,
) -> Result<WorkerReport, ClusterError> {
    worker_runtime(&config)?.block_on(worker_main(config, stop))
}

/// Checks `config` and builds the worker's current-thread runtime.
fn worker_runtime(config: &WorkerConfig) -> Result<tokio::runtime::Runtime, ClusterError> {
    if config.threads == 0 {
        return Err(ClusterError::Config {
            field: "threads",
            message: "must be at least 1".into(),
        });
    }
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .map_err(|e| ClusterError::Network(format!("cannot start the runtime: {e}")))
}

fn net_err(e: impl std::fmt::Display) -> ClusterError {
    ClusterError::Network(e.to_string())
}

async fn worker_main(
    config: WorkerConfig,
    stop: Arc<AtomicBool>,
) -> Result<WorkerReport, ClusterError> {
    let bind: SocketAddr = if config.coordinator.is_ipv4() {
        ([0, 0, 0, 0], 0).into()
    } else {
        ([0u16; 8], 0).into()
    };
    let udp = Arc::new(crate::udp_count::UdpCounts::default());
    let mut endpoint =
        crate::udp_count::counting_endpoint(bind, None, udp.clone()).map_err(net_err)?;
    endpoint.set_default_client_config(client_config(&config.tls, Arc::new(AtomicU64::new(0)))?);
    let connecting = endpoint
        .connect(config.coordinator, SERVER_NAME)
        .map_err(net_err)?;
    // A handshake with no coordinator there lasts until the idle timeout (3 s): the stop flag
    // is watched meanwhile, so that SIGTERM ends a waiting worker at once.
    let conn = match until_stopped(&stop, connecting).await {
        None => return Err(stopped_before_joining()),
        Some(Ok(conn)) => conn,
        Some(Err(e)) => {
            return Err(refusal(config.coordinator, &e)
                .unwrap_or_else(|| connect_error(config.coordinator, &e)))
        }
    };
    let cache = AssetsCache::new(config.cache_dir.clone());
    let joined = match until_stopped(&stop, join(&conn, &cache)).await {
        Some(joined) => joined,
        None => {
            conn.close(close::code(close::CLOSE_WORKER_STOPPED), b"worker stopped");
            endpoint.close(close::code(close::CLOSE_WORKER_STOPPED), b"bye");
            let _ = tokio::time::timeout(Duration::from_millis(200), endpoint.wait_idle()).await;
            return Err(stopped_before_joining());
        }
    };
    let (scene, worker_id, scene_transferred) = match joined {
        Ok(joined) => joined,
        Err(e) => {
            // A join that failed because the coordinator closed the connection: say why it did.
            let why = conn.close_reason();
            return Err(why
                .and_then(|why| refusal(config.coordinator, &why))
                .unwrap_or(e));
        }
    };
    tracing::info!(
        worker_id,
        scene_transferred,
        "joined {}",
        config.coordinator
    );

    let mut answer = Answerer::new(scene, config.threads)?;
    let mut invalid = 0u64;
    let mut coordinator_closed = false;
    let ended = loop {
        tokio::select! {
            datagram = conn.read_datagram() => match datagram {
                Ok(bytes) => {
                    answer.batch.clear();
                    if let Some(request) = answer.decode(&bytes, &mut invalid) {
                        answer.queue(request);
                    }
                    // Requests queued meanwhile: only the newest frame's are answered (the
                    // coordinator has given up on the older ones).
                    while let Some(Ok(bytes)) = try_read_datagram(&conn) {
                        if let Some(request) = answer.decode(&bytes, &mut invalid) {
                            answer.queue(request);
                        }
                    }
                    if !answer.reply_all(&conn) {
                        break conn
                            .close_reason()
                            .map_or_else(|| "send failed".into(), |e| e.to_string());
                    }
                }
                Err(e) => {
                    tracing::debug!("connection ended: {e}");
                    // Replaced by a newer connection with this certificate: stop, rather than
                    // rejoin and take turns with the process that replaced this one.
                    if let Some(refused) = refusal(config.coordinator, &e) {
                        endpoint.close(close::code(close::CLOSE_WORKER_STOPPED), b"bye");
                        return Err(refused);
                    }
                    coordinator_closed = closed_by_coordinator(&e);
                    break e.to_string();
                }
            },
            _ = tokio::time::sleep(STOP_POLL) => {
                if stop.load(Ordering::Relaxed) {
                    conn.close(close::code(close::CLOSE_WORKER_STOPPED), b"worker stopped");
                    break "stopped".into();
                }
            }
        }
    };
    endpoint.close(close::code(close::CLOSE_WORKER_STOPPED), b"bye");
    let _ = tokio::time::timeout(Duration::from_millis(200), endpoint.wait_idle()).await;
    Ok(WorkerReport {
        worker_id,
        scene_transferred,
        requests: answer.requests,
        replies: answer.replies,
        superseded: answer.superseded,
        invalid_datagrams: invalid,
        udp_not_quic: udp.not_quic(),
        udp_foreign: udp.foreign(),
        ended,
        coordinator_closed,
    })
}

/// How often a worker waiting on the network looks at its stop flag (the signal handlers only set
/// an atomic).
const STOP_POLL: Duration = Duration::from_millis(20);

/// `future`'s output, or `None` once `stop` is set first (looked at every [`STOP_POLL`]).
async fn until_stopped<F: Future>(stop: &AtomicBool, future: F) -> Option<F::Output> {
    let mut future = std::pin::pin!(future);
    loop {
        tokio::select! {
            out = &mut future => return Some(out),
            _ = tokio::time::sleep(STOP_POLL) => {
                if stop.load(Ordering::Relaxed) {
                    return None;
                }
            }
        }
    }
}

/// The error of a worker stopped (its stop flag set) before it joined.
fn stopped_before_joining() -> ClusterError {
    ClusterError::Network("stopped before joining".into())
}

/// A failed connection to `coordinator` that is not a refusal; a handshake that timed out (no
/// coordinator answered) says what to check.
fn connect_error(coordinator: SocketAddr, e: &quinn::ConnectionError) -> ClusterError {
    let hint = if matches!(e, quinn::ConnectionError::TimedOut) {
        format!(
            " (no coordinator answered at {coordinator}: is `vps coordinator` running on that host and listening on that address (its `listen`)? is UDP port {} open in its firewall? is `coordinator` in this worker's config (worker.toml, or --coordinator) the coordinator's right IP:port?)",
            coordinator.port()
        )
    } else {
        String::new()
    };
    ClusterError::Network(format!("connect to {coordinator}: {e}{hint}"))
}

/// Whether `e` is the coordinator closing the connection at the end of its session or when
/// stopped (what [`WorkerReport::coordinator_closed`] records).
fn closed_by_coordinator(e: &quinn::ConnectionError) -> bool {
    let expected = [close::CLOSE_SESSION_DONE, close::CLOSE_COORDINATOR_STOPPING].map(u64::from);
    matches!(e, quinn::ConnectionError::ApplicationClosed(a)
        if expected.contains(&a.error_code.into_inner()))
}

/// The refusal for good that a connection error means, if it means one: a TLS failure (a
/// certificate not pinned on one side) or a coordinator's close with a refusal code
/// ([`close::is_refusal`]). `None` for anything retrying may cure (timeouts, a coordinator
/// closing or stopping, a reset).
fn refusal(coordinator: SocketAddr, e: &quinn::ConnectionError) -> Option<ClusterError> {
    use quinn::ConnectionError as E;
    let is_tls = |code: quinn::TransportErrorCode| (0x100..0x200).contains(&u64::from(code));
    match e {
        E::TransportError(t) if is_tls(t.code) => Some(ClusterError::Refused(format!(
            "the coordinator at {coordinator} presented a certificate this worker does not accept (check --pin): {e}"
        ))),
        E::ConnectionClosed(c) if is_tls(c.error_code) => Some(ClusterError::Refused(format!(
            "the coordinator at {coordinator} refused this worker's certificate: certificate not pinned there (pin this worker's .crt on the coordinator with --pin) ({e})"
        ))),
        E::ApplicationClosed(a) if close::is_refusal(a.error_code.into_inner()) => {
            Some(ClusterError::Refused(format!(
                "refused by the coordinator: {} (coordinator at {coordinator})",
                String::from_utf8_lossy(&a.reason)
            )))
        }
        _ => None,
    }
}

/// How a worker service waits between coordinators: `first`, doubling up to `max`, each wait
/// drawn uniformly from its upper half (jitter, so that many workers do not re-join in step).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rejoin {
    /// The first wait after a coordinator goes away (s). Default 100 ms.
    pub first: Duration,
    /// The longest wait. Default 5 s.
    pub max: Duration,
    /// End (`Ok`) when the first coordinator joined goes away instead of waiting for the next
    /// one (the local cluster's child workers, which must not outlive it). Default false.
    pub exit_with_coordinator: bool,
}

impl Default for Rejoin {
    fn default() -> Self {
        Rejoin {
            first: Duration::from_millis(100),
            max: Duration::from_secs(5),
            exit_with_coordinator: false,
        }
    }
}

/// What a worker service did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WorkerService {
    /// Coordinators joined (sessions served), one report each.
    pub sessions: Vec<WorkerReport>,
    /// Connection attempts that failed and were retried.
    pub failed_attempts: u64,
}

/// Runs a worker as a long-lived service (see the module docs): joins the coordinator, serves
/// it, and when it goes away waits ([`Rejoin`]) and joins the next one, until `stop` is set
/// (then `Ok`, within about 20 ms, closing its connection). Errors: an invalid config, or
/// [`ClusterError::Refused`] for a refusal for good. Blocking.
pub fn run_worker_service(
    config: WorkerConfig,
    stop: Arc<AtomicBool>,
    rejoin: Rejoin,
) -> Result<WorkerService, ClusterError> {
    worker_runtime(&config)?.block_on(async {
        let mut service = WorkerService::default();
        let mut wait = rejoin.first;
        let mut rng = rand::thread_rng();
        let mut join_log = crate::join_log::JoinLog::new(rejoin.max);
        while !stop.load(Ordering::Relaxed) {
            match worker_main(config.clone(), stop.clone()).await {
                Ok(report) => {
                    join_log.joined();
                    let stopped = report.ended == "stopped";
                    // A session that ended or a coordinator that was stopped is routine (info);
                    // a coordinator lost without a close is worth a warning.
                    let next = if rejoin.exit_with_coordinator {
                        "exiting with it"
                    } else {
                        "waiting for the next one"
                    };
                    let (coordinator, why) = (config.coordinator, &report.ended);
                    if report.coordinator_closed {
                        tracing::info!("coordinator {coordinator} went away ({why}); {next}");
                    } else if !stopped {
                        tracing::warn!("coordinator {coordinator} went away ({why}); {next}");
                    }
                    service.sessions.push(report);
                    if stopped || rejoin.exit_with_coordinator {
                        break;
                    }
                    wait = rejoin.first;
                }
                Err(e @ ClusterError::Refused(_)) => return Err(e),
                // Stopped while connecting or joining: not a failure to report.
                Err(_) if stop.load(Ordering::Relaxed) => break,
                Err(e) if rejoin.exit_with_coordinator => return Err(e),
                Err(e) => {
                    service.failed_attempts += 1;
                    let coordinator = config.coordinator.to_string();
                    let now = std::time::Instant::now();
                    if let Some(line) = join_log.failed(&coordinator, &e.to_string(), now) {
                        tracing::warn!("{line}");
                    }
                }
            }
            let jittered = wait.mul_f64(rand::Rng::gen_range(&mut rng, 0.5..=1.0));
            let until = tokio::time::Instant::now() + jittered;
            while tokio::time::Instant::now() < until && !stop.load(Ordering::Relaxed) {
                tokio::time::sleep(STOP_POLL).await;
            }
            wait = (wait * 2).min(rejoin.max);
        }
        Ok(service)
    })
}

/// A datagram already received, without waiting (`None`: none queued).
fn try_read_datagram(
    conn: &quinn::Connection,
) -> Option<Result<bytes::Bytes, quinn::ConnectionError>> {
    let mut read = std::pin::pin!(conn.read_datagram());
    let mut cx = std::task::Context::from_waker(std::task::Waker::noop());
    match read.as_mut().poll(&mut cx) {
        std::task::Poll::Ready(r) => Some(r),
        std::task::Poll::Pending => None,
    }
}

/// Computes and sends replies on the network thread itself, sampling each share on the local
/// class pool (`vps_runtime::ClassPool`, the loop's own sampler): the network thread claims
/// classes with the pool's `threads − 1` threads; with one compute thread it samples alone (no
/// thread hand-off between a request's arrival and its reply).
struct Answerer {
    scene: ClusterAssets,
    pool: ClassPool<VoxelTree>,
    /// The requests to answer now: the newest frame's, one per job.
    batch: Vec<FrameRequest>,
    buf: [u8; REPLY_LEN],
    requests: u64,
    replies: u64,
    superseded: u64,
}

impl Answerer {
    fn new(scene: ClusterAssets, threads: usize) -> Result<Answerer, ClusterError> {
        let pool = scene.class_pool(threads.max(1), "threads")?;
        Ok(Answerer {
            scene,
            pool,
            batch: Vec::with_capacity(MAX_JOBS),
            buf: [0; REPLY_LEN],
            requests: 0,
            replies: 0,
            superseded: 0,
        })
    }

    /// A frame request, or `None` (counted in `invalid`) for a malformed datagram or one naming
    /// a job these assets cannot sample.
    fn decode(&mut self, bytes: &[u8], invalid: &mut u64) -> Option<FrameRequest> {
        match FrameRequest::decode(bytes) {
            Ok(request) if self.scene.target(request.job).is_none() => {
                *invalid += 1;
                tracing::debug!(
                    "dropped a request for shell {} in voxmap {}: no such asset",
                    request.job.shell,
                    request.job.map
                );
                None
            }
            Ok(request) => {
                self.requests += 1;
                Some(request)
            }
            Err(e) => {
                *invalid += 1;
                tracing::debug!("dropped a malformed datagram: {e}");
                None
            }
        }
    }

    /// Adds `request` to the batch to answer: a newer frame's replaces the batch (the older
    /// requests are superseded), an older frame's is superseded, the same frame's joins it (up
    /// to one per job). Does not allocate.
    fn queue(&mut self, request: FrameRequest) {
        match self.batch.last().map(|r| r.seq) {
            Some(seq) if request.seq > seq => {
                self.superseded += self.batch.len() as u64;
                self.batch.clear();
            }
            Some(seq) if request.seq < seq => {
                self.superseded += 1;
                return;
            }
            _ => {}
        }
        if self.batch.len() < MAX_JOBS {
            self.batch.push(request);
        } else {
            self.superseded += 1;
        }
    }

    /// Answers every request of the batch; false when the connection is gone.
    fn reply_all(&mut self, conn: &quinn::Connection) -> bool {
        let batch = std::mem::take(&mut self.batch);
        let ok = batch.iter().all(|request| self.reply(conn, request));
        self.batch = batch;
        ok
    }

    /// Samples the requested classes and sends the reply; false when the connection is gone.
    fn reply(&mut self, conn: &quinn::Connection, request: &FrameRequest) -> bool {
        let (job, pose, classes) = (request.job, &request.pose, request.classes);
        // `decode` dropped requests naming a job these assets lack.
        let sums = match self.scene.target_handles(job) {
            Some((map, shell)) => self.pool.sample_mask(map, shell, pose, classes),
            None => PartialSums::default(),
        };
        FrameReply {
            seq: request.seq,
            classes,
            job,
            sums,
        }
        .encode(&mut self.buf);
        let sent = conn
            .send_datagram(bytes::Bytes::copy_from_slice(&self.buf))
            .is_ok();
        self.replies += u64::from(sent);
        sent
    }
}

/// The join exchange (see [`JoinMessage`]): returns the assets, the worker id and whether an asset
/// file was transferred.
async fn join(
    conn: &quinn::Connection,
    cache: &AssetsCache,
) -> Result<(ClusterAssets, u32, bool), ClusterError> {
    let (mut send, mut recv) = conn.open_bi().await.map_err(net_err)?;
    write_join(
        &mut send,
        &JoinMessage::Hello {
            version: PROTOCOL_VERSION,
        },
    )
    .await?;
    let (worker_id, identity) = match read_join(&mut recv).await? {
        JoinMessage::Welcome { worker_id, assets } => (worker_id, assets),
        JoinMessage::Reject { reason } => {
            return Err(ClusterError::Refused(format!(
                "the coordinator rejected the join: {reason}"
            )))
        }
        other => return Err(ClusterError::Join(format!("unexpected {other:?}"))),
    };
    check_sizes(&identity)?;
    // Reading, hashing and decoding a scene takes seconds for large ones: off the runtime's
    // thread, so that the connection keeps answering (and sending keep-alives) meanwhile. A
    // cached file that does not decode to its hash is fetched again.
    let mut held: Vec<Option<(Vec<u8>, AssetData)>> = {
        let (cache, identity) = (cache.clone(), identity.clone());
        blocking(move || {
            identity
                .files
                .iter()
                .map(|file| {
                    let bytes = cache.read(file)?;
                    let data = ClusterAssets::decode_file(file, &bytes).ok()?;
                    Some((bytes, data))
                })
                .collect()
        })
        .await?
    };
    let needed = held
        .iter()
        .enumerate()
        .filter(|(_, h)| h.is_none())
        .fold(0u64, |mask, (k, _)| mask | 1 << k);
    write_join(&mut send, &JoinMessage::Need { files: needed }).await?;
    for (k, slot) in held.iter_mut().enumerate() {
        if slot.is_some() {
            continue;
        }
        let file = identity.files[k];
        let bytes = read_file(&mut recv, file.len, file.kind.name()).await?;
        let cache = cache.clone();
        *slot = Some(
            blocking(move || {
                let data = ClusterAssets::decode_file(&file, &bytes)?;
                cache.store(&file, &bytes);
                Ok::<_, ClusterError>((bytes, data))
            })
            .await??,
        );
    }
    let transfer = needed != 0;
    let scene = blocking(move || {
        ClusterAssets::from_decoded(&identity, held.into_iter().flatten().collect())
    })
    .await??;
    write_join(&mut send, &JoinMessage::Ready).await?;
    let _ = send.finish();
    Ok((scene, worker_id, transfer))
}

/// Runs `f` on tokio's blocking pool.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> T + Send + 'static,
) -> Result<T, ClusterError> {
    tokio::task::spawn_blocking(f)
        .await
        .map_err(|e| ClusterError::Scene(format!("loading the scene failed: {e}")))
}

async fn read_file(
    recv: &mut quinn::RecvStream,
    expected: u64,
    what: &str,
) -> Result<Vec<u8>, ClusterError> {
    if expected > MAX_ASSET_FILE {
        return Err(ClusterError::Join(format!(
            "{what} file of {expected} bytes exceeds the limit"
        )));
    }
    let bytes = read_frame(recv, expected).await?;
    if bytes.len() as u64 != expected {
        return Err(ClusterError::Join(format!(
            "{what} file: {} bytes received, {expected} announced",
            bytes.len()
        )));
    }
    Ok(bytes)
}
