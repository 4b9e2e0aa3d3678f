//! `vps bench fidelity`: the analytic benchmark of `vps-fidelity` over the documented grid, as JSON.

use anyhow::{bail, Result};
use vps_app::output::print_report;
use vps_fidelity::measure::{FidelityGrid, ForceModel};

/// Runs the benchmark at `voxel_sizes` (m) for `models`, every width and shell method, `poses` per scene and
/// separation, and prints the report. Blocking, parallel.
///
/// Errors: `--poses` outside 1..=64, a `--voxel-sizes` value outside [0.5 mm, 20 mm].
pub fn run(voxel_sizes: Vec<f64>, poses: usize, models: Vec<ForceModel>, json: bool) -> Result<()> {
    if !(1..=64).contains(&poses) {
        bail!("--poses {poses} is out of range: allowed 1..=64");
    }
    if let Some(bad) = voxel_sizes
        .iter()
        .find(|s| !(s.is_finite() && (0.0005..=0.02).contains(*s)))
    {
        bail!("--voxel-sizes: {bad} m is out of range: allowed 0.5 mm to 20 mm");
    }
    let grid = FidelityGrid {
        voxel_sizes_m: voxel_sizes,
        poses,
        models,
        ..FidelityGrid::full()
    };
    print_report(
        "bench fidelity: voxel force and torque against the exact answer",
        &vps_fidelity::run(&grid)?,
        json,
    )
}
