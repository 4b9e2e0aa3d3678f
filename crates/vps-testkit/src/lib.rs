//! Shared fixtures for the tests of the vps workspace (`publish = false`, used only as a
//! dev-dependency).
//!
//! - [`scene`]: hand-made voxmaps (the flat test wall, small grids) and the wall as a lookup
//!   that runs a hook once armed (to make lookups panic or stall on chosen threads).
//! - [`shell`]: point shells (the Fibonacci sphere shell and its directions).
//! - [`device`]: a device wrapper that logs every write and fails or trips on demand.
//! - [`full_stdout`]: the check that a command writing to a full stdout fails cleanly.
//! - [`hand`]: the scripted simulated hand that approaches the wall and rests on it.
//! - [`obj`]: mesh files as test input (the OBJ text of a box).
//! - [`parts`]: scenes of two moving parts (`left` and `right`) as scene-file text.
//! - [`scene_edit`]: bad variants of a good scene file's text, each with the field its error
//!   must name.
//! - [`table`]: the CSV tables the binary writes, read back as numbers by column name.
//! - [`process`]: running the `vps` binary from the root package's tests with a private cache
//!   directory (`VPS_CACHE_DIR`), so that tests never write into the user's cache.
//! - `cluster` (feature `cluster`): the standard one-process session and a loopback coordinator,
//!   for the cluster tests of `vps-cluster` and of the root package.
//!
//! None of this is on a frame path; everything may allocate and panic on failure (these are
//! test fixtures).
//!
//! Where this crate sits in vps: `docs/architecture.md#crates` at the repository root.

#![warn(missing_docs)]

#[cfg(feature = "cluster")]
pub mod cluster;
pub mod device;
pub mod full_stdout;
pub mod hand;
pub mod obj;
pub mod parts;
pub mod process;
pub mod scene;
pub mod scene_edit;
pub mod shell;
pub mod table;
