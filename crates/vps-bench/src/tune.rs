//! `vps tune`: measures this machine's frame compute time on a scene at voxel sizes from coarse to
//! fine, proposes the finest size whose p99.9 stays under a budget, prints the accuracy the
//! committed sweep measured at that size with the scene's force model and, beside it, with the
//! other model (so the two can be compared), and verifies the choice with a paced run.
//! SIGINT, SIGTERM and SIGHUP stop it: the running session's device is written zero, the report
//! so far is printed (`complete: false`, `end` says why) and the exit status is `128 + N`.

use crate::sweep::session::{run_sweep_session, session_on, SweepRow, SweepSession, SweepTable};
use anyhow::{bail, Result};
use serde::Serialize;
use std::path::Path;
use vps_app::exit::{outcome, SessionExit};
use vps_runtime::{SessionEnd, SignalStop, StatsSummary};
use vps_session::file::ForceModelName;
use vps_session::{stop_on_signals, CachePolicy, LoadedScene};

/// What `vps tune` is asked: the scene, the budget and the frames of each measurement.
#[derive(Debug, Clone)]
pub struct TuneRequest {
    /// The scene (a scene file or `builtin:NAME`).
    pub scene: String,
    /// Always voxelize: neither read nor write the voxmap cache.
    pub no_cache: bool,
    /// The share of the 1 ms frame that frame compute p99.9 may take (0 to 1).
    pub budget_fraction: f64,
    /// Frames per free-running measurement.
    pub frames: u64,
    /// Frames of the paced verification run.
    pub verify_frames: u64,
    /// A sweep table (`vps sweep --json FILE`) for the predicted accuracy; `None`: the built-in
    /// one.
    pub sweep: Option<std::path::PathBuf>,
    /// Print as JSON.
    pub json: bool,
}

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
    /// False when a signal stopped tune (the figures cover what ran).
    complete: bool,
    /// Why tune ended: "done", or "stopped by SIGINT while ...".
    end: String,
    budget_us: f64,
    measured: Vec<Measured>,
    chosen_voxel_size_mm: Option<f64>,
    /// The sweep table's row at the chosen size with the scene's own force model.
    predicted_accuracy: Option<SweepRow>,
    /// The same row with the other force model, for comparison (its frame compute was measured
    /// by the sweep, not by this tune).
    other_model_accuracy: Option<SweepRow>,
    /// Why the sweep table could not be read, when it could not.
    #[serde(skip_serializing_if = "Option::is_none")]
    sweep_error: Option<String>,
    verify_frames: u64,
    verify_realtime_granted: Option<bool>,
    verify: Option<StatsSummary>,
}

/// The largest sweep table read, in bytes (256 MiB; a sweep's table is a few hundred KiB).
const MAX_SWEEP_TABLE_BYTES: u64 = 256 << 20;

/// The built-in sweep table: docs/sweep/sweep.json as built into vps (the built-in scenes' rows),
/// used without `--sweep`.
const BUILTIN_SWEEP_TABLE: &str = include_str!("../../../docs/sweep/sweep.json");

/// How the report names [`BUILTIN_SWEEP_TABLE`].
const BUILTIN_SWEEP_TABLE_NAME: &str = "the built-in sweep table (docs/sweep/sweep.json)";

/// The sweep table at `path` (`None`: the built-in one), or why it cannot be used (naming the
/// file).
fn read_sweep(path: Option<&Path>) -> Result<SweepTable, String> {
    let Some(path) = path else {
        return serde_json::from_str(BUILTIN_SWEEP_TABLE)
            .map_err(|e| format!("{BUILTIN_SWEEP_TABLE_NAME}: not a sweep table: {e}"));
    };
    let text = vps_files::read_regular_to_string(path, MAX_SWEEP_TABLE_BYTES)
        .map_err(|e| format!("cannot read {}: {e} (give --sweep FILE)", path.display()))?;
    serde_json::from_str(&text).map_err(|e| format!("{}: not a sweep table: {e}", path.display()))
}

/// How the report names the sweep table `path` (`None`: the built-in one).
fn sweep_name(path: Option<&Path>) -> String {
    path.map_or(BUILTIN_SWEEP_TABLE_NAME.into(), |p| {
        vps_files::printable(&p.display().to_string()).into_owned()
    })
}

/// The sweep table's rows for this scene, method, voxel width and size: with the scene's own
/// force model, and with the other one (each `None` when the table has none); an error when the
/// table cannot be read.
fn sweep_rows(
    path: Option<&Path>,
    scene: &LoadedScene,
    size_mm: f64,
) -> Result<(Option<SweepRow>, Option<SweepRow>), String> {
    let table = read_sweep(path)?;
    let voxels = &scene.file.voxels;
    let row = |model: ForceModelName| {
        table
            .rows
            .iter()
            .find(|r| {
                r.scene == scene.name
                    && r.method == voxels.shell_method
                    && r.voxel_width == u32::from(voxels.voxel_width)
                    && r.force_model == model
                    && (r.voxel_size_mm - size_mm).abs() < 1e-9
            })
            .cloned()
    };
    Ok((
        row(voxels.force_model),
        row(other_model(voxels.force_model)),
    ))
}

/// The force model that is not `model`.
fn other_model(model: ForceModelName) -> ForceModelName {
    match model {
        ForceModelName::TangentPlane => ForceModelName::Distance,
        ForceModelName::Distance => ForceModelName::TangentPlane,
    }
}

/// A sweep row's accuracy figures in words.
fn accuracy_figures(r: &SweepRow) -> String {
    format!(
        "force direction error p50 {} deg, magnitude error p50 {}, penetration ratio {}, min \
         exact separation {} mm, frame compute p50 {:.1} µs in the sweep",
        shown(r.direction_error_deg_p50),
        shown(r.magnitude_error_p50),
        shown(r.penetration_ratio),
        shown(r.min_separation_mm),
        r.compute_p50_us
    )
}

/// Prints `report` (stopped by a signal while `what`) and fails with exit status `128 + N`.
fn stopped(
    args: &TuneRequest,
    mut report: TuneReport,
    signals: &SignalStop,
    what: &str,
) -> Result<()> {
    let (end, code) = outcome(&SessionEnd::Stopped, Some(signals));
    report.complete = false;
    report.end = format!("{end} while {what}");
    if args.json {
        vps_app::output::print_json(&report)?;
    } else {
        println!(
            "tune: {} (partial; the device was sent zero force)",
            report.end
        );
    }
    Err(SessionExit {
        code,
        reason: format!("tune ended early: {}", report.end),
    }
    .into())
}

/// Runs `vps tune`.
pub fn run(args: &TuneRequest) -> Result<()> {
    if !(args.budget_fraction > 0.0 && args.budget_fraction <= 1.0) {
        bail!(
            "--budget-fraction {} must be in (0, 1]",
            args.budget_fraction
        );
    }
    let scene = LoadedScene::load(&args.scene)?;
    scene.print_warnings();
    let width = scene.width()?;
    let cache = if args.no_cache {
        CachePolicy::Off
    } else {
        CachePolicy::from_env()
    };
    let budget_us = 1000.0 * args.budget_fraction;
    let mut report = TuneReport {
        scene: scene.name.clone(),
        complete: true,
        end: "done".into(),
        budget_us,
        measured: Vec::new(),
        chosen_voxel_size_mm: None,
        predicted_accuracy: None,
        other_model_accuracy: None,
        sweep_error: None,
        verify_frames: args.verify_frames,
        verify_realtime_granted: None,
        verify: None,
    };
    let signals = stop_on_signals()?;
    let mut chosen: Option<(f64, SweepSession)> = None;
    let longest = args.frames.max(args.verify_frames) as f64 * scene.params.dt;
    if !args.json {
        println!(
            "{}: frame compute over {} free-running frames per voxel size (budget p99.9 ≤ \
             {budget_us:.0} µs); {}-bit voxels, {} shell points",
            vps_files::printable(&scene.name),
            vps_app::output::grouped(args.frames),
            width.bits(),
            match scene.file.voxels.shell_method {
                vps_session::file::ShellMethodName::Centres => "voxel-centre",
                vps_session::file::ShellMethodName::Exact => "exact-surface",
            }
        );
        println!(
            "{:>10} {:>9} {:>12} {:>14}",
            "voxel size", "points", "compute p50", "compute p99.9"
        );
    }
    for size_mm in SIZES_MM {
        let s = size_mm * 1e-3;
        let map = scene.build_voxmap(s, width, &cache, true)?;
        let session = session_on(&scene, &map, s, scene.file.voxels.shell_method, longest)?;
        let run = run_sweep_session(&session, args.frames, false, &signals)?;
        if !run.end.is_complete() {
            return stopped(args, report, &signals, &format!("measuring {size_mm} mm"));
        }
        let stats = run.stats;
        let p999 = stats.compute_ns.p999 as f64 / 1e3;
        let within = p999 <= budget_us;
        if !args.json {
            println!(
                "{:>7} mm {:>9} {:>9.1} µs {:>11.1} µs{}",
                size_mm,
                vps_app::output::grouped(session.shell.len() as u64),
                stats.compute_ns.p50 as f64 / 1e3,
                p999,
                if within { "" } else { "  over budget" }
            );
        }
        report.measured.push(Measured {
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
    report.chosen_voxel_size_mm = Some(size_mm);
    match sweep_rows(args.sweep.as_deref(), &scene, size_mm) {
        Ok((own, other)) => {
            report.predicted_accuracy = own;
            report.other_model_accuracy = other;
        }
        Err(why) => report.sweep_error = Some(why),
    }
    let verify = run_sweep_session(&session, args.verify_frames, true, &signals)?;
    if !verify.end.is_complete() {
        return stopped(args, report, &signals, &format!("verifying {size_mm} mm"));
    }
    report.verify_realtime_granted = Some(verify.rt.fifo);
    let verify = report.verify.insert(verify.stats).clone();
    if args.json {
        return vps_app::output::print_json(&report);
    }
    let finer = if report.measured.len() < SIZES_MM.len() {
        "the next finer size was over budget"
    } else {
        "the finest size tried"
    };
    println!(
        "recommended: voxel_size = \"{size_mm}mm\" for {} on this machine: the finest size whose \
         frame compute p99.9 fits {budget_us:.0} µs ({finer})",
        vps_files::printable(&scene.name)
    );
    let table_name = sweep_name(args.sweep.as_deref());
    let own = scene.file.voxels.force_model;
    match &report.predicted_accuracy {
        Some(r) => println!(
            "accuracy at {size_mm} mm from {table_name}, {} model (this scene's): {}",
            own.name(),
            accuracy_figures(r)
        ),
        None => match &report.sweep_error {
            Some(why) => println!("accuracy: unknown: {why}; {}", how_to_measure(&args.scene)),
            None => println!(
                "accuracy: {table_name} has no row for {} at {size_mm} mm; {}",
                vps_files::printable(&scene.name),
                how_to_measure(&args.scene)
            ),
        },
    }
    if let Some(r) = &report.other_model_accuracy {
        let other = other_model(own);
        println!(
            "  beside it, the {} model at {size_mm} mm: {}; to use it, set [voxels] force_model \
             = \"{}\" (docs/scenes.md \"Force models\") and run vps tune again to measure its \
             frame compute here",
            other.name(),
            accuracy_figures(r),
            other.name()
        );
    }
    vps_app::finish::print_summary(
        &format!(
            "verification: {} paced frames at {size_mm} mm",
            args.verify_frames
        ),
        &verify,
        None,
    );
    Ok(())
}

/// How a user gets accuracy figures for `scene` (a scene file or `builtin:NAME`): the committed
/// table has rows only for the standard scenes, so a scene of one's own must be swept first.
fn how_to_measure(scene: &str) -> String {
    format!(
        "to measure it: vps sweep --scene {scene} --json {SWEEP_OUT}, then vps tune --scene \
         {scene} --sweep {SWEEP_OUT}"
    )
}

/// The table file [`how_to_measure`] suggests.
const SWEEP_OUT: &str = "my-sweep.json";

/// A figure of the sweep table, `-` when the table has none.
fn shown(value: Option<f64>) -> String {
    value.map_or("-".into(), |v| format!("{v:.3}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sweep file that is missing (tune run outside the repository, where the default
    /// `docs/sweep/sweep.json` does not exist) or not a table says so, naming the file; it used to
    /// read as "has no row for SCENE (run vps sweep)".
    /// A scene of one's own has no row in the committed table: tune said "(run vps sweep)"
    /// (which, without `--scene` and `--json`, sweeps the standard scenes and prints to the
    /// terminal); it now gives the two commands that measure the scene and use the result.
    #[test]
    fn the_way_to_accuracy_for_a_scene_of_ones_own_is_spelled_out() {
        let text = how_to_measure("bay.toml");
        assert!(
            text.contains("vps sweep --scene bay.toml --json my-sweep.json")
                && text.contains("vps tune --scene bay.toml --sweep my-sweep.json"),
            "{text}"
        );
    }

    #[test]
    fn a_missing_or_bad_sweep_file_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("../../docs/sweep/sweep.json");
        let err = read_sweep(Some(&missing)).err().unwrap();
        assert!(
            err.contains(&format!("cannot read {}", missing.display())) && err.contains("--sweep"),
            "{err}"
        );
        let bad = dir.path().join("bad.json");
        std::fs::write(&bad, "[1, 2]").unwrap();
        let err = read_sweep(Some(&bad)).err().unwrap();
        assert!(err.contains("bad.json: not a sweep table"), "{err}");
        let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/sweep/sweep.json");
        assert!(!read_sweep(Some(&committed)).unwrap().rows.is_empty());
        // The built-in table is the committed one.
        assert_eq!(
            read_sweep(None).unwrap().rows.len(),
            read_sweep(Some(&committed)).unwrap().rows.len()
        );
    }

    /// The built-in table holds both force models of the built-in scenes, so tune prints the
    /// other model's accuracy beside the scene's own at every size it can choose.
    #[test]
    fn the_built_in_table_compares_both_models_of_the_built_in_scenes() {
        for name in ["builtin:rig-teapot", "builtin:bay-teapot"] {
            let scene = LoadedScene::load(name).unwrap();
            let sizes: &[f64] = if name.contains("rig") {
                &SIZES_MM
            } else {
                &SIZES_MM[..3]
            };
            for &size in sizes {
                let (own, other) = sweep_rows(None, &scene, size).unwrap();
                let (own, other) = (own.unwrap(), other.unwrap());
                assert_eq!(
                    own.force_model, scene.file.voxels.force_model,
                    "{name} {size}"
                );
                assert_eq!(
                    other.force_model,
                    other_model(own.force_model),
                    "{name} {size}"
                );
                assert!(accuracy_figures(&other).contains("force direction error p50"));
            }
        }
    }
}
