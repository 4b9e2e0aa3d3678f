//! The exact contact reference that the voxel force is held against (docs/fidelity.md).
//!
//! For a part pose, every shell point is measured against the static triangle meshes themselves
//! (not the voxmap): signed distance to the nearest triangle through a bounding-volume hierarchy,
//! sign from angle-weighted pseudo-normals (Bærentzen and Aanæs 2005), positive outside. The sum
//! of `depth × outward normal` over the points closer than a chosen offset gives the reference
//! force direction and magnitude (see [`reference_contact`]).
//!
//! Module map:
//! - [`bvh`]: a median-split AABB tree with branch-and-bound nearest queries.
//! - closest point on a triangle and its feature: [`vps_mesh::closest_point`].
//! - [`components`]: connected components of a mesh and whether each is closed and oriented.
//! - [`orient`]: triangles turned to face outward (for the winding number of meshes written
//!   clockwise or in mixed order).
//! - [`scene`]: [`ExactScene`], [`SignedDistance`].
//! - [`contact`]: [`reference_contact`], [`ReferenceContact`].
//! - [`clearance`]: [`RigidClearance`], the exact distance between a posed part's mesh and each
//!   static object's mesh.
//! - [`winding`]: the generalized winding number, exact and fast hierarchical ([`winding::WindingTree`]).
//!
//! What the sign means: each connected component (triangles sharing vertex indices) that is closed
//! and consistently oriented is a solid; its signed distance is negative inside. The scene's value
//! is the minimum over components (the union of solids): outside every solid it is the exact
//! distance; inside overlapping solids it is the largest single-component depth, a lower bound on
//! the distance to the union's boundary. A component that is open or inconsistently oriented (a
//! sheet, the tessellated Bezier teapot) has no inside: its distance is unsigned (never negative)
//! and [`ExactScene::unsigned_components`] counts such components. All lengths are metres.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod bvh;
pub mod clearance;
pub mod components;
pub mod contact;
pub mod orient;
pub mod scene;
pub mod winding;

pub use clearance::{Closest, RigidClearance};
pub use contact::{reference_contact, reference_contact_points, ReferenceContact};
pub use scene::{ExactScene, SignedDistance};

/// Why an [`ExactScene`] cannot be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ReferenceError {
    /// No mesh, or only meshes without triangles.
    #[error("the exact reference needs at least one mesh with triangles")]
    Empty,
    /// A triangle names a vertex that does not exist.
    #[error(
        "mesh {mesh}, triangle {triangle}: vertex index {index} out of range ({vertices} vertices)"
    )]
    VertexIndex {
        /// Mesh index in the slice given.
        mesh: usize,
        /// Triangle index in that mesh.
        triangle: usize,
        /// The bad index.
        index: u32,
        /// Vertices in that mesh.
        vertices: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("mesh {mesh}, vertex {vertex}: {value} is not finite")]
    NonFinite {
        /// Mesh index.
        mesh: usize,
        /// Vertex index.
        vertex: usize,
        /// The coordinates.
        value: glam::DVec3,
    },
}
