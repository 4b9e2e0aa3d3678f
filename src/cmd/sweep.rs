//! `vps sweep`: speed against accuracy over voxel sizes and point-shell methods on standard scenes
//! (scene files) and their scripted sessions. Per setting: point count, voxmap memory,
//! voxelization time, frame compute p50/p99.9 (free-running 1 kHz loop), penetration ratio, and at
//! sampled touching frames the voxel contact force against the exact reference (vps-reference):
//! direction and magnitude error, minimum exact separation. Writes JSON, CSV and SVG plots.

use crate::cli::SweepArgs;
use crate::scene_config::{SceneConfig, ShellMethodName};
use crate::session::{classed, laps_script, SessionScene};
use anyhow::{bail, Context, Result};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;
use vps_device::{HandParams, HapticDevice, SimulatedHand};
use vps_haptic::{sample_all, step, HapticParams, KernelPose, PartState};
use vps_mesh::TriMesh;
use vps_reference::{reference_contact, ExactScene};
use vps_runtime::{run_loop, LoopConfig, StatsSummary};
use vps_voxelize::{
    grid_for, point_shell, voxelize_in_with_stats, voxelize_with_stats, VoxelizeOptions,
};
use vps_voxmap::{TreeConfig, VoxelTree};

/// The sweep file (`configs/sweep.toml`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepConfig {
    /// Voxel sizes (mm) for every run that does not list its own.
    voxel_sizes_mm: Vec<f64>,
    /// Shell methods.
    methods: Vec<ShellMethodName>,
    /// Reference cost budget: the exact reference is computed at every Nth touching frame with
    /// N = ceil(shell points / this).
    #[serde(default = "default_points_per_frame")]
    reference_points_per_frame: usize,
    /// The runs.
    run: Vec<RunSpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RunSpec {
    /// Scene file, relative to the sweep file.
    scene: PathBuf,
    /// Voxel sizes (mm) for this run.
    voxel_sizes_mm: Option<Vec<f64>>,
    /// Longest session (s); default the whole script.
    seconds: Option<f64>,
}

fn default_points_per_frame() -> usize {
    500
}

/// One row of the table: one scene × shell method × voxel size.
#[derive(Clone, Debug, Serialize)]
pub struct SweepRow {
    /// Scene name.
    pub scene: String,
    /// Shell method.
    pub method: ShellMethodName,
    /// Voxel edge (mm).
    pub voxel_size_mm: f64,
    /// What was voxelized: `scene` or `workspace`.
    pub voxelized: String,
    /// Shell points.
    pub shell_points: usize,
    /// Voxmap (tree) memory (bytes).
    pub voxmap_bytes: usize,
    /// Voxelization and tree build (ms).
    pub voxelize_ms: f64,
    /// Frames in the session.
    pub frames: u64,
    /// Frame compute p50 (µs), free-running loop, one thread.
    pub compute_p50_us: f64,
    /// Frame compute p99.9 (µs).
    pub compute_p999_us: f64,
    /// Frames with a point in Interior over frames with a point in Surface or Interior.
    pub penetration_ratio: Option<f64>,
    /// Touching frames where the reference was computed.
    pub compared_frames: u64,
    /// Compared frames where both the voxel force and the reference force are non-zero.
    pub both_force_frames: u64,
    /// Compared frames with a voxel force but no reference force.
    pub voxel_only_frames: u64,
    /// Compared frames with a reference force but no voxel force.
    pub reference_only_frames: u64,
    /// Angle between voxel and reference force (degrees): median over `both_force_frames`.
    pub direction_error_deg_p50: Option<f64>,
    /// The same, 95th percentile.
    pub direction_error_deg_p95: Option<f64>,
    /// |(|F_vox| − |F_ref|) / |F_ref||, median over `both_force_frames`.
    pub magnitude_error_p50: Option<f64>,
    /// |F_vox| / |F_ref|, median (below 1: the voxel field is softer than the reference).
    pub magnitude_ratio_p50: Option<f64>,
    /// Smallest exact signed distance of any shell point over the compared frames (mm; negative =
    /// the exact surface was penetrated).
    pub min_separation_mm: Option<f64>,
}

/// Runs the sweep.
pub fn run(args: &SweepArgs) -> Result<()> {
    let text = std::fs::read_to_string(&args.config)
        .with_context(|| format!("reading {}", args.config.display()))?;
    let config: SweepConfig =
        toml::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", args.config.display()))?;
    if config.run.is_empty() || config.methods.is_empty() {
        bail!(
            "{}: needs at least one [[run]] and one method",
            args.config.display()
        );
    }
    let base = args.config.parent().unwrap_or(Path::new("."));
    let mut rows = Vec::new();
    for spec in &config.run {
        let path = base.join(&spec.scene);
        let scene = SceneConfig::from_file(&path)?;
        scene.voxels.check_supported(&path)?;
        let scene_dir = path.parent().unwrap_or(Path::new("."));
        let (objects, part) = scene.load_meshes(scene_dir)?;
        let exact = ExactScene::new(&objects)
            .with_context(|| format!("{}: building the exact reference", path.display()))?;
        let mut sizes = spec
            .voxel_sizes_mm
            .clone()
            .unwrap_or(config.voxel_sizes_mm.clone());
        let mut seconds = spec.seconds;
        if args.quick {
            sizes.retain(|&s| s >= 5.0);
            sizes.truncate(2);
            seconds = Some(seconds.unwrap_or(f64::INFINITY).min(QUICK_SECONDS));
        }
        for &size_mm in &sizes {
            if !(size_mm.is_finite() && size_mm > 0.0) {
                bail!(
                    "{}: voxel size {size_mm} mm is not a positive length",
                    args.config.display()
                );
            }
            for &method in &config.methods {
                eprintln!("sweep: {} {} mm {:?}", scene.name, size_mm, method);
                let setting = Setting {
                    scene: &scene,
                    objects: &objects,
                    part: &part,
                    exact: &exact,
                    voxel_size: size_mm * 1e-3,
                    method,
                    seconds,
                    points_per_frame: config.reference_points_per_frame.max(1),
                };
                rows.push(measure(&setting)?);
            }
        }
    }
    write_outputs(args, &rows)
}

/// Sessions in `--quick` mode are cut to this length (s).
const QUICK_SECONDS: f64 = 2.0;

struct Setting<'a> {
    scene: &'a SceneConfig,
    objects: &'a [TriMesh],
    part: &'a TriMesh,
    exact: &'a ExactScene,
    voxel_size: f64,
    method: ShellMethodName,
    seconds: Option<f64>,
    points_per_frame: usize,
}

/// Voxelizes the scene (its workspace region only, when it declares one) and builds the shell.
pub fn build_session(
    scene: &SceneConfig,
    objects: &[TriMesh],
    part: &TriMesh,
    voxel_size: f64,
    method: ShellMethodName,
) -> Result<SessionScene> {
    let opts = VoxelizeOptions {
        voxel_size,
        offset_layers: scene.voxels.offset_layers,
        ..VoxelizeOptions::default()
    };
    let t = Instant::now();
    let (dense, _) = match &scene.workspace {
        Some(region) => voxelize_in_with_stats(objects, grid_for(&region.aabb(), &opts)?, &opts)?,
        None => voxelize_with_stats(objects, &opts)?,
    };
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default())?;
    let voxelize_ms = t.elapsed().as_secs_f64() * 1e3;
    drop(dense);
    let shell = point_shell(part, voxel_size, method.method())?;
    Ok(SessionScene {
        tree: Arc::new(tree),
        shell,
        corridor: scene.waypoints(),
        scene_triangles: objects.iter().map(TriMesh::triangle_count).sum(),
        voxelize_ms,
    })
}

/// The haptic parameters of a scene at a voxel size.
pub fn session_params(
    scene: &SceneConfig,
    session: &SessionScene,
    voxel_size: f64,
) -> Result<HapticParams> {
    Ok(HapticParams {
        braking: scene.voxels.braking,
        ..HapticParams::default()
    }
    .with_scene(voxel_size, session.shell.max_radius())?)
}

fn measure(set: &Setting) -> Result<SweepRow> {
    let session = build_session(set.scene, set.objects, set.part, set.voxel_size, set.method)?;
    let params = session_params(set.scene, &session, set.voxel_size)?;
    let script = laps_script(
        &session.tree,
        &session.corridor,
        set.scene.corridor.reach,
        set.scene.corridor.laps,
    )?;
    let seconds = set.seconds.unwrap_or(f64::INFINITY).min(script.duration());
    let frames = ((seconds / params.dt).round() as u64).max(1);
    let (start, orientation) = script.sample(0.0);
    let initial = PartState::at_rest(start, orientation);
    // Timing pass: the runtime's loop, free-running (frames back to back), one thread.
    let timed = run_loop(
        session.tree.clone(),
        classed(&session.shell),
        params,
        Box::new(SimulatedHand::new(script.clone(), HandParams::default())?),
        initial,
        LoopConfig {
            frames: Some(frames),
            threads: 1,
            realtime: false,
            free_running: true,
            ..LoopConfig::default()
        },
        None,
        Arc::new(AtomicBool::new(false)),
    )?;
    if let Some(err) = &timed.device_error {
        bail!("the simulated hand failed: {err}");
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
    Ok(row(set, &session, &timed.stats, accuracy))
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
}

/// Replays the session deterministically through the sans-IO core (the same physics as the
/// runtime's loop: read, sample, step, saturate, write) and at every `stride`-th touching frame
/// compares the voxel force with the exact reference at the same pose.
///
/// Voxel force `K_ff Σ d_i N_i` (before the N ≥ 10 averaging, which scales both alike); reference
/// `K_ff Σ e_i n_i` with exact depths from the surface offset by `δ = (offset_layers + ½) s`: the
/// voxel field starts to push where a point passes the centre of an outermost force-layer voxel,
/// which lies `offset_layers × s` plus up to one voxel from the exact surface; `δ` is the middle of
/// that band. Frames with no point in Surface or Interior are skipped: every point is then in a
/// Free or Proximity voxel, at least `offset_layers × s` from the exact surface (one voxel less
/// than `δ` at worst, so a reference force there would be under `K_ff s` per point); the
/// reference is not computed there.
fn accuracy_pass(
    set: &Setting,
    session: &SessionScene,
    params: &HapticParams,
    mut hand: SimulatedHand,
    initial: PartState,
    frames: u64,
    stride: u64,
) -> Result<Accuracy> {
    let shell = classed(&session.shell);
    let limits = hand.limits();
    let offset = (f64::from(set.scene.voxels.offset_layers) + 0.5) * set.voxel_size;
    let reach = offset + 2.0 * set.voxel_size;
    let mut state = initial;
    let mut acc = Accuracy::default();
    let mut touching = 0u64;
    for frame in 0..frames {
        let handle = hand.read(frame as f64 * params.dt)?;
        let sums = sample_all(&*session.tree, &shell, &KernelPose::from_state(&state));
        if sums.surface + sums.interior > 0 {
            touching += 1;
            if touching % stride == 0 {
                let reference = reference_contact(
                    set.exact,
                    &session.shell.points,
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
    Ok(acc)
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

fn row(set: &Setting, session: &SessionScene, stats: &StatsSummary, acc: Accuracy) -> SweepRow {
    let errors: Vec<f64> = acc.ratios.iter().map(|r| (r - 1.0).abs()).collect();
    SweepRow {
        scene: set.scene.name.clone(),
        method: set.method,
        voxel_size_mm: set.voxel_size * 1e3,
        voxelized: if set.scene.workspace.is_some() {
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
        penetration_ratio: stats.penetration_ratio,
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

fn csv(rows: &[SweepRow]) -> Result<String> {
    let mut out = CSV_COLUMNS.join(",") + "\n";
    for r in rows {
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
    Ok(out)
}

fn write_outputs(args: &SweepArgs, rows: &[SweepRow]) -> Result<()> {
    let json = serde_json::to_string_pretty(rows)?;
    match &args.json {
        Some(path) => {
            std::fs::write(path, &json).with_context(|| format!("writing {}", path.display()))?
        }
        None => println!("{json}"),
    }
    if let Some(path) = &args.csv {
        std::fs::write(path, csv(rows)?).with_context(|| format!("writing {}", path.display()))?;
    }
    if let Some(dir) = &args.plots {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        super::sweep_plots::plot_all(rows, dir)?;
    }
    Ok(())
}
