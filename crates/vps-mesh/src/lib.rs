//! Triangle meshes for vps.
//!
//! All coordinates are metres (SI), in f64 so that voxelization of a 3 m scene at sub-millimetre voxels
//! keeps full precision. A [`TriMesh`] is an indexed triangle list; it may be open (the scan converter
//! and flood fill do not need watertight input).
//!
//! Module map:
//! - [`mesh`]: the [`TriMesh`] type, bounds, transforms.
//! - [`validate`](mod@validate): checks with errors naming the element at fault.
//! - [`load`]: OBJ, STL (binary and ASCII), PLY readers.
//! - [`builtin`]: deterministic built-in scenes (teapot, aircraft bay) and primitives.
//! - [`weld`]: merging coincident vertices.
//! - [`closest_point`](mod@closest_point): the point of a triangle nearest to a point.
//! - [`health`]: whether a mesh is closed, and what is wrong when it is not.
//! - [`union_find`]: connected pieces over vertex ids.
//! - [`triangle_distance`](mod@triangle_distance): the nearest points of two triangles.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod builtin;
pub mod closest_point;
pub mod health;
pub mod load;
pub mod mesh;
pub mod triangle_distance;
pub mod union_find;
pub mod validate;
pub mod weld;

pub use health::{mesh_health, MeshHealth};
pub use load::{
    load_mesh, load_mesh_scaled, load_mesh_with, parse_mesh, parse_step, LoadedMesh, MeshFormat,
    StepSettings, StepSummary, DEFAULT_STEP_CHORD_TOLERANCE, DEFAULT_STEP_MAX_TRIANGLES,
};
pub use mesh::{Aabb, TriMesh};
pub use validate::{validate, MeshError, ValidationReport};
pub use weld::weld_vertices;
