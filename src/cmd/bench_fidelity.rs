//! `vps bench fidelity`: the analytic benchmark of `vps-fidelity` over the documented grid, as JSON.

use super::output::print_json;
use anyhow::Result;
use vps_fidelity::measure::FidelityGrid;

/// Runs the benchmark at `voxel_sizes` (m), every width and shell method, `poses` per scene and
/// separation, and prints the report. Blocking, parallel.
pub fn run(voxel_sizes: Vec<f64>, poses: usize) -> Result<()> {
    let grid = FidelityGrid {
        voxel_sizes_m: voxel_sizes,
        poses,
        ..FidelityGrid::full()
    };
    print_json(&vps_fidelity::run(&grid)?)
}
