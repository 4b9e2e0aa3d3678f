//! The integration tests of vps-input as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-input --test integration FILE::`.

mod bridge_loopback;
mod bridge_mapping;
mod common;
