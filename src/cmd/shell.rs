//! `vps shell`: mesh → `.vshell` point shell.

use crate::cli::{ShellArgs, ShellMethodArg};
use crate::mesh_arg::{load_mesh_for, units_hint};
use anyhow::{Context, Result};
use serde::Serialize;
use vps_app::output::{print_summary, ShellFigures};
use vps_voxelize::{point_shell_within, ShellMethod};

#[derive(Serialize)]
struct ShellSummary {
    source: String,
    output: String,
    method: &'static str,
    #[serde(flatten)]
    figures: ShellFigures,
}

impl std::fmt::Display for ShellSummary {
    /// "SOURCE (METHOD): FIGURES, written to OUTPUT".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} ({}): {}, written to {}",
            self.source, self.method, self.figures, self.output
        )
    }
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
    let scene = load_mesh_for(&args.mesh, &args.build, args.voxel_size)?;
    let budget = args
        .build
        .max_memory
        .unwrap_or_else(vps_voxelize::default_memory_budget);
    let shell = point_shell_within(&scene.mesh, args.voxel_size, method_of(args.method), budget)
        .with_context(|| {
            format!(
                "building the point shell of {}{}",
                scene.source,
                units_hint(&scene, args.build.units)
            )
        })?;
    vps_voxmap::file::save_shell(&shell, &args.build.output)?;
    let summary = ShellSummary {
        source: scene.source,
        output: args.build.output.display().to_string(),
        method: match shell.method {
            ShellMethod::VoxelCentres => "voxel-centres",
            ShellMethod::ExactSurface => "exact-surface",
        },
        figures: ShellFigures::of(&shell),
    };
    print_summary(&summary, args.build.json)
}
