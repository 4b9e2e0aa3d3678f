//! The clearance benchmark: does a peg go into a hole that it fits, and how close does it come to
//! the exact walls on the way?
//!
//! A peg (a 20 mm square peg, or a 32-facet round peg of 20 mm diameter; both 40 mm long) hangs
//! 10 mm above a square hole 40 mm deep with a floor, whose half-width is the peg's half-width
//! plus the clearance per side. A simulated hand, centred over the hole (0.05 mm off centre on
//! each horizontal axis, so the run is not perfectly symmetric), moves straight down at 50 mm/s to
//! 5 mm below the floor's top and holds there; the part follows it through the virtual coupling
//! with the default haptic parameters for the voxel size, at 1 kHz, for 1.5 s. Every frame samples
//! the whole shell (the haptic frame of `vps_haptic::step`, as a session does) and measures the
//! shell points against the exact meshes.
//!
//! Figures per run: whether the peg **entered** (its lowest shell point went deeper than half the
//! hole, 20 mm below the top face), how deep it went, the **minimum exact separation** of any shell
//! point from the walls and floor over the run (mm; negative: a shell point inside the scene), and
//! the **penetrating frames** (frames with a shell point inside). The tangent-plane rows use the
//! scenes' default of 2 offset layers; the distance rows the default stand-off of half a voxel and
//! a tight one of an eighth.
//! Blocking, allocating, parallel over runs (rayon).

use crate::held::HeldPart;
use crate::measure::ForceModel;
use glam::{DQuat, DVec3};
use rayon::prelude::*;
use vps_haptic::{HandleSample, HapticParams};
use vps_mesh::builtin::{cuboid, cylinder};
use vps_mesh::TriMesh;
use vps_reference::ExactScene;
use vps_voxelize::{point_shell, ShellMethod, VoxelWidth};

/// The peg's half-width (m): 10 mm.
pub const PEG_HALF_WIDTH: f64 = 0.01;
/// The hole's depth (m): 40 mm.
pub const HOLE_DEPTH: f64 = 0.04;
/// Frames per run (1.5 s at 1 kHz).
pub const FRAMES: usize = 1500;
/// The hand's speed (m/s).
pub const HAND_SPEED: f64 = 0.05;

/// Which peg.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Peg {
    /// A 20 × 20 mm square peg, 40 mm long.
    Square,
    /// A 32-facet round peg of radius 10 mm (vertices on the circle), 40 mm long.
    Round,
}

impl Peg {
    /// `square` or `round`.
    pub fn name(self) -> &'static str {
        match self {
            Peg::Square => "square",
            Peg::Round => "round",
        }
    }

    fn mesh(self) -> TriMesh {
        match self {
            Peg::Square => cuboid(DVec3::new(PEG_HALF_WIDTH, PEG_HALF_WIDTH, 0.02)),
            Peg::Round => cylinder(PEG_HALF_WIDTH, 0.02, 32),
        }
    }
}

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct ClearanceGrid {
    /// Voxel sizes (m).
    pub voxel_sizes_m: Vec<f64>,
    /// Clearances per side, in voxels.
    pub clearances_voxels: Vec<f64>,
    /// Pegs.
    pub pegs: Vec<Peg>,
    /// Force models.
    pub models: Vec<ForceModel>,
}

impl ClearanceGrid {
    /// The documented grid: 2 and 1 mm voxels, clearances 0.1, 0.25, 0.5, 1 and 2 voxels a side,
    /// both pegs, the tangent-plane model and the distance model at its default stand-off (half a
    /// voxel), an eighth and a sixteenth of a voxel (80 runs).
    pub fn full() -> ClearanceGrid {
        ClearanceGrid {
            voxel_sizes_m: vec![0.002, 0.001],
            clearances_voxels: vec![0.1, 0.25, 0.5, 1.0, 2.0],
            pegs: vec![Peg::Square, Peg::Round],
            models: vec![
                ForceModel::TangentPlane,
                ForceModel::DISTANCE,
                ForceModel::Distance {
                    standoff_voxels: 0.125,
                },
                ForceModel::Distance {
                    standoff_voxels: 0.0625,
                },
            ],
        }
    }
}

/// One run's figures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ClearanceRow {
    /// `square` or `round`.
    pub peg: &'static str,
    /// `tangent-plane` or `distance`.
    pub model: &'static str,
    /// The distance model's stand-off (voxels); 0 for the tangent-plane model.
    pub standoff_voxels: f64,
    /// Voxel size (mm).
    pub voxel_size_mm: f64,
    /// Clearance per side (voxels).
    pub clearance_voxels: f64,
    /// Clearance per side (mm).
    pub clearance_mm: f64,
    /// The peg's lowest shell point went deeper than half the hole (20 mm below the top face).
    pub entered: bool,
    /// How far below the hole's top face the peg's lowest shell point went (mm; negative: it
    /// stayed above the top face).
    pub deepest_mm: f64,
    /// Smallest exact signed distance of any shell point to the walls and floor over the run (mm;
    /// negative: a shell point inside the scene); `None` when no point came within 2 voxels.
    pub min_separation_mm: Option<f64>,
    /// Frames with a shell point inside the scene (exact).
    pub penetrating_frames: usize,
    /// Frames run.
    pub frames: usize,
    /// Shell points of the peg.
    pub shell_points: usize,
}

/// Why a run could not be set up.
#[derive(Debug, thiserror::Error)]
#[error("clearance benchmark ({what}): {message}")]
pub struct ClearanceError {
    what: String,
    message: String,
}

/// Runs every combination of `grid`. Blocking, parallel (rayon over runs), allocates.
pub fn run(grid: &ClearanceGrid) -> Result<Vec<ClearanceRow>, ClearanceError> {
    let mut jobs = Vec::new();
    for &model in &grid.models {
        for &s in &grid.voxel_sizes_m {
            for &peg in &grid.pegs {
                for &c in &grid.clearances_voxels {
                    jobs.push((model, s, peg, c));
                }
            }
        }
    }
    jobs.par_iter()
        .map(|&(model, s, peg, c)| run_one(model, s, peg, c))
        .collect()
}

/// The four walls of a square hole of half-width `h` and depth [`HOLE_DEPTH`] (top face at
/// z = 0) and the floor under it.
fn fixture(h: f64) -> Vec<TriMesh> {
    let t = 0.015;
    let zc = -HOLE_DEPTH / 2.0;
    let at = |half: DVec3, centre: DVec3| {
        let mut m = cuboid(half);
        m.transform(1.0, DQuat::IDENTITY, centre);
        m
    };
    let half_depth = HOLE_DEPTH / 2.0;
    vec![
        at(
            DVec3::new(t / 2.0, h + t, half_depth),
            DVec3::new(h + t / 2.0, 0.0, zc),
        ),
        at(
            DVec3::new(t / 2.0, h + t, half_depth),
            DVec3::new(-h - t / 2.0, 0.0, zc),
        ),
        at(
            DVec3::new(h, t / 2.0, half_depth),
            DVec3::new(0.0, h + t / 2.0, zc),
        ),
        at(
            DVec3::new(h, t / 2.0, half_depth),
            DVec3::new(0.0, -h - t / 2.0, zc),
        ),
        at(
            DVec3::new(h + t, h + t, t / 2.0),
            DVec3::new(0.0, 0.0, -HOLE_DEPTH - t / 2.0),
        ),
    ]
}

fn run_one(
    model: ForceModel,
    s: f64,
    peg: Peg,
    clearance_voxels: f64,
) -> Result<ClearanceRow, ClearanceError> {
    let what = format!(
        "{} peg, {} model, {} mm voxels, {} voxel clearance",
        peg.name(),
        model.name(),
        s * 1e3,
        clearance_voxels
    );
    let err = |message: String| ClearanceError {
        what: what.clone(),
        message,
    };
    let walls = fixture(PEG_HALF_WIDTH + clearance_voxels * s);
    let tree = model
        .voxmap("clearance", &walls, s, VoxelWidth::Four)
        .map_err(|e| err(e.to_string()))?;
    let exact = ExactScene::new(&walls).map_err(|e| err(e.to_string()))?;
    let shell =
        point_shell(&peg.mesh(), s, ShellMethod::ExactSurface).map_err(|e| err(e.to_string()))?;
    let params = HapticParams::default()
        .with_scene(s, shell.max_radius())
        .map_err(|e| err(e.to_string()))?;
    // The part's origin is its centre of mass (the shell's frame); its bottom is 20 mm below.
    let bottom_below_origin = shell
        .points
        .iter()
        .map(|p| f64::from(p.z))
        .fold(f64::MAX, f64::min);
    let start_z = 0.01 - bottom_below_origin;
    let end_z = -HOLE_DEPTH - 0.005 - bottom_below_origin;
    let offset = DVec3::new(5e-5, 5e-5, 0.0);
    let start = DVec3::new(0.0, 0.0, start_z) + offset;
    let mut part = HeldPart::at_rest(&tree, &exact, &shell, &params, start, DQuat::IDENTITY);
    let (mut deepest, mut min_sep, mut penetrating) = (f64::MIN, f64::MAX, 0usize);
    for k in 0..FRAMES {
        let t = k as f64 * params.dt;
        let z = (start_z - HAND_SPEED * t).max(end_z);
        let moving = z > end_z;
        let handle = HandleSample {
            position: DVec3::new(0.0, 0.0, z) + offset,
            orientation: DQuat::IDENTITY,
            linear_velocity: DVec3::new(0.0, 0.0, if moving { -HAND_SPEED } else { 0.0 }),
            angular_velocity: DVec3::ZERO,
        };
        let r = part.frame(&handle, 2.0 * s);
        if let Some(m) = r.min_separation_m {
            min_sep = min_sep.min(m);
        }
        penetrating += usize::from(r.penetrating_points > 0);
        let lowest = part.world_points().map(|p| p.z).fold(f64::MAX, f64::min);
        deepest = deepest.max(-lowest);
    }
    Ok(ClearanceRow {
        peg: peg.name(),
        model: model.name(),
        standoff_voxels: match model {
            ForceModel::TangentPlane => 0.0,
            ForceModel::Distance { standoff_voxels } => standoff_voxels,
        },
        voxel_size_mm: s * 1e3,
        clearance_voxels,
        clearance_mm: clearance_voxels * s * 1e3,
        entered: deepest > HOLE_DEPTH / 2.0,
        deepest_mm: deepest * 1e3,
        min_separation_mm: (min_sep < f64::MAX).then_some(min_sep * 1e3),
        penetrating_frames: penetrating,
        frames: FRAMES,
        shell_points: shell.len(),
    })
}
