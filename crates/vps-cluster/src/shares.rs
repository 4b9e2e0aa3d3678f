//! The frame-path gatherer: [`RemoteShares`] hands class shares to the joined workers, computes the
//! coordinator's own share on local threads, collects replies until the deadline and computes
//! every missing or rejected share locally. It implements [`FrameSampler`], so the runtime's frame
//! loop ([`vps_runtime::spawn_loop_with`]) drives it.
//!
//! Assignment (between frames): [`split_classes`] deals the classes between the coordinator
//! (weight 1) and the active workers in proportion to their weights, which adapt to each
//! worker's replies ([`Adapt`]: additive increase while it answers with room to spare, halved on
//! a miss; see [`crate::split`]). With adaptation off ([`GatherConfig::adaptive_shares`]) every
//! weight stays 1: class `c` goes to party `c mod (W + 1)`, party 0 being the coordinator. A
//! worker whose share is not merged (no reply by the deadline, or
//! an invalid reply) `bench_after` frames in a row is benched: it gets no work, only a one-class
//! probe every `probe_every` frames whose result is checked but not used; `unbench_after` probes
//! answered in time in a row give it work again. A worker that sends `disconnect_after` bad
//! replies (undecodable, or implausible sums) with no valid one between them is disconnected
//! (application close code [`CLOSE_BAD_REPLIES`]).
//!
//! Fallback (at the deadline): every missing share (no reply, or a rejected one) is recomputed on
//! local threads; only when that cannot finish before the device write is due (one reply window
//! after the deadline) are shares stood in for by their sums from up to
//! [`StalePolicy::max_age_frames`] frames earlier, largest first, counted as `stale_shares`
//! ([`crate::fallback`]). The sums are then no longer those of one pose; `StalePolicy::NEVER`
//! keeps them exact whatever the timing.
//!
//! Validation: a reply is used only if it decodes strictly, carries this frame's sequence number
//! (older ones are counted late and dropped), echoes the requested class mask and passes
//! [`PartialSums::is_plausible`] and [`PartialSums::torque_within`] for the share's point count,
//! the voxel size and the shell's radius.

use crate::coordinator::{Control, Datagram};
use crate::fallback::{plan_fallback, FallbackAction, MissingShare, StalePolicy};
use crate::metrics::{Board, PeerMetrics, Reporter};
use crate::protocol::{FrameReply, FrameRequest, REQUEST_LEN};
use crate::scene::ClusterScene;
use crate::split::{split_classes, Adapt, ShareOutcome};
use crate::ClusterError;
use bytes::Bytes;
use crossbeam::channel::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vps_haptic::{KernelPose, PartialSums};
use vps_runtime::{FrameSampler, Percentiles, PoolResult};

/// How the gatherer runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GatherConfig {
    /// Threads computing the coordinator's share and the fallback (≥ 1).
    pub local_threads: usize,
    /// How long before the deadline the frame thread stops sleeping on the reply channel and
    /// spins. Default 100 µs.
    pub spin_margin: Duration,
    /// Consecutive unmerged shares before a worker is benched (≥ 1). Default 5.
    pub bench_after: u32,
    /// A benched worker is probed every this many frames (≥ 1). Default 10: a one-class request
    /// every 10 ms costs nothing, and a worker benched by a short host stall is back within 30
    /// frames (with 100, a 100k-point session on the project's 2-core VM spent 20–57 % of its
    /// frames without its worker in three runs of 3·10^4 frames, against 0.7–1.3 % with 10;
    /// docs/cluster.md).
    pub probe_every: u64,
    /// Consecutive timely probe replies before a benched worker gets work again (≥ 1). Default 3.
    pub unbench_after: u32,
    /// Bad replies in a row (datagrams that fail to decode, or replies with implausible sums or
    /// the wrong classes), with no valid reply between them, after which the worker's
    /// connection is closed (≥ 1; `u32::MAX`: never). Default 50: a benched worker still
    /// answers a probe every `probe_every` frames, so a worker that only sends garbage is gone
    /// within 50 of its datagrams, while any valid reply (work or probe) resets the count.
    pub disconnect_after: u32,
    /// Period of the metrics thread's `info` summary per worker (`None`: no summary; transitions
    /// are still logged). Default 1 s.
    pub log_every: Option<Duration>,
    /// Adapt each worker's share to its round trips ([`crate::split`]); off: equal shares.
    /// Default on.
    pub adaptive_shares: bool,
    /// When a missing share may be stood in for by its sums from an earlier frame instead of
    /// being recomputed ([`crate::fallback`]); `max_age_frames: 0` always recomputes (exact).
    /// Default: up to 3 frames old, only when the recompute cannot finish before the write.
    pub stale: StalePolicy,
}

impl Default for GatherConfig {
    fn default() -> Self {
        GatherConfig {
            local_threads: 1,
            spin_margin: Duration::from_micros(100),
            bench_after: 5,
            probe_every: 10,
            unbench_after: 3,
            disconnect_after: 50,
            log_every: Some(Duration::from_secs(1)),
            adaptive_shares: true,
            stale: StalePolicy::default(),
        }
    }
}

/// One worker's figures (a [`ClusterMetrics`](crate::ClusterMetrics) snapshot or the final report).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct PeerReport {
    /// The worker id given at join (a restarted worker gets a new id).
    pub id: u32,
    /// Requests sent (work and probes).
    pub requests: u64,
    /// Shares merged from this worker's replies.
    pub merged: u64,
    /// Replies that arrived after their frame's deadline (dropped by sequence number).
    pub late: u64,
    /// Work shares with no reply by the deadline.
    pub lost: u64,
    /// Datagrams on this worker's authenticated connection that failed to decode (garbage,
    /// truncated, wrong kind or version).
    pub malformed: u64,
    /// Replies that decoded but were rejected: wrong class mask, duplicate, unrequested or
    /// implausible sums.
    pub invalid: u64,
    /// Work shares recomputed locally (lost, invalid or unsendable).
    pub recomputed: u64,
    /// Times the worker was benched.
    pub benched_times: u64,
    /// Times a benched worker was given work again.
    pub unbenched_times: u64,
    /// Benched at the time of the report.
    pub benched: bool,
    /// Still connected at the time of the report.
    pub connected: bool,
    /// The coordinator closed its connection for bad replies ([`GatherConfig::disconnect_after`]).
    pub disconnected_for_bad_replies: bool,
    /// The coordinator sent it the scene files at join (false: it had them in its cache).
    pub scene_sent: bool,
    /// Round-trip samples in `rtt_ns`.
    pub rtt_samples: u64,
    /// Request-to-reply time of timely, valid replies (ns), from an HDR histogram (1 % resolution).
    pub rtt_ns: Percentiles,
    /// Classes asked of it in the latest frame (its adapted share; 0 while benched).
    pub classes: u64,
    /// Its missing shares stood in for by an earlier frame's sums ([`crate::fallback`]).
    pub stale: u64,
}

/// The cluster's figures for a session.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct ClusterReport {
    /// Frames gathered.
    pub frames: u64,
    /// Worker shares computed locally, summed over frames.
    pub fallback_shares: u64,
    /// Missing worker shares stood in for by an earlier frame's sums (degraded accuracy, when
    /// recomputing them could not finish before the device write), summed over frames.
    pub stale_shares: u64,
    /// Frames in which no worker had work (everything local).
    pub local_only_frames: u64,
    /// Datagrams from workers that are no longer known.
    pub orphan_datagrams: u64,
    /// Datagrams dropped because the frame thread's queue was full.
    pub queue_full_datagrams: u64,
    /// Round-trip samples the metrics thread could not take (its queue was full).
    pub rtt_samples_dropped: u64,
    /// Workers beyond [`MAX_TRACKED_WORKERS`](crate::metrics::MAX_TRACKED_WORKERS) joins, missing
    /// from live snapshots (the final report lists them).
    pub untracked_workers: u64,
    /// Datagrams the coordinator's UDP socket received.
    pub udp_datagrams: u64,
    /// Of those, datagrams that cannot be QUIC packets by their shape (garbage; see
    /// [`crate::udp_count`]).
    pub udp_not_quic: u64,
    /// Of those, datagrams shaped like QUIC that no connection of the coordinator can own (an
    /// unknown version or connection ID: garbage, or a peer's stateless reset; see
    /// [`crate::udp_count`]).
    pub udp_foreign: u64,
    /// Every worker seen, by id (join order).
    pub peers: Vec<PeerReport>,
}

/// Where the gatherer leaves its [`ClusterReport`] when it is dropped (at the end of a session).
pub type ReportSlot = Arc<Mutex<Option<ClusterReport>>>;

struct Peer {
    conn: Option<quinn::Connection>,
    benched: bool,
    /// Share weight relative to the coordinator's 1 (see [`crate::split`]).
    weight: f64,
    /// Round trip of this frame's merged reply.
    rtt: Duration,
    /// The latest merged work reply: its class mask, sums and frame sequence number.
    held: Option<(u64, PartialSums, u64)>,
    misses: u32,
    probe_hits: u32,
    /// Bad replies since the last valid one (see [`GatherConfig::disconnect_after`]).
    bad_replies: u32,
    /// This frame: the classes asked for (0: nothing asked), whether it is a probe, the points
    /// in those classes, when it was sent, whether a reply settled it, whether it was merged.
    asked: u64,
    probing: bool,
    points: u64,
    sent_at: Instant,
    settled: bool,
    merged: bool,
    metrics: Arc<PeerMetrics>,
}

/// The frame thread's view of the cluster. See the module docs.
pub struct RemoteShares {
    scene: Arc<ClusterScene>,
    control: Receiver<Control>,
    datagrams: Receiver<Datagram>,
    config: GatherConfig,
    pool: rayon::ThreadPool,
    peers: Vec<Peer>,
    retired: Vec<Arc<PeerMetrics>>,
    active: Vec<usize>,
    seq: u64,
    board: Arc<Board>,
    reporter: Reporter,
    slot: ReportSlot,
    request: [u8; REQUEST_LEN],
    adapt: Adapt,
    /// Local cost of one class, from the latest frame in which the coordinator had a share.
    per_class: Duration,
    /// Scratch for the fallback plan: (peer index, missing share).
    missing: Vec<(usize, MissingShare)>,
    /// Scratch for the assignment: the parties' weights.
    weights: Vec<f64>,
}

/// The QUIC application close code for a worker disconnected for bad replies.
pub const CLOSE_BAD_REPLIES: u32 = 3;

fn config_err(field: &'static str) -> ClusterError {
    ClusterError::Config {
        field,
        message: "must be at least 1".into(),
    }
}

impl RemoteShares {
    pub(crate) fn new(
        scene: Arc<ClusterScene>,
        control: Receiver<Control>,
        datagrams: Receiver<Datagram>,
        board: Arc<Board>,
        config: GatherConfig,
    ) -> Result<RemoteShares, ClusterError> {
        if config.local_threads == 0 {
            return Err(config_err("local_threads"));
        }
        if config.bench_after == 0 {
            return Err(config_err("bench_after"));
        }
        if config.probe_every == 0 {
            return Err(config_err("probe_every"));
        }
        if config.unbench_after == 0 {
            return Err(config_err("unbench_after"));
        }
        if config.disconnect_after == 0 {
            return Err(config_err("disconnect_after"));
        }
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(config.local_threads)
            .thread_name(|i| format!("vps-local-{i}"))
            .build()
            .map_err(|e| ClusterError::Config {
                field: "local_threads",
                message: e.to_string(),
            })?;
        let reporter = Reporter::start(board.clone(), config.log_every)
            .map_err(|e| ClusterError::Network(format!("cannot start the metrics thread: {e}")))?;
        Ok(RemoteShares {
            scene,
            control,
            datagrams,
            config,
            pool,
            peers: Vec::new(),
            retired: Vec::new(),
            active: Vec::new(),
            seq: 0,
            board,
            reporter,
            slot: Arc::new(Mutex::new(None)),
            request: [0; REQUEST_LEN],
            adapt: Adapt::default(),
            per_class: Duration::ZERO,
            missing: Vec::new(),
            weights: Vec::new(),
        })
    }

    /// The slot that receives the final [`ClusterReport`] when this gatherer is dropped.
    pub fn report_slot(&self) -> ReportSlot {
        self.slot.clone()
    }

    /// The figures so far, every worker included (round-trip percentiles as last published by
    /// the metrics thread, at most [`REPORT_TICK`](crate::metrics::REPORT_TICK) old). Allocates.
    pub fn report(&self) -> ClusterReport {
        let mut peers: Vec<PeerReport> = self
            .retired
            .iter()
            .chain(self.peers.iter().map(|p| &p.metrics))
            .map(|m| m.report())
            .collect();
        peers.sort_by_key(|p| p.id);
        self.board.report_with(peers)
    }

    /// Workers currently given work (joined, connected, not benched).
    pub fn active_workers(&self) -> usize {
        self.peers
            .iter()
            .filter(|p| p.conn.is_some() && !p.benched)
            .count()
    }

    /// Admits joined workers and retires closed ones. Allocates only when membership changes.
    fn update_membership(&mut self) {
        while let Ok(event) = self.control.try_recv() {
            match event {
                Control::Joined {
                    id,
                    conn,
                    scene_sent,
                } => {
                    let metrics = PeerMetrics::new(id, scene_sent);
                    self.board.track(&metrics);
                    self.peers.push(Peer {
                        conn: Some(conn),
                        benched: false,
                        weight: 1.0,
                        rtt: Duration::ZERO,
                        held: None,
                        misses: 0,
                        probe_hits: 0,
                        bad_replies: 0,
                        asked: 0,
                        probing: false,
                        points: 0,
                        sent_at: Instant::now(),
                        settled: false,
                        merged: false,
                        metrics,
                    });
                }
                Control::Closed { id } => {
                    if let Some(i) = self.peers.iter().position(|p| p.metrics.id() == id) {
                        let peer = self.peers.swap_remove(i);
                        peer.metrics.set_disconnected();
                        self.retired.push(peer.metrics);
                    }
                }
            }
        }
        // Peers are looked up by id; keep them in join order so the assignment is reproducible.
        self.peers.sort_by_key(|p| p.metrics.id());
    }

    /// Decides this frame's shares; returns the coordinator's own class mask.
    fn assign(&mut self) -> u64 {
        self.active.clear();
        let class_count = self.scene.shell.class_count();
        for (i, peer) in self.peers.iter_mut().enumerate() {
            peer.asked = 0;
            peer.probing = false;
            peer.settled = false;
            peer.merged = false;
            if peer.conn.is_some() && !peer.benched {
                self.active.push(i);
            } else if peer.conn.is_some() && self.seq.is_multiple_of(self.config.probe_every) {
                let class = (self.seq / self.config.probe_every) % u64::from(class_count);
                peer.asked = 1 << class;
                peer.probing = true;
            }
        }
        self.weights.clear();
        self.weights.push(1.0);
        for &i in &self.active {
            let weight = self.peers[i].weight;
            self.weights.push(if self.config.adaptive_shares {
                weight
            } else {
                1.0
            });
        }
        let masks = split_classes(class_count, &self.weights);
        for (&i, &mask) in self.active.iter().zip(&masks[1..]) {
            self.peers[i].asked = mask;
        }
        for peer in &self.peers {
            let classes = if peer.probing {
                0
            } else {
                peer.asked.count_ones()
            };
            peer.metrics
                .classes
                .store(u64::from(classes), std::sync::atomic::Ordering::Relaxed);
        }
        masks[0]
    }

    /// Sends every request; returns how many are awaited. One small allocation per request
    /// (the datagram buffer); never blocks.
    fn send_requests(&mut self, pose: &KernelPose) -> usize {
        let mut pending = 0;
        for peer in &mut self.peers {
            let Some(conn) = &peer.conn else { continue };
            if peer.asked == 0 {
                continue;
            }
            peer.points = crate::protocol::mask_classes(peer.asked)
                .map(|c| self.scene.shell.class_len(c) as u64)
                .sum();
            FrameRequest {
                seq: self.seq,
                classes: peer.asked,
                pose: *pose,
            }
            .encode(&mut self.request);
            peer.metrics.bump(|m| &m.requests);
            peer.sent_at = Instant::now();
            if conn
                .send_datagram(Bytes::copy_from_slice(&self.request))
                .is_ok()
            {
                pending += 1;
            } else {
                peer.settled = true;
            }
        }
        pending
    }

    /// Handles one datagram; returns true when it settled a share awaited this frame.
    fn accept(&mut self, datagram: Datagram, sums: &mut PartialSums) -> bool {
        let Some(peer) = self
            .peers
            .iter_mut()
            .find(|p| p.metrics.id() == datagram.id)
        else {
            self.board.bump(|b| &b.orphan_datagrams);
            return false;
        };
        let reply = match FrameReply::decode(&datagram.bytes) {
            Ok(reply) => reply,
            Err(e) => {
                peer.metrics.bump(|m| &m.malformed);
                peer.bad_replies = peer.bad_replies.saturating_add(1);
                tracing::debug!(worker = peer.metrics.id(), "malformed reply: {e}");
                return false;
            }
        };
        if reply.seq != self.seq {
            peer.metrics.bump(|m| &m.late);
            return false;
        }
        if peer.asked == 0 || peer.settled {
            peer.metrics.bump(|m| &m.invalid);
            return false;
        }
        peer.settled = true;
        let max_depth = PartialSums::max_contact_depth(
            self.scene.map.spec().voxel_size,
            self.scene.map.width().surface_layers(),
        );
        let valid = reply.classes == peer.asked
            && reply.sums.is_plausible(peer.points, max_depth)
            && reply
                .sums
                .torque_within(self.scene.shell.max_radius(), max_depth);
        if !valid {
            peer.metrics.bump(|m| &m.invalid);
            peer.bad_replies = peer.bad_replies.saturating_add(1);
            tracing::debug!(worker = peer.metrics.id(), "implausible reply dropped");
            return true;
        }
        let rtt = datagram.at.saturating_duration_since(peer.sent_at);
        self.board.record_rtt(
            &peer.metrics,
            rtt.as_nanos().min(u128::from(u64::MAX)) as u64,
        );
        peer.bad_replies = 0;
        if peer.probing {
            peer.probe_hits += 1;
        } else {
            sums.merge(&reply.sums);
            peer.merged = true;
            peer.rtt = rtt;
            peer.held = Some((peer.asked, reply.sums, self.seq));
            peer.metrics.bump(|m| &m.merged);
        }
        true
    }

    /// Waits for `pending` replies until `deadline`: sleeps on the channel until `spin_margin`
    /// before it, then spins. Never waits on a tokio timer. Past the deadline (the local share
    /// may take that long) it still takes, without waiting, the replies already queued: they
    /// arrived while the frame thread was computing.
    fn gather(&mut self, mut pending: usize, deadline: Instant, sums: &mut PartialSums) {
        while pending > 0 {
            let now = Instant::now();
            if now >= deadline {
                while pending > 0 {
                    match self.datagrams.try_recv() {
                        Ok(d) if d.at <= deadline => pending -= usize::from(self.accept(d, sums)),
                        Ok(d) => {
                            self.accept_late(d);
                        }
                        Err(_) => break,
                    }
                }
                break;
            }
            let datagram = if deadline - now > self.config.spin_margin {
                match self
                    .datagrams
                    .recv_deadline(deadline - self.config.spin_margin)
                {
                    Ok(d) => d,
                    Err(RecvTimeoutError::Timeout) => continue,
                    Err(RecvTimeoutError::Disconnected) => break,
                }
            } else {
                match self.datagrams.try_recv() {
                    Ok(d) => d,
                    Err(TryRecvError::Empty) => {
                        std::hint::spin_loop();
                        continue;
                    }
                    Err(TryRecvError::Disconnected) => break,
                }
            };
            if self.accept(datagram, sums) {
                pending -= 1;
            }
        }
    }

    /// A reply that arrived after this frame's deadline: counted late, never merged.
    fn accept_late(&mut self, datagram: Datagram) {
        match self.peers.iter().find(|p| p.metrics.id() == datagram.id) {
            Some(peer) => peer.metrics.bump(|m| &m.late),
            None => self.board.bump(|b| &b.orphan_datagrams),
        }
    }

    /// Closes the connection of every worker that sent [`GatherConfig::disconnect_after`] bad
    /// replies in a row (this frame's shares are already settled); it leaves the session as a
    /// worker that went away does, and may join again.
    fn disconnect_misbehaving(&mut self) {
        let limit = self.config.disconnect_after;
        let mut i = 0;
        while i < self.peers.len() {
            if self.peers[i].bad_replies < limit {
                i += 1;
                continue;
            }
            let peer = self.peers.swap_remove(i);
            if let Some(conn) = &peer.conn {
                conn.close(CLOSE_BAD_REPLIES.into(), b"too many bad replies");
            }
            tracing::warn!(
                worker = peer.metrics.id(),
                bad_replies = peer.bad_replies,
                "worker disconnected: bad replies in a row"
            );
            peer.metrics.set_disconnected_for_bad_replies();
            self.retired.push(peer.metrics);
        }
    }

    /// Books the frame's outcome per worker (benching, un-benching, share weight against the reply
    /// `deadline`) and lists the missing work shares in `self.missing`.
    fn settle(&mut self, deadline: Instant) {
        self.missing.clear();
        for (index, peer) in self.peers.iter_mut().enumerate() {
            if peer.asked == 0 {
                continue;
            }
            if peer.probing {
                let answered = peer.settled && peer.probe_hits > 0;
                if !answered {
                    peer.probe_hits = 0;
                }
                if peer.probe_hits >= self.config.unbench_after {
                    peer.benched = false;
                    // Back with a cautious share; it grows while the worker keeps up.
                    peer.weight = self.adapt.min_weight.max(0.5);
                    peer.misses = 0;
                    peer.probe_hits = 0;
                    peer.metrics.set_benched(false);
                }
                continue;
            }
            if peer.merged {
                peer.misses = 0;
                let window = deadline.saturating_duration_since(peer.sent_at);
                let outcome = ShareOutcome::Merged {
                    rtt: peer.rtt,
                    window,
                };
                peer.weight = self.adapt.next_weight(peer.weight, outcome);
                continue;
            }
            peer.weight = self.adapt.next_weight(peer.weight, ShareOutcome::Missed);
            if !peer.settled {
                peer.metrics.bump(|m| &m.lost);
            }
            let stale_age = match peer.held {
                Some((classes, _, seq)) if classes == peer.asked => Some(self.seq - seq),
                _ => None,
            };
            self.missing.push((
                index,
                MissingShare {
                    classes: peer.asked.count_ones(),
                    stale_age,
                },
            ));
            peer.misses += 1;
            if peer.misses >= self.config.bench_after && !peer.benched {
                peer.benched = true;
                peer.probe_hits = 0;
                peer.metrics.set_benched(true);
            }
        }
    }

    /// Stands in for the missing shares ([`crate::fallback`]): recomputes them on local threads,
    /// or, where that cannot finish `write_margin` before the write is due (`write_due`), merges
    /// their sums from an earlier frame. Returns how many shares were recomputed.
    fn fall_back(&mut self, pose: &KernelPose, write_due: Instant, sums: &mut PartialSums) -> u32 {
        if self.missing.is_empty() {
            return 0;
        }
        let shares: Vec<MissingShare> = self.missing.iter().map(|m| m.1).collect();
        let left = write_due.saturating_duration_since(Instant::now());
        let plan = plan_fallback(&shares, left, self.per_class, self.config.stale);
        let mut recompute = 0u64;
        let mut recomputed = 0;
        for (&(index, _), action) in self.missing.iter().zip(plan) {
            let peer = &self.peers[index];
            match (action, peer.held) {
                (FallbackAction::ReuseStale, Some((_, held, _))) => {
                    sums.merge(&held);
                    peer.metrics.bump(|m| &m.stale);
                    self.board.bump(|b| &b.stale_shares);
                }
                _ => {
                    recompute |= peer.asked;
                    recomputed += 1;
                    peer.metrics.bump(|m| &m.recomputed);
                }
            }
        }
        if recompute != 0 {
            sums.merge(&self.sample(pose, recompute));
        }
        recomputed
    }
}

impl RemoteShares {
    /// The sums of the classes in `mask`: on the frame thread itself with one local thread (no
    /// hand-off), else on the local pool. Blocks until done; does not allocate.
    fn sample(&self, pose: &KernelPose, mask: u64) -> PartialSums {
        if self.config.local_threads == 1 {
            self.scene.sample_mask_serial(pose, mask)
        } else {
            self.pool.install(|| self.scene.sample_mask(pose, mask))
        }
    }
}

impl FrameSampler for RemoteShares {
    /// One frame: membership, assignment, requests, own share on local threads, gather until
    /// `deadline`, fallback (recompute, or stand in with earlier sums). Allocates one datagram
    /// buffer per request, the share split, and the fallback plan when shares are missing (and on
    /// membership changes); blocks only on the reply channel (never past `deadline`) and on local
    /// compute.
    fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult {
        let entered = Instant::now();
        self.seq += 1;
        self.update_membership();
        // Replies from earlier frames still queued: counted late, never merged.
        let mut unused = PartialSums::default();
        while let Ok(stale) = self.datagrams.try_recv() {
            self.accept(stale, &mut unused);
        }
        let local = self.assign();
        let pending = self.send_requests(pose);
        let started = Instant::now();
        let mut sums = self.sample(pose, local);
        if local != 0 {
            self.per_class = started.elapsed() / local.count_ones();
        }
        self.gather(pending, deadline, &mut sums);
        self.settle(deadline);
        // The write is due one reply window after the reply deadline (see `crate::fallback`).
        let write_due = deadline
            .checked_add(deadline.saturating_duration_since(entered))
            .unwrap_or(deadline);
        let fallback_shares = self.fall_back(pose, write_due, &mut sums);
        self.disconnect_misbehaving();
        self.board.bump(|b| &b.frames);
        self.board
            .add(|b| &b.fallback_shares, u64::from(fallback_shares));
        if self.active.is_empty() {
            self.board.bump(|b| &b.local_only_frames);
        }
        PoolResult {
            sums,
            fallback_shares,
        }
    }
}

impl Drop for RemoteShares {
    /// Leaves the final report in the [`ReportSlot`].
    fn drop(&mut self) {
        self.reporter.finish();
        let report = self.report();
        if let Ok(mut slot) = self.slot.lock() {
            *slot = Some(report);
        }
    }
}
