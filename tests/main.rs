//! The integration tests of vps (the binary, run as a process) as one test binary: each file of this folder is a
//! module, so the workspace is linked once for them all instead of once per file. Run one
//! file's tests with `cargo test --test integration FILE::`.

mod binary_layout;
mod bounds;
mod bridge_clients;
mod cli;
mod cluster_affinity;
mod cluster_netem;
mod cluster_processes;
mod cluster_rejoin;
mod deploy;
mod docs_links;
mod findings;
mod hostile_output;
mod import_cycles;
mod inside_outside;
mod parts;
mod safe_stop;
mod scene;
mod scene_memory;
mod service_mistakes;
mod study;
mod sweep;
mod viewer;
mod worker_service;
