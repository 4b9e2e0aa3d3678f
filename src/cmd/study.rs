//! `vps study TRACE --scene FILE -o DIR`: the assembly study of a recorded trace, on the scene it
//! was recorded on (`vps_app::study`). A scene of several moving parts reads each other
//! part's trace beside TRACE (`vps_app::session_files::part_trace_path`, as `--record` wrote them) and
//! writes one study per part.

use crate::cli::StudyArgs;
use anyhow::{bail, Context, Result};
use vps_app::prepare::prepare;
use vps_app::study::{write_study, OtherPartRun, Print, StudyRun};
use vps_app::SessionRequest;
use vps_session::DeviceChoice;

/// `vps study TRACE --scene FILE -o DIR`.
pub fn run(args: &StudyArgs) -> Result<()> {
    let trace_path = args.trace.display().to_string();
    let session = SessionRequest {
        scene: args.scene.request(),
        haptic: args.haptic.clone(),
        voxel_size: args.voxel_size,
        device: Some(format!("replay:{trace_path}")),
        study: Some(args.output.clone()),
        replay_every_part: true,
        ..SessionRequest::default()
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
    // With several moving parts, each other part's trace (read beside TRACE when the devices
    // were opened) and its state at the first frame.
    let others = match &prepared.plan.setup.parts {
        None => Vec::new(),
        Some(parts) => parts
            .others
            .iter()
            .zip(&prepared.assets.more_parts)
            .map(|(part, assets)| match &assets.device {
                DeviceChoice::Replay(source) => Ok((source.trace()?, part.initial)),
                _ => bail!(
                    "vps study: part '{}' was not prepared as a replay",
                    part.name
                ),
            })
            .collect::<Result<Vec<_>>>()?,
    };
    let run = StudyRun {
        assets: &prepared.assets,
        params: prepared.plan.setup.params,
        trace: &trace,
        initial: prepared.plan.setup.initial,
        source: &format!("the trace {trace_path}"),
        stale_shares: 0,
        swept_voxel_size: args.swept_voxel_size,
        others: others
            .iter()
            .map(|(trace, initial)| OtherPartRun {
                trace,
                initial: *initial,
            })
            .collect(),
    };
    let print = if args.json { Print::Json } else { Print::Text };
    write_study(&run, &args.output, args.every, print)
}
