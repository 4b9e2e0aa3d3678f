//! The file formats a person writes for vps: scene files ([`file::SceneFile`]: the static
//! objects, the moving parts, their hands and devices, the voxel settings, in units the file
//! names) and sweep files ([`sweep_file::SweepFile`]), read with bounds on size and structure
//! and checked field by field: every error names the file, the line when the parser places it,
//! the dotted field and the allowed range ([`error::SceneError`]).
//!
//! This crate is the schema only: it depends on no device, runtime or network crate, so a tool
//! that reads or writes scene files needs none of them. Building a scene's voxmap and shell and
//! opening its devices is `vps-session`'s (which also checks the device settings' ranges against
//! the device layer's, when it makes a session's devices).
//!
//! Module map: [`file`](mod@file) (scene files), [`sweep_file`] (sweep files), [`device_kind`] (a device's
//! `kind` as written), [`length`] (lengths with units, `5mm`), [`error`] (what is wrong, where).
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod device_kind;
pub mod error;
pub mod file;
pub mod length;
pub mod sweep_file;

pub use error::SceneError;
pub use file::SceneFile;
