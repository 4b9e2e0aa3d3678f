//! `vps shell`: mesh → `.vshell` point shell.

use crate::cli::{ShellArgs, ShellMethodArg};
use crate::output::{check_output_path, outln, print_json};
use crate::scene;
use anyhow::{Context, Result};
use serde::Serialize;
use vps_voxelize::{point_shell_within, ShellMethod};

#[derive(Serialize)]
struct ShellSummary {
    source: String,
    output: String,
    points: usize,
    voxel_size_m: f64,
    method: &'static str,
    volume_m3: f64,
    center_of_mass_m: [f64; 3],
    max_radius_m: f64,
}

/// Maps the command-line choice to the library's.
pub fn method_of(arg: ShellMethodArg) -> ShellMethod {
    match arg {
        ShellMethodArg::Centres => ShellMethod::VoxelCentres,
        ShellMethodArg::Exact => ShellMethod::ExactSurface,
    }
}

/// Runs the command.
pub fn run(args: &ShellArgs) -> Result<()> {
    check_output_path(&args.output, &crate::output::mesh_inputs(&args.mesh))?;
    let scene = scene::load(&args.mesh)?;
    let budget = args
        .max_memory
        .unwrap_or_else(vps_voxelize::default_memory_budget);
    let shell = point_shell_within(&scene.mesh, args.voxel_size, method_of(args.method), budget)
        .with_context(|| format!("building the point shell of {}", scene.source))?;
    vps_voxmap::file::save_shell(&shell, &args.output)?;
    let summary = ShellSummary {
        source: scene.source,
        output: args.output.display().to_string(),
        points: shell.len(),
        voxel_size_m: shell.voxel_size,
        method: match shell.method {
            ShellMethod::VoxelCentres => "voxel-centres",
            ShellMethod::ExactSurface => "exact-surface",
        },
        volume_m3: shell.mass.volume,
        center_of_mass_m: shell.mass.center_of_mass.to_array(),
        max_radius_m: shell.max_radius(),
    };
    if args.json {
        return print_json(&summary);
    }
    outln!(
        "{}: {} points ({}) at {} m, volume {:.3e} m³, max radius {:.4} m, written to {}",
        summary.source,
        summary.points,
        summary.method,
        summary.voxel_size_m,
        summary.volume_m3,
        summary.max_radius_m,
        summary.output
    )?;
    Ok(())
}
