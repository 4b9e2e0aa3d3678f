//! The application layer of vps: one way to prepare and run a session, used by every session
//! command of the `vps` binary and by its benchmarks.
//!
//! A [`SessionRequest`] (the scene and the command line's overrides, no parser in it) is made
//! into a [`Prepared`] session by [`prepare()`] (outputs checked, scene built once, device opened,
//! loop settings fixed), which [`Prepared::run`] runs on a [`Backend`]: this process's threads or
//! a coordinator with workers ([`cluster`]). Its end ([`finish()`]) writes the recording, report
//! and study ([`study`]) and prints the figures.
//!
//! Module map: [`request`] (what is asked), [`prepare`](mod@prepare) (scene, device, plan),
//! [`run`](mod@run) (backends), [`cluster`] (coordinated sessions), [`demo`] (`vps demo`: the main job), [`scripted`] (the simulated
//! hand's scripted session of `vps demo` and the benchmarks), [`finish`](mod@finish) (a session's
//! end: files and figures), [`session_files`] (the files a session writes, checked first),
//! [`study`] (a session's assembly study), [`study_view`] (a study as the viewer's page scrubs
//! it), [`scene_view`] (what the viewer draws of a scene), [`parts_report`] (the per-part lines
//! of a report), [`output`] (stdout, JSON, output
//! files), [`exit`] (exit statuses), [`limits`] (bounds on what a command line asks).
//!
//! Units: SI (m, s, N, N·m) unless a name says otherwise (`_ms`, `_us`, `_deg`).
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod cluster;
pub mod demo;
pub mod exit;
pub mod finish;
pub mod kernel_timing;
pub mod limits;
pub mod output;
pub mod parts_report;
pub mod prepare;
pub mod request;
pub mod run;
pub mod scene_check;
pub mod scene_view;
pub mod scripted;
pub mod session_files;
pub mod study;
pub mod study_view;

pub use cluster::{ClusterBackend, CoordinatedRun, Workers, DEFAULT_JOIN_WAIT};
pub use finish::finish;
pub use prepare::{prepare, LiveSession, Prepared};
pub use request::{BridgeOverrides, SceneRequest, SessionRequest};
pub use run::Backend;
