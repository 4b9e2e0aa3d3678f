//! A network device bridge: a separate process streams handle poses in over UDP and receives the
//! commanded wrenches back, so any tracker, robot or script can drive the haptic loop.
//!
//! Module map: [`protocol`] (datagram format), [`config`] ([`BridgeConfig`]), [`error`] ([`BridgeError`]),
//! [`mapping`] ([`WorkspaceMapping`]: device workspace → scene, forces back, re-anchoring),
//! [`device`] ([`BridgeDevice`], the `HapticDevice`: clutch and pose timeout), [`monitor`]
//! ([`BridgeMonitor`]: counters and sent wrenches, readable after the device moved into the
//! loop), [`client`] ([`BridgeClient`]).
//!
//! Security: by default the device binds a loopback address and accepts any local sender (the
//! token field is ignored when no token is configured). Binding any other address (including
//! `0.0.0.0`) requires `allow_remote = true` and a non-zero 16-byte shared token; every datagram
//! must then carry that token, compared in constant time, and the device's replies carry it too.
//! The token only authenticates (no encryption, no replay protection beyond the sequence check):
//! use it on a trusted network.

pub mod client;
pub mod config;
pub mod device;
pub mod error;
pub mod mapping;
pub mod monitor;
pub mod protocol;

pub use client::{BridgeClient, WrenchReply};
pub use config::{parse_token_hex, BridgeConfig};
pub use device::BridgeDevice;
pub use error::BridgeError;
pub use mapping::{Anchor, WorkspaceMapping};
pub use monitor::{BridgeCounters, BridgeMonitor, SentWrench};
pub use protocol::{Datagram, Message, ProtocolError, Token};
