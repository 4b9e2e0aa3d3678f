//! Sessions from scene files: one TOML file describes the static objects, the part, the voxel
//! settings, the haptic parameters, the simulated hand's path and the default device
//! ([`file::SceneFile`]); [`scene::LoadedScene`] loads and places its meshes; [`scene::SessionAssets`]
//! holds the built voxmap (cached on disk, [`cache`]), point shell, parameters, device choice and
//! hand plan; and [`plan::SessionPlan`] is the one way the runtime's `SessionSetup` is made.
//!
//! Module map: [`file`](mod@file) (the scene file), [`mesh_source`] (mesh files and built-ins, placed),
//! [`length`] (lengths with unit suffixes), [`hints`] (a CAD user's likely slips),
//! [`estimate`] (a voxmap's cost before it is built),
//! [`cache`] (the voxmap cache), [`scene`] (scene file → [`LoadedScene`] → [`SessionAssets`]),
//! [`script`] (the simulated hand's scripts), [`start_pose`] (a part
//! that starts inside a static object), [`device`] (the device a session is driven by),
//! [`parts`] (the moving parts after the first, `[[part]]`), [`plan`] ([`SessionPlan`], signal
//! handlers), [`sweep_file`] (the sweep file), [`error`]
//! ([`SceneError`]).
//!
//! Units: metres, kilograms, seconds throughout; mesh files may declare cm, mm or inches.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod cache;
pub mod device;
pub mod error;
pub mod estimate;
pub mod hints;
pub mod mesh_source;
pub mod parts;
pub mod plan;
pub mod scene;
pub mod script;
pub mod start_pose;

/// The scene file's schema (from `vps-scene-file`).
pub use vps_scene_file::file;
/// Lengths with units (from `vps-scene-file`).
pub use vps_scene_file::length;
/// The sweep file's schema (from `vps-scene-file`).
pub use vps_scene_file::sweep_file;

// The scene file's part count and the runtime's are one bound.
const _: () = assert!(file::MAX_PARTS == vps_runtime::MAX_OTHER_PARTS + 1);

pub use cache::CachePolicy;
pub use device::{BridgeSettings, DeviceChoice, OpenedDevice, ReplaySource};
pub use error::SceneError;
pub use file::SceneFile;
pub use plan::{stop_on_signals, SessionPlan};
pub use scene::{BuildOptions, HandPlan, LoadedScene, PartView, SessionAssets, DEFAULT_SCENE};

use std::sync::Arc;
use vps_haptic::ClassedShell;
use vps_voxmap::PointShell;

/// Classes the shell is split into. Fixed, independent of the thread count: a class is the unit
/// of work and of exact summation, so the same class count gives a bit-identical wrench however
/// the classes are spread over threads or worker processes.
pub const CLASS_COUNT: u32 = 64;

/// A moving part's point shell (in its grip frame) and the same shell split into
/// [`CLASS_COUNT`] classes for the kernel, built together once: whatever samples the part (the
/// loop's pools, a study, the cluster's assets) shares the one split. Immutable; a new shell is a
/// new `PartShell`.
#[derive(Clone)]
pub struct PartShell {
    points: PointShell,
    classed: Arc<ClassedShell>,
}

impl PartShell {
    /// Splits `points` into classes. Allocates; setup-time only.
    pub fn new(points: PointShell) -> PartShell {
        let classed = Arc::new(ClassedShell::new(&points, CLASS_COUNT));
        PartShell { points, classed }
    }

    /// The points and normals (m, grip frame) with the part's mass properties.
    pub fn points(&self) -> &PointShell {
        &self.points
    }

    /// The shell split into [`CLASS_COUNT`] classes (shared, not copied).
    pub fn classed(&self) -> Arc<ClassedShell> {
        self.classed.clone()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether the shell has no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}
