//! The integration tests of vps-study as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-study --test integration FILE::`.

mod analytic;
mod swept;
