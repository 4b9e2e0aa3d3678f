//! One benchmark setting measured over every scene, and the sliding-box smoothness run.
//!
//! Per pose: the voxel sums `Σ d N`, `Σ (P − x) × d N` (the kernel at that pose, no dynamics) and
//! the exact reference `Σ e n`, `Σ (P − x) × e n` for the same shell points, depths measured from
//! `δ = (offset_layers + ½) s` (the outer edge of the band where the outermost force layer starts to
//! push; see docs/sweep.md). Compared where both are non-zero:
//! - force direction error: the angle between the two sums (degrees);
//! - force ratio `|Σ d N| / |Σ e n|` (where the lattice put the force layer, see docs/sweep.md);
//! - torque direction error (degrees), where the exact torque is significant, `|T| > 0.1 |F| r_max`;
//! - lever error `|T_v / |F_v| − T_r / |F_r|| / r_max`: how far the voxel force's effective point
//!   of action is from the exact one, as a fraction of the part's radius (0 = exact torque for the
//!   force).

use crate::scenes::SceneKind;
use crate::FidelityError;
use glam::{DQuat, DVec3, Vec3};
use rayon::prelude::*;
use vps_haptic::contact::contact_wrench;
use vps_haptic::{sample_all, ClassedShell, HapticParams, KernelPose, PartState, PartialSums};
use vps_mesh::TriMesh;
use vps_reference::{reference_contact, ExactScene, ReferenceContact};
use vps_voxelize::distance::distance_band;
use vps_voxelize::{point_shell, voxelize_tree, ShellMethod, VoxelWidth, VoxelizeOptions};
use vps_voxmap::{TreeConfig, VoxelTree};

/// Force layers grown outside each obstacle (the scenes' default, 2).
pub const OFFSET_LAYERS: u32 = 2;

/// Depths (voxels) at which the `distance` model is measured: its separations are
/// `standoff − depth` (the tangent-plane model's come from [`FidelityGrid::separations_voxels`],
/// measured from its own offset of `offset_layers + ½` voxels). From one voxel deep to a
/// thirty-second of a voxel (resting contact sits near `s / 40` with the default gains), and one
/// pose set half a voxel clear of the stand-off (no contact expected).
pub const DISTANCE_DEPTHS_VOXELS: [f64; 7] = [1.0, 0.5, 0.25, 0.125, 0.0625, 0.03125, -0.5];

/// Which force model a row measures.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ForceModel {
    /// The paper's tangent-plane model on the voxel layers (offset `OFFSET_LAYERS`).
    TangentPlane,
    /// The signed-distance band with a stand-off of `standoff_voxels` voxels.
    Distance {
        /// Stand-off in voxels.
        standoff_voxels: f64,
    },
}

impl ForceModel {
    /// The distance model at its default stand-off.
    pub const DISTANCE: ForceModel = ForceModel::Distance {
        standoff_voxels: vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS,
    };

    /// `tangent-plane` or `distance`.
    pub fn name(self) -> &'static str {
        match self {
            ForceModel::TangentPlane => "tangent-plane",
            ForceModel::Distance { .. } => "distance",
        }
    }

    /// Where the exact reference's depths start (m): the tangent-plane model's offset
    /// (`offset_layers + ½` voxels) or the stand-off.
    pub fn reference_offset_m(self, s: f64) -> f64 {
        match self {
            ForceModel::TangentPlane => (f64::from(OFFSET_LAYERS) + 0.5) * s,
            ForceModel::Distance { standoff_voxels } => standoff_voxels * s,
        }
    }

    /// The voxmap of `obstacles` (world frame, m) that this model samples, at voxel size `s` (m)
    /// and `width`: voxelized with [`OFFSET_LAYERS`] offset layers, plus, for the distance model,
    /// the distance band at its stand-off. `scene` names the scene in errors. Blocking, parallel,
    /// allocates the map.
    pub fn voxmap(
        self,
        scene: &'static str,
        obstacles: &[TriMesh],
        s: f64,
        width: VoxelWidth,
    ) -> Result<VoxelTree, FidelityError> {
        let opts = VoxelizeOptions {
            voxel_size: s,
            offset_layers: OFFSET_LAYERS,
            width,
            ..VoxelizeOptions::default()
        };
        let (tree, _) =
            voxelize_tree(obstacles, &opts, TreeConfig::default()).map_err(|source| {
                FidelityError::Voxelize {
                    scene,
                    voxel_size_m: s,
                    source,
                }
            })?;
        Ok(match self {
            ForceModel::TangentPlane => tree,
            ForceModel::Distance { standoff_voxels } => {
                let band = distance_band(&tree, obstacles, standoff_voxels * s, u64::MAX)
                    .map_err(|source| FidelityError::Band { scene, source })?;
                tree.with_distance_band(band)
            }
        })
    }

    /// The separations (voxels) this model is measured at.
    pub fn separations_voxels(self, grid: &FidelityGrid) -> Vec<f64> {
        match self {
            ForceModel::TangentPlane => grid.separations_voxels.clone(),
            ForceModel::Distance { standoff_voxels } => DISTANCE_DEPTHS_VOXELS
                .iter()
                .map(|d| standoff_voxels - d)
                .collect(),
        }
    }
}

/// Exact torque counted as significant above this fraction of `|F| r_max`.
const SIGNIFICANT_TORQUE: f64 = 0.1;

/// What to measure.
#[derive(Clone, Debug, PartialEq)]
pub struct FidelityGrid {
    /// Voxel sizes (m).
    pub voxel_sizes_m: Vec<f64>,
    /// Bits per voxel of the obstacles' voxmaps.
    pub widths: Vec<VoxelWidth>,
    /// Shell methods of the part.
    pub methods: Vec<ShellMethod>,
    /// Separations, in voxels (gap between the part's mesh and the obstacle's; negative =
    /// penetration).
    pub separations_voxels: Vec<f64>,
    /// Poses per scene and separation (jittered inside a voxel and about the free axes).
    pub poses: usize,
    /// Frames of the sliding-box run (0.1 mm per frame).
    pub slide_frames: usize,
    /// Force models measured (each setting once per model).
    pub models: Vec<ForceModel>,
}

impl FidelityGrid {
    /// The documented grid: 10, 5, 2.5, 1.25 mm × 2/4/8 bits × both methods, separations −1 to 3
    /// voxels in half voxels, 8 poses each, a 40 mm slide.
    pub fn full() -> Self {
        Self {
            voxel_sizes_m: vec![0.01, 0.005, 0.0025, 0.00125],
            widths: VoxelWidth::ALL.to_vec(),
            methods: vec![ShellMethod::VoxelCentres, ShellMethod::ExactSurface],
            separations_voxels: vec![-1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0],
            poses: 8,
            slide_frames: 400,
            models: vec![ForceModel::TangentPlane, ForceModel::DISTANCE],
        }
    }

    /// Checks the grid; errors name the field.
    pub fn validate(&self) -> Result<(), FidelityError> {
        let bad = |m: &str| Err(FidelityError::Grid(m.to_owned()));
        if self.voxel_sizes_m.is_empty()
            || self.widths.is_empty()
            || self.methods.is_empty()
            || self.models.is_empty()
        {
            return bad(
                "voxel sizes, widths, methods and models must each list at least one value",
            );
        }
        if self.models.iter().any(|m| match m {
            ForceModel::TangentPlane => false,
            ForceModel::Distance { standoff_voxels } => {
                !(0.0..=vps_voxmap::distance::MAX_STANDOFF_VOXELS).contains(standoff_voxels)
            }
        }) {
            return bad("a distance model's stand-off must be within 0..=1 voxel");
        }
        if self
            .voxel_sizes_m
            .iter()
            .any(|s| !(s.is_finite() && (0.0005..=0.02).contains(s)))
        {
            return bad("voxel sizes must be in [0.5 mm, 20 mm]");
        }
        if self
            .separations_voxels
            .iter()
            .any(|d| !(d.is_finite() && (-2.0..=4.0).contains(d)))
            || self.separations_voxels.is_empty()
        {
            return bad("separations must be in [-2, 4] voxels (at least one)");
        }
        if !(1..=64).contains(&self.poses) || !(2..=100_000).contains(&self.slide_frames) {
            return bad("poses must be in 1..=64 and slide frames in 2..=100000");
        }
        Ok(())
    }
}

/// The figures of one scene (or of all scenes together) at one setting.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SceneFigures {
    /// Scene name, or `all`.
    pub scene: String,
    /// Shell points of the part (0 for `all`).
    pub shell_points: usize,
    /// Poses measured.
    pub poses: usize,
    /// Poses where both the voxel and the exact force are non-zero.
    pub compared: usize,
    /// Poses with a voxel force but no exact one (the lattice put the force layer beyond δ).
    pub voxel_only: usize,
    /// Poses with an exact force but no voxel one (a miss: no field where the reference pushes).
    pub reference_only: usize,
    /// Poses with a shell point in an Interior voxel.
    pub interior_poses: usize,
    /// Force direction error (degrees), median and 95th percentile (nearest rank) over `compared`.
    pub force_dir_err_deg_p50: f64,
    /// See `force_dir_err_deg_p50`.
    pub force_dir_err_deg_p95: f64,
    /// Median of `|Σ d N| / |Σ e n|` over `compared`.
    pub force_ratio_p50: f64,
    /// Poses whose exact torque is significant (`|T| > 0.1 |F| r_max`) and the voxel torque non-zero.
    pub torque_compared: usize,
    /// Torque direction error (degrees), median over `torque_compared` (0 when none).
    pub torque_dir_err_deg_p50: f64,
    /// Lever error as a fraction of r_max, median and 95th percentile over `compared`.
    pub lever_err_p50: f64,
    /// See `lever_err_p50`.
    pub lever_err_p95: f64,
}

/// Smoothness of the force while a box slides along a plane at constant depth.
///
/// The 30 mm cube, turned 17° about z, slides along x at 0.1 mm per frame (0.1 m/s at 1 kHz) with
/// its bottom face `gap_voxels` voxels above the plane (exact depth from δ: `2.5 − gap_voxels`
/// voxels, constant). Force: the contact force the part would feel, `K_ff Σ d N` with the paper's
/// averaging, default gains for the voxel size (N).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct SlideFigures {
    /// Gap between the cube's bottom face and the plane (voxels).
    pub gap_voxels: f64,
    /// Frames.
    pub frames: usize,
    /// Mean |F| over the frames (N).
    pub mean_force_n: f64,
    /// 99th percentile (nearest rank) of |F(k) − F(k − 1)| (N).
    pub p99_jump_n: f64,
    /// Largest frame-to-frame jump (N).
    pub max_jump_n: f64,
    /// `p99_jump_n / mean_force_n` (0 when the mean is 0).
    pub p99_jump_relative: f64,
    /// The same p99 for the exact reference force (with the same averaging rule) (N): what the
    /// geometry alone gives.
    pub reference_p99_jump_n: f64,
}

/// One setting: force model, voxel size, width, shell method; every scene and the slide.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SettingRow {
    /// `tangent-plane` or `distance`.
    pub model: &'static str,
    /// The distance model's stand-off (voxels); 0 for the tangent-plane model.
    pub standoff_voxels: f64,
    /// Voxel size (mm).
    pub voxel_size_mm: f64,
    /// Bits per voxel.
    pub bits: u32,
    /// `centres` or `exact`.
    pub method: &'static str,
    /// All scenes pooled.
    pub all: SceneFigures,
    /// Per scene, in [`SceneKind::ALL`] order.
    pub scenes: Vec<SceneFigures>,
    /// The sliding box, shallow. Tangent plane: 2 voxels above the plane (exact depth ½ voxel:
    /// where resting contact sits, in the outermost force layer). Distance: 1/16 voxel into the
    /// stand-off.
    pub slide_shallow: SlideFigures,
    /// The sliding box, deep. Tangent plane: 1 voxel above the plane (exact depth 1½ voxels: one
    /// voxel deeper than the outermost force layer, Interior in a 2-bit map). Distance: 1 voxel
    /// into the stand-off (a voxel-centre shell's points lie up to half a voxel inside the part's
    /// faces, so less would leave them without contact).
    pub slide_deep: SlideFigures,
}

/// The benchmark's output.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FidelityReport {
    /// Separations swept (voxels).
    pub separations_voxels: Vec<f64>,
    /// Poses per scene and separation.
    pub poses_per_separation: usize,
    /// Force layers grown around the obstacles.
    pub offset_layers: u32,
    /// The exact reference's depth offset δ in voxels (`offset_layers + ½`).
    pub reference_offset_voxels: f64,
    /// One row per setting.
    pub rows: Vec<SettingRow>,
}

/// Measures every setting of `grid`. Blocking, parallel, allocates (voxmaps of the obstacles).
pub fn run(grid: &FidelityGrid) -> Result<FidelityReport, FidelityError> {
    grid.validate()?;
    let mut rows = Vec::new();
    for &model in &grid.models {
        for &s in &grid.voxel_sizes_m {
            for &width in &grid.widths {
                for &method in &grid.methods {
                    rows.push(measure_setting(grid, model, s, width, method)?);
                }
            }
        }
    }
    Ok(FidelityReport {
        separations_voxels: grid.separations_voxels.clone(),
        poses_per_separation: grid.poses,
        offset_layers: OFFSET_LAYERS,
        reference_offset_voxels: f64::from(OFFSET_LAYERS) + 0.5,
        rows,
    })
}

/// One pose's comparison.
#[derive(Clone, Copy, Debug, Default)]
struct PoseSample {
    voxel_force: DVec3,
    voxel_torque: DVec3,
    exact_force: DVec3,
    exact_torque: DVec3,
    interior: bool,
}

/// A scene prepared at one setting.
struct Prepared {
    tree: VoxelTree,
    exact: ExactScene,
    shell_points: Vec<Vec3>,
    classed: ClassedShell,
    body_vertices: Vec<DVec3>,
    max_radius: f64,
    /// Where the exact reference's depths start (m), [`ForceModel::reference_offset_m`].
    reference_offset_m: f64,
}

fn prepare(
    scene: SceneKind,
    model: ForceModel,
    s: f64,
    width: VoxelWidth,
    method: ShellMethod,
    obstacles: &[TriMesh],
    part: &TriMesh,
) -> Result<Prepared, FidelityError> {
    let voxelize_err = |source| FidelityError::Voxelize {
        scene: scene.name(),
        voxel_size_m: s,
        source,
    };
    let tree = model.voxmap(scene.name(), obstacles, s, width)?;
    let shell = point_shell(part, s, method).map_err(voxelize_err)?;
    let exact = ExactScene::new(obstacles).map_err(|source| FidelityError::Reference {
        scene: scene.name(),
        source,
    })?;
    let com = shell.mass.center_of_mass;
    Ok(Prepared {
        tree,
        exact,
        classed: ClassedShell::new(&shell, 1),
        max_radius: shell.max_radius(),
        shell_points: shell.points,
        body_vertices: part.vertices.iter().map(|v| *v - com).collect(),
        reference_offset_m: model.reference_offset_m(s),
    })
}

impl Prepared {
    /// The voxel sums of the part at rest at `position`, `orientation` over voxels of `s` (m),
    /// and the exact contact of its shell points, counted from the model's reference offset
    /// ([`ForceModel::reference_offset_m`]), over one voxel.
    fn sums_and_reference(
        &self,
        s: f64,
        position: DVec3,
        orientation: DQuat,
    ) -> (PartialSums, ReferenceContact) {
        let state = PartState::at_rest(position, orientation);
        let sums = sample_all(&self.tree, &self.classed, &KernelPose::from_state(&state));
        let offset = self.reference_offset_m;
        let reference = reference_contact(
            &self.exact,
            &self.shell_points,
            position,
            orientation,
            offset,
            offset + s,
        );
        (sums, reference)
    }

    fn sample(&self, s: f64, position: DVec3, orientation: DQuat) -> PoseSample {
        let (sums, reference) = self.sums_and_reference(s, position, orientation);
        PoseSample {
            voxel_force: sums.depth_normal_si(),
            voxel_torque: sums.depth_torque_si(),
            exact_force: reference.depth_normal_sum_m,
            exact_torque: reference.depth_torque_sum_m2,
            interior: sums.interior > 0,
        }
    }
}

/// The `k`-th point of a 3-D low-discrepancy sequence in [0, 1)³ (R3 sequence, Roberts 2018).
fn jitter(k: usize) -> [f64; 3] {
    const G: f64 = 1.220_744_084_605_759_5; // the plastic-like constant of the R3 sequence
    let a = [1.0 / G, 1.0 / (G * G), 1.0 / (G * G * G)];
    let k = k as f64 + 1.0;
    a.map(|ai| (0.5 + ai * k).fract())
}

fn measure_setting(
    grid: &FidelityGrid,
    model: ForceModel,
    s: f64,
    width: VoxelWidth,
    method: ShellMethod,
) -> Result<SettingRow, FidelityError> {
    let mut scenes = Vec::new();
    let mut pooled = Vec::new();
    let mut pooled_radius = Vec::new();
    for scene in SceneKind::ALL {
        let prepared = prepare(
            scene,
            model,
            s,
            width,
            method,
            &scene.obstacles(s),
            &scene.part(),
        )?;
        let poses: Vec<(f64, usize)> = model
            .separations_voxels(grid)
            .iter()
            .flat_map(|&d| (0..grid.poses).map(move |k| (d, k)))
            .collect();
        let samples: Vec<PoseSample> = poses
            .par_iter()
            .map(|&(d, k)| {
                let (position, orientation) =
                    scene.pose(&prepared.body_vertices, d * s, s, jitter(k));
                prepared.sample(s, position, orientation)
            })
            .collect();
        let mut figures = figures(scene.name(), &samples, prepared.max_radius);
        figures.shell_points = prepared.shell_points.len();
        scenes.push(figures);
        pooled_radius.extend(std::iter::repeat_n(prepared.max_radius, samples.len()));
        pooled.extend(samples);
    }
    let all = figures_with_radii("all", &pooled, &pooled_radius);
    let (shallow, deep) = match model {
        ForceModel::TangentPlane => (2.0, 1.0),
        ForceModel::Distance { standoff_voxels } => {
            (standoff_voxels - 0.0625, standoff_voxels - 1.0)
        }
    };
    let slide_shallow = slide(grid, model, s, width, method, shallow)?;
    let slide_deep = slide(grid, model, s, width, method, deep)?;
    Ok(SettingRow {
        model: model.name(),
        standoff_voxels: match model {
            ForceModel::TangentPlane => 0.0,
            ForceModel::Distance { standoff_voxels } => standoff_voxels,
        },
        voxel_size_mm: s * 1e3,
        bits: width.bits(),
        method: match method {
            ShellMethod::VoxelCentres => "centres",
            ShellMethod::ExactSurface => "exact",
        },
        all,
        scenes,
        slide_shallow,
        slide_deep,
    })
}

fn figures(name: &str, samples: &[PoseSample], max_radius: f64) -> SceneFigures {
    figures_with_radii(name, samples, &vec![max_radius; samples.len()])
}

fn figures_with_radii(name: &str, samples: &[PoseSample], radii: &[f64]) -> SceneFigures {
    let mut out = SceneFigures {
        scene: name.to_owned(),
        poses: samples.len(),
        ..SceneFigures::default()
    };
    let (mut dir, mut ratio, mut torque_dir, mut lever) = (vec![], vec![], vec![], vec![]);
    for (p, &r_max) in samples.iter().zip(radii) {
        out.interior_poses += usize::from(p.interior);
        let (fv, fr) = (p.voxel_force.length(), p.exact_force.length());
        match (fv > 0.0, fr > 0.0) {
            (true, true) => {}
            (true, false) => {
                out.voxel_only += 1;
                continue;
            }
            (false, true) => {
                out.reference_only += 1;
                continue;
            }
            (false, false) => continue,
        }
        out.compared += 1;
        dir.push(angle_deg(p.voxel_force, p.exact_force));
        ratio.push(fv / fr);
        lever.push((p.voxel_torque / fv - p.exact_torque / fr).length() / r_max);
        if p.exact_torque.length() > SIGNIFICANT_TORQUE * fr * r_max
            && p.voxel_torque.length() > 0.0
        {
            out.torque_compared += 1;
            torque_dir.push(angle_deg(p.voxel_torque, p.exact_torque));
        }
    }
    out.force_dir_err_deg_p50 = percentile(&mut dir, 50.0);
    out.force_dir_err_deg_p95 = percentile(&mut dir, 95.0);
    out.force_ratio_p50 = percentile(&mut ratio, 50.0);
    out.torque_dir_err_deg_p50 = percentile(&mut torque_dir, 50.0);
    out.lever_err_p50 = percentile(&mut lever, 50.0);
    out.lever_err_p95 = percentile(&mut lever, 95.0);
    out
}

/// The sliding-box run of [`SlideFigures`].
fn slide(
    grid: &FidelityGrid,
    model: ForceModel,
    s: f64,
    width: VoxelWidth,
    method: ShellMethod,
    gap_voxels: f64,
) -> Result<SlideFigures, FidelityError> {
    let scene = SceneKind::SpherePlane; // only its obstacle (the plane slab) is used
    let part = vps_mesh::builtin::cuboid(DVec3::splat(0.015));
    let prepared = prepare(scene, model, s, width, method, &scene.obstacles(s), &part)?;
    let params = HapticParams::default().with_scene(s, prepared.max_radius)?;
    let gains = params.gains();
    let orientation = DQuat::from_rotation_z(17f64.to_radians());
    let lowest = prepared
        .body_vertices
        .iter()
        .map(|v| (orientation * *v).z)
        .fold(f64::MAX, f64::min);
    let step = 1e-4;
    let start = -0.5 * step * grid.slide_frames as f64;
    let forces: Vec<(DVec3, DVec3)> = (0..grid.slide_frames)
        .into_par_iter()
        .map(|k| {
            let position = DVec3::new(start + step * k as f64, 0.3 * s, gap_voxels * s - lowest);
            let (sums, r) = prepared.sums_and_reference(s, position, orientation);
            let voxel = contact_wrench(&params, &gains, &sums).force;
            let n = r.contact_points as f64;
            let threshold = f64::from(params.contact_average_threshold);
            let scale = if n >= threshold { threshold / n } else { 1.0 };
            (voxel, r.depth_normal_sum_m * gains.k_ff * scale)
        })
        .collect();
    let mut jumps: Vec<f64> = forces
        .windows(2)
        .map(|w| (w[1].0 - w[0].0).length())
        .collect();
    let mut exact_jumps: Vec<f64> = forces
        .windows(2)
        .map(|w| (w[1].1 - w[0].1).length())
        .collect();
    let mean = forces.iter().map(|f| f.0.length()).sum::<f64>() / forces.len() as f64;
    let p99 = percentile(&mut jumps, 99.0);
    Ok(SlideFigures {
        gap_voxels,
        frames: forces.len(),
        mean_force_n: mean,
        p99_jump_n: p99,
        max_jump_n: jumps.iter().copied().fold(0.0, f64::max),
        p99_jump_relative: if mean > 0.0 { p99 / mean } else { 0.0 },
        reference_p99_jump_n: percentile(&mut exact_jumps, 99.0),
    })
}

/// Angle between two non-zero vectors (degrees).
fn angle_deg(a: DVec3, b: DVec3) -> f64 {
    (a.dot(b) / (a.length() * b.length()))
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// Nearest-rank percentile `p` (0–100) of `v` (sorted in place); 0 for an empty slice.
fn percentile(v: &mut [f64], p: f64) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    let rank = ((p / 100.0) * v.len() as f64).ceil() as usize;
    v[rank.clamp(1, v.len()) - 1]
}
