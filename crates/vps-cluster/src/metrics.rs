//! Live per-worker metrics: counters the frame thread bumps with plain atomic stores, round-trip
//! samples it hands to a reporter thread through a lock-free queue, and a [`ClusterMetrics`]
//! handle from which any thread (a viewer, the CLI) reads a snapshot without taking a lock.
//!
//! Threads: the frame thread is the only writer of the counters (so a bump is a relaxed load and
//! store, no read-modify-write); the reporter thread (`vps-metrics`) owns the RTT histograms,
//! publishes their percentiles every [`REPORT_TICK`], logs sidelined/reinstated transitions
//! ([`crate::sideline_log`]: the first at once, then at most one line per worker per 10 s) and a
//! one-line summary per worker every `log_every` at `info` level. Nothing in this
//! module blocks or allocates on the frame path except `PeerMetrics::new` (at join).
//!
//! Consistency: every field of a snapshot is read atomically, but fields are read one after the
//! other, so a snapshot taken mid-frame may mix adjacent frames (e.g. `requests` one ahead of
//! `merged`). Final reports are taken after the frame loop and the reporter have stopped.

use crate::report::{ClusterReport, PeerReport, SplitReport};
use crate::sideline_log::{SidelineLine, SidelineLog, SIDELINE_LOG_PERIOD};
use crossbeam::queue::ArrayQueue;
use hdrhistogram::Histogram;
use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use vps_runtime::Percentiles;

/// Workers a snapshot can show (joins per session; later joiners still work and appear in the
/// final report, and are counted in [`ClusterReport::untracked_workers`]).
pub const MAX_TRACKED_WORKERS: usize = 256;
/// How often the reporter thread drains round-trip samples and publishes percentiles.
pub const REPORT_TICK: Duration = Duration::from_millis(50);
/// Round-trip samples queued for the reporter before newer ones are dropped (counted).
const RTT_QUEUE: usize = 16_384;
/// Largest round-trip time the histograms resolve (ns): 10 s.
const MAX_RTT_NS: u64 = 10_000_000_000;

/// Adds one to a counter that only one thread writes: a relaxed load and store (no locked
/// instruction). Never blocks or allocates.
fn bump(counter: &AtomicU64) {
    counter.store(counter.load(Ordering::Relaxed) + 1, Ordering::Relaxed);
}

/// One worker's live figures. Counters are written by the frame thread only; the `rtt_*` fields
/// by the reporter thread only.
#[derive(Debug)]
pub struct PeerMetrics {
    id: u32,
    scene_sent: bool,
    connected: AtomicBool,
    disconnected_for_bad_replies: AtomicBool,
    sidelined: AtomicBool,
    pub(crate) requests: AtomicU64,
    pub(crate) merged: AtomicU64,
    pub(crate) late: AtomicU64,
    pub(crate) lost: AtomicU64,
    pub(crate) malformed: AtomicU64,
    pub(crate) invalid: AtomicU64,
    pub(crate) recomputed: AtomicU64,
    /// Classes asked of the worker in the latest frame (0 when sidelined).
    pub(crate) classes: AtomicU64,
    /// Missing shares stood in for by an earlier frame's sums.
    pub(crate) stale: AtomicU64,
    sidelined_times: AtomicU64,
    reinstated_times: AtomicU64,
    rtt_samples: AtomicU64,
    rtt: [AtomicU64; 4],
}

impl PeerMetrics {
    /// Fresh metrics of a connected worker, not sidelined. Allocates (once per join).
    pub(crate) fn new(id: u32, scene_sent: bool) -> Arc<PeerMetrics> {
        Arc::new(PeerMetrics {
            id,
            scene_sent,
            connected: AtomicBool::new(true),
            disconnected_for_bad_replies: AtomicBool::new(false),
            sidelined: AtomicBool::new(false),
            requests: AtomicU64::new(0),
            merged: AtomicU64::new(0),
            late: AtomicU64::new(0),
            lost: AtomicU64::new(0),
            malformed: AtomicU64::new(0),
            invalid: AtomicU64::new(0),
            recomputed: AtomicU64::new(0),
            classes: AtomicU64::new(0),
            stale: AtomicU64::new(0),
            sidelined_times: AtomicU64::new(0),
            reinstated_times: AtomicU64::new(0),
            rtt_samples: AtomicU64::new(0),
            rtt: Default::default(),
        })
    }

    /// The worker id given at join.
    pub fn id(&self) -> u32 {
        self.id
    }

    /// Adds one to `counter` (one of this struct's counters). Frame thread only.
    pub(crate) fn bump(&self, counter: fn(&PeerMetrics) -> &AtomicU64) {
        bump(counter(self));
    }

    /// Records that the worker was sidelined (`true`) or reinstated (`false`). Frame thread only.
    pub(crate) fn set_sidelined(&self, sidelined: bool) {
        self.sidelined.store(sidelined, Ordering::Relaxed);
        bump(if sidelined {
            &self.sidelined_times
        } else {
            &self.reinstated_times
        });
    }

    /// Marks the worker's connection closed.
    pub(crate) fn set_disconnected(&self) {
        self.connected.store(false, Ordering::Relaxed);
    }

    /// Marks the worker's connection closed by the coordinator for bad replies.
    pub(crate) fn set_disconnected_for_bad_replies(&self) {
        self.disconnected_for_bad_replies
            .store(true, Ordering::Relaxed);
        self.set_disconnected();
    }

    /// A consistent-enough copy (see the module docs). Allocates nothing.
    pub fn report(&self) -> PeerReport {
        let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
        PeerReport {
            id: self.id,
            requests: load(&self.requests),
            merged: load(&self.merged),
            late: load(&self.late),
            lost: load(&self.lost),
            malformed: load(&self.malformed),
            invalid: load(&self.invalid),
            recomputed: load(&self.recomputed),
            classes: load(&self.classes),
            stale: load(&self.stale),
            sidelined_times: load(&self.sidelined_times),
            reinstated_times: load(&self.reinstated_times),
            sidelined: self.sidelined.load(Ordering::Relaxed),
            connected: self.connected.load(Ordering::Relaxed),
            disconnected_for_bad_replies: self.disconnected_for_bad_replies.load(Ordering::Relaxed),
            scene_sent: self.scene_sent,
            rtt_samples: load(&self.rtt_samples),
            rtt_ns: Percentiles {
                p50: load(&self.rtt[0]),
                p99: load(&self.rtt[1]),
                p999: load(&self.rtt[2]),
                max: load(&self.rtt[3]),
            },
        }
    }
}

/// Session-wide counters and the tracked workers. One per coordinator.
#[derive(Debug)]
pub(crate) struct Board {
    pub(crate) frames: AtomicU64,
    pub(crate) fallback_shares: AtomicU64,
    pub(crate) stale_shares: AtomicU64,
    pub(crate) local_only_frames: AtomicU64,
    pub(crate) job_samples: AtomicU64,
    pub(crate) orphan_datagrams: AtomicU64,
    /// Written by the network tasks (several threads): incremented with `fetch_add`.
    pub(crate) queue_full: AtomicU64,
    rtt_dropped: AtomicU64,
    untracked: AtomicU64,
    tracked: AtomicUsize,
    slots: Box<[OnceLock<Arc<PeerMetrics>>]>,
    rtt_queue: ArrayQueue<(Arc<PeerMetrics>, u64)>,
    /// What the coordinator's UDP socket received (written by its socket wrapper).
    pub(crate) udp: Arc<crate::udp_count::UdpCounts>,
    /// The split decisions so far (the frame thread publishes them when the lock is free).
    split: Mutex<SplitReport>,
}

impl Board {
    pub(crate) fn new() -> Arc<Board> {
        Arc::new(Board {
            frames: AtomicU64::new(0),
            fallback_shares: AtomicU64::new(0),
            stale_shares: AtomicU64::new(0),
            local_only_frames: AtomicU64::new(0),
            job_samples: AtomicU64::new(0),
            orphan_datagrams: AtomicU64::new(0),
            queue_full: AtomicU64::new(0),
            rtt_dropped: AtomicU64::new(0),
            untracked: AtomicU64::new(0),
            tracked: AtomicUsize::new(0),
            slots: (0..MAX_TRACKED_WORKERS).map(|_| OnceLock::new()).collect(),
            udp: Arc::default(),
            rtt_queue: ArrayQueue::new(RTT_QUEUE),
            split: Mutex::default(),
        })
    }

    /// Publishes the split decisions so far. Frame thread only; never blocks (when a reader
    /// holds the lock this frame's figures are skipped, the next frame's follow) or allocates.
    pub(crate) fn set_split(&self, stats: &SplitReport) {
        if let Ok(mut split) = self.split.try_lock() {
            split.clone_from(stats);
        }
    }

    /// Adds one to a session counter written only by the frame thread.
    pub(crate) fn bump(&self, counter: fn(&Board) -> &AtomicU64) {
        bump(counter(self));
    }

    /// Adds `n` to a session counter written only by the frame thread.
    pub(crate) fn add(&self, counter: fn(&Board) -> &AtomicU64, n: u64) {
        let c = counter(self);
        c.store(c.load(Ordering::Relaxed) + n, Ordering::Relaxed);
    }

    /// Makes a joined worker visible to snapshots (frame thread, at join). Never blocks.
    pub(crate) fn track(&self, peer: &Arc<PeerMetrics>) {
        let index = self.tracked.load(Ordering::Relaxed);
        match self.slots.get(index) {
            Some(slot) => {
                let _ = slot.set(peer.clone());
                self.tracked.store(index + 1, Ordering::Release);
            }
            None => bump(&self.untracked),
        }
    }

    /// Hands one round-trip sample (ns) to the reporter. Never blocks or allocates (one `Arc`
    /// count increment); a full queue drops the sample and counts it.
    pub(crate) fn record_rtt(&self, peer: &Arc<PeerMetrics>, ns: u64) {
        if self.rtt_queue.push((peer.clone(), ns)).is_err() {
            bump(&self.rtt_dropped);
        }
    }

    fn tracked_peers(&self) -> impl Iterator<Item = &Arc<PeerMetrics>> {
        let n = self.tracked.load(Ordering::Acquire);
        self.slots[..n].iter().filter_map(OnceLock::get)
    }

    /// The session's figures with `peers` as the worker list.
    pub(crate) fn report_with(&self, peers: Vec<PeerReport>) -> ClusterReport {
        let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
        ClusterReport {
            frames: load(&self.frames),
            fallback_shares: load(&self.fallback_shares),
            stale_shares: load(&self.stale_shares),
            local_only_frames: load(&self.local_only_frames),
            job_samples: load(&self.job_samples),
            orphan_datagrams: load(&self.orphan_datagrams),
            queue_full_datagrams: load(&self.queue_full),
            rtt_samples_dropped: load(&self.rtt_dropped),
            untracked_workers: load(&self.untracked),
            udp_datagrams: self.udp.datagrams(),
            udp_not_quic: self.udp.not_quic(),
            udp_foreign: self.udp.foreign(),
            split: self.split.lock().map(|s| s.clone()).unwrap_or_default(),
            peers,
        }
    }
}

/// A cheap, cloneable, read-only view of a coordinator's live figures, for any thread (a viewer,
/// a periodic printer). See the module docs for consistency.
#[derive(Clone, Debug)]
pub struct ClusterMetrics {
    board: Arc<Board>,
}

impl ClusterMetrics {
    pub(crate) fn new(board: Arc<Board>) -> ClusterMetrics {
        ClusterMetrics { board }
    }

    /// The figures now: session counters and every tracked worker (joined this session, by id),
    /// without locking. Allocates the peer list.
    pub fn snapshot(&self) -> ClusterReport {
        let mut peers: Vec<PeerReport> = self.board.tracked_peers().map(|p| p.report()).collect();
        peers.sort_by_key(|p| p.id);
        self.board.report_with(peers)
    }
}

/// The reporter thread: drains round-trip samples into per-worker histograms, publishes their
/// percentiles, logs transitions and periodic summaries. Stopped (and joined, after a last
/// drain) by [`Reporter::finish`] or on drop.
pub(crate) struct Reporter {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Reporter {
    /// Starts the `vps-metrics` thread; `log_every` is the period of the `info` summary (`None`:
    /// none); `keep_off`, when given, keeps the thread off the frame thread's core.
    pub(crate) fn start(
        board: Arc<Board>,
        log_every: Option<Duration>,
        keep_off: Option<vps_runtime::KeepOffFrameCore>,
    ) -> std::io::Result<Self> {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("vps-metrics".into())
            .spawn(move || {
                if let Some(keep) = keep_off {
                    keep.pin_this_thread("metrics thread");
                }
                report_loop(&board, &flag, log_every)
            })?;
        Ok(Reporter {
            stop,
            thread: Some(thread),
        })
    }

    /// Stops the thread after a last drain, so that every sample is in the published figures.
    pub(crate) fn finish(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            thread.thread().unpark();
            let _ = thread.join();
        }
    }
}

impl Drop for Reporter {
    fn drop(&mut self) {
        self.finish();
    }
}

struct Tracked {
    peer: Arc<PeerMetrics>,
    rtt: Histogram<u64>,
    sideline_log: SidelineLog,
}

fn report_loop(board: &Board, stop: &AtomicBool, log_every: Option<Duration>) {
    let mut peers: HashMap<u32, Tracked> = HashMap::new();
    let mut last_log = Instant::now();
    loop {
        let stopping = stop.load(Ordering::Relaxed);
        drain(board, &mut peers);
        for peer in board.tracked_peers() {
            peers
                .entry(peer.id)
                .or_insert_with(|| tracked(peer.clone()));
        }
        let now = Instant::now();
        for t in peers.values_mut() {
            log_transitions(t, now, stopping);
        }
        if log_every.is_some_and(|e| last_log.elapsed() >= e) {
            last_log = Instant::now();
            log_summary(board, &peers);
        }
        if stopping {
            return;
        }
        std::thread::park_timeout(REPORT_TICK);
    }
}

fn tracked(peer: Arc<PeerMetrics>) -> Tracked {
    Tracked {
        peer,
        // 2 significant digits: 1 % resolution; bounds are constants, so this cannot fail.
        rtt: Histogram::new_with_bounds(1, MAX_RTT_NS, 2).expect("valid histogram bounds"),
        sideline_log: SidelineLog::default(),
    }
}

/// Moves queued samples into histograms and publishes the percentiles of those that changed.
fn drain(board: &Board, peers: &mut HashMap<u32, Tracked>) {
    let mut changed = Vec::new();
    while let Some((peer, ns)) = board.rtt_queue.pop() {
        let t = peers
            .entry(peer.id)
            .or_insert_with(|| tracked(peer.clone()));
        let _ = t.rtt.record(ns.clamp(1, MAX_RTT_NS));
        changed.push(peer.id);
    }
    changed.sort_unstable();
    changed.dedup();
    for id in changed {
        let t = &peers[&id];
        let h = &t.rtt;
        let store = |i: usize, v: u64| t.peer.rtt[i].store(v, Ordering::Relaxed);
        store(0, h.value_at_quantile(0.5));
        store(1, h.value_at_quantile(0.99));
        store(2, h.value_at_quantile(0.999));
        store(3, h.max());
        t.peer.rtt_samples.store(h.len(), Ordering::Relaxed);
    }
}

/// Logs a worker's sideline transitions, at most one line per [`SIDELINE_LOG_PERIOD`] (see
/// [`SidelineLog`]); `stopping` logs what is pending.
fn log_transitions(t: &mut Tracked, now: Instant, stopping: bool) {
    let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
    let line = t.sideline_log.observe(
        load(&t.peer.sidelined_times),
        load(&t.peer.reinstated_times),
        t.peer.sidelined.load(Ordering::Relaxed),
        now,
        stopping,
    );
    let worker = t.peer.id;
    match line {
        None => {}
        Some(SidelineLine::Sidelined) => tracing::warn!(
            worker,
            "sidelined (missed or invalid replies); its shares are computed locally"
        ),
        Some(SidelineLine::Recovered) => tracing::info!(worker, "recovered: given work again"),
        Some(SidelineLine::Flapping {
            sidelined,
            recovered,
            now_sidelined,
        }) => tracing::warn!(
            worker,
            sidelined,
            recovered,
            now_sidelined,
            "sidelined and reinstated (late or invalid replies) since the last line, which is at \
             most one per {} s; sidelined shares are computed locally",
            SIDELINE_LOG_PERIOD.as_secs()
        ),
    }
}

fn log_summary(board: &Board, peers: &HashMap<u32, Tracked>) {
    let load = |a: &AtomicU64| a.load(Ordering::Relaxed);
    tracing::info!(
        frames = load(&board.frames),
        fallback_shares = load(&board.fallback_shares),
        "cluster"
    );
    let mut ids: Vec<_> = peers.keys().copied().collect();
    ids.sort_unstable();
    for id in ids {
        let r = peers[&id].peer.report();
        if !r.connected {
            continue;
        }
        tracing::info!(
            worker = r.id,
            rtt_p50_us = r.rtt_ns.p50 / 1000,
            rtt_p999_us = r.rtt_ns.p999 / 1000,
            merged = r.merged,
            late = r.late,
            lost = r.lost,
            malformed = r.malformed,
            invalid = r.invalid,
            recomputed = r.recomputed,
            classes = r.classes,
            stale = r.stale,
            sidelined = r.sidelined,
            "worker"
        );
    }
}
