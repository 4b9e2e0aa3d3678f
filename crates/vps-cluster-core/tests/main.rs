//! The integration tests of vps-cluster-core as one test binary: no socket, sleep or thread
//! anywhere (the crate has none to offer). Run one file's tests with
//! `cargo test -p vps-cluster-core --test integration FILE::`.

mod gather;
