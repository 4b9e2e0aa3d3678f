//! The frame-path gatherer: [`RemoteShares`] hands class shares to the joined workers, computes the
//! coordinator's own share on local threads, collects replies until the deadline and computes
//! every missing or rejected share locally. It implements [`FrameSampler`], so the runtime's frame
//! loop ([`vps_runtime::spawn_loop_with`]) drives it.
//!
//! It is the I/O driver around the pure [`GatherCore`] ([`crate::gather`]), which makes every
//! decision below: this module only sends the requests on the workers' `quinn::Connection`s,
//! waits on the reply channel, reads the clock, computes its own share and the fallback on the
//! local class pool (`vps_runtime::ClassPool`, the loop's own sampler) and keeps the metrics board.
//!
//! Prediction (default, [`GatherConfig::predict`]): a worker gets its share only when the core
//! predicts that this shortens the frame; a worker given none is sent a one-class probe that no
//! frame waits for, checked against the coordinator's own sums of that class, its round trip
//! booked at the next frame ([`crate::gather::SplitDecision`]). The rest of this section is the
//! split itself, as `--split always` applies it every frame.
//!
//! Assignment (at the start of each frame, [`GatherCore::assign`]):
//! [`split_classes`](crate::split::split_classes) deals the classes between the coordinator
//! (weight 1) and the active workers in proportion to their weights, which adapt to each worker's
//! replies ([`Adapt`](crate::split::Adapt): additive increase while it answers with room to spare,
//! halved on a miss; see [`crate::split`]). With adaptation off
//! ([`GatherConfig::adaptive_shares`]) every weight stays 1: class `c` goes to party
//! `c mod (W + 1)`, party 0 being the coordinator. A worker whose share is not merged (no reply by the
//! deadline, or an invalid reply) `sideline_after` frames in a row is sidelined: it gets no work, only
//! a one-class probe every `probe_every` frames whose result is checked but not used;
//! `reinstate_after` probes answered in time in a row give it work again. A worker that sends
//! `disconnect_after` bad replies (undecodable, or implausible sums) with no valid one between
//! them is disconnected (application close code [`CLOSE_BAD_REPLIES`]).
//!
//! Fallback (at the deadline): every missing share (no reply, or a rejected one) is recomputed on
//! local threads; only when that cannot finish before the device write is due (one reply window
//! after the deadline) are shares stood in for by their sums from up to
//! [`StalePolicy::max_age_frames`] frames earlier, largest first, counted as `stale_shares`
//! ([`crate::fallback`]). The sums are then no longer those of one pose; `StalePolicy::NEVER`
//! keeps them exact whatever the timing.
//!
//! Several parts ([`FrameSampler::compute_jobs`]): a frame of several jobs
//! ([`vps_haptic::job`]: every part in the static scene, both directions of every pair the broad
//! phase keeps) is split as one shell is: each party gets the same classes of every job, a
//! worker one request datagram per job and one reply per job, merged when all are in; a missing
//! share is recomputed for every job. Probes ask for the first job alone.
//!
//! Validation: a reply is used only if it decodes strictly, carries this frame's sequence number
//! (older ones are counted late and dropped), echoes the requested class mask and passes
//! [`PartialSums::is_plausible`] and [`PartialSums::torque_within`] for the share's point count,
//! the voxel size and the shell's radius.

use crate::assets::ClusterAssets;
use crate::events::{Control, Datagram, Outgoing};
use crate::fallback::StalePolicy;
use crate::gather::{Acceptance, GatherCore, Policy, Shape, Transition};
use crate::metrics::{Board, PeerMetrics, Reporter};
use crate::protocol::{FrameRequest, REQUEST_LEN};
use crate::report::{ClusterReport, PeerReport};
use crate::ClusterError;
use crossbeam::channel::{Receiver, RecvTimeoutError, TryRecvError};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vps_cluster_core::frame::{FrameStart, Handled, Request};
use vps_haptic::job::{JobTarget, SampleJob, MAX_JOBS};
use vps_haptic::{KernelPose, PartialSums};
use vps_runtime::{ClassPool, FrameSampler, PoolResult};
use vps_voxmap::VoxelTree;

/// How the gatherer runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GatherConfig {
    /// Threads computing the coordinator's share and the fallback (≥ 1).
    pub local_threads: usize,
    /// How long before the deadline the frame thread stops sleeping on the reply channel and
    /// spins. Default 100 µs.
    pub spin_margin: Duration,
    /// Consecutive unmerged shares before a worker is sidelined (≥ 1). Default 5.
    pub sideline_after: u32,
    /// A sidelined worker is probed every this many frames (≥ 1). Default 10: a one-class request
    /// every 10 ms costs nothing, and a worker sidelined by a short host stall is back within 30
    /// frames (with 100, a 100k-point session on the project's 2-core VM spent 20–57 % of its
    /// frames without its worker in three runs of 3·10^4 frames, against 0.7–1.3 % with 10;
    /// docs/cluster.md).
    pub probe_every: u64,
    /// Consecutive timely probe replies before a sidelined worker gets work again (≥ 1). Default 3.
    pub reinstate_after: u32,
    /// Bad replies in a row (datagrams that fail to decode, or replies with implausible sums or
    /// the wrong classes), with no valid reply between them, after which the worker's
    /// connection is closed (≥ 1; `u32::MAX`: never). Default 50: a sidelined worker still
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
    /// Send a worker its share only when that is predicted to shorten the frame, measuring the
    /// workers with probes no frame waits for ([`crate::gather::SplitDecision`]); off: the plain
    /// split every frame, sidelined workers probed with awaited probes. Default on.
    pub predict: bool,
}

impl Default for GatherConfig {
    fn default() -> Self {
        GatherConfig {
            local_threads: 1,
            spin_margin: Duration::from_micros(100),
            sideline_after: 5,
            probe_every: 10,
            reinstate_after: 3,
            disconnect_after: 50,
            log_every: Some(Duration::from_secs(1)),
            adaptive_shares: true,
            stale: StalePolicy::default(),
            predict: true,
        }
    }
}

/// Where the gatherer leaves its [`ClusterReport`] when it is dropped (at the end of a session).
pub type ReportSlot = Arc<Mutex<Option<ClusterReport>>>;

/// A joined worker's connection and live figures (the core tracks its standing by the same id).
struct Link {
    id: u32,
    conn: quinn::Connection,
    /// Its requests' queue to its network task (never quinn from the frame thread).
    outgoing: tokio::sync::mpsc::Sender<Outgoing>,
    metrics: Arc<PeerMetrics>,
}

/// The frame thread's view of the cluster: the I/O driver around [`GatherCore`]. See the
/// module docs.
pub struct RemoteShares {
    assets: Arc<ClusterAssets>,
    control: Receiver<Control>,
    datagrams: Receiver<Datagram>,
    config: GatherConfig,
    /// The coordinator's own share and the fallback of every job, on `local_threads` threads
    /// (the frame thread and `local_threads − 1` pool threads).
    pool: ClassPool<VoxelTree>,
    core: GatherCore,
    /// Joined workers, in join order.
    links: Vec<Link>,
    retired: Vec<Arc<PeerMetrics>>,
    board: Arc<Board>,
    reporter: Reporter,
    slot: ReportSlot,
    /// Scratch: this frame's requests.
    requests_scratch: Vec<Request>,
    /// Scratch: workers to disconnect for bad replies (id, bad replies in a row).
    misbehaving: Vec<(u32, u32)>,
    /// Scratch: this frame's job targets.
    targets: Vec<JobTarget>,
    /// A frame named a job the assets cannot sample: the session must end.
    failure: Option<String>,
}

/// The shape of `target`'s shell and voxmap in `assets`, for checking replies.
fn shape_of(assets: &ClusterAssets, target: JobTarget) -> Shape {
    let (map, shell) = assets
        .target(target)
        .expect("the assets' own targets are theirs");
    let s = map.spec().voxel_size;
    let layered = PartialSums::max_contact_depth(s, map.width().surface_layers());
    Shape {
        class_points: (0..shell.class_count())
            .map(|c| shell.class_len(c) as u64)
            .collect(),
        // A map with a distance band pushes by the band's depth at most.
        max_depth: map
            .distance_band()
            .map_or(layered, |band| layered.max(band.max_contact_depth(s))),
        max_radius: shell.max_radius(),
    }
}

pub use crate::close::CLOSE_BAD_REPLIES;

impl GatherConfig {
    /// The rules the pure core applies ([`crate::gather::Policy`]).
    pub fn policy(&self) -> Policy {
        Policy {
            sideline_after: self.sideline_after,
            probe_every: self.probe_every,
            reinstate_after: self.reinstate_after,
            disconnect_after: self.disconnect_after,
            adaptive_shares: self.adaptive_shares,
            stale: self.stale,
            predict: self.predict,
        }
    }
}

impl RemoteShares {
    pub(crate) fn new(
        assets: Arc<ClusterAssets>,
        control: Receiver<Control>,
        datagrams: Receiver<Datagram>,
        board: Arc<Board>,
        config: GatherConfig,
        keep_off: Option<vps_runtime::KeepOffFrameCore>,
    ) -> Result<RemoteShares, ClusterError> {
        if config.local_threads == 0 {
            return Err(ClusterError::Config {
                field: "local_threads",
                message: "must be at least 1".into(),
            });
        }
        let mut core = GatherCore::new(config.policy(), shape_of(&assets, JobTarget::FIRST))?;
        for target in assets.targets().into_iter().skip(1) {
            core.add_target(target, shape_of(&assets, target))?;
        }
        // The local pool is deliberately NOT kept off the frame core: its threads work only
        // inside a frame, beside the frame thread, which claims classes itself; keeping them off
        // would halve the local share's parallelism on a 2-core machine. With one local thread
        // the pool has no thread of its own: the frame thread computes its share itself.
        let pool = assets.class_pool(config.local_threads, "local_threads")?;
        let reporter = Reporter::start(board.clone(), config.log_every, keep_off)
            .map_err(|e| ClusterError::Network(format!("cannot start the metrics thread: {e}")))?;
        Ok(RemoteShares {
            assets,
            control,
            datagrams,
            config,
            pool,
            core,
            links: Vec::new(),
            retired: Vec::new(),
            board,
            reporter,
            slot: Arc::new(Mutex::new(None)),
            requests_scratch: Vec::new(),
            misbehaving: Vec::new(),
            targets: Vec::with_capacity(MAX_JOBS),
            failure: None,
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
            .chain(self.links.iter().map(|l| &l.metrics))
            .map(|m| m.report())
            .collect();
        peers.sort_by_key(|p| p.id);
        self.board.report_with(peers)
    }

    /// Workers currently given work (joined, connected, not sidelined).
    pub fn active_workers(&self) -> usize {
        self.core.peers().iter().filter(|p| !p.sidelined).count()
    }

    fn link(&self, id: u32) -> Option<&Link> {
        self.links.iter().find(|l| l.id == id)
    }

    /// Retires worker `id`'s link (its connection ended or was closed); returns it.
    fn retire(&mut self, id: u32) -> Option<Link> {
        let i = self.links.iter().position(|l| l.id == id)?;
        let link = self.links.remove(i);
        self.retired.push(link.metrics.clone());
        Some(link)
    }

    /// Admits joined workers and retires closed ones. Allocates only when membership changes.
    fn update_membership(&mut self) {
        while let Ok(event) = self.control.try_recv() {
            match event {
                Control::Joined {
                    id,
                    conn,
                    outgoing,
                    scene_sent,
                } => {
                    let metrics = PeerMetrics::new(id, scene_sent);
                    self.board.track(&metrics);
                    self.core.join(id);
                    let at = self.links.partition_point(|l| l.id < id);
                    self.links.insert(
                        at,
                        Link {
                            id,
                            conn,
                            outgoing,
                            metrics,
                        },
                    );
                }
                Control::Closed { id } => {
                    self.core.leave(id);
                    if let Some(link) = self.retire(id) {
                        link.metrics.set_disconnected();
                    }
                }
            }
        }
    }

    /// Publishes each worker's share size of this frame (0 while probing or sidelined).
    fn publish_classes(&self) {
        for peer in self.core.peers() {
            let Some(link) = self.link(peer.id) else {
                continue;
            };
            let classes = if peer.probing {
                0
            } else {
                peer.asked.count_ones()
            };
            link.metrics
                .classes
                .store(u64::from(classes), std::sync::atomic::Ordering::Relaxed);
        }
    }

    /// Queues every request of the plan (`seq`) for the workers' network tasks, one datagram per
    /// job asked; returns how many workers are awaited. A full or closed queue counts as not
    /// sent. Does not allocate (after the first frame) or block.
    fn send_requests(&mut self, seq: u64, jobs: &[SampleJob]) -> usize {
        let mut pending = 0;
        let mut datagram: Outgoing = [0; REQUEST_LEN];
        let mut requests = std::mem::take(&mut self.requests_scratch);
        requests.clear();
        requests.extend(self.core.frame_requests());
        for request in &requests {
            let Some(link) = self.link(request.peer) else {
                continue;
            };
            link.metrics.bump(|m| &m.requests);
            let at = Instant::now();
            let mut sent = true;
            for job in &jobs[..request.jobs] {
                FrameRequest {
                    seq,
                    classes: request.classes,
                    job: job.target,
                    pose: job.pose,
                }
                .encode(&mut datagram);
                sent &= link.outgoing.try_send(datagram).is_ok();
            }
            pending += usize::from(self.core.sent(request.peer, at, sent));
        }
        self.requests_scratch = requests;
        pending
    }

    /// Handles one datagram that arrived before the deadline; returns true when it settled a
    /// share awaited this frame (merging the share's sums into `sums`, one per job).
    fn accept(&mut self, datagram: Datagram, sums: &mut [PartialSums]) -> bool {
        let Some(metrics) = self.link(datagram.id).map(|l| l.metrics.clone()) else {
            self.board.bump(|b| &b.orphan_datagrams);
            return false;
        };
        let acceptance = match self
            .core
            .handle_datagram(datagram.id, &datagram.bytes, datagram.at)
        {
            Handled::Judged(acceptance) => acceptance,
            Handled::Malformed { error, .. } => {
                metrics.bump(|m| &m.malformed);
                tracing::debug!(worker = datagram.id, "malformed reply: {error}");
                return false;
            }
        };
        self.book(datagram.id, acceptance, &metrics, sums);
        acceptance.settles()
    }

    /// Mirrors what became of a reply from worker `id` in its metrics; a merged share's sums are
    /// added to `sums`.
    fn book(
        &self,
        id: u32,
        acceptance: Acceptance,
        metrics: &Arc<PeerMetrics>,
        sums: &mut [PartialSums],
    ) {
        match acceptance {
            Acceptance::Unknown => self.board.bump(|b| &b.orphan_datagrams),
            Acceptance::Late => metrics.bump(|m| &m.late),
            Acceptance::Unrequested => metrics.bump(|m| &m.invalid),
            Acceptance::Rejected => {
                metrics.bump(|m| &m.invalid);
                tracing::debug!(worker = id, "implausible reply dropped");
            }
            Acceptance::Probe { rtt } | Acceptance::Probed { rtt: Some(rtt), .. } => {
                self.board.record_rtt(metrics, nanos(rtt))
            }
            Acceptance::Probed { rtt: None } => {
                metrics.bump(|m| &m.invalid);
                tracing::debug!(worker = id, "wrong probe reply");
            }
            Acceptance::Partial => {}
            Acceptance::Merged { rtt } => {
                self.board.record_rtt(metrics, nanos(rtt));
                for (sum, share) in sums.iter_mut().zip(self.core.merged_sums(id)) {
                    sum.merge(share);
                }
                metrics.bump(|m| &m.merged);
            }
        }
    }

    /// Waits for `pending` replies until `deadline`: sleeps on the channel until `spin_margin`
    /// before it, then spins. Never waits on a tokio timer. Past the deadline (the local share
    /// may take that long) it still takes, without waiting, the replies already queued: they
    /// arrived while the frame thread was computing.
    fn gather(&mut self, mut pending: usize, deadline: Instant, sums: &mut [PartialSums]) {
        while pending > 0 {
            let now = Instant::now();
            if now >= deadline {
                while pending > 0 {
                    match self.datagrams.try_recv() {
                        Ok(d) if d.at <= deadline => pending -= usize::from(self.accept(d, sums)),
                        Ok(d) => self.accept_late(d),
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

    /// A reply that arrived after this frame's deadline: counted late, never merged; the answer
    /// to an unawaited probe is taken whenever it comes.
    fn accept_late(&mut self, datagram: Datagram) {
        let acceptance = self
            .core
            .handle_late_datagram(datagram.id, &datagram.bytes, datagram.at);
        match self.link(datagram.id).map(|l| l.metrics.clone()) {
            Some(metrics) => self.book(datagram.id, acceptance, &metrics, &mut []),
            None => self.board.bump(|b| &b.orphan_datagrams),
        }
    }

    /// Closes the connection of every worker that sent [`GatherConfig::disconnect_after`] bad
    /// replies in a row (this frame's shares are already settled); it leaves the session as a
    /// worker that went away does, and may join again.
    fn disconnect_misbehaving(&mut self) {
        let mut gone = std::mem::take(&mut self.misbehaving);
        gone.clear();
        self.core.take_misbehaving(&mut gone);
        for &(id, bad_replies) in &gone {
            let Some(link) = self.retire(id) else {
                continue;
            };
            link.conn
                .close(CLOSE_BAD_REPLIES.into(), b"too many bad replies");
            tracing::warn!(
                worker = id,
                bad_replies,
                "worker disconnected: bad replies in a row"
            );
            link.metrics.set_disconnected_for_bad_replies();
        }
        self.misbehaving = gone;
    }

    /// At the deadline: books the frame's outcome per worker in the core, mirrors its
    /// transitions to the metrics and stands in for the missing shares ([`crate::fallback`]):
    /// recomputes them on local threads, for every job, or, where that cannot finish before the
    /// write is due (`write_due`), merges their sums from an earlier frame of the same jobs.
    /// Returns how many shares were recomputed.
    fn finish(
        &mut self,
        jobs: &[SampleJob],
        deadline: Instant,
        write_due: Instant,
        sums: &mut [PartialSums],
    ) -> u32 {
        let left = write_due.saturating_duration_since(Instant::now());
        self.core.finish(deadline, left);
        // Read back through shared borrows: the held sums below are the core's too.
        for &(id, transition) in self.core.transitions() {
            let Some(link) = self.link(id) else {
                continue;
            };
            match transition {
                Transition::Lost => link.metrics.bump(|m| &m.lost),
                Transition::Sidelined => link.metrics.set_sidelined(true),
                Transition::Reinstated => link.metrics.set_sidelined(false),
            }
        }
        let plan = self.core.fallback();
        for id in &plan.stale {
            for (sum, held) in sums.iter_mut().zip(self.core.held_sums(*id)) {
                sum.merge(held);
            }
            if let Some(link) = self.link(*id) {
                link.metrics.bump(|m| &m.stale);
            }
            self.board.bump(|b| &b.stale_shares);
        }
        for id in &plan.recomputed {
            if let Some(link) = self.link(*id) {
                link.metrics.bump(|m| &m.recomputed);
            }
        }
        let (recompute, recomputed) = (plan.recompute, plan.recomputed.len() as u32);
        if recompute != 0 {
            for (sum, job) in sums.iter_mut().zip(jobs) {
                sum.merge(&self.sample(job, recompute));
            }
        }
        recomputed
    }
}

fn nanos(d: Duration) -> u64 {
    d.as_nanos().min(u128::from(u64::MAX)) as u64
}

impl RemoteShares {
    /// The sums of the classes in `mask` of `job` on the local class pool (the frame thread and
    /// the pool's threads; with one local thread the frame thread alone); zero sums for a target
    /// the assets lack. Blocks until done (no deadline: a share computed here is the frame's
    /// last word); does not allocate.
    fn sample(&mut self, job: &SampleJob, mask: u64) -> PartialSums {
        match self.assets.target_handles(job.target) {
            Some((map, shell)) => self.pool.sample_mask(map, shell, &job.pose, mask),
            None => PartialSums::default(),
        }
    }

    /// One frame of `jobs` into `sums` (one per job): membership, assignment, requests, own
    /// share on local threads, gather until `deadline`, fallback (recompute, or stand in with
    /// earlier sums). Returns the shares recomputed locally. A job the assets cannot sample
    /// ends the session ([`FrameSampler::failure`]). Allocates the share split, and the fallback
    /// plan when shares are missing (and on membership changes); requests go to the workers'
    /// network tasks through bounded queues; blocks only on the reply channel (never past
    /// `deadline`) and on local compute.
    fn compute_frame(
        &mut self,
        jobs: &[SampleJob],
        deadline: Instant,
        sums: &mut [PartialSums],
    ) -> u32 {
        let entered = Instant::now();
        sums.iter_mut().for_each(|s| *s = PartialSums::default());
        self.update_membership();
        self.targets.clear();
        self.targets.extend(jobs.iter().map(|j| j.target));
        let start = FrameStart {
            jobs: &self.targets,
            reply_window: deadline.saturating_duration_since(Instant::now()),
        };
        let plan = match self.core.start_frame(start) {
            Ok(plan) => plan,
            Err(e) => {
                self.failure = Some(format!("the cluster cannot sample this frame: {e}"));
                return 0;
            }
        };
        // Replies from earlier frames still queued: counted late, never merged.
        while let Ok(stale) = self.datagrams.try_recv() {
            self.accept(stale, &mut []);
        }
        self.publish_classes();
        self.board.set_split(self.core.split_stats());
        let pending = self.send_requests(plan.seq, jobs);
        let started = Instant::now();
        // An unawaited probe's class is computed on its own: the probe reply must equal it.
        for (sum, job) in sums.iter_mut().zip(jobs) {
            *sum = self.sample(job, plan.local & !plan.probe);
        }
        let probe_sums = (plan.probe != 0).then(|| self.sample(&jobs[0], plan.probe));
        if let Some(own) = &probe_sums {
            sums[0].merge(own);
        }
        self.core.local_done(
            plan.local.count_ones(),
            started.elapsed(),
            probe_sums.as_ref(),
        );
        self.gather(pending, deadline, sums);
        // The write is due one reply window after the reply deadline (see `crate::fallback`).
        let write_due = deadline
            .checked_add(deadline.saturating_duration_since(entered))
            .unwrap_or(deadline);
        let fallback_shares = self.finish(jobs, deadline, write_due, sums);
        self.disconnect_misbehaving();
        self.board.bump(|b| &b.frames);
        self.board.add(|b| &b.job_samples, jobs.len() as u64);
        self.board
            .add(|b| &b.fallback_shares, u64::from(fallback_shares));
        if self.core.active_workers() == 0 {
            self.board.bump(|b| &b.local_only_frames);
        }
        fallback_shares
    }
}

impl FrameSampler for RemoteShares {
    /// One frame of the first part alone: membership, assignment, requests, own share on local
    /// threads, gather until `deadline`, fallback (recompute, or stand in with earlier sums).
    /// Allocates the share split, and the fallback plan when shares are missing (and on
    /// membership changes); blocks only on the reply channel (never past `deadline`) and on local
    /// compute.
    fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult {
        let job = [SampleJob {
            target: JobTarget::FIRST,
            pose: *pose,
        }];
        let mut first = [PartialSums::default()];
        let fallback_shares = self.compute_frame(&job, deadline, &mut first);
        PoolResult {
            sums: first[0],
            fallback_shares,
        }
    }

    /// Every job of a frame of several parts, split over the workers like one shell (see
    /// [`RemoteShares::compute`]; one request datagram per job and worker).
    fn compute_jobs(
        &mut self,
        jobs: &[SampleJob],
        deadline: Instant,
        sums: &mut [PartialSums],
    ) -> Option<u32> {
        Some(self.compute_frame(jobs, deadline, sums))
    }

    /// Allocates the message (only after a frame named a job the assets lack).
    fn failure(&self) -> Option<String> {
        self.failure.clone()
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
