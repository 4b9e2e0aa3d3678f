//! `vps-fuzz`: long mutation-fuzzing campaigns over every vps parser and decoder.
//!
//! `cargo run --release -p vps-fuzz -- --target all --inputs 1000000` prints one line per target
//! (inputs, accepted, rejected, panics, unnamed errors, peak memory per input, time) and, with
//! `--json FILE`, writes the reports as JSON. Exits 1 when any target has a finding. A finding is
//! reproduced with `--target NAME --seed S --dump INDEX > input`.

use clap::Parser;
use std::path::PathBuf;
use vps_fuzz::{all_targets, run_target, CountingAlloc, TargetReport};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc::new();

/// Mutation fuzzing of the vps parsers and decoders.
#[derive(Parser)]
#[command(name = "vps-fuzz")]
struct Args {
    /// Target names, comma-separated, or `all`.
    #[arg(long, default_value = "all")]
    target: String,
    /// Inputs per target.
    #[arg(long, default_value_t = 100_000)]
    inputs: u64,
    /// Campaign seed (input i of a target is a function of the seed and i).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Peak live allocation allowed per input (MiB).
    #[arg(long, default_value_t = 64)]
    budget_mib: u64,
    /// Write the reports as JSON to this file.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Instead of fuzzing, write input INDEX of the single `--target` (with `--seed`) to stdout,
    /// to reproduce a finding.
    #[arg(long, value_name = "INDEX")]
    dump: Option<u64>,
    /// Instead of fuzzing, write the crafted map of the viewer finding to PATH: a valid 16 KiB
    /// `.vmap` of 8192³ (2^39) 1 mm voxels, every one Interior, with a correct hash (a dense copy
    /// would be 549 GB).
    #[arg(long, value_name = "PATH")]
    write_huge_vmap: Option<PathBuf>,
}

fn main() {
    let args = Args::parse();
    let targets = all_targets();
    let wanted: Vec<&str> = args.target.split(',').map(str::trim).collect();
    let unknown: Vec<&&str> = wanted
        .iter()
        .filter(|w| **w != "all" && !targets.iter().any(|t| t.name == **w))
        .collect();
    if !unknown.is_empty() {
        let names: Vec<&str> = targets.iter().map(|t| t.name).collect();
        eprintln!(
            "vps-fuzz: unknown target(s) {unknown:?}; known: all, {}",
            names.join(", ")
        );
        std::process::exit(2);
    }
    if let Some(path) = &args.write_huge_vmap {
        let bytes = vps_fuzz::seeds::uniform_vmap([8192; 3], 0.001, 1);
        if let Err(e) = std::fs::write(path, bytes) {
            eprintln!("vps-fuzz: {}: {e}", path.display());
            std::process::exit(2);
        }
        return;
    }
    if let Some(index) = args.dump {
        let Some(target) = targets.iter().find(|t| t.name == args.target) else {
            eprintln!("vps-fuzz: --dump needs one --target name");
            std::process::exit(2);
        };
        let mutator = vps_fuzz::mutate::Mutator::new((target.seeds)(), target.max_len);
        let input = mutator.input(args.seed, index);
        if let Err(e) = std::io::Write::write_all(&mut std::io::stdout(), &input) {
            eprintln!("vps-fuzz: stdout: {e}");
            std::process::exit(2);
        }
        return;
    }
    let budget = args.budget_mib * 1024 * 1024;
    // A single request far above the budget is refused before it can exhaust the machine.
    ALLOC.set_request_cap((budget * 16) as usize);
    let mut reports: Vec<TargetReport> = Vec::new();
    println!(
        "{:<17} {:>9} {:>9} {:>9} {:>6} {:>8} {:>8} {:>12} {:>8}",
        "target",
        "inputs",
        "accepted",
        "rejected",
        "panics",
        "caught",
        "unnamed",
        "peak/input",
        "seconds"
    );
    for (index, target) in targets.iter().enumerate() {
        if !wanted.contains(&"all") && !wanted.contains(&target.name) {
            continue;
        }
        let r = run_target(target, index, args.inputs, args.seed, Some(&ALLOC), budget);
        println!(
            "{:<17} {:>9} {:>9} {:>9} {:>6} {:>8} {:>8} {:>10.2}MiB {:>8.1}",
            r.target,
            r.inputs,
            r.accepted,
            r.rejected,
            r.panics,
            r.caught_dependency_panics,
            r.unnamed_errors + r.empty_messages,
            r.max_peak_bytes.unwrap_or(0) as f64 / (1024.0 * 1024.0),
            r.seconds
        );
        for s in &r.samples {
            println!("    {s}");
        }
        reports.push(r);
    }
    if let Some(path) = &args.json {
        let json = serde_json::json!({
            "seed": args.seed,
            "inputs_per_target": args.inputs,
            "budget_bytes": budget,
            "targets": reports,
        });
        let text = serde_json::to_string_pretty(&json).expect("reports serialise");
        if let Err(e) = std::fs::write(path, text + "\n") {
            eprintln!("vps-fuzz: {}: {e}", path.display());
            std::process::exit(2);
        }
    }
    if reports.iter().any(|r| !r.clean()) {
        std::process::exit(1);
    }
}
