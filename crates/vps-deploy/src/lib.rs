//! The cluster services' configuration: what a long-lived `vps coordinator` or `vps worker`
//! reads from its `--config` file ([`service_files`]), and the ready layout `vps deploy init`
//! writes for a list of hosts or a loopback rehearsal ([`layout`]): per host its certificate and
//! key, the pinned peers' certificates and its config file.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod layout;
pub mod service_files;
