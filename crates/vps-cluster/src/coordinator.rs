//! The coordinator's network side: a QUIC server endpoint on a small tokio runtime that admits
//! pinned workers (join exchange, asset transfer) and turns each worker's datagrams into events on
//! crossbeam channels, which the frame thread polls through [`RemoteShares`]. Nothing here is on
//! the frame path.
//!
//! One live connection per pinned certificate, the newest: a worker presenting the certificate of
//! a connection the coordinator still holds replaces it. The older connection is closed with
//! [`crate::close::CLOSE_REPLACED`] and the reason [`crate::close::REPLACED_REASON`], logged and
//! counted ([`Coordinator::replaced_connections`]). A worker restarted within seconds of a crash
//! (its dead connection not yet past the idle timeout) so joins at once, where it used to be
//! refused for good; a second live process with the same certificate takes over and the first is
//! told why and stops (a refusal: the two do not take turns).

use crate::assets::ClusterAssets;
use crate::events::{Control, Datagram, Outgoing, OUTGOING_QUEUE};
use crate::metrics::{Board, ClusterMetrics};
use crate::protocol::{read_join, write_frame, write_join, JoinMessage, PROTOCOL_VERSION};
use crate::shares::{GatherConfig, RemoteShares};
use crate::tls::{server_config, PeerTls};
use crate::ClusterError;
use crossbeam::channel::{bounded, unbounded, Receiver, Sender};
use rustls::pki_types::CertificateDer;
use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vps_runtime::{KeepOffFrameCore, Placement};

/// How long a worker may take to join, asset transfer included.
pub const JOIN_TIMEOUT: Duration = Duration::from_secs(60);
/// Datagrams queued for the frame thread before newer ones are dropped (counted as lost).
const DATAGRAM_QUEUE: usize = 4096;

/// How the coordinator listens.
#[derive(Clone, Debug)]
pub struct CoordinatorConfig {
    /// UDP address to listen on (port 0: any free port, see [`Coordinator::local_addr`]).
    pub listen: SocketAddr,
    /// The coordinator's certificate and key, and the worker certificates admitted.
    pub tls: PeerTls,
    /// When set, the coordinator's network threads and its metrics thread are kept off the frame
    /// thread's core (see [`vps_runtime::KeepOffFrameCore`]); `None`: they may run anywhere.
    pub keep_off: Option<KeepOffFrameCore>,
}

/// Counters shared between the network tasks and the owner.
#[derive(Default)]
struct NetCounters {
    joined: AtomicUsize,
    admitted: AtomicU64,
    refused: Arc<AtomicU64>,
    replaced: AtomicU64,
    failed_joins: AtomicU64,
}

/// A running coordinator endpoint. Dropping it closes every connection (see [`crate::close`]).
pub struct Coordinator {
    runtime: tokio::runtime::Runtime,
    endpoint: quinn::Endpoint,
    assets: Arc<ClusterAssets>,
    control: Receiver<Control>,
    datagrams: Receiver<Datagram>,
    counters: Arc<NetCounters>,
    board: Arc<Board>,
    gatherer_made: AtomicBool,
    keep_off: Option<KeepOffFrameCore>,
}

impl Coordinator {
    /// Binds the endpoint and starts admitting workers in the background. Allocates and spawns.
    pub fn start(
        config: CoordinatorConfig,
        assets: Arc<ClusterAssets>,
    ) -> Result<Coordinator, ClusterError> {
        // One network thread: a datagram's connection driver and its reader task then run on the
        // same thread, with no hand-off between them.
        let mut builder = tokio::runtime::Builder::new_multi_thread();
        builder
            .worker_threads(1)
            .thread_name("vps-coord-net")
            .enable_all();
        if let Some(keep) = config.keep_off.clone() {
            // Worker and blocking threads alike, as each starts.
            builder.on_thread_start(move || keep.pin_this_thread("coordinator network thread"));
        }
        let runtime = builder
            .build()
            .map_err(|e| ClusterError::Network(format!("cannot start the runtime: {e}")))?;
        let counters = Arc::new(NetCounters::default());
        let board = Board::new();
        let server = server_config(&config.tls, counters.refused.clone())?;
        let endpoint = {
            let _guard = runtime.enter();
            crate::udp_count::counting_endpoint(config.listen, Some(server), board.udp.clone())
                .map_err(|e| ClusterError::Network(format!("listen on {}: {e}", config.listen)))?
        };
        let (control_tx, control) = unbounded();
        let (datagram_tx, datagrams) = bounded(DATAGRAM_QUEUE);
        let links = Links {
            assets: assets.clone(),
            control: control_tx,
            datagrams: datagram_tx,
            counters: counters.clone(),
            board: board.clone(),
            next_id: Arc::new(AtomicU32::new(0)),
            live: LiveIdentities::default(),
        };
        runtime.spawn(accept_loop(endpoint.clone(), links));
        Ok(Coordinator {
            keep_off: config.keep_off,
            runtime,
            endpoint,
            assets,
            control,
            datagrams,
            counters,
            board,
            gatherer_made: AtomicBool::new(false),
        })
    }

    /// The live figures of this coordinator's session, readable from any thread without a lock
    /// (see [`crate::metrics`]). Valid before, during and after the session.
    pub fn metrics(&self) -> ClusterMetrics {
        ClusterMetrics::new(self.board.clone())
    }

    /// Workers admitted since the start (monotonic; a restarted worker counts again). When this
    /// reaches `n`, the `n`-th join is already queued for the frame thread.
    pub fn admitted_workers(&self) -> u64 {
        self.counters.admitted.load(Ordering::Acquire)
    }

    /// Blocks (sleeping in 2 ms steps) until [`Coordinator::admitted_workers`] reaches `n` or
    /// `timeout` passes. Not for the frame path.
    pub fn wait_for_admitted(&self, n: u64, timeout: Duration) -> Result<(), ClusterError> {
        poll_until(timeout, Duration::from_millis(2), || {
            let admitted = self.admitted_workers();
            (admitted >= n)
                .then_some(())
                .ok_or_else(|| format!("{admitted} of {n} joins"))
        })
    }

    /// The address the endpoint listens on.
    pub fn local_addr(&self) -> Result<SocketAddr, ClusterError> {
        self.endpoint
            .local_addr()
            .map_err(|e| ClusterError::Network(e.to_string()))
    }

    /// The assets (voxmap, classed shell, identity) the workers are given.
    pub fn assets(&self) -> &Arc<ClusterAssets> {
        &self.assets
    }

    /// Workers currently joined and connected.
    pub fn joined_workers(&self) -> usize {
        self.counters.joined.load(Ordering::Relaxed)
    }

    /// Connections refused because their certificate was not pinned.
    pub fn refused_unpinned(&self) -> u64 {
        self.counters.refused.load(Ordering::Relaxed)
    }

    /// Connections closed because a newer connection presented the same certificate (closed
    /// with [`crate::close::CLOSE_REPLACED`]).
    pub fn replaced_connections(&self) -> u64 {
        self.counters.replaced.load(Ordering::Relaxed)
    }

    /// Joins that failed after the TLS handshake (version, timeout, malformed message).
    pub fn failed_joins(&self) -> u64 {
        self.counters.failed_joins.load(Ordering::Relaxed)
    }

    /// Blocks (sleeping in 5 ms steps) until at least `n` workers have joined or `timeout` passes.
    /// Not for the frame path.
    pub fn wait_for_workers(&self, n: usize, timeout: Duration) -> Result<(), ClusterError> {
        self.wait_for_workers_until(n, timeout, &AtomicBool::new(false))
    }

    /// [`Coordinator::wait_for_workers`], also returning `Ok` as soon as `stop` is set (the
    /// session then starts stopped: its device is written zero and its report says why).
    pub fn wait_for_workers_until(
        &self,
        n: usize,
        timeout: Duration,
        stop: &AtomicBool,
    ) -> Result<(), ClusterError> {
        poll_until(timeout, Duration::from_millis(5), || {
            let joined = self.joined_workers();
            (joined >= n || stop.load(Ordering::SeqCst))
                .then_some(())
                .ok_or_else(|| format!("{joined} of {n} workers joined"))
        })
    }

    /// The frame-path gatherer fed by this coordinator's workers. One per coordinator (a second
    /// call is an error): the gatherer owns the session's events and figures.
    pub fn shares(&self, config: GatherConfig) -> Result<RemoteShares, ClusterError> {
        if self.gatherer_made.swap(true, Ordering::Relaxed) {
            return Err(ClusterError::Config {
                field: "shares",
                message: "this coordinator already made its gatherer (one session per coordinator)"
                    .into(),
            });
        }
        RemoteShares::new(
            self.assets.clone(),
            self.control.clone(),
            self.datagrams.clone(),
            self.board.clone(),
            config,
            self.keep_off.clone(),
        )
    }

    /// Where this coordinator's threads were placed, and any local worker processes spawned with
    /// the same [`KeepOffFrameCore`]: `None` when nothing is kept off the frame core (one core,
    /// or not asked).
    pub fn placement(&self) -> Option<Placement> {
        self.keep_off.as_ref().map(KeepOffFrameCore::placement)
    }
}

impl Coordinator {
    /// Closes every connection with `code` (see [`crate::close`]) and `reason`, and waits up to
    /// 200 ms for the workers to acknowledge. Later calls (and the drop) change nothing.
    pub fn close(&self, code: u32, reason: &str) {
        self.endpoint
            .close(crate::close::code(code), reason.as_bytes());
        let endpoint = self.endpoint.clone();
        let _ = self.runtime.block_on(async {
            tokio::time::timeout(Duration::from_millis(200), endpoint.wait_idle()).await
        });
    }
}

impl Drop for Coordinator {
    /// Closes with [`crate::close::CLOSE_SESSION_DONE`] unless [`Coordinator::close`] was called.
    fn drop(&mut self) {
        self.close(crate::close::CLOSE_SESSION_DONE, "coordinator done");
    }
}

/// Calls `check` every `step` (sleeping between) until it returns `Ok`, or fails with its last
/// message and `timeout`. Not for the frame path.
fn poll_until(
    timeout: Duration,
    step: Duration,
    mut check: impl FnMut() -> Result<(), String>,
) -> Result<(), ClusterError> {
    let until = Instant::now() + timeout;
    loop {
        let last = match check() {
            Ok(()) => return Ok(()),
            Err(last) => last,
        };
        if Instant::now() >= until {
            return Err(ClusterError::Network(format!("{last} within {timeout:?}")));
        }
        std::thread::sleep(step);
    }
}

#[derive(Clone)]
struct Links {
    assets: Arc<ClusterAssets>,
    control: Sender<Control>,
    datagrams: Sender<Datagram>,
    counters: Arc<NetCounters>,
    board: Arc<Board>,
    next_id: Arc<AtomicU32>,
    live: LiveIdentities,
}

/// Whether a worker's connection ended because this coordinator closed it (its session done, or
/// stopping): the normal end, logged as information, where any other end is a warning.
fn closed_here(reason: &quinn::ConnectionError) -> bool {
    matches!(reason, quinn::ConnectionError::LocallyClosed)
}

async fn accept_loop(endpoint: quinn::Endpoint, links: Links) {
    while let Some(incoming) = endpoint.accept().await {
        tokio::spawn(serve(incoming, links.clone()));
    }
}

async fn serve(incoming: quinn::Incoming, links: Links) {
    let remote = incoming.remote_address();
    let conn = match incoming.await {
        Ok(conn) => conn,
        Err(e) => {
            // Not a refusal by itself: an unpinned certificate is logged by the verifier just before;
            // a timeout is a peer that gave up or went away mid-handshake.
            tracing::warn!("no connection from {remote}: its handshake failed: {e}");
            return;
        }
    };
    let id = links.next_id.fetch_add(1, Ordering::Relaxed);
    // One live connection per pinned certificate, the newest: held until this task ends (the
    // connection is gone or was replaced); an older one with the same certificate is closed.
    let (_live, replaced) = links.live.claim(&conn);
    if let Some(old) = replaced {
        tracing::warn!(
            "worker {id} at {remote} presents the certificate of the connection from {}: \
             closed that one (a worker restarted after a crash, or a second process with the \
             same certificate)",
            old.remote_address()
        );
        links.counters.replaced.fetch_add(1, Ordering::Relaxed);
        old.close(
            crate::close::code(crate::close::CLOSE_REPLACED),
            crate::close::REPLACED_REASON.as_bytes(),
        );
    }
    let scene_sent = match tokio::time::timeout(JOIN_TIMEOUT, admit(&conn, id, &links.assets)).await
    {
        Ok(Ok(sent)) => sent,
        Ok(Err(e)) => return fail_join(&conn, &links, id, remote, &e.to_string()),
        Err(_) => return fail_join(&conn, &links, id, remote, "timed out"),
    };
    tracing::info!("worker {id} at {remote} joined (scene sent: {scene_sent})");
    // Queue the join for the frame thread before counting it, so that a caller who sees the
    // count knows the frame thread will admit the worker at its next frame.
    let (outgoing, requests) = tokio::sync::mpsc::channel(OUTGOING_QUEUE);
    tokio::spawn(send_requests(conn.clone(), requests));
    let _ = links.control.send(Control::Joined {
        id,
        conn: conn.clone(),
        outgoing,
        scene_sent,
    });
    links.counters.joined.fetch_add(1, Ordering::Relaxed);
    links.counters.admitted.fetch_add(1, Ordering::Release);
    let reason = loop {
        match conn.read_datagram().await {
            Ok(bytes) => {
                let datagram = Datagram {
                    id,
                    bytes,
                    at: Instant::now(),
                };
                if links.datagrams.try_send(datagram).is_err() {
                    links.board.queue_full.fetch_add(1, Ordering::Relaxed);
                }
            }
            Err(e) => break e,
        }
    };
    if closed_here(&reason) {
        tracing::info!("worker {id} at {remote} left: {reason} (by this coordinator)");
    } else {
        tracing::warn!("worker {id} at {remote} left: {reason}");
    }
    links.counters.joined.fetch_sub(1, Ordering::Relaxed);
    let _ = links.control.send(Control::Closed { id });
}

/// Sends the frame thread's requests to one worker, in order, until the connection or the queue
/// ends. A datagram quinn refuses (the connection closing) ends the task; the frame thread then
/// finds the queue closed and counts its requests as not sent.
async fn send_requests(
    conn: quinn::Connection,
    mut requests: tokio::sync::mpsc::Receiver<Outgoing>,
) {
    while let Some(request) = requests.recv().await {
        if conn
            .send_datagram(bytes::Bytes::copy_from_slice(&request))
            .is_err()
        {
            break;
        }
    }
}

/// The newest connection of each certificate (by BLAKE3 of the end-entity certificate), with the
/// number of the claim that holds it.
#[derive(Clone, Default)]
struct LiveIdentities(Arc<Mutex<LiveMap>>);

#[derive(Default)]
struct LiveMap {
    next_claim: u64,
    by_certificate: HashMap<[u8; 32], (u64, quinn::Connection)>,
}

/// A claimed certificate; released on drop unless a newer claim has taken it.
struct LiveClaim {
    set: LiveIdentities,
    key: [u8; 32],
    claim: u64,
}

impl LiveIdentities {
    /// Claims `conn`'s peer certificate for it and returns the connection that held it before
    /// (to be closed), if any. A connection without a certificate (impossible: the server
    /// requires one) claims nothing and is let through to the join, which the pinning already
    /// gated.
    fn claim(&self, conn: &quinn::Connection) -> (Option<LiveClaim>, Option<quinn::Connection>) {
        let certs = conn
            .peer_identity()
            .and_then(|any| any.downcast::<Vec<CertificateDer<'static>>>().ok());
        let Some(cert) = certs.as_ref().and_then(|c| c.first()) else {
            return (None, None);
        };
        let key = *blake3::hash(cert.as_ref()).as_bytes();
        let mut map = self.0.lock().unwrap_or_else(|e| e.into_inner());
        map.next_claim += 1;
        let claim = map.next_claim;
        let old = map.by_certificate.insert(key, (claim, conn.clone()));
        let claimed = LiveClaim {
            set: self.clone(),
            key,
            claim,
        };
        (Some(claimed), old.map(|(_, c)| c))
    }
}

impl Drop for LiveClaim {
    fn drop(&mut self) {
        let mut map = self.set.0.lock().unwrap_or_else(|e| e.into_inner());
        if map
            .by_certificate
            .get(&self.key)
            .is_some_and(|(claim, _)| *claim == self.claim)
        {
            map.by_certificate.remove(&self.key);
        }
    }
}

fn fail_join(conn: &quinn::Connection, links: &Links, id: u32, remote: SocketAddr, why: &str) {
    tracing::warn!("worker {id} at {remote} failed to join: {why}");
    links.counters.failed_joins.fetch_add(1, Ordering::Relaxed);
    conn.close(
        crate::close::code(crate::close::CLOSE_JOIN_FAILED),
        format!("join failed: {why}").as_bytes(),
    );
}

/// The coordinator's half of the join exchange (see [`JoinMessage`]); returns whether an asset file
/// (voxmap or shell) was sent.
async fn admit(
    conn: &quinn::Connection,
    id: u32,
    scene: &ClusterAssets,
) -> Result<bool, ClusterError> {
    let (mut send, mut recv) = conn
        .accept_bi()
        .await
        .map_err(|e| ClusterError::Join(e.to_string()))?;
    match read_join(&mut recv).await? {
        JoinMessage::Hello { version } if version == PROTOCOL_VERSION => {}
        JoinMessage::Hello { version } => {
            let reason = format!("protocol version {version}, coordinator has {PROTOCOL_VERSION}");
            write_join(
                &mut send,
                &JoinMessage::Reject {
                    reason: reason.clone(),
                },
            )
            .await?;
            // Let the refusal reach the worker before the connection is closed.
            let _ = send.finish();
            let _ = tokio::time::timeout(Duration::from_secs(1), send.stopped()).await;
            return Err(ClusterError::Join(reason));
        }
        other => return Err(ClusterError::Join(format!("expected Hello, got {other:?}"))),
    }
    write_join(
        &mut send,
        &JoinMessage::Welcome {
            worker_id: id,
            assets: scene.identity.clone(),
        },
    )
    .await?;
    let needed = match read_join(&mut recv).await? {
        JoinMessage::Need { files } => files,
        other => return Err(ClusterError::Join(format!("expected Need, got {other:?}"))),
    };
    if needed & !scene.identity.all_files() != 0 {
        return Err(ClusterError::Join(format!(
            "the worker asked for files {needed:#x}; there are {}",
            scene.identity.files.len()
        )));
    }
    for k in (0..scene.identity.files.len()).filter(|k| needed >> k & 1 == 1) {
        write_frame(&mut send, scene.file(k)).await?;
    }
    match read_join(&mut recv).await? {
        JoinMessage::Ready => Ok(needed != 0),
        other => Err(ClusterError::Join(format!("expected Ready, got {other:?}"))),
    }
}

#[cfg(test)]
mod tests {
    use super::closed_here;
    use quinn::ConnectionError;

    /// A session that ends normally logged "worker 0 at ... left: closed" as a WARN in the
    /// coordinator's service log; only other ends are warnings now.
    #[test]
    fn only_a_connection_this_coordinator_closed_is_a_normal_end() {
        assert!(closed_here(&ConnectionError::LocallyClosed));
        assert!(!closed_here(&ConnectionError::TimedOut));
        assert!(!closed_here(&ConnectionError::Reset));
    }
}
