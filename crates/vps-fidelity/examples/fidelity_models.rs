//! Both force models on 4-bit maps with exact-surface shells, as markdown tables (pooled, then
//! per scene): `cargo run --release -p vps-fidelity --example fidelity_models -- 0.01 0.005
//! 0.0025 0.00125` (voxel sizes in m). `vps bench fidelity` gives every width and method as JSON.

use vps_fidelity::measure::{FidelityGrid, ForceModel};
use vps_voxelize::{ShellMethod, VoxelWidth};

fn main() {
    let sizes: Vec<f64> = std::env::args()
        .skip(1)
        .filter_map(|a| a.parse().ok())
        .collect();
    let grid = FidelityGrid {
        voxel_sizes_m: if sizes.is_empty() { vec![0.005] } else { sizes },
        widths: vec![VoxelWidth::Four],
        methods: vec![ShellMethod::ExactSurface],
        models: vec![ForceModel::TangentPlane, ForceModel::DISTANCE],
        ..FidelityGrid::full()
    };
    let report = vps_fidelity::run(&grid).expect("benchmark");
    println!("| model | voxel (mm) | compared | direction p50 (°) | p95 (°) | tilted box p50 | corner p50 | magnitude ratio p50 | lever p50 | slide p99 jump / mean (shallow, deep) |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for row in &report.rows {
        let scene = |name: &str| {
            row.scenes
                .iter()
                .find(|s| s.scene == name)
                .map_or(f64::NAN, |s| s.force_dir_err_deg_p50)
        };
        println!(
            "| {} | {} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {:.3} | {:.3} | {:.4}, {:.4} |",
            row.model,
            row.voxel_size_mm,
            row.all.compared,
            row.all.force_dir_err_deg_p50,
            row.all.force_dir_err_deg_p95,
            scene("tilted-box"),
            scene("corner"),
            row.all.force_ratio_p50,
            row.all.lever_err_p50,
            row.slide_shallow.p99_jump_relative,
            row.slide_deep.p99_jump_relative,
        );
    }
    println!();
    println!("| model | voxel (mm) | scene | compared | field only | exact only | direction p50 (°) | p95 (°) | ratio p50 |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for row in &report.rows {
        for f in &row.scenes {
            println!(
                "| {} | {} | {} | {} | {} | {} | {:.2} | {:.2} | {:.3} |",
                row.model,
                row.voxel_size_mm,
                f.scene,
                f.compared,
                f.voxel_only,
                f.reference_only,
                f.force_dir_err_deg_p50,
                f.force_dir_err_deg_p95,
                f.force_ratio_p50
            );
        }
    }
}
