//! The vps robustness suite: seeded, deterministic mutation fuzzing of every parser and decoder
//! that reads untrusted bytes (mesh OBJ, STL and PLY; `.vmap`; `.vshell`; haptic TOML; scene
//! files; sweep files; handle traces; bridge datagrams; cluster datagrams and join messages).
//!
//! - [`seeds`]: seed corpora generated from real valid inputs (encoded by the project's own
//!   writers, or by small writers of the mesh formats).
//! - [`mutate`]: the mutator: bit flips, random bytes, insertions, deletions, duplications, splices
//!   with other seeds, interesting integers and floats (binary and as text), truncations. Input `i`
//!   of a target is a pure function of (seed, target, i), so every finding is reproducible.
//! - [`alloc`]: a counting global allocator (install it with `#[global_allocator]` in a test or
//!   binary) recording peak live bytes per input, and refusing single requests above a hard cap.
//! - [`targets`]: what each target runs and which name its errors must carry.
//! - [`runner`]: runs a target over N inputs under `catch_unwind` and reports panics, rejections
//!   without a message, errors that do not name their source, and peak memory per input.
//!
//! The `vps-fuzz` binary runs long campaigns (`--inputs 1000000`); the `robustness` test runs 5·10^4
//! inputs per target in CI.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod alloc;
pub mod mutate;
pub mod runner;
pub mod seeds;
pub mod targets;

pub use alloc::CountingAlloc;
pub use runner::{run_target, TargetReport};
pub use targets::{all_targets, Target};
