//! The vps cluster (docs/architecture.md#exact-sums-and-the-cluster): a coordinator that owns the device and the 1 kHz frame loop, and
//! workers that hold a copy of its assets (the scene's voxmap and the part's classed point shell,
//! [`ClusterAssets`]) and compute the class shares they are sent, over QUIC (quinn) with
//! operator-pinned mutual TLS.
//!
//! Topology: workers dial the coordinator (the QUIC server), so workers can join at any time and
//! `vps cluster --local-workers N` only needs the coordinator's address. Joining uses one reliable
//! stream (version check, the assets' identity by content hash, the voxmap and shell files shipped
//! when the worker lacks them); frames use unreliable datagrams (pose + class mask out, partial
//! sums back).
//!
//! The frame thread never waits on a tokio timer: [`RemoteShares`] (a
//! [`vps_runtime::FrameSampler`]) sends the requests, computes the coordinator's own share on local
//! threads, waits on a crossbeam channel until shortly before the deadline and then spins, and
//! computes every share still missing locally, or, when that cannot finish before the device
//! write is due, stands in for it with that share's sums from up to 3 frames earlier (by default;
//! counted, [`fallback`]). Partial sums are integers, so the result is bit-identical to a
//! one-process run whoever computed each share, in every frame without such a stand-in
//! ([`fallback::StalePolicy::NEVER`] rules them out).
//!
//! Everything the cluster decides without waiting (the wire formats, the gather state machine,
//! split and fallback arithmetic, the log-rate rules) is the sans-IO crate `vps-cluster-core`,
//! whose modules are re-exported here under their old names: [`gather`], [`split`],
//! [`fallback`], [`sideline_log`], [`join_log`], and the codecs in [`protocol`]. This crate is its
//! I/O driver.
//!
//! Module map: [`protocol`] (wire formats, and the join stream's framing on QUIC), [`tls`]
//! (certificates, pinning verifiers, QUIC configs), [`assets`] ([`ClusterAssets`]: voxmap,
//! classed shell, identity, worker cache), [`worker`] ([`run_worker`]), [`coordinator`]
//! ([`Coordinator`]: endpoint, joins, one live connection per certificate), [`shares`]
//! ([`RemoteShares`]: the I/O driver around the gather core), [`metrics`] and [`report`] (live
//! figures and the final report), [`close`] (close codes), [`session`] ([`run_coordinator_session`],
//! [`spawn_local_workers`]), [`udp_count`] (datagrams counted on the UDP socket before quinn sees
//! them). The loopback impairment relay and the raw UDP baseline are in the `vps-netem` crate.

#![warn(missing_docs)]

pub mod assets;
pub mod close;
pub mod coordinator;
mod events;
pub mod metrics;
pub mod protocol;
pub mod report;
pub mod session;
pub mod shares;
pub mod tls;
pub mod udp_count;
pub mod worker;

// The sans-IO core's modules, under the names this crate has always given them.
pub use vps_cluster_core::{fallback, frame, gather, join_log, sideline_log, split};

pub use assets::ClusterAssets;
pub use coordinator::{Coordinator, CoordinatorConfig};
pub use metrics::ClusterMetrics;
pub use report::{ClusterReport, PeerReport, SplitReport};
pub use session::{
    local_cluster_certs, run_coordinator_session, spawn_local_workers, LocalCerts, LocalWorkerArgs,
    LocalWorkers,
};
pub use shares::{GatherConfig, RemoteShares};
pub use tls::{make_cert, CertFiles, PeerTls, TlsIdentity};
pub use worker::{
    run_worker, run_worker_service, run_worker_until, Rejoin, WorkerConfig, WorkerReport,
    WorkerService,
};

use std::path::PathBuf;

/// Why a cluster operation failed.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    /// Certificate generation, loading or TLS configuration.
    #[error("TLS: {0}")]
    Tls(String),
    /// Reading or writing a file.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// The QUIC endpoint or connection.
    #[error("network: {0}")]
    Network(String),
    /// The join exchange failed (version, assets' identity, malformed message, refused).
    #[error("join: {0}")]
    Join(String),
    /// The coordinator and this worker refuse each other for good (a certificate not pinned on
    /// one side, a duplicate identity, an incompatible protocol): retrying cannot help until an
    /// operator acts.
    /// The message says who refused and why.
    #[error("{0}")]
    Refused(String),
    /// The cluster's assets (voxmap, classed shell, their files) cannot be built, encoded, read
    /// or used; the message says which.
    #[error("scene: {0}")]
    Scene(String),
    /// A configuration value is invalid.
    #[error("config `{field}`: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The frame loop failed to start or finish.
    #[error(transparent)]
    Runtime(#[from] vps_runtime::RuntimeError),
}

impl From<vps_cluster_core::ConfigError> for ClusterError {
    fn from(e: vps_cluster_core::ConfigError) -> ClusterError {
        ClusterError::Config {
            field: e.field,
            message: e.message,
        }
    }
}
