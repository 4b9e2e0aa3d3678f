//! Voxelization of static scenes and point shells of dynamic objects (docs/architecture.md#voxmaps-and-point-shells).
//!
//! Pipeline, one module per step:
//! - [`tri_box`]: exact triangle / box overlap (13-axis separating axis test).
//! - `scan_convert`: voxels overlapped by triangles become Surface (parallel over triangles).
//! - `flood_fill`: Free space flooded from the box walls, 6-connected; the rest is Interior.
//! - `winding`: open parts classified by generalized winding number, and flood-fill seeds on walls
//!   cut by the grid (a workspace) kept to the outside.
//! - `proximity`: Free 26-neighbours of Surface.
//! - `offset`: the force layer grown outward by `k` layers.
//! - `merge`: objects combined by precedence Interior > Surface > Proximity > Free.
//! - [`pipeline`]: [`voxelize`] and friends, options, statistics.
//! - [`sparse`]: the chunked pipeline behind [`voxelize_tree`]: same voxels, memory that follows
//!   the surface, optional distance layers (4- and 8-bit voxels).
//! - [`distance`]: the signed-distance band (the `distance` force model) from the exact triangles.
//! - [`mass`]: volume, centre of mass and bounding radius of a mesh.
//! - [`shell`]: the point shell of the dynamic object.
//! - [`memory`]: working-memory estimates made before any voxel is computed, and the budget.
//! - [`stats`]: what one voxelization measured; [`error`]: why it failed.
//!
//! Internally every step works on bit planes (one bit per voxel, rows padded to 64-bit words), so a
//! 72-million-voxel scene needs about 9 MB per plane and word operations handle 64 voxels at once.
//! All lengths are metres.

#![warn(missing_docs)]

mod bitgrid;
pub mod distance;
pub mod error;
mod flood_fill;
pub mod mass;
pub mod memory;
mod merge;
mod offset;
pub mod pipeline;
mod proximity;
mod scan_convert;
pub mod shell;
pub mod sparse;
pub mod stats;
pub mod tri_box;
mod winding;

pub use error::{VoxelizeError, MAX_SPARSE_VOXELS, MAX_VOXELS};
pub use mass::{is_closed_and_oriented, mass_properties};
pub use memory::{default_memory_budget, MemoryEstimate};
pub use pipeline::{
    clip_to_workspace, grid_for, inside_map_in, tree_grid, voxelize, voxelize_in,
    voxelize_in_with_stats, voxelize_tree, voxelize_tree_in, voxelize_tree_keeping_inside,
    voxelize_with_stats, VoxelizeOptions,
};
pub use shell::{point_shell, point_shell_within};
pub use sparse::InsideMap;
pub use stats::VoxelizeStats;
pub use tri_box::triangle_box_overlap;
pub use vps_voxmap::shell::ShellMethod;
pub use vps_voxmap::VoxelWidth;
