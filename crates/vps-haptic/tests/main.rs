//! The integration tests of vps-haptic as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-haptic --test integration FILE::`.

mod common;
mod frame;
mod kernel;
mod pair;
mod params;
mod stability;
