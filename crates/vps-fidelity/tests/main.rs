//! The integration tests of vps-fidelity as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-fidelity --test integration FILE::`.

mod analytic;
mod clearance;
mod deep;
mod edge_and_corner;
mod tunnelling;
