//! The integration tests of vps-voxmap as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-voxmap --test integration FILE::`.

mod common;
mod directory;
mod loaded_memory;
mod shell_file;
mod tree_lookup;
mod vmap_file;
mod wide_voxels;
