//! `vps tune`: measures this machine's frame compute time on a scene at voxel sizes from coarse to
//! fine, proposes the finest size whose p99.9 stays under a budget, prints the accuracy the
//! committed sweep measured at that size, and verifies the choice with a paced run.

use super::sweep::{run_sweep_session, session_on, SweepSession};
use crate::cli::TuneArgs;
use anyhow::{bail, Result};
use serde::Serialize;
use std::path::Path;
use vps_runtime::StatsSummary;
use vps_session::{CachePolicy, LoadedScene};

/// Candidate voxel sizes (mm), coarse to fine.
const SIZES_MM: [f64; 5] = [10.0, 5.0, 2.5, 1.25, 0.625];

#[derive(Serialize)]
struct Measured {
    voxel_size_mm: f64,
    shell_points: usize,
    frames: u64,
    compute_p50_us: f64,
    compute_p999_us: f64,
    within_budget: bool,
}

#[derive(Serialize)]
struct TuneReport {
    scene: String,
    budget_us: f64,
    measured: Vec<Measured>,
    chosen_voxel_size_mm: f64,
    predicted_accuracy: Option<serde_json::Value>,
    verify_frames: u64,
    verify_realtime_granted: bool,
    verify: StatsSummary,
}

/// The committed sweep's row for this scene, method, voxel width and size, if the file has one.
fn sweep_row(path: &Path, scene: &LoadedScene, size_mm: f64) -> Option<serde_json::Value> {
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()?;
    let voxels = &scene.file.voxels;
    let method = serde_json::to_value(voxels.shell_method).ok()?;
    rows.into_iter().find(|r| {
        r["scene"] == scene.name.as_str()
            && r["method"] == method
            && r["voxel_width"].as_u64() == Some(u64::from(voxels.voxel_width))
            && r["voxel_size_mm"]
                .as_f64()
                .is_some_and(|s| (s - size_mm).abs() < 1e-9)
    })
}

/// Runs `vps tune`.
pub fn run(args: &TuneArgs) -> Result<()> {
    if !(args.budget_fraction > 0.0 && args.budget_fraction <= 1.0) {
        bail!(
            "--budget-fraction {} must be in (0, 1]",
            args.budget_fraction
        );
    }
    let scene = LoadedScene::load(&args.scene)?;
    for w in &scene.warnings {
        eprintln!("{}: warning: {w}", scene.label);
    }
    let width = scene.width()?;
    let cache = if args.no_cache {
        CachePolicy::Off
    } else {
        CachePolicy::from_env()
    };
    let budget_us = 1000.0 * args.budget_fraction;
    let mut measured = Vec::new();
    let mut chosen: Option<(f64, SweepSession)> = None;
    let longest = args.frames.max(args.verify_frames) as f64 * scene.params.dt;
    for size_mm in SIZES_MM {
        let s = size_mm * 1e-3;
        let map = scene.build_voxmap(s, width, &cache, true)?;
        let session = session_on(&scene, &map, s, scene.file.voxels.shell_method, longest)?;
        let stats = run_sweep_session(&session, args.frames, false)?.stats;
        let p999 = stats.compute_ns.p999 as f64 / 1e3;
        let within = p999 <= budget_us;
        if !args.json {
            println!(
                "{size_mm:>6} mm: {:>7} points, compute p50 {:.1} µs, p99.9 {:.1} µs{}",
                session.shell.len(),
                stats.compute_ns.p50 as f64 / 1e3,
                p999,
                if within { "" } else { "  (over budget)" }
            );
        }
        measured.push(Measured {
            voxel_size_mm: size_mm,
            shell_points: session.shell.len(),
            frames: stats.frames,
            compute_p50_us: stats.compute_ns.p50 as f64 / 1e3,
            compute_p999_us: p999,
            within_budget: within,
        });
        if !within {
            break;
        }
        chosen = Some((size_mm, session));
    }
    let Some((size_mm, session)) = chosen else {
        bail!(
            "even {} mm voxels miss the {budget_us:.0} µs p99.9 budget on this machine",
            SIZES_MM[0]
        );
    };
    let predicted = sweep_row(&args.sweep, &scene, size_mm);
    let verify = run_sweep_session(&session, args.verify_frames, true)?;
    let report = TuneReport {
        scene: scene.name.clone(),
        budget_us,
        measured,
        chosen_voxel_size_mm: size_mm,
        predicted_accuracy: predicted,
        verify_frames: args.verify_frames,
        verify_realtime_granted: verify.rt.fifo,
        verify: verify.stats,
    };
    if args.json {
        return crate::output::print_json(&report);
    }
    println!("budget: frame compute p99.9 ≤ {budget_us:.0} µs; chosen voxel size {size_mm} mm");
    match &report.predicted_accuracy {
        Some(r) => println!(
            "accuracy at {size_mm} mm from {}: force direction error p50 {} deg, magnitude error p50 {}, penetration ratio {}, min exact separation {} mm",
            args.sweep.display(),
            r["direction_error_deg_p50"],
            r["magnitude_error_p50"],
            r["penetration_ratio"],
            r["min_separation_mm"]
        ),
        None => println!("accuracy: {} has no row for {} at {size_mm} mm (run vps sweep)", args.sweep.display(), scene.name),
    }
    crate::session_io::print_summary(
        &format!(
            "verification: {} paced frames at {size_mm} mm",
            args.verify_frames
        ),
        &report.verify,
        None,
    );
    Ok(())
}
