//! The gather state machine, free of I/O: which classes each worker is asked for, which replies
//! are accepted, who is benched, and what the coordinator computes itself when shares are missing.
//! [`crate::shares::RemoteShares`] is the driver around it (sockets, channels, clocks, the local
//! thread pool, the metrics board), the way `quinn` drives `quinn-proto`.
//!
//! Nothing here reads a clock, touches a socket, spawns a thread or waits on a channel: times are
//! passed in ([`Instant`]s taken by the driver, a [`Duration`] left before the device write), and
//! workers are named by their join id. So every rule below can be tested frame by frame without a
//! network (`tests/gather.rs`).
//!
//! One frame, in the order the driver calls it:
//! 1. [`GatherCore::begin_frame`]: a new sequence number; replies carrying an older one are late.
//! 2. [`GatherCore::join`] / [`GatherCore::leave`]: membership changes queued since the last frame.
//! 3. [`GatherCore::assign`]: the class split ([`crate::split::split_classes`]) between the
//!    coordinator (weight 1) and the active workers (adapted weights, see [`crate::split`]); a
//!    benched worker is asked for one probe class every [`Policy::probe_every`] frames. Returns
//!    the coordinator's own class mask; [`GatherCore::requests`] lists what to send.
//! 4. [`GatherCore::sent`]: when each request left (or that it could not be sent).
//! 5. [`GatherCore::accept`] / [`GatherCore::malformed`] / [`GatherCore::late`]: each reply.
//! 6. [`GatherCore::settle`]: at the deadline, books the outcome per worker (weights, benching,
//!    un-benching) and lists the missing work shares.
//! 7. [`GatherCore::plan_fallback`]: which missing shares are recomputed locally and which are
//!    stood in for by held sums from an earlier frame ([`crate::fallback`]).
//! 8. [`GatherCore::take_misbehaving`]: workers to disconnect for bad replies in a row.
//!
//! Allocation: membership changes allocate; a frame allocates the split's masks (one small `Vec`),
//! with [`Policy::predict`] the list of predicted round trips (one small `Vec`), and the fallback
//! plan when shares are missing; everything else reuses scratch buffers. Nothing blocks.

use crate::fallback::{plan_fallback, FallbackAction, MissingShare, StalePolicy};
use crate::protocol::{mask_classes, FrameReply};
use crate::split::{split_classes, Adapt, ShareOutcome};
use crate::ClusterError;
use std::time::{Duration, Instant};
use vps_haptic::PartialSums;

/// The rules of the gather (the part of [`crate::GatherConfig`] the core uses).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Policy {
    /// Consecutive unmerged work shares before a worker is benched (≥ 1).
    pub bench_after: u32,
    /// A benched worker is probed every this many frames (≥ 1).
    pub probe_every: u64,
    /// Consecutive timely probe replies before a benched worker gets work again (≥ 1).
    pub unbench_after: u32,
    /// Bad replies in a row after which a worker is to be disconnected (≥ 1).
    pub disconnect_after: u32,
    /// Adapt each worker's share to its round trips; off: equal shares.
    pub adaptive_shares: bool,
    /// When a missing share may be stood in for by earlier sums.
    pub stale: StalePolicy,
    /// Keep the whole frame local when the predicted split is no faster than computing every
    /// class on the coordinator (see [`SplitDecision`]).
    pub predict: bool,
}

/// How a frame's work was split, and why ([`Policy::predict`]).
///
/// The prediction: the coordinator's cost per class `c` (measured on its own share, passed in
/// with [`GatherCore::set_local_cost`]) and, per worker, a smoothed fixed round-trip cost `b`
/// (the merged reply's round trip less `c` per class it computed: network and wake-ups; the
/// worker is taken to compute as fast as the coordinator). With `k₀` classes local and `kᵢ` at
/// worker `i`, the split frame is predicted to take `max(k₀·c, maxᵢ(bᵢ + kᵢ·c))`. Starting from
/// the worker predicted slowest, a share is kept on the coordinator while that does not make the
/// predicted frame slower; when every share is kept, the frame is local (`C·c` for all `C`
/// classes). So a worker whose round trip costs more than it saves is not waited for, and adding
/// workers cannot make a frame slower than the coordinator alone by more than the prediction's
/// error. A worker with no estimate yet, and every `probe_every`-th frame, is given its share
/// anyway, so the estimates follow the network.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitDecision {
    /// Prediction off, or no worker to split with: the plain split (or everything local).
    Plain,
    /// The split is predicted faster than local: shares go to the workers.
    Split,
    /// The split is predicted no faster: every class stays local this frame.
    KeptLocal,
    /// Split to measure (a worker without an estimate, or a periodic refresh).
    Measure,
}

/// Frames per [`SplitDecision`] and the latest prediction (ns), for the cluster report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SplitStats {
    /// Frames split because the prediction favoured it.
    pub split: u64,
    /// Frames kept local because the prediction did not favour splitting.
    pub kept_local: u64,
    /// Frames split to measure the workers' round trips.
    pub measured: u64,
    /// Worker shares kept on the coordinator, summed over frames (all of a kept-local frame's
    /// shares included).
    pub shares_kept_local: u64,
    /// The latest predicted time of the split frame (ns).
    pub predicted_split_ns: u64,
    /// The latest predicted time of the all-local frame (ns).
    pub predicted_local_ns: u64,
}

/// What the core needs to know of the shell and the voxmap to check replies.
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    /// Points in each class (its length is the class count, 1..=64).
    pub class_points: Vec<u64>,
    /// The deepest plausible contact (m), [`PartialSums::max_contact_depth`].
    pub max_depth: f64,
    /// The shell's largest point radius about its centre (m).
    pub max_radius: f64,
}

/// A worker's latest merged work reply: what may stand in for its share in a later frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HeldShare {
    /// The class mask the sums cover.
    pub classes: u64,
    /// The sums the worker returned.
    pub sums: PartialSums,
    /// The frame (sequence number) they were computed for.
    pub seq: u64,
}

/// One worker as the core tracks it.
#[derive(Clone, Debug)]
pub struct PeerState {
    /// The join id.
    pub id: u32,
    /// Given no work, only probes.
    pub benched: bool,
    /// Share weight relative to the coordinator's 1 (see [`crate::split`]).
    pub weight: f64,
    /// The latest merged work reply.
    pub held: Option<HeldShare>,
    /// Consecutive unmerged work shares.
    pub misses: u32,
    /// Consecutive timely probe replies while benched.
    pub probe_hits: u32,
    /// Bad replies since the last valid one.
    pub bad_replies: u32,
    /// This frame: the classes asked for (0: nothing asked).
    pub asked: u64,
    /// This frame's request is a probe (checked, never merged).
    pub probing: bool,
    /// This frame: the points in the classes asked for.
    pub points: u64,
    /// This frame: when the request left.
    pub sent_at: Option<Instant>,
    /// This frame: a reply (or a failed send) settled the request.
    pub settled: bool,
    /// This frame: the reply was merged.
    pub merged: bool,
    /// This frame: the round trip of the merged reply.
    pub rtt: Duration,
    /// Smoothed fixed cost of a round trip (its round trip less the compute of its classes at
    /// the coordinator's cost per class); `None` before its first merged reply.
    pub base_rtt: Option<Duration>,
}

impl PeerState {
    fn new(id: u32) -> PeerState {
        PeerState {
            id,
            benched: false,
            weight: 1.0,
            held: None,
            misses: 0,
            probe_hits: 0,
            bad_replies: 0,
            asked: 0,
            probing: false,
            points: 0,
            sent_at: None,
            settled: false,
            merged: false,
            rtt: Duration::ZERO,
            base_rtt: None,
        }
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
    /// For this frame, but the class mask or the sums are wrong: the share is settled as missing.
    Rejected,
    /// A probe answered in time: round trip `rtt`; never merged.
    Probe {
        /// Request to reply.
        rtt: Duration,
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
    /// Benched: no more work until it answers probes.
    Benched,
    /// Given work again after `unbench_after` timely probes.
    Unbenched,
}

/// The fallback for this frame's missing shares.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Fallback {
    /// The classes the coordinator recomputes locally (union of the recomputed shares).
    pub recompute: u64,
    /// The workers whose shares are recomputed.
    pub recomputed: Vec<u32>,
    /// The workers whose shares are stood in for, with the held sums to merge.
    pub stale: Vec<(u32, PartialSums)>,
}

fn config_err(field: &'static str) -> ClusterError {
    ClusterError::Config {
        field,
        message: "must be at least 1".into(),
    }
}

/// The gather state machine (see the module docs).
#[derive(Clone, Debug)]
pub struct GatherCore {
    policy: Policy,
    shape: Shape,
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
    split_stats: SplitStats,
}

impl GatherCore {
    /// A core with no workers. Errors when a count of `policy` is 0 or the class count is not
    /// in 1..=64.
    pub fn new(policy: Policy, shape: Shape) -> Result<GatherCore, ClusterError> {
        if policy.bench_after == 0 {
            return Err(config_err("bench_after"));
        }
        if policy.probe_every == 0 {
            return Err(config_err("probe_every"));
        }
        if policy.unbench_after == 0 {
            return Err(config_err("unbench_after"));
        }
        if policy.disconnect_after == 0 {
            return Err(config_err("disconnect_after"));
        }
        if !(1..=64).contains(&shape.class_points.len()) {
            return Err(ClusterError::Config {
                field: "class_count",
                message: format!("{} is outside 1..=64", shape.class_points.len()),
            });
        }
        Ok(GatherCore {
            policy,
            shape,
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
            split_stats: SplitStats::default(),
        })
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

    /// Workers given work this frame (joined, not benched), as of the latest [`GatherCore::assign`].
    pub fn active_workers(&self) -> usize {
        self.active.len()
    }

    /// The coordinator's measured cost of one class (its own share's time over its classes), for
    /// the prediction and the fallback plan.
    pub fn set_local_cost(&mut self, per_class: Duration) {
        self.per_class = per_class;
    }

    /// This frame's split decision (as of the latest [`GatherCore::assign`]).
    pub fn decision(&self) -> SplitDecision {
        self.decision
    }

    /// Frames per decision and the latest prediction.
    pub fn split_stats(&self) -> SplitStats {
        self.split_stats
    }

    /// Starts the next frame: a new sequence number. Call before membership changes and the
    /// assignment.
    pub fn begin_frame(&mut self) -> u64 {
        self.seq += 1;
        self.seq
    }

    /// Admits worker `id` (un-benched, weight 1). A known id is left as it is. Allocates.
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
        let class_count = self.shape.class_points.len() as u32;
        let (seq, probe_every) = (self.seq, self.policy.probe_every);
        for (i, peer) in self.peers.iter_mut().enumerate() {
            peer.asked = 0;
            peer.probing = false;
            peer.settled = false;
            peer.merged = false;
            peer.sent_at = None;
            if !peer.benched {
                self.active.push(i);
            } else if seq.is_multiple_of(probe_every) {
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
        for peer in &mut self.peers {
            peer.points = mask_classes(peer.asked)
                .map(|c| self.shape.class_points[c as usize])
                .sum();
        }
        masks[0]
    }

    /// Decides which shares of the split `masks` (party 0 the coordinator, then the active
    /// workers) are worth sending ([`SplitDecision`]): starting from the worker predicted
    /// slowest, a share moves to the coordinator while that does not make the predicted frame
    /// slower. Moves the kept shares into `masks[0]`; books the decision.
    fn decide(&mut self, masks: &mut [u64]) -> SplitDecision {
        if !self.policy.predict || self.active.is_empty() {
            return SplitDecision::Plain;
        }
        let c = self.per_class;
        let cost = |mask: u64| c.saturating_mul(mask.count_ones());
        // (party, predicted remote time), slowest first.
        let mut remote: Vec<(usize, Duration)> = Vec::with_capacity(self.active.len());
        let mut unknown = false;
        for (party, &i) in self.active.iter().enumerate() {
            match self.peers[i].base_rtt {
                Some(base) => remote.push((party + 1, base.saturating_add(cost(masks[party + 1])))),
                None => unknown = true,
            }
        }
        let local_all = c.saturating_mul(self.shape.class_points.len() as u32);
        if c.is_zero() || unknown || self.seq.is_multiple_of(self.policy.probe_every) {
            self.split_stats.measured += 1;
            return SplitDecision::Measure;
        }
        remote.sort_by_key(|r| std::cmp::Reverse(r.1));
        let mut local = masks[0];
        let mut kept = 0;
        for (k, &(party, time)) in remote.iter().enumerate() {
            let rest = remote.get(k + 1).map_or(Duration::ZERO, |r| r.1);
            let now = cost(local).max(time);
            let if_kept = cost(local | masks[party]).max(rest);
            if if_kept > now {
                break;
            }
            local |= masks[party];
            kept += 1;
        }
        for &(party, _) in &remote[..kept] {
            masks[party] = 0;
        }
        masks[0] = local;
        let slowest = remote.get(kept).map_or(Duration::ZERO, |r| r.1);
        self.split_stats.predicted_split_ns = nanos(cost(local).max(slowest));
        self.split_stats.predicted_local_ns = nanos(local_all);
        self.split_stats.shares_kept_local += kept as u64;
        if kept == remote.len() {
            self.split_stats.kept_local += 1;
            SplitDecision::KeptLocal
        } else {
            self.split_stats.split += 1;
            SplitDecision::Split
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
    /// settled as missing at once).
    pub fn sent(&mut self, id: u32, at: Instant, sent: bool) {
        if let Some(peer) = self.peer_mut(id) {
            peer.sent_at = Some(at);
            if !sent {
                peer.settled = true;
            }
        }
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

    /// Judges a decoded reply from worker `id` that arrived at `at`. It is merged only when it
    /// carries this frame's sequence number, answers a request not yet settled, echoes the
    /// requested class mask and passes [`PartialSums::is_plausible`] and
    /// [`PartialSums::torque_within`] for the share.
    pub fn accept(&mut self, id: u32, reply: &FrameReply, at: Instant) -> Acceptance {
        let seq = self.seq;
        let (max_depth, max_radius) = (self.shape.max_depth, self.shape.max_radius);
        let Some(peer) = self.peer_mut(id) else {
            return Acceptance::Unknown;
        };
        if reply.seq != seq {
            return Acceptance::Late;
        }
        if peer.asked == 0 || peer.settled {
            return Acceptance::Unrequested;
        }
        peer.settled = true;
        let valid = reply.classes == peer.asked
            && reply.sums.is_plausible(peer.points, max_depth)
            && reply.sums.torque_within(max_radius, max_depth);
        if !valid {
            peer.bad_replies = peer.bad_replies.saturating_add(1);
            return Acceptance::Rejected;
        }
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
            peer.held = Some(HeldShare {
                classes: peer.asked,
                sums: reply.sums,
                seq,
            });
            Acceptance::Merged { rtt }
        }
    }

    /// Books the frame's outcome per worker at the reply `deadline`: a probe streak long enough
    /// un-benches; a merged share adapts the weight against the time the worker had (request
    /// sent to `deadline`); a missed share halves it, counts towards the bench and is listed for
    /// [`GatherCore::plan_fallback`]. Returns the transitions (worker id, what changed).
    pub fn settle(&mut self, deadline: Instant) -> &[(u32, Transition)] {
        self.missing.clear();
        self.transitions.clear();
        for (index, peer) in self.peers.iter_mut().enumerate() {
            if peer.asked == 0 {
                continue;
            }
            if peer.probing {
                let answered = peer.settled && peer.probe_hits > 0;
                if !answered {
                    peer.probe_hits = 0;
                }
                if peer.probe_hits >= self.policy.unbench_after {
                    peer.benched = false;
                    // Back with a cautious share; it grows while the worker keeps up.
                    peer.weight = self.adapt.min_weight.max(0.5);
                    peer.misses = 0;
                    peer.probe_hits = 0;
                    self.transitions.push((peer.id, Transition::Unbenched));
                }
                continue;
            }
            if peer.merged {
                peer.misses = 0;
                // The round trip's fixed part, smoothed by 1/8 as TCP smooths its RTT.
                let compute = self.per_class.saturating_mul(peer.asked.count_ones());
                let base = peer.rtt.saturating_sub(compute);
                peer.base_rtt = Some(match peer.base_rtt {
                    Some(old) => old.saturating_mul(7).saturating_add(base) / 8,
                    None => base,
                });
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
            let stale_age = match peer.held {
                Some(held) if held.classes == peer.asked => Some(self.seq - held.seq),
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
            if peer.misses >= self.policy.bench_after && !peer.benched {
                peer.benched = true;
                peer.probe_hits = 0;
                self.transitions.push((peer.id, Transition::Benched));
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
            match (action, peer.held) {
                (FallbackAction::ReuseStale, Some(held)) => {
                    self.fallback.stale.push((peer.id, held.sums));
                }
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
