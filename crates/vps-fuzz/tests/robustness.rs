//! The robustness suite in CI: 5·10^4 mutated inputs per parser and decoder (5·10^3 for
//! `scene-mesh`, which writes and loads files; 10^5 for the two STEP targets), each asserting no
//! panic,
//! a non-empty error naming the file or field for every rejection, and at most 64 MiB of peak live
//! allocation per input. The targets run one after another (the allocator's counters are global).
//! Longer campaigns: `cargo run --release -p vps-fuzz -- --target all --inputs 1000000`.

use vps_fuzz::{all_targets, run_target, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

/// Inputs per target in CI.
const INPUTS: u64 = 50_000;
/// Peak live allocation allowed per input (bytes).
const BUDGET: u64 = 64 * 1024 * 1024;

#[test]
fn every_parser_survives_fifty_thousand_mutated_inputs() {
    ALLOC.set_request_cap((BUDGET * 16) as usize);
    let mut failures = Vec::new();
    for (index, target) in all_targets().iter().enumerate() {
        // `scene-mesh` writes its scene and mesh files to a fresh directory and loads them (about
        // 3 ms of wall time an input on a loaded machine), so CI runs a tenth as many.
        // The STEP path runs 10^5 inputs in CI, its structure (`step-structure`) and its whole
        // read (`step`, truck's tessellation included: about 1.5 ms an input here, about a dozen
        // in 2,000 made truck loop before `vps_step::guard`); longer campaigns in
        // docs/robustness.md.
        let inputs = match target.name {
            "scene-mesh" => INPUTS / 10,
            "step-structure" | "step" => INPUTS * 2,
            _ => INPUTS,
        };
        let r = run_target(target, index, inputs, 0x5EED, Some(&ALLOC), BUDGET);
        eprintln!(
            "{}: {} inputs, {} accepted, {} rejected, {} panics ({} caught in a dependency), peak {} bytes, {:.1} s",
            r.target,
            r.inputs,
            r.accepted,
            r.rejected,
            r.panics,
            r.caught_dependency_panics,
            r.max_peak_bytes.unwrap_or(0),
            r.seconds
        );
        assert_eq!(r.inputs, inputs);
        assert!(
            r.max_peak_bytes.is_some(),
            "the counting allocator is installed"
        );
        // The mutations must both keep some inputs valid and break most of them, or the campaign
        // exercises nothing.
        assert!(r.accepted > 0, "{}: no input accepted", r.target);
        assert!(
            r.rejected > inputs / 4,
            "{}: only {} rejected",
            r.target,
            r.rejected
        );
        if !r.clean() {
            failures.push(format!("{r:#?}"));
        }
    }
    assert!(failures.is_empty(), "findings:\n{}", failures.join("\n"));
}
