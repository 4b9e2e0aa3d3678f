//! The gather state machine, free of I/O: which classes each worker is asked for, which replies
//! are accepted, who is sidelined, and what the coordinator computes itself when shares are missing.
//! `vps_cluster::RemoteShares` is the driver around it (sockets, channels, clocks, the local
//! thread pool, the metrics board), the way `quinn` drives `quinn-proto`.
//!
//! Nothing here reads a clock, touches a socket, spawns a thread or waits on a channel: times are
//! passed in ([`Instant`]s taken by the driver, a [`Duration`] left before the device write), and
//! workers are named by their join id. So every rule below can be tested frame by frame without a
//! network (`tests/gather.rs`).
//!
//! A frame samples one or more jobs ([`vps_haptic::job`]: the first part in the static scene,
//! and in a session of several parts the others and the pairs): every work share is the same
//! classes of every job, requested and answered job by job, merged when its last job is in; a
//! probe asks for the first job alone. Each job's reply is checked against its own shell's and
//! voxmap's [`Shape`] ([`GatherCore::add_target`]).
//!
//! One frame, in the order the driver calls it:
//! 1. [`GatherCore::begin_frame`]: a new sequence number; replies carrying an older one are late.
//!    [`GatherCore::set_jobs`]: the frame's jobs, when they change.
//! 2. [`GatherCore::join`] / [`GatherCore::leave`]: membership changes queued since the last frame.
//! 3. [`GatherCore::assign`]: the class split ([`crate::split::split_classes`]) between the
//!    coordinator (weight 1) and the active workers (adapted weights, see [`crate::split`]); with
//!    [`Policy::predict`] each share goes out only when that is predicted to shorten the frame
//!    ([`SplitDecision`]), and a worker without a share is sent an unawaited probe. Without it, a
//!    sidelined worker is asked for one awaited probe class every [`Policy::probe_every`] frames.
//!    Returns the coordinator's own class mask; [`GatherCore::requests`] lists what to send.
//! 4. [`GatherCore::sent`]: when each request left (or that it could not be sent), and whether
//!    its reply is awaited this frame. [`GatherCore::probe_classes`] /
//!    [`GatherCore::set_probe_result`]: the local sums an unawaited probe is checked against.
//! 5. [`GatherCore::accept`] / [`GatherCore::malformed`] / [`GatherCore::late`]: each reply.
//! 6. [`GatherCore::settle`]: at the deadline, books the outcome per worker (weights, sidelining,
//!    reinstating, round-trip estimates, unawaited probes answered since the last frame) and
//!    lists the missing work shares.
//! 7. [`GatherCore::plan_fallback`]: which missing shares are recomputed locally and which are
//!    stood in for by held sums from an earlier frame ([`crate::fallback`]).
//! 8. [`GatherCore::take_misbehaving`]: workers to disconnect for bad replies in a row.
//!
//! Allocation: membership changes allocate; a frame allocates the split's masks (one small `Vec`),
//! with [`Policy::predict`] the list of predicted round trips (one small `Vec`), and the fallback
//! plan when shares are missing; everything else reuses scratch buffers. Nothing blocks.

use crate::fallback::{plan_fallback, FallbackAction, MissingShare, StalePolicy};
use crate::protocol::{mask_classes, FrameReply};
use crate::report::SplitReport;
use crate::split::{split_classes, Adapt, ShareOutcome};
use crate::ConfigError;
use std::time::{Duration, Instant};
use vps_haptic::job::{JobTarget, MAX_JOBS};
use vps_haptic::PartialSums;

/// The rules of the gather (the part of `vps_cluster::GatherConfig` the core uses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Policy {
    /// Consecutive unmerged work shares before a worker is sidelined (≥ 1).
    pub sideline_after: u32,
    /// A sidelined worker is probed every this many frames (≥ 1); with [`Policy::predict`], so is
    /// every worker given no share, and an unanswered probe is given up after as many frames.
    pub probe_every: u64,
    /// Consecutive timely probe replies before a sidelined worker gets work again (≥ 1).
    pub reinstate_after: u32,
    /// Bad replies in a row after which a worker is to be disconnected (≥ 1).
    pub disconnect_after: u32,
    /// Adapt each worker's share to its round trips; off: equal shares.
    pub adaptive_shares: bool,
    /// When a missing share may be stood in for by earlier sums.
    pub stale: StalePolicy,
    /// Send a work share only when the split is predicted to shorten the frame, and measure the
    /// workers with unawaited probes (see [`SplitDecision`]); off: the plain split every frame.
    pub predict: bool,
}

/// How a frame's work was split, and why ([`Policy::predict`]).
///
/// The prediction: the coordinator's cost per class `c` (measured on its own share, passed in
/// with [`GatherCore::set_local_cost`]) and, per worker, a pessimistic fixed round-trip cost
/// `bᵢ = min(srttᵢ + 4·rttvarᵢ, W)` (smoothed as TCP smooths its round trip, RFC 6298) of the
/// samples "round trip less `c` per class computed" (network and wake-ups; the worker is taken
/// to compute as fast as the coordinator). `W` is the reply window
/// ([`GatherCore::set_reply_window`]): no frame waits longer for a reply, a share missing then
/// is recomputed locally, so a worker never costs a frame more than `W` plus its share's compute. With `k₀` classes local and `kᵢ` at worker `i`, the split
/// frame is predicted to take `max(k₀·c, maxᵢ(bᵢ + kᵢ·c))`. Starting from the worker predicted
/// slowest, a share is kept on the coordinator while that does not make the predicted frame
/// slower (a tie keeps it); a worker with no estimate yet keeps none. When every share is kept,
/// the frame is local (`C·c` for all `C` classes).
///
/// The samples come from merged work shares and from probes that no frame waits for: a worker
/// given no share this frame (kept, sidelined, or not yet measured) is sent one class of the
/// coordinator's own share at most every [`Policy::probe_every`] frames (at once when it has no
/// estimate), with one probe outstanding per worker. While its predicted fixed cost alone is no
/// less than computing every class locally (`bᵢ ≥ C·c`: no share of it can shorten a frame), it
/// is probed [`FAR_PROBE_FACTOR`] times less often. The coordinator computes that class too
/// and the reply must equal its sums exactly (they are integers); it is never merged, and its
/// round trip, timed when the datagram arrived, is booked at the first [`GatherCore::settle`]
/// after it. A probe unanswered for `probe_every` frames is booked as a round trip as long as
/// it has waited, at most its frame's reply window. So a frame waits for a worker only when the prediction says that shortens it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitDecision {
    /// Prediction off, or no worker to split with: the plain split (or everything local).
    Plain,
    /// The split is predicted faster than local: shares go to the workers.
    Split,
    /// The split is predicted no faster (or a worker is not yet measured): every class stays
    /// local this frame.
    KeptLocal,
}

/// An unawaited probe of [`Policy::predict`], outstanding until booked at a settle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OpenProbe {
    /// The frame it was sent in.
    pub seq: u64,
    /// The one class asked for.
    pub classes: u64,
    /// When it left (`None` before [`GatherCore::sent`]).
    pub sent_at: Option<Instant>,
    /// The coordinator's own sums of `classes` ([`GatherCore::set_probe_result`]).
    pub expect: Option<PartialSums>,
    /// The reply window its frame had (request to that frame's deadline), set at that settle.
    pub window: Option<Duration>,
    /// The reply: its round trip, or `None` for a wrong reply. `None` while unanswered.
    pub answer: Option<Option<Duration>>,
}

/// How many times less often a worker is probed while no share of it can shorten a frame
/// (see [`SplitDecision`]): every 100 ms with the default `probe_every` of 10 frames.
pub const FAR_PROBE_FACTOR: u64 = 10;

/// What the core needs to know of one job's shell and voxmap to check its replies.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    /// Points in each class (its length is the class count, 1..=64).
    pub class_points: Vec<u64>,
    /// The deepest plausible contact (m), [`PartialSums::max_contact_depth`].
    pub max_depth: f64,
    /// The shell's largest point radius about its centre (m).
    pub max_radius: f64,
}

/// A worker's latest merged work reply: what may stand in for its share in a later frame of the
/// same jobs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct HeldShare {
    /// The class mask the sums cover.
    pub classes: u64,
    /// The frame's jobs.
    pub jobs: Vec<JobTarget>,
    /// The sums the worker returned, one per job.
    pub sums: Vec<PartialSums>,
    /// The frame (sequence number) they were computed for.
    pub seq: u64,
}

/// One worker as the core tracks it.
#[derive(Clone, Debug)]
pub struct PeerState {
    /// The join id.
    pub id: u32,
    /// Given no work, only probes.
    pub sidelined: bool,
    /// Share weight relative to the coordinator's 1 (see [`crate::split`]).
    pub weight: f64,
    /// The latest merged work reply.
    pub held: Option<HeldShare>,
    /// Consecutive unmerged work shares.
    pub misses: u32,
    /// Consecutive timely probe replies while sidelined.
    pub probe_hits: u32,
    /// Bad replies since the last valid one.
    pub bad_replies: u32,
    /// This frame: the classes asked for (0: nothing asked), of every job of the frame (of the
    /// first job only for a probe).
    pub asked: u64,
    /// This frame: the jobs answered so far (bit `k`: job `k` of [`GatherCore::jobs`]).
    pub answered: u64,
    /// This frame: the sums of the jobs answered, per job (room for every job).
    pub sums: Vec<PartialSums>,
    /// This frame's request is a probe (checked, never merged).
    pub probing: bool,
    /// This frame: when the request left.
    pub sent_at: Option<Instant>,
    /// This frame: a reply (or a failed send) settled the request.
    pub settled: bool,
    /// This frame: the reply was merged.
    pub merged: bool,
    /// This frame: the round trip of the merged reply.
    pub rtt: Duration,
    /// Smoothed fixed cost of a round trip (its round trip less the compute of its classes at
    /// the coordinator's cost per class); `None` before its first sample.
    pub base_rtt: Option<Duration>,
    /// Smoothed mean deviation of those samples (RFC 6298's `RTTVAR`).
    pub base_dev: Duration,
    /// The outstanding unawaited probe ([`Policy::predict`]).
    pub probe: Option<OpenProbe>,
    /// The frame of the latest unawaited probe sent (0: none yet).
    pub probed_seq: u64,
}

impl PeerState {
    fn new(id: u32) -> PeerState {
        PeerState {
            id,
            sidelined: false,
            weight: 1.0,
            held: None,
            misses: 0,
            probe_hits: 0,
            bad_replies: 0,
            asked: 0,
            answered: 0,
            sums: vec![PartialSums::default(); MAX_JOBS],
            probing: false,
            sent_at: None,
            settled: false,
            merged: false,
            rtt: Duration::ZERO,
            base_rtt: None,
            base_dev: Duration::ZERO,
            probe: None,
            probed_seq: 0,
        }
    }

    /// Books one sample of the fixed round-trip cost, smoothed as TCP smooths its round trip
    /// (RFC 6298: the deviation by 1/4, the mean by 1/8; the first sample sets the mean, half of
    /// it the deviation).
    fn book_base(&mut self, sample: Duration) {
        match self.base_rtt {
            Some(old) => {
                let gap = old.abs_diff(sample);
                self.base_dev = (self.base_dev.saturating_mul(3).saturating_add(gap)) / 4;
                self.base_rtt = Some(old.saturating_mul(7).saturating_add(sample) / 8);
            }
            None => {
                self.base_dev = sample / 2;
                self.base_rtt = Some(sample);
            }
        }
    }

    /// The pessimistic fixed round-trip cost the prediction uses (`srtt + 4·rttvar`).
    pub fn predicted_base(&self) -> Option<Duration> {
        self.base_rtt
            .map(|b| b.saturating_add(self.base_dev.saturating_mul(4)))
    }
}

/// What became of one reply.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Acceptance {
    /// From a worker the core does not know (gone, or never joined).
    Unknown,
    /// For another frame than this one: dropped.
    Late,
    /// For this frame, but nothing was asked or the request is already settled (a duplicate).
    Unrequested,
    /// One job of a work share or probe of several jobs, in time and plausible: kept until the
    /// share's last job arrives (then [`Acceptance::Merged`] or [`Acceptance::Probe`]).
    Partial,
    /// For this frame, but the class mask or the sums are wrong: the share is settled as missing.
    Rejected,
    /// A probe answered in time: round trip `rtt`; never merged.
    Probe {
        /// Request to reply.
        rtt: Duration,
    },
    /// An unawaited probe's reply ([`Policy::predict`]), whenever it came: never merged, never
    /// awaited; booked at the next settle. `rtt` is `None` when it was wrong (a bad reply).
    Probed {
        /// Request to reply.
        rtt: Option<Duration>,
    },
    /// A work share answered in time: merge its sums. Round trip `rtt`.
    Merged {
        /// Request to reply.
        rtt: Duration,
    },
}

impl Acceptance {
    /// True when the reply settled a request awaited this frame (the driver awaits one fewer).
    pub fn settles(self) -> bool {
        matches!(
            self,
            Acceptance::Rejected | Acceptance::Probe { .. } | Acceptance::Merged { .. }
        )
    }
}

/// A change in a worker's standing booked by [`GatherCore::settle`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transition {
    /// Its work share had no reply at all (no datagram settled it).
    Lost,
    /// Sidelined: no more work until it answers probes.
    Sidelined,
    /// Given work again after `reinstate_after` timely probes.
    Reinstated,
}

/// The fallback for this frame's missing shares.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Fallback {
    /// The classes the coordinator recomputes locally (union of the recomputed shares).
    pub recompute: u64,
    /// The workers whose shares are recomputed.
    pub recomputed: Vec<u32>,
    /// The workers whose shares are stood in for by their held sums (one per job,
    /// [`GatherCore::held_sums`]).
    pub stale: Vec<u32>,
}

fn config_err(field: &'static str) -> ConfigError {
    ConfigError {
        field,
        message: "must be at least 1".into(),
    }
}

/// The gather state machine (see the module docs).
#[derive(Clone, Debug)]
pub struct GatherCore {
    policy: Policy,
    /// The shape of each job target the frames may name; the first is [`JobTarget::FIRST`]'s.
    targets: Vec<(JobTarget, Shape)>,
    /// This frame's jobs ([`GatherCore::set_jobs`]), each with its index in `targets`.
    jobs: Vec<JobTarget>,
    job_shapes: Vec<usize>,
    adapt: Adapt,
    seq: u64,
    /// In join order (ascending id), so the assignment is reproducible.
    peers: Vec<PeerState>,
    /// Scratch: indices of the peers given work this frame.
    active: Vec<usize>,
    /// Scratch: the parties' weights.
    weights: Vec<f64>,
    /// Scratch: this frame's missing work shares (peer index, share).
    missing: Vec<(usize, MissingShare)>,
    /// Scratch: this frame's transitions.
    transitions: Vec<(u32, Transition)>,
    fallback: Fallback,
    /// The coordinator's cost of one class (latest measurement).
    per_class: Duration,
    decision: SplitDecision,
    split_stats: SplitReport,
    /// This frame's unawaited probe class (0: none).
    probe_class: u64,
    /// The reply window (request to deadline) of the latest frame.
    window: Duration,
}

impl GatherCore {
    /// A core with no workers. Errors when a count of `policy` is 0 or the class count is not
    /// in 1..=64.
    pub fn new(policy: Policy, shape: Shape) -> Result<GatherCore, ConfigError> {
        if policy.sideline_after == 0 {
            return Err(config_err("sideline_after"));
        }
        if policy.probe_every == 0 {
            return Err(config_err("probe_every"));
        }
        if policy.reinstate_after == 0 {
            return Err(config_err("reinstate_after"));
        }
        if policy.disconnect_after == 0 {
            return Err(config_err("disconnect_after"));
        }
        if !(1..=64).contains(&shape.class_points.len()) {
            return Err(ConfigError {
                field: "class_count",
                message: format!("{} is outside 1..=64", shape.class_points.len()),
            });
        }
        Ok(GatherCore {
            policy,
            targets: vec![(JobTarget::FIRST, shape)],
            jobs: vec![JobTarget::FIRST],
            job_shapes: vec![0],
            adapt: Adapt::default(),
            seq: 0,
            peers: Vec::new(),
            active: Vec::new(),
            weights: Vec::new(),
            missing: Vec::new(),
            transitions: Vec::new(),
            fallback: Fallback::default(),
            per_class: Duration::ZERO,
            decision: SplitDecision::Plain,
            split_stats: SplitReport::default(),
            probe_class: 0,
            window: Duration::MAX,
        })
    }

    /// Registers another job target the frames may name ([`vps_haptic::job`]) with the shape of
    /// its shell and voxmap, which must have the first target's class count. Setup-time;
    /// allocates. Re-registering a target replaces its shape.
    pub fn add_target(&mut self, target: JobTarget, shape: Shape) -> Result<(), ConfigError> {
        let classes = self.targets[0].1.class_points.len();
        if shape.class_points.len() != classes {
            return Err(ConfigError {
                field: "class_count",
                message: format!(
                    "job target (shell {}, voxmap {}) has {} classes, the first {classes}",
                    target.shell,
                    target.map,
                    shape.class_points.len()
                ),
            });
        }
        match self.targets.iter_mut().find(|(t, _)| *t == target) {
            Some(known) => known.1 = shape,
            None => self.targets.push((target, shape)),
        }
        Ok(())
    }

    /// Sets this frame's jobs (call between [`GatherCore::begin_frame`] and
    /// [`GatherCore::assign`]; they stay until set again): 1..=[`MAX_JOBS`] registered targets,
    /// no two alike, the first [`JobTarget::FIRST`] (probes ask for it alone). Errors, leaving
    /// the jobs as they were, otherwise. Does not allocate.
    pub fn set_jobs(&mut self, jobs: &[JobTarget]) -> Result<(), ConfigError> {
        let bad = |message: String| {
            Err(ConfigError {
                field: "jobs",
                message,
            })
        };
        if jobs.is_empty() || jobs.len() > MAX_JOBS || jobs[0] != JobTarget::FIRST {
            return bad(format!(
                "{} jobs: 1..={MAX_JOBS} are allowed, the first part in the scene first",
                jobs.len()
            ));
        }
        for (k, job) in jobs.iter().enumerate() {
            if jobs[..k].contains(job) {
                return bad(format!("job {k} is named twice"));
            }
            if !self.targets.iter().any(|(t, _)| t == job) {
                return bad(format!(
                    "job {k} (shell {}, voxmap {}) is not one of the assets' targets",
                    job.shell, job.map
                ));
            }
        }
        self.jobs.clear();
        self.job_shapes.clear();
        for job in jobs {
            self.jobs.push(*job);
            let shape = self.targets.iter().position(|(t, _)| t == job);
            self.job_shapes.push(shape.unwrap_or(0));
        }
        Ok(())
    }

    /// This frame's jobs; a work request asks for every one, a probe for the first alone.
    pub fn jobs(&self) -> &[JobTarget] {
        &self.jobs
    }

    /// How many jobs worker `id`'s request of this frame names (0: none asked).
    pub fn jobs_asked(&self, id: u32) -> usize {
        match self.peer(id) {
            Some(p) if p.asked == 0 => 0,
            Some(p) if p.probing => 1,
            Some(_) => self.jobs.len(),
            None => 0,
        }
    }

    /// The sums of worker `id`'s share this frame, one per job: what to merge after
    /// [`Acceptance::Merged`]. Empty when `id` is unknown.
    pub fn merged_sums(&self, id: u32) -> &[PartialSums] {
        let n = self.jobs.len();
        self.peer(id).map_or(&[], |p| &p.sums[..n])
    }

    /// The held sums of worker `id`, one per job of this frame: what stands in for its share
    /// when the fallback plan lists it as stale ([`Fallback::stale`]). Empty when none is held.
    pub fn held_sums(&self, id: u32) -> &[PartialSums] {
        self.peer(id)
            .and_then(|p| p.held.as_ref())
            .map_or(&[], |h| &h.sums)
    }

    /// This frame's sequence number (0 before the first frame).
    pub fn seq(&self) -> u64 {
        self.seq
    }

    /// The workers, in join order.
    pub fn peers(&self) -> &[PeerState] {
        &self.peers
    }

    /// Worker `id`, if known.
    pub fn peer(&self, id: u32) -> Option<&PeerState> {
        self.peers.iter().find(|p| p.id == id)
    }

    fn peer_mut(&mut self, id: u32) -> Option<&mut PeerState> {
        self.peers.iter_mut().find(|p| p.id == id)
    }

    /// Workers given work this frame (joined, not sidelined), as of the latest [`GatherCore::assign`].
    pub fn active_workers(&self) -> usize {
        self.active.len()
    }

    /// The coordinator's measured cost of one class (its own share's time over its classes), for
    /// the prediction and the fallback plan.
    pub fn set_local_cost(&mut self, per_class: Duration) {
        self.per_class = per_class;
        self.split_stats.per_class_ns = nanos(per_class);
    }

    /// The coordinator's latest measured cost of one class ([`GatherCore::set_local_cost`]).
    pub fn local_cost(&self) -> Duration {
        self.per_class
    }

    /// The transitions booked by the latest [`GatherCore::settle`].
    pub fn transitions(&self) -> &[(u32, Transition)] {
        &self.transitions
    }

    /// The fallback planned by the latest [`GatherCore::plan_fallback`].
    pub fn fallback(&self) -> &Fallback {
        &self.fallback
    }

    /// The time this frame's replies are awaited, from the requests to the deadline: the most a
    /// worker's round trip can cost a frame before its share is recomputed locally (the
    /// prediction's cap). Unset: no cap.
    pub fn set_reply_window(&mut self, window: Duration) {
        self.window = window;
    }

    /// This frame's unawaited probe class (a class of the coordinator's own mask; 0: no probe).
    /// The driver computes its sums separately and hands them to [`GatherCore::set_probe_result`].
    pub fn probe_classes(&self) -> u64 {
        self.probe_class
    }

    /// The coordinator's own sums of [`GatherCore::probe_classes`]: this frame's probe replies
    /// must equal them. Without them a probe reply is only checked for plausibility.
    pub fn set_probe_result(&mut self, sums: &PartialSums) {
        let seq = self.seq;
        for peer in &mut self.peers {
            if let Some(probe) = peer.probe.as_mut().filter(|p| p.seq == seq) {
                probe.expect = Some(*sums);
            }
        }
    }

    /// This frame's split decision (as of the latest [`GatherCore::assign`]).
    pub fn decision(&self) -> SplitDecision {
        self.decision
    }

    /// Frames per decision and the latest prediction.
    pub fn split_stats(&self) -> &SplitReport {
        &self.split_stats
    }

    /// Starts the next frame: a new sequence number. Call before membership changes and the
    /// assignment.
    pub fn begin_frame(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    /// Admits worker `id` (reinstated, weight 1). A known id is left as it is. Allocates.
    pub fn join(&mut self, id: u32) {
        if self.peer(id).is_some() {
            return;
        }
        let at = self.peers.partition_point(|p| p.id < id);
        self.peers.insert(at, PeerState::new(id));
    }

    /// Forgets worker `id` (its connection ended); true when it was known.
    pub fn leave(&mut self, id: u32) -> bool {
        match self.peers.iter().position(|p| p.id == id) {
            Some(i) => {
                self.peers.remove(i);
                true
            }
            None => false,
        }
    }

    /// Decides this frame's shares; returns the coordinator's own class mask. Together with the
    /// work shares of [`GatherCore::requests`] it covers every class exactly once (probes are
    /// extra). Allocates the split's masks.
    pub fn assign(&mut self) -> u64 {
        self.active.clear();
        let class_count = self.targets[0].1.class_points.len() as u32;
        let (seq, probe_every) = (self.seq, self.policy.probe_every);
        for (i, peer) in self.peers.iter_mut().enumerate() {
            peer.asked = 0;
            peer.answered = 0;
            peer.probing = false;
            peer.settled = false;
            peer.merged = false;
            peer.sent_at = None;
            if !peer.sidelined {
                self.active.push(i);
            } else if !self.policy.predict && seq.is_multiple_of(probe_every) {
                let class = (seq / probe_every) % u64::from(class_count);
                peer.asked = 1 << class;
                peer.probing = true;
            }
        }
        self.weights.clear();
        self.weights.push(1.0);
        for &i in &self.active {
            let weight = self.peers[i].weight;
            self.weights.push(if self.policy.adaptive_shares {
                weight
            } else {
                1.0
            });
        }
        let mut masks = split_classes(class_count, &self.weights);
        self.decision = self.decide(&mut masks);
        if self.decision == SplitDecision::KeptLocal {
            self.active.clear();
        }
        for (&i, &mask) in self.active.iter().zip(&masks[1..]) {
            self.peers[i].asked = mask;
        }
        self.open_probes(masks[0]);
        masks[0]
    }

    /// Decides which shares of the split `masks` (party 0 the coordinator, then the active
    /// workers) are worth sending ([`SplitDecision`]): a worker not yet measured keeps none;
    /// then, starting from the worker predicted slowest, a share moves to the coordinator while
    /// that does not make the predicted frame slower. Moves the kept shares into `masks[0]`;
    /// books the decision. Allocates the list of predictions (one small `Vec`).
    fn decide(&mut self, masks: &mut [u64]) -> SplitDecision {
        if !self.policy.predict || self.active.is_empty() {
            return SplitDecision::Plain;
        }
        let c = self.per_class;
        let cost = |mask: u64| c.saturating_mul(mask.count_ones());
        // (party, predicted remote time), slowest first; unmeasured workers keep no share.
        let mut remote: Vec<(usize, Duration)> = Vec::with_capacity(self.active.len());
        let mut local = masks[0];
        let mut kept = 0;
        for (party, &i) in self.active.iter().enumerate() {
            let base = self.peers[i].predicted_base().map(|b| b.min(self.window));
            match base.filter(|_| !c.is_zero()) {
                Some(base) => remote.push((party + 1, base.saturating_add(cost(masks[party + 1])))),
                None => {
                    local |= std::mem::take(&mut masks[party + 1]);
                    kept += 1;
                }
            }
        }
        self.split_stats.worker_base_ns = self
            .active
            .iter()
            .filter_map(|&i| self.peers[i].predicted_base())
            .min()
            .map(|b| b.min(self.window))
            .map_or(0, nanos);
        remote.sort_by_key(|r| std::cmp::Reverse(r.1));
        let mut moved = 0;
        for (k, &(party, time)) in remote.iter().enumerate() {
            let rest = remote.get(k + 1).map_or(Duration::ZERO, |r| r.1);
            let now = cost(local).max(time);
            let if_kept = cost(local | masks[party]).max(rest);
            if if_kept > now {
                break;
            }
            local |= masks[party];
            moved += 1;
        }
        for &(party, _) in &remote[..moved] {
            masks[party] = 0;
        }
        masks[0] = local;
        let slowest = remote.get(moved).map_or(Duration::ZERO, |r| r.1);
        self.split_stats.predicted_split_ns = nanos(cost(local).max(slowest));
        self.split_stats.predicted_local_ns =
            nanos(c.saturating_mul(self.targets[0].1.class_points.len() as u32));
        self.split_stats.shares_kept_local += (kept + moved) as u64;
        if moved == remote.len() {
            self.split_stats.kept_local_frames += 1;
            SplitDecision::KeptLocal
        } else {
            self.split_stats.split_frames += 1;
            SplitDecision::Split
        }
    }

    /// Opens an unawaited probe ([`Policy::predict`]) for each worker given no share this frame
    /// and none outstanding, when it has no estimate yet or its last probe is `probe_every`
    /// frames old (times [`FAR_PROBE_FACTOR`] while no share of it can shorten a frame): one class of the coordinator's own mask `local`, rotating with the frame.
    fn open_probes(&mut self, local: u64) {
        self.probe_class = 0;
        if !self.policy.predict || local == 0 {
            return;
        }
        let (seq, every) = (self.seq, self.policy.probe_every);
        let nth = (seq % u64::from(local.count_ones())) as usize;
        let Some(class) = mask_classes(local).nth(nth) else {
            return;
        };
        let local_all = self
            .per_class
            .saturating_mul(self.targets[0].1.class_points.len() as u32);
        let window = self.window;
        for peer in &mut self.peers {
            let far = !local_all.is_zero()
                && peer
                    .predicted_base()
                    .is_some_and(|b| b.min(window) >= local_all);
            let every = if far {
                every.saturating_mul(FAR_PROBE_FACTOR)
            } else {
                every
            };
            let due = peer.base_rtt.is_none() || seq >= peer.probed_seq.saturating_add(every);
            if peer.asked != 0 || peer.probe.is_some() || !due {
                continue;
            }
            peer.asked = 1 << class;
            peer.probing = true;
            peer.probed_seq = seq;
            peer.probe = Some(OpenProbe {
                seq,
                classes: 1 << class,
                sent_at: None,
                expect: None,
                window: None,
                answer: None,
            });
            self.probe_class = 1 << class;
            self.split_stats.probes += 1;
        }
    }

    /// This frame's requests: (worker id, class mask, is a probe), in join order.
    pub fn requests(&self) -> impl Iterator<Item = (u32, u64, bool)> + '_ {
        self.peers
            .iter()
            .filter(|p| p.asked != 0)
            .map(|p| (p.id, p.asked, p.probing))
    }

    /// Records that worker `id`'s request left at `at` (`sent`), or could not be sent (then it is
    /// settled as missing at once, or an unawaited probe forgotten). Returns true when the driver
    /// is to await its reply this frame (sent, and not an unawaited probe).
    pub fn sent(&mut self, id: u32, at: Instant, sent: bool) -> bool {
        let unawaited = self.policy.predict;
        let Some(peer) = self.peer_mut(id) else {
            return false;
        };
        peer.sent_at = Some(at);
        if peer.probing && unawaited {
            peer.settled = true;
            if sent {
                if let Some(probe) = peer.probe.as_mut() {
                    probe.sent_at = Some(at);
                }
            } else {
                peer.probe = None;
            }
            return false;
        }
        if !sent {
            peer.settled = true;
        }
        sent
    }

    /// True when a reply from worker `id` for frame `seq` would answer its outstanding
    /// unawaited probe (the driver takes such a reply whenever it arrives).
    pub fn answers_probe(&self, id: u32, seq: u64) -> bool {
        self.peer(id)
            .and_then(|p| p.probe)
            .is_some_and(|p| p.seq == seq && p.answer.is_none())
    }

    /// A datagram from worker `id` that did not decode; false when `id` is unknown.
    pub fn malformed(&mut self, id: u32) -> bool {
        match self.peer_mut(id) {
            Some(peer) => {
                peer.bad_replies = peer.bad_replies.saturating_add(1);
                true
            }
            None => false,
        }
    }

    /// A reply from worker `id` that arrived after this frame's deadline: never merged, never a
    /// bad reply. False when `id` is unknown.
    pub fn late(&self, id: u32) -> bool {
        self.peer(id).is_some()
    }

    /// Judges a decoded reply from worker `id` that arrived at `at`. It is kept only when it
    /// carries this frame's sequence number, answers a job of a request not yet settled (not
    /// answered before), echoes the requested class mask and passes
    /// [`PartialSums::is_plausible`] and [`PartialSums::torque_within`] for its job's share; the
    /// share is merged when its last job is in. A reply for a job not asked settles the share as
    /// rejected. Allocates only when a worker's first share is merged (its held copy).
    pub fn accept(&mut self, id: u32, reply: &FrameReply, at: Instant) -> Acceptance {
        let seq = self.seq;
        let Some(index) = self.peers.iter().position(|p| p.id == id) else {
            return Acceptance::Unknown;
        };
        let first = &self.targets[0].1;
        let peer = &mut self.peers[index];
        if let Some(probe) = peer.probe.as_mut().filter(|p| p.seq == reply.seq) {
            if probe.answer.is_some() {
                return Acceptance::Unrequested;
            }
            let points = mask_classes(probe.classes)
                .map(|c| first.class_points[c as usize])
                .sum();
            let valid = reply.classes == probe.classes
                && reply.job == JobTarget::FIRST
                && probe.expect.map_or(
                    reply.sums.is_plausible(points, first.max_depth)
                        && reply.sums.torque_within(first.max_radius, first.max_depth),
                    |expect| expect == reply.sums,
                );
            let rtt = probe
                .sent_at
                .filter(|_| valid)
                .map(|sent| at.saturating_duration_since(sent));
            probe.answer = Some(rtt);
            if rtt.is_none() {
                peer.bad_replies = peer.bad_replies.saturating_add(1);
            } else {
                peer.bad_replies = 0;
            }
            return Acceptance::Probed { rtt };
        }
        if reply.seq != seq {
            return Acceptance::Late;
        }
        if peer.asked == 0 || peer.settled {
            return Acceptance::Unrequested;
        }
        let asked_jobs = if peer.probing { 1 } else { self.jobs.len() };
        let job = self.jobs[..asked_jobs].iter().position(|t| *t == reply.job);
        if job.is_some_and(|k| peer.answered >> k & 1 == 1) {
            return Acceptance::Unrequested;
        }
        let valid = job.is_some_and(|k| {
            let shape = &self.targets[self.job_shapes[k]].1;
            let points = mask_classes(peer.asked)
                .map(|c| shape.class_points[c as usize])
                .sum();
            reply.classes == peer.asked
                && reply.sums.is_plausible(points, shape.max_depth)
                && reply.sums.torque_within(shape.max_radius, shape.max_depth)
        });
        let Some(job) = job.filter(|_| valid) else {
            peer.settled = true;
            peer.bad_replies = peer.bad_replies.saturating_add(1);
            return Acceptance::Rejected;
        };
        peer.answered |= 1 << job;
        peer.sums[job] = reply.sums;
        if peer.answered.count_ones() as usize != asked_jobs {
            return Acceptance::Partial;
        }
        peer.settled = true;
        let rtt = peer
            .sent_at
            .map_or(Duration::ZERO, |sent| at.saturating_duration_since(sent));
        peer.bad_replies = 0;
        if peer.probing {
            peer.probe_hits += 1;
            Acceptance::Probe { rtt }
        } else {
            peer.merged = true;
            peer.rtt = rtt;
            let sums = &peer.sums[..asked_jobs];
            match peer.held.as_mut() {
                Some(held) => {
                    held.classes = peer.asked;
                    held.seq = seq;
                    held.jobs.clone_from(&self.jobs);
                    held.sums.clear();
                    held.sums.extend_from_slice(sums);
                }
                None => {
                    peer.held = Some(HeldShare {
                        classes: peer.asked,
                        jobs: self.jobs.clone(),
                        sums: sums.to_vec(),
                        seq,
                    })
                }
            }
            Acceptance::Merged { rtt }
        }
    }

    /// Books the frame's outcome per worker at the reply `deadline`: a probe streak long enough
    /// reinstates; a merged share adapts the weight against the time the worker had (request
    /// sent to `deadline`); a missed share halves it, counts towards sidelining and is listed for
    /// [`GatherCore::plan_fallback`]. Returns the transitions (worker id, what changed).
    pub fn settle(&mut self, deadline: Instant) -> &[(u32, Transition)] {
        self.missing.clear();
        self.transitions.clear();
        let (seq, per_class, policy) = (self.seq, self.per_class, self.policy);
        for (index, peer) in self.peers.iter_mut().enumerate() {
            if let Some(probe) = peer.probe.as_mut().filter(|p| p.seq == seq) {
                probe.window = probe.sent_at.map(|s| deadline.saturating_duration_since(s));
            }
            if let Some(probe) = peer.probe {
                let booked = book_probe(peer, probe, seq, deadline, per_class, policy);
                match booked {
                    Some(true) => self.split_stats.probe_replies += 1,
                    Some(false) => self.split_stats.probes_failed += 1,
                    None => {}
                }
                if booked.is_some() && peer.sidelined && peer.probe_hits >= policy.reinstate_after {
                    reinstate(peer, &self.adapt);
                    self.transitions.push((peer.id, Transition::Reinstated));
                }
            }
            if peer.asked == 0 || (peer.probing && policy.predict) {
                continue;
            }
            if peer.probing {
                let answered = peer.settled && peer.probe_hits > 0;
                if !answered {
                    peer.probe_hits = 0;
                }
                if peer.probe_hits >= self.policy.reinstate_after {
                    reinstate(peer, &self.adapt);
                    self.transitions.push((peer.id, Transition::Reinstated));
                }
                continue;
            }
            if peer.merged {
                peer.misses = 0;
                // The round trip's fixed part.
                let compute = self.per_class.saturating_mul(peer.asked.count_ones());
                peer.book_base(peer.rtt.saturating_sub(compute));
                let window = peer
                    .sent_at
                    .map_or(Duration::ZERO, |s| deadline.saturating_duration_since(s));
                let outcome = ShareOutcome::Merged {
                    rtt: peer.rtt,
                    window,
                };
                peer.weight = self.adapt.next_weight(peer.weight, outcome);
                continue;
            }
            peer.weight = self.adapt.next_weight(peer.weight, ShareOutcome::Missed);
            if !peer.settled {
                self.transitions.push((peer.id, Transition::Lost));
            }
            let stale_age = match &peer.held {
                Some(held) if held.classes == peer.asked && held.jobs == self.jobs => {
                    Some(self.seq - held.seq)
                }
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
            if peer.misses >= self.policy.sideline_after && !peer.sidelined {
                peer.sidelined = true;
                peer.probe_hits = 0;
                self.transitions.push((peer.id, Transition::Sidelined));
            }
        }
        &self.transitions
    }

    /// The missing work shares listed by the latest [`GatherCore::settle`]: (worker id, classes).
    pub fn missing(&self) -> impl Iterator<Item = (u32, u64)> + '_ {
        self.missing
            .iter()
            .map(|&(i, _)| (self.peers[i].id, self.peers[i].asked))
    }

    /// Plans the fallback for the missing shares ([`crate::fallback::plan_fallback`]): `left` is
    /// the time until the device write is due, `per_class` the local cost of one class this
    /// frame. Allocates the plan when shares are missing.
    pub fn plan_fallback(&mut self, left: Duration, per_class: Duration) -> &Fallback {
        self.fallback.recompute = 0;
        self.fallback.recomputed.clear();
        self.fallback.stale.clear();
        if self.missing.is_empty() {
            return &self.fallback;
        }
        let shares: Vec<MissingShare> = self.missing.iter().map(|m| m.1).collect();
        let plan = plan_fallback(&shares, left, per_class, self.policy.stale);
        for (&(index, _), action) in self.missing.iter().zip(plan) {
            let peer = &self.peers[index];
            match (action, &peer.held) {
                (FallbackAction::ReuseStale, Some(_)) => self.fallback.stale.push(peer.id),
                _ => {
                    self.fallback.recompute |= peer.asked;
                    self.fallback.recomputed.push(peer.id);
                }
            }
        }
        &self.fallback
    }

    /// Removes and returns (id, bad replies) of every worker that sent
    /// [`Policy::disconnect_after`] bad replies in a row; the driver closes their connections.
    pub fn take_misbehaving(&mut self, out: &mut Vec<(u32, u32)>) {
        let limit = self.policy.disconnect_after;
        self.peers.retain(|p| {
            let keep = p.bad_replies < limit;
            if !keep {
                out.push((p.id, p.bad_replies));
            }
            keep
        });
    }
}

fn nanos(d: Duration) -> u64 {
    d.as_nanos().min(u128::from(u64::MAX)) as u64
}

/// Gives a sidelined worker work again, with a cautious share that grows while it keeps up.
fn reinstate(peer: &mut PeerState, adapt: &Adapt) {
    peer.sidelined = false;
    peer.weight = adapt.min_weight.max(0.5);
    peer.misses = 0;
    peer.probe_hits = 0;
}

/// Books `peer`'s outstanding unawaited `probe` at the settle of frame `seq` (reply deadline
/// `deadline`), if it is answered, or unanswered for `probe_every` frames. A correct answer is a
/// round-trip sample (less `per_class` for its one class) and, within the reply window its
/// frame had, a timely probe towards reinstating; a wrong or missing one resets the streak, and
/// a missing one books the time it has waited, at most that window, as a sample. Returns whether it was answered
/// correctly, `None` while it stays outstanding.
fn book_probe(
    peer: &mut PeerState,
    probe: OpenProbe,
    seq: u64,
    deadline: Instant,
    per_class: Duration,
    policy: Policy,
) -> Option<bool> {
    let waited = probe
        .sent_at
        .map_or(Duration::ZERO, |s| deadline.saturating_duration_since(s));
    let answered = match probe.answer {
        Some(Some(rtt)) => {
            peer.book_base(rtt.saturating_sub(per_class));
            let timely = probe.window.is_some_and(|w| rtt <= w);
            peer.probe_hits = if timely { peer.probe_hits + 1 } else { 0 };
            true
        }
        Some(None) => {
            peer.probe_hits = 0;
            false
        }
        None if seq.saturating_sub(probe.seq) >= policy.probe_every => {
            peer.book_base(waited.min(probe.window.unwrap_or(waited)));
            peer.probe_hits = 0;
            false
        }
        None => return None,
    };
    peer.probe = None;
    Some(answered)
}
