//! The integration tests of vps-view as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-view --test integration FILE::`.

mod browser;
mod hardening;
mod server;
