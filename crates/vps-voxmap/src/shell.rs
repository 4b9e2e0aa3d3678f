//! The point shell of the dynamic object (docs/architecture.md#voxmaps-and-point-shells): surface points with inward unit normals in the
//! body frame, whose origin is the object's centre of mass as built (a session may move it to the
//! part's grip, `vps_session::LoadedScene::build_shell`).

use glam::{DVec3, Vec3};

/// Mass properties of the dynamic object, from its mesh and a density.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MassProperties {
    /// Enclosed volume (m³).
    pub volume: f64,
    /// Centre of mass in the mesh's own frame (m).
    pub center_of_mass: DVec3,
    /// Radius of the smallest COM-centred sphere containing the mesh (m).
    pub bounding_radius: f64,
}

/// How shell points were placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum ShellMethod {
    /// Centres of the object's Surface voxels (the paper's method).
    VoxelCentres = 0,
    /// One point per Surface voxel on the exact mesh surface (closest point to the voxel centre).
    ExactSurface = 1,
}

/// The point shell. Invariants: `points.len() == normals.len()`, every normal is finite and unit
/// length, or exactly zero for every point of a part with no inside (two-sided: the distance force
/// model pushes such a point along the scene's normal; `vps_session::LoadedScene::part_two_sided`),
/// points are in the body frame (m), Morton ordered. The body origin is the centre of mass
/// as built by the voxelizer; a session's shell has its origin at the part's grip instead
/// (`vps_session::LoadedScene::build_shell` shifts the points, not `mass`).
#[derive(Clone, Debug, PartialEq)]
pub struct PointShell {
    /// Body-frame points (m), f32 for the sampling kernel.
    pub points: Vec<Vec3>,
    /// Inward unit normals, one per point (all zero for a two-sided part).
    pub normals: Vec<Vec3>,
    /// The voxel size the shell was sampled at (m).
    pub voxel_size: f64,
    /// How the points were placed.
    pub method: ShellMethod,
    /// Mass properties of the source mesh, in the mesh's own frame (its COM is the body origin
    /// unless the points were shifted to a grip).
    pub mass: MassProperties,
}

impl PointShell {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// True for a shell with no points.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// Largest distance of a point from the body origin (m), for the tunnelling guard.
    pub fn max_radius(&self) -> f64 {
        self.points
            .iter()
            .map(|p| p.length() as f64)
            .fold(0.0, f64::max)
    }
}
