//! Network rehearsal tools for the vps cluster, independent of it: [`relay`] (a userspace UDP
//! relay on loopback that adds a seeded delay, jitter and loss, what `vps netem-relay` runs) and
//! [`transport_bench`] (the raw UDP ping-pong baseline of `vps bench transport`). See
//! docs/architecture.md#exact-sums-and-the-cluster for the cluster they rehearse.

#![warn(missing_docs)]

pub mod relay;
pub mod transport_bench;

pub use relay::{Relay, RelayConfig, RelayStats};

/// Why a relay could not start.
#[derive(Debug, thiserror::Error)]
pub enum NetemError {
    /// A socket or thread failed.
    #[error("network: {0}")]
    Network(String),
    /// A configuration value is invalid.
    #[error("config `{field}`: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
}
