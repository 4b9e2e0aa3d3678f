//! `vps sweep`: speed against accuracy over voxel sizes, voxel widths (2, 4, 8 bits) and point-shell
//! methods on standard scenes (scene files) and their scripted sessions. Per setting: point count, voxmap memory,
//! voxelization time, frame compute p50/p99.9 (free-running 1 kHz loop), penetration ratio, and at
//! sampled touching frames the voxel contact force against the exact reference (vps-reference):
//! direction and magnitude error, minimum exact separation. Prints the table as text with a
//! recommendation per scene (`sweep_text`), or JSON (a [`SweepTable`]) with `--json`; writes JSON,
//! CSV and SVG plots to files; rows whose width and method are the scene file's own are marked
//! `default`. Without `--config` the built-in sweep file and scenes are used (any folder).
//! SIGINT, SIGTERM and SIGHUP stop it: the running session's device is written zero and the rows
//! done are written as a partial table (exit status 128 + N). See docs/sweep.md.

use crate::sweep::session::{run_sweep_session, session_on, SweepRow, SweepSession, SweepTable};
use anyhow::{Context, Result};
use glam::DVec3;
use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;
use std::time::Instant;
use vps_app::exit::SessionExit;
use vps_app::output::{check_outputs, write_file};
use vps_device::{HandParams, HapticDevice, SimulatedHand};
use vps_haptic::{sample_all, step, HapticParams, KernelPose, PartState, Wrench};
use vps_reference::{reference_contact, ExactScene};
use vps_runtime::{SessionEnd, SignalStop, StatsSummary};
use vps_session::file::{ForceModelName, ShellMethodName};
use vps_session::scene::BuiltVoxmap;
use vps_session::sweep_file::{
    builtin_run_scene, SweepFile, SweepRun, BUILTIN_SWEEP_FILE, BUILTIN_SWEEP_NAME,
    MAX_SWEEP_FILE_BYTES,
};
use vps_session::{stop_on_signals, CachePolicy, LoadedScene};

pub mod plots;
pub mod session;
pub mod text;

/// What `vps sweep` is asked: the sweep file, where its table goes and how much of it runs.
#[derive(Debug, Clone, Default)]
pub struct SweepRequest {
    /// The sweep file (TOML); `None`: the built-in one.
    pub config: Option<std::path::PathBuf>,
    /// Write the table as JSON here; `-`: print it as JSON instead of text.
    pub json: Option<std::path::PathBuf>,
    /// Write the table as CSV here.
    pub csv: Option<std::path::PathBuf>,
    /// Write SVG plots into this folder.
    pub plots: Option<std::path::PathBuf>,
    /// Test-sized: each scene at its own voxel size and at twice it, sessions cut to 2 s.
    pub quick: bool,
    /// Sweep this scene (file or `builtin:NAME`) instead of the sweep file's runs.
    pub scene: Option<String>,
}

/// Runs the sweep. SIGINT, SIGTERM and SIGHUP stop it: the running session's device is written
/// zero, the rows done so far are written (marked partial, with the reason) and the command fails
/// with exit status `128 + N`.
pub fn run(args: &SweepRequest) -> Result<()> {
    let (config, config_name) = match &args.config {
        Some(path) => {
            let text = vps_files::read_regular_to_string(path, MAX_SWEEP_FILE_BYTES).with_context(
                || {
                    format!(
                        "reading the sweep file {} (voxel sizes, widths and methods, also for \
                         --scene; without --config the built-in one is used)",
                        path.display()
                    )
                },
            )?;
            let name = path.display().to_string();
            (SweepFile::from_toml_str(&text, &name)?, name)
        }
        None => (
            SweepFile::from_toml_str(BUILTIN_SWEEP_FILE, BUILTIN_SWEEP_NAME)?,
            BUILTIN_SWEEP_NAME.to_string(),
        ),
    };
    let json_file = args
        .json
        .as_deref()
        .filter(|p| *p != Path::new(JSON_TO_STDOUT));
    let outputs: Vec<(&str, &Path)> = [("--json", json_file), ("--csv", args.csv.as_deref())]
        .into_iter()
        .filter_map(|(flag, path)| Some((flag, path?)))
        .collect();
    let inputs: Vec<&Path> = args.config.as_deref().into_iter().collect();
    check_outputs(&outputs, &inputs)?;
    let mut runs = config.run.iter().collect::<Vec<_>>();
    let only;
    if let Some(scene) = &args.scene {
        only = SweepRun::of_scene(PathBuf::from(scene));
        runs = vec![&only];
    }
    let signals = stop_on_signals()?;
    let mut rows = Vec::new();
    for spec in runs {
        let path = if args.scene.is_some() {
            spec.scene.display().to_string()
        } else if let Some(file) = &args.config {
            let base = file.parent().unwrap_or(Path::new("."));
            base.join(&spec.scene).display().to_string()
        } else {
            builtin_run_scene(&spec.scene).with_context(|| {
                format!(
                    "{config_name}: run scene {} is not a built-in scene",
                    spec.scene.display()
                )
            })?
        };
        let mut scene = LoadedScene::load(&path)?;
        scene.print_warnings();
        let widths = match config.widths_of(spec) {
            Some(widths) => widths.to_vec(),
            None => vec![scene.width()?],
        };
        let methods = config.methods_of(spec);
        let exact = ExactScene::new(&scene.placed_statics())
            .with_context(|| format!("{path}: building the exact reference"))?;
        let mut sizes = config.sizes_mm(spec).to_vec();
        let mut seconds = spec.seconds;
        if args.quick {
            sizes = quick_sizes_mm(scene.file.voxels.voxel_size);
            seconds = Some(seconds.unwrap_or(f64::INFINITY).min(QUICK_SECONDS));
        }
        let own_force_model = scene.file.voxels.force_model;
        let models = config
            .force_models_of(spec)
            .map_or_else(|| vec![own_force_model], <[_]>::to_vec);
        for &model in &models {
            // The scene as if its file said `force_model = MODEL` (a stand-off it states applies to
            // the distance model; the tangent-plane model ignores it).
            scene.file.voxels.force_model = model;
            let scene = &scene;
            for &size_mm in &sizes {
                for &width in &widths {
                    let voxel_size = size_mm * 1e-3;
                    // Sweeps time voxelization: never from the cache.
                    let map = scene.build_voxmap(voxel_size, width, &CachePolicy::Off, false)?;
                    for &method in methods {
                        let what = format!(
                            "{} {} {size_mm} mm {}-bit {method:?}",
                            scene.name,
                            model.name(),
                            width.bits()
                        );
                        eprintln!("sweep: {what}");
                        let setting = Setting {
                            scene,
                            own_force_model,
                            exact: &exact,
                            voxel_size,
                            method,
                            seconds,
                            points_per_frame: config.reference_points_per_frame.max(1),
                            signals: &signals,
                        };
                        let t = Instant::now();
                        let measured = if signals.flag().load(Ordering::SeqCst) {
                            None
                        } else {
                            measure(&setting, &map)?
                        };
                        let Some(row) = measured else {
                            return stopped(args, &rows, &signals, &what);
                        };
                        rows.push(row);
                        eprintln!(
                            "sweep: row done in {:.1} s (voxelization {:.1} s)",
                            t.elapsed().as_secs_f64(),
                            map.voxelize_ms / 1e3
                        );
                    }
                }
            }
        }
    }
    if let Some(note) = no_contact_note(&rows, args.quick) {
        eprintln!("sweep: {note}");
    }
    let table = SweepTable {
        complete: true,
        end: "all rows done".into(),
        rows,
    };
    write_outputs(args, &table)
}

/// A note when no row's session touched a static object: every accuracy column is then empty
/// (null), which reads like a failure of the reference rather than a path that never meets a
/// surface. `quick`: the sessions were cut to [`QUICK_SECONDS`].
fn no_contact_note(rows: &[SweepRow], quick: bool) -> Option<String> {
    if rows.is_empty() || rows.iter().any(|r| r.penetration_ratio.is_some()) {
        return None;
    }
    let cut = if quick {
        format!(" (--quick cut each session to its first {QUICK_SECONDS} s)")
    } else {
        String::new()
    };
    Some(format!(
        "no row's session touched a static object{cut}, so the accuracy columns \
         (penetration_ratio, direction and magnitude error, min_separation_mm) are empty (null); \
         give the scene a hand path that presses the part against a surface early on \
         ([hand] waypoints, docs/scenes.md)"
    ))
}

/// The sweep was stopped by a signal during `what` (its device already written zero): writes
/// the rows done, marked partial with the reason, and fails with exit status `128 + N`.
fn stopped(args: &SweepRequest, rows: &[SweepRow], signals: &SignalStop, what: &str) -> Result<()> {
    let (end, code) = vps_app::exit::outcome(&SessionEnd::Stopped, Some(signals));
    let end = format!(
        "{end} during {what} (that row is left out; {} rows done)",
        rows.len()
    );
    let table = SweepTable {
        complete: false,
        end: end.clone(),
        rows: rows.to_vec(),
    };
    write_outputs(args, &table)?;
    Err(SessionExit {
        code,
        reason: format!("the sweep ended early: {end}; the partial table was written"),
    }
    .into())
}

/// The voxel sizes (mm) of a `--quick` sweep of a scene whose own voxel size is `own_m` (m):
/// twice it and it, coarse to fine (rounded to the nanometre, so that 2 × 2.5 mm is 5 mm).
fn quick_sizes_mm(own_m: f64) -> Vec<f64> {
    let mm = |x: f64| (x * 1e6).round() / 1e3;
    vec![mm(2.0 * own_m), mm(own_m)]
}

/// `--json` without a file: the table as JSON on stdout.
const JSON_TO_STDOUT: &str = "-";

/// Sessions in `--quick` mode are cut to this length (s).
const QUICK_SECONDS: f64 = 2.0;

struct Setting<'a> {
    /// The scene, its `voxels.force_model` set to this row's model.
    scene: &'a LoadedScene,
    /// The force model the scene file itself states.
    own_force_model: ForceModelName,
    exact: &'a ExactScene,
    voxel_size: f64,
    method: ShellMethodName,
    seconds: Option<f64>,
    points_per_frame: usize,
    /// The command's stop handlers: a set flag ends the running session (device written zero).
    signals: &'a SignalStop,
}

/// One row, or `None` when a signal stopped the sweep during it (the device was written zero).
fn measure(set: &Setting, map: &BuiltVoxmap) -> Result<Option<SweepRow>> {
    // Seconds 0: the script as the scene declares it (its own laps).
    let session = session_on(set.scene, map, set.voxel_size, set.method, 0.0)?;
    let seconds = set
        .seconds
        .unwrap_or(f64::INFINITY)
        .min(session.script.duration());
    let frames = ((seconds / session.params.dt).round() as u64).max(1);
    let (start, orientation) = session.script.sample(0.0);
    let initial = PartState::at_rest(start, orientation);
    let params = session.params;
    let script = session.script.clone();
    // Timing pass: the runtime's loop, free-running (frames back to back), one thread.
    let timed = run_sweep_session(&session, frames, false, set.signals)?;
    if !timed.end.is_complete() {
        return Ok(None);
    }
    let stride = session.shell.len().div_ceil(set.points_per_frame).max(1) as u64;
    let accuracy = accuracy_pass(
        set,
        &session,
        &params,
        SimulatedHand::new(script, HandParams::default())?,
        initial,
        frames,
        stride,
    )?;
    Ok(accuracy.map(|a| row(set, &session, &timed.stats, a)))
}

/// Per compared frame: (direction error deg, magnitude ratio) when both forces exist.
#[derive(Default)]
struct Accuracy {
    compared: u64,
    voxel_only: u64,
    reference_only: u64,
    angles_deg: Vec<f64>,
    ratios: Vec<f64>,
    min_separation_m: Option<f64>,
    /// Frames with a point in Surface or Interior, over the whole replay.
    touching: u64,
    /// Frames with a point in Interior, over the whole replay.
    penetrating: u64,
}

/// Replays the session deterministically through the sans-IO core (the same physics as the
/// runtime's loop: read, sample, step, saturate, write) and at every `stride`-th touching frame
/// compares the voxel force with the exact reference at the same pose. Ends with the exact zero
/// wrench written to the hand; `None` when the command's stop flag was set (checked every frame).
///
/// Voxel force `K_ff Σ d_i N_i` (before the N ≥ 10 averaging, which scales both alike); reference
/// `K_ff Σ e_i n_i` with exact depths `e_i = max(0, δ − φ_i)` from the surface offset by
/// [`reference_offset`] `δ = (offset_layers + ½) s`, or from the stand-off with the `distance`
/// force model. Frames with no point in Surface or Interior
/// are skipped: every point is then in a Free or Proximity voxel, whose near face lies at least
/// `offset_layers × s` from a plane (see [`reference_offset`]), so a reference force there would be
/// under `K_ff s / 2` per point; the reference is not computed there.
fn accuracy_pass(
    set: &Setting,
    session: &SweepSession,
    params: &HapticParams,
    mut hand: SimulatedHand,
    initial: PartState,
    frames: u64,
    stride: u64,
) -> Result<Option<Accuracy>> {
    let shell = session.shell.classed();
    let limits = hand.limits();
    // The distance model's force starts at its stand-off from the exact surface: the reference's
    // depths do too.
    let offset = set
        .scene
        .file
        .voxels
        .standoff_at(set.voxel_size)
        .unwrap_or_else(|| reference_offset(set.scene.file.voxels.offset_layers, set.voxel_size));
    let reach = offset + 2.0 * set.voxel_size;
    let mut state = initial;
    let mut acc = Accuracy::default();
    let mut touching = 0u64;
    let stop = set.signals.flag();
    for frame in 0..frames {
        if stop.load(Ordering::Relaxed) {
            hand.write(&Wrench::ZERO)?;
            return Ok(None);
        }
        let handle = hand.read(frame as f64 * params.dt)?;
        let sums = sample_all(&*session.tree, &shell, &KernelPose::from_state(&state));
        if sums.surface + sums.interior > 0 {
            touching += 1;
            acc.touching += 1;
            if sums.interior > 0 {
                acc.penetrating += 1;
            }
            if touching.is_multiple_of(stride) {
                let reference = reference_contact(
                    set.exact,
                    &session.shell.points().points,
                    state.position,
                    state.orientation,
                    offset,
                    reach,
                );
                acc.add(sums.depth_normal_si(), &reference);
            }
        }
        let out = step(params, &state, &handle, &sums);
        hand.write(&limits.saturate(&out.device_wrench))?;
        state = out.next_state;
    }
    hand.write(&Wrench::ZERO)?;
    Ok(Some(acc))
}

/// The offset `δ` (m) the reference measures depths from: `(offset_layers + ½) × s`, the outer
/// edge of the band the outermost force-layer voxel centres (where the voxel field starts to push,
/// `N·(C − P) = 0`) lie in, so every point the field can push is in the reference's contact set.
///
/// A plane at fraction `f ∈ [0, 1)` of the scan-converted voxel below its outer face puts that
/// voxel's outer face `(1 − f) s` out, and after `offset_layers = k` grown layers the outermost
/// force-layer voxel spans `[(k − f) s, (k + 1 − f) s]`: its centre lies `(k + ½ − f) s` out, from
/// `(k − ½) s` to `(k + ½) s`, `k s` on average over placements. The reference depth therefore
/// exceeds the field's by `f s` per point (`s / 2` on average): at resting contact, where the
/// field's depths are a small fraction of a voxel, `|F_vox| / |F_ref|` measures where the lattice
/// put the force layer, not the field's stiffness. (A mean offset `k s` was tried: where `f` is
/// small the field then holds the part outside `δ` and most frames have no reference force.)
pub fn reference_offset(offset_layers: u32, voxel_size: f64) -> f64 {
    (f64::from(offset_layers) + 0.5) * voxel_size
}

impl Accuracy {
    fn add(&mut self, voxel: DVec3, reference: &vps_reference::ReferenceContact) {
        self.compared += 1;
        if let Some(m) = reference.min_separation_m {
            self.min_separation_m = Some(self.min_separation_m.map_or(m, |x: f64| x.min(m)));
        }
        let exact = reference.depth_normal_sum_m;
        match (voxel.try_normalize(), exact.try_normalize()) {
            (Some(v), Some(r)) => {
                self.angles_deg
                    .push(v.dot(r).clamp(-1.0, 1.0).acos().to_degrees());
                self.ratios.push(voxel.length() / exact.length());
            }
            (Some(_), None) => self.voxel_only += 1,
            (None, Some(_)) => self.reference_only += 1,
            (None, None) => {}
        }
    }
}

/// The `q` quantile (0..=1) of `values` (nearest rank), `None` when empty.
fn quantile(values: &[f64], q: f64) -> Option<f64> {
    let mut v: Vec<f64> = values.to_vec();
    v.sort_by(f64::total_cmp);
    let i = ((v.len() as f64 - 1.0) * q).round() as usize;
    v.get(i).copied()
}

fn row(set: &Setting, session: &SweepSession, stats: &StatsSummary, acc: Accuracy) -> SweepRow {
    let errors: Vec<f64> = acc.ratios.iter().map(|r| (r - 1.0).abs()).collect();
    let own = &set.scene.file.voxels;
    let bits = session.tree.width().bits();
    SweepRow {
        scene: set.scene.name.clone(),
        method: set.method,
        voxel_size_mm: set.voxel_size * 1e3,
        voxel_width: bits,
        force_model: own.force_model,
        default: bits == u32::from(own.voxel_width)
            && set.method == own.shell_method
            && own.force_model == set.own_force_model,
        default_size: (set.voxel_size - own.voxel_size).abs() <= 1e-9 * own.voxel_size,
        voxelized: if set.scene.file.workspace.is_some() {
            "workspace"
        } else {
            "scene"
        }
        .into(),
        shell_points: session.shell.len(),
        voxmap_bytes: session.tree.memory_bytes(),
        voxelize_ms: session.voxelize_ms,
        frames: stats.frames,
        compute_p50_us: stats.compute_ns.p50 as f64 / 1e3,
        compute_p999_us: stats.compute_ns.p999 as f64 / 1e3,
        // From the deterministic replay, not the timed run: under load the runtime's watchdog
        // zeroes the wrench of frames that overran, which moves the simulated hand differently
        // from run to run.
        penetration_ratio: (acc.touching > 0).then(|| acc.penetrating as f64 / acc.touching as f64),
        compared_frames: acc.compared,
        both_force_frames: acc.angles_deg.len() as u64,
        voxel_only_frames: acc.voxel_only,
        reference_only_frames: acc.reference_only,
        direction_error_deg_p50: quantile(&acc.angles_deg, 0.5),
        direction_error_deg_p95: quantile(&acc.angles_deg, 0.95),
        magnitude_error_p50: quantile(&errors, 0.5),
        magnitude_ratio_p50: quantile(&acc.ratios, 0.5),
        min_separation_mm: acc.min_separation_m.map(|m| m * 1e3),
    }
}

/// The CSV columns, in order (the JSON has the same names).
pub const CSV_COLUMNS: &[&str] = &[
    "scene",
    "method",
    "voxel_size_mm",
    "voxel_width",
    "force_model",
    "default",
    "default_size",
    "voxelized",
    "shell_points",
    "voxmap_bytes",
    "voxelize_ms",
    "frames",
    "compute_p50_us",
    "compute_p999_us",
    "penetration_ratio",
    "compared_frames",
    "both_force_frames",
    "voxel_only_frames",
    "reference_only_frames",
    "direction_error_deg_p50",
    "direction_error_deg_p95",
    "magnitude_error_p50",
    "magnitude_ratio_p50",
    "min_separation_mm",
];

/// The table as CSV: the header of [`CSV_COLUMNS`], one line per row; a partial table ends with
/// a `# partial: REASON` line.
fn csv(table: &SweepTable) -> Result<String> {
    let mut out = CSV_COLUMNS.join(",") + "\n";
    for r in &table.rows {
        let value = serde_json::to_value(r)?;
        let cells: Vec<String> = CSV_COLUMNS
            .iter()
            .map(|c| match &value[*c] {
                serde_json::Value::Null => String::new(),
                serde_json::Value::String(s) => s.clone(),
                v => v.to_string(),
            })
            .collect();
        out += &(cells.join(",") + "\n");
    }
    if !table.complete {
        out += &format!("# partial: {}\n", table.end);
    }
    Ok(out)
}

/// Writes the JSON (to stdout with `--json`, else to its file), the CSV and the plots, and prints
/// the table as text with its recommendation unless the JSON went to stdout; files are written
/// atomically.
fn write_outputs(args: &SweepRequest, table: &SweepTable) -> Result<()> {
    let json = serde_json::to_string_pretty(table)? + "\n";
    match &args.json {
        Some(path) if path == Path::new(JSON_TO_STDOUT) => {
            vps_app::output::outln!("{}", json.trim_end())?
        }
        Some(path) => write_file(path, json.as_bytes())?,
        None => {}
    }
    if args.json.as_deref() != Some(Path::new(JSON_TO_STDOUT)) {
        vps_app::output::outln!("{}", text::table_text(table).trim_end())?;
    }
    if let Some(path) = &args.csv {
        write_file(path, csv(table)?.as_bytes())?;
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        plots::plot_all(&table.rows, dir)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vps_mesh::TriMesh;
    use vps_voxelize::{grid_for, voxelize_in, voxelize_tree};
    use vps_voxmap::TreeConfig;
    use vps_voxmap::VoxelWidth;
    use vps_voxmap::{LayeredVoxel, Voxel, VoxelLookup};

    fn rig() -> LoadedScene {
        LoadedScene::load("builtin:rig-teapot").unwrap()
    }

    /// The outermost force-layer voxel centres of an axis-aligned wall lie `(k ± ½) s` from it,
    /// `k s` on average over wall placements; the reference offset is the band's outer edge.
    #[test]
    fn reference_offset_is_the_mean_force_layer_centre_distance() {
        let objects = [vps_mesh::builtin::cuboid(glam::DVec3::new(
            0.05, 0.05, 0.05,
        ))];
        let s = 0.004;
        let k = 2;
        let mut distances = Vec::new();
        for step in 0..16 {
            let shift = s * (step as f64 + 0.37) / 16.0;
            let moved: Vec<TriMesh> = objects
                .iter()
                .map(|m| {
                    let mut m = m.clone();
                    m.vertices.iter_mut().for_each(|v| v.z += shift);
                    m
                })
                .collect();
            let opts = vps_voxelize::VoxelizeOptions {
                voxel_size: s,
                offset_layers: k,
                ..Default::default()
            };
            let (tree, _) = voxelize_tree(&moved, &opts, TreeConfig::default()).unwrap();
            let spec = *tree.spec();
            let top = 0.05 + shift;
            // Up the z axis through the top face's centre: the outermost Surface voxel.
            let outermost = (0..spec.dims[2] as i32)
                .rev()
                .map(|z| spec.index_of(glam::DVec3::new(0.0, 0.0, 0.0)).with_z(z))
                .find(|&ijk| tree.get(ijk) == Voxel::Surface)
                .unwrap();
            distances.push(spec.center_of(outermost).z - top);
        }
        let (lo, hi) = ((k as f64 - 0.5) * s, (k as f64 + 0.5) * s);
        assert!(
            distances
                .iter()
                .all(|d| (lo - 1e-9..=hi + 1e-9).contains(d)),
            "{distances:?}"
        );
        let mean = distances.iter().sum::<f64>() / distances.len() as f64;
        assert!(
            (mean - k as f64 * s).abs() < 0.05 * s,
            "{mean} {distances:?}"
        );
        assert!((reference_offset(k, s) - hi).abs() < 1e-12);
    }

    /// The sparse 2-bit map of the rig's workspace holds the same voxels as the dense pipeline on
    /// the region's own padded grid (what the sweep used before wide voxels), and the wide maps
    /// hold the same kinds at layer 0 with deeper layers inside.
    #[test]
    fn rig_map_matches_the_dense_pipeline_and_wide_maps_add_layers() {
        let scene = rig();
        let s = 0.01;
        let opts = scene.voxelize_options(s, VoxelWidth::Two);
        let region = scene.file.workspace.unwrap().aabb();
        let dense = voxelize_in(
            &scene.placed_statics(),
            grid_for(&region, &opts).unwrap(),
            &opts,
        )
        .unwrap();
        let maps: Vec<BuiltVoxmap> = VoxelWidth::ALL
            .iter()
            .map(|&w| scene.build_voxmap(s, w, &CachePolicy::Off, false).unwrap())
            .collect();
        let spec = *maps[0].tree.spec();
        let (mut deep, mut checked) = (0, 0);
        for i in 0..spec.dims[0] as i32 {
            for j in 0..spec.dims[1] as i32 {
                for k in 0..spec.dims[2] as i32 {
                    let ijk = glam::IVec3::new(i, j, k);
                    let centre = spec.center_of(ijk);
                    let want = dense.get(dense.spec().index_of(centre));
                    assert_eq!(maps[0].tree.get(ijk), want, "{centre}");
                    checked += 1;
                    for wide in &maps[1..] {
                        let v: LayeredVoxel = wide.tree.get_layered(ijk);
                        match want {
                            Voxel::Interior => assert!(
                                v.kind == Voxel::Interior || v.kind == Voxel::Surface,
                                "{centre}"
                            ),
                            Voxel::Surface => assert_eq!(v.kind, Voxel::Surface),
                            _ => assert!(v.kind != Voxel::Interior),
                        }
                        if want == Voxel::Interior && v.kind == Voxel::Surface {
                            assert!(v.layer >= 1, "{centre}");
                            deep += 1;
                        }
                    }
                }
            }
        }
        assert!(checked > 1000 && deep > 100, "{checked} {deep}");
    }
}
