//! The cluster's figures as plain data: [`ClusterReport`] (a session's counters and every worker)
//! and [`PeerReport`] (one worker). The gatherer ([`crate::shares`]) leaves the final report, the
//! live [`ClusterMetrics`](crate::ClusterMetrics) handle ([`crate::metrics`]) reads snapshots of
//! the same shape. Serialisable (serde), no behaviour.

pub use vps_cluster_core::SplitReport;
use vps_runtime::Percentiles;

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
    /// Times the worker was sidelined.
    pub sidelined_times: u64,
    /// Times a sidelined worker was given work again.
    pub reinstated_times: u64,
    /// Sidelined at the time of the report.
    pub sidelined: bool,
    /// Still connected at the time of the report.
    pub connected: bool,
    /// The coordinator closed its connection for bad replies ([`GatherConfig::disconnect_after`](crate::GatherConfig::disconnect_after)).
    pub disconnected_for_bad_replies: bool,
    /// The coordinator sent it the voxmap or shell file at join (false: it had both in its
    /// cache). The name predates the cluster assets; it is a key of the session report.
    pub scene_sent: bool,
    /// Round-trip samples in `rtt_ns`.
    pub rtt_samples: u64,
    /// Request-to-reply time of timely, valid replies (ns), from an HDR histogram (1 % resolution).
    pub rtt_ns: Percentiles,
    /// Classes asked of it in the latest frame (its adapted share; 0 while sidelined).
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
    /// Sampling jobs gathered, summed over frames ([`vps_haptic::job`]): one a frame for one
    /// part; with several, one per part and two per pair the broad phase kept.
    pub job_samples: u64,
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
    /// How the work was split and why ([`GatherConfig::predict`](crate::GatherConfig::predict)).
    #[serde(default)]
    pub split: SplitReport,
    /// Every worker seen, by id (join order).
    pub peers: Vec<PeerReport>,
}
