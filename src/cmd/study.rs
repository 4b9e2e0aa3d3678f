//! `vps study TRACE --scene FILE -o DIR`: the assembly study of a recorded trace, on the scene it
//! was recorded on (`crate::session_study`).

use crate::cli::{RunArgs, StudyArgs};
use crate::session_io::prepare;
use crate::session_study::{write_study, Print, StudyRun};
use anyhow::{Context, Result};

/// `vps study TRACE --scene FILE -o DIR`.
pub fn run(args: &StudyArgs) -> Result<()> {
    let trace_path = args.trace.display().to_string();
    let session = RunArgs {
        scene: args.scene.clone(),
        haptic: args.haptic.clone(),
        voxel_size: args.voxel_size,
        device: Some(format!("replay:{trace_path}")),
        study: Some(args.output.clone()),
        ..RunArgs::default()
    };
    // The same preparation as `vps replay`: scene, parameters, and the part at rest at the
    // trace's first pose; the outputs are checked against every input first.
    let prepared = prepare(&session)?;
    let trace = vps_device::trace::load_trace(&args.trace)
        .with_context(|| format!("reading the trace {trace_path}"))?;
    let run = StudyRun {
        assets: &prepared.assets,
        params: prepared.plan.setup.params,
        trace: &trace,
        initial: prepared.plan.setup.initial,
        source: &format!("the trace {trace_path}"),
        swept_voxel_size: args.swept_voxel_size,
    };
    let print = if args.json { Print::Json } else { Print::Text };
    write_study(&run, &args.output, args.every, print)
}
