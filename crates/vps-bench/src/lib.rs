//! The benchmarks of vps, one module per `vps bench` subcommand. Each runs real sessions, sockets
//! or kernels (sessions through the application layer, `vps-app`) and prints a report, as text
//! or as the JSON that `docs/results/` keeps, with the command that produced it and the machine's
//! state beside every timing ([`machine`]). Timings belong here, never in pass/fail tests.
//!
//! Module map: [`kernel`] (ns per contact point; its synthetic case is `vps_app::kernel_timing`, also
//! timed by `vps scene check`), [`frame_loop`] (`vps bench loop`: the 1 kHz loop end to end),
//! [`parts`] (several moving parts), [`cluster`] (a paced session over local worker processes),
//! [`transport`] (gather round trip beside raw UDP), [`scaling`] (points per frame over threads
//! and workers), [`bridge`] (the UDP device bridge's round trip), [`viewer`] (the viewer's cost
//! on the loop), [`voxelize`] (voxelizer time and memory, tree memory), [`host`] (how often the
//! machine takes the frame thread's core away), [`fidelity`] (the analytic benchmark),
//! [`sweep`] (speed against accuracy over voxel settings, with its [`sweep::session`]s, text and
//! plots), [`tune`] (the finest voxel size this machine runs in budget), [`svg`] (plots),
//! [`machine`] (load and idle settings recorded beside timings).
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

pub mod bridge;
pub mod cluster;
pub mod fidelity;
pub mod frame_loop;
pub mod host;
pub mod kernel;
pub mod machine;
pub mod parts;
pub mod scaling;
pub mod svg;
pub mod sweep;
pub mod transport;
pub mod tune;
pub mod viewer;
pub mod voxelize;
