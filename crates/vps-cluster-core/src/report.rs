//! The split's figures as plain data ([`SplitReport`]), kept by the gather core and reported in
//! the cluster's session report (`vps_cluster::ClusterReport::split`). Serialisable (serde), no
//! behaviour.

/// How the coordinator split its frames and why ([`crate::gather::SplitDecision`]); all zero
/// with the prediction off. A frame is split when the predicted split time is below the
/// predicted local time.
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SplitReport {
    /// Frames whose classes were split (some shares possibly kept local) because that was
    /// predicted faster.
    pub split_frames: u64,
    /// Frames kept wholly local because the split was predicted no faster (or no worker was
    /// measured yet).
    pub kept_local_frames: u64,
    /// Worker shares kept on the coordinator because their round trip would have cost more than
    /// it saved (or the worker was not measured yet), summed over frames.
    pub shares_kept_local: u64,
    /// Probes sent to workers given no share, never awaited by a frame.
    pub probes: u64,
    /// Of those, answered with sums equal to the coordinator's (round-trip samples).
    pub probe_replies: u64,
    /// Of those, answered wrongly or not within `probe_every` frames.
    pub probes_failed: u64,
    /// The coordinator's latest cost of one class (ns).
    pub per_class_ns: u64,
    /// The latest smallest pessimistic fixed round-trip cost of a measured worker: smoothed
    /// round trip less its compute plus 4 mean deviations, at most the reply window (ns; 0:
    /// none measured).
    pub worker_base_ns: u64,
    /// The latest predicted time of the split frame (ns): the slowest of the coordinator's own
    /// share and each worker's fixed round-trip cost plus its share's compute.
    pub predicted_split_ns: u64,
    /// The latest predicted time of the frame computed wholly on the coordinator (ns).
    pub predicted_local_ns: u64,
}
