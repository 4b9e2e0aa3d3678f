//! The integration tests of vps-cluster as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test -p vps-cluster --test integration FILE::`.

mod cluster;
mod common;
mod identity;
mod session;
mod tls_and_worker;
mod worker_args;
