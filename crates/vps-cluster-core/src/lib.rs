//! The vps cluster's sans-IO core (docs/architecture.md#exact-sums-and-the-cluster), as
//! quinn-proto is under quinn: everything the cluster decides, and nothing that waits. No socket,
//! clock read, thread, channel or async runtime is here (`.ci/run` checks the dependency tree for
//! network and runtime crates); callers pass the times in (`Instant`s they read) and do the I/O.
//! `vps-cluster` drives it over QUIC.
//!
//! Module map: [`protocol`] (the frame datagrams and join messages, strict decoding), [`frame`]
//! (a frame as four events: start, own share done, each datagram, deadline), [`gather`]
//! ([`GatherCore`]: per frame, class assignment, reply acceptance, sidelining, the fallback plan,
//! the predicted split), [`split`] (dealing classes by adapted weights) and [`fallback`] (which
//! missing shares are recomputed and which stood in for), [`report`] ([`SplitReport`]),
//! [`sideline_log`] and [`join_log`] (how often the log speaks of a worker being sidelined and
//! reinstated, and of a worker's failed joins). A worker is *sidelined* (given no share, only
//! probes) after consecutive missed shares and *reinstated* after timely probes; "bench" means a
//! benchmark only.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod fallback;
pub mod frame;
pub mod gather;
pub mod join_log;
pub mod protocol;
pub mod report;
pub mod sideline_log;
pub mod split;

pub use gather::GatherCore;
pub use report::SplitReport;

/// A gather setting out of its range.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("config `{field}`: {message}")]
pub struct ConfigError {
    /// The setting.
    pub field: &'static str,
    /// What is wrong with it.
    pub message: String,
}
