//! Both force models at one setting, as a compact table: `cargo run --release -p vps-fidelity
//! --example fidelity_models -- 0.005` (voxel size in m; 4-bit voxels, exact-surface shells).

use vps_fidelity::measure::{FidelityGrid, ForceModel};
use vps_voxelize::{ShellMethod, VoxelWidth};

fn main() {
    let s: f64 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(0.005);
    let grid = FidelityGrid {
        voxel_sizes_m: vec![s],
        widths: vec![VoxelWidth::Four],
        methods: vec![ShellMethod::ExactSurface],
        models: vec![ForceModel::TangentPlane, ForceModel::DISTANCE],
        ..FidelityGrid::full()
    };
    let report = vps_fidelity::run(&grid).expect("benchmark");
    for row in &report.rows {
        println!(
            "{} {} mm: slide p99 rel {:.4} / {:.4}",
            row.model,
            row.voxel_size_mm,
            row.slide_shallow.p99_jump_relative,
            row.slide_deep.p99_jump_relative
        );
        for f in std::iter::once(&row.all).chain(&row.scenes) {
            println!(
                "  {:13} cmp {:3} vox_only {:3} ref_only {:3} dir p50 {:6.2} p95 {:6.2} ratio {:.3} lever p50 {:.3}",
                f.scene,
                f.compared,
                f.voxel_only,
                f.reference_only,
                f.force_dir_err_deg_p50,
                f.force_dir_err_deg_p95,
                f.force_ratio_p50,
                f.lever_err_p50
            );
        }
    }
}
