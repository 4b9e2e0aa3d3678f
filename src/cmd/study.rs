//! `vps study TRACE --scene FILE -o DIR`: the assembly study of a recorded trace, on the scene it
//! was recorded on (`crate::session_study`).

use crate::cli::{RunArgs, StudyArgs};
use crate::session_io::prepare;
use crate::session_study::{write_study, Print, StudyRun};
use anyhow::{bail, Context, Result};
use vps_session::DeviceChoice;

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
    // The trace the replay device was opened with, read once.
    let DeviceChoice::Replay(source) = &prepared.device else {
        bail!("vps study: the session was not prepared as a replay of {trace_path}");
    };
    let trace = source
        .trace()
        .with_context(|| format!("reading the trace {trace_path}"))?;
    let run = StudyRun {
        assets: &prepared.assets,
        params: prepared.plan.setup.params,
        trace: &trace,
        initial: prepared.plan.setup.initial,
        source: &format!("the trace {trace_path}"),
        stale_shares: 0,
        swept_voxel_size: args.swept_voxel_size,
    };
    let print = if args.json { Print::Json } else { Print::Text };
    write_study(&run, &args.output, args.every, print)
}
