//! The integration tests of vps-voxelize as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-voxelize --test integration FILE::`.

mod analytic_shapes;
mod closed_unchanged;
mod common;
mod memory_budget;
mod merge_and_offset;
mod open_meshes;
mod point_shell;
mod sparse_equals_dense;
mod sparse_memory_and_layers;
mod teapot_shell;
mod thin_features;
