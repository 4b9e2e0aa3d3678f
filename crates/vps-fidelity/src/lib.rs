//! The analytic fidelity benchmark of vps (in the manner of Weller et al.'s 6-DOF collision-response
//! benchmark): scenes whose true contact force and torque follow from geometry, swept over poses at
//! set separations, the voxel force and torque compared with the exact answer.
//!
//! Module map:
//! - [`scenes`]: the five scenes (sphere on a plane, a tilted box on a plane, a box in a 90°
//!   corner, a peg in a hole with clearance, a cylinder in a 90° V wedge) and their poses.
//! - [`clearance`]: a square and a round peg pushed into holes of sub-voxel to two-voxel
//!   clearance through the haptic frame, both force models.
//! - [`held`]: a part held by a simulated hand, stepped through the haptic frame and measured
//!   against the exact meshes frame by frame (the clearance benchmark's, the tunnelling test's).
//! - [`measure`]: one setting (voxel size, bits per voxel, shell method) measured over every scene,
//!   and the sliding-box smoothness run; [`run`] over a grid of settings.
//!
//! The exact answer is `vps_reference::reference_contact`: the same penalty law as the voxel field,
//! `K_ff Σ e_i n_i`, with exact signed distances to the meshes, so its direction and torque are the
//! geometry's (checked against the analytic direction of each scene by this crate's tests).
//! Everything here is offline (blocking, allocating, parallel with rayon).
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod clearance;
pub mod held;
pub mod measure;
pub mod scenes;

pub use measure::{
    run, FidelityGrid, FidelityReport, ForceModel, SceneFigures, SettingRow, SlideFigures,
};
pub use scenes::SceneKind;

/// Why a benchmark setting could not be built.
#[derive(Debug, thiserror::Error)]
pub enum FidelityError {
    /// Voxelizing the obstacles or building the part's shell failed.
    #[error("{scene} at {voxel_size_m} m: {source}")]
    Voxelize {
        /// The scene.
        scene: &'static str,
        /// The voxel size (m).
        voxel_size_m: f64,
        /// The voxelizer's error.
        source: vps_voxelize::VoxelizeError,
    },
    /// The distance band of the obstacles could not be built.
    #[error("{scene}: distance band: {source}")]
    Band {
        /// The scene.
        scene: &'static str,
        /// The builder's error.
        source: vps_voxelize::distance::BandBuildError,
    },
    /// The exact reference rejected the obstacle meshes.
    #[error("{scene}: exact reference: {source}")]
    Reference {
        /// The scene.
        scene: &'static str,
        /// The reference's error.
        source: vps_reference::ReferenceError,
    },
    /// A parameter is out of range.
    #[error("{0}")]
    Params(#[from] vps_haptic::ParamsError),
    /// The grid asks for something the benchmark cannot do.
    #[error("invalid benchmark grid: {0}")]
    Grid(String),
}
