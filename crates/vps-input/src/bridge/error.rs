//! [`BridgeError`]: why a bridge could not be set up or used (configuration, socket).

use std::net::SocketAddr;

/// Why a bridge could not be set up or used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BridgeError {
    /// An invalid configuration field.
    #[error("bridge config field `{field}`: {message}")]
    Config {
        /// The field name.
        field: &'static str,
        /// What is wrong with it.
        message: String,
    },
    /// The socket could not be bound.
    #[error("cannot bind UDP socket to {addr}: {message}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// The OS message.
        message: String,
    },
    /// A socket operation failed.
    #[error("bridge socket {what} failed: {message}")]
    Io {
        /// Which operation ("send", "receive", "set non-blocking", ...).
        what: &'static str,
        /// The OS message.
        message: String,
    },
}

impl BridgeError {
    pub(crate) fn io(what: &'static str, e: std::io::Error) -> Self {
        Self::Io {
            what,
            message: e.to_string(),
        }
    }
}
