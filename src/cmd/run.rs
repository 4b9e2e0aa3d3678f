//! `vps run`, `vps record`, `vps replay` and `vps devices`: one paced 1 kHz session on a scene
//! (`--scene`, default the built-in bay) with a chosen device, parameters from a TOML file, and
//! handle traces to and from files.

use crate::cli::{RecordArgs, ReplayArgs, RunArgs};
use crate::output::print_json;
use crate::session_io::{finish, prepare, LiveSession, SessionOutputs};
use anyhow::{bail, Result};
use vps_runtime::{run_loop, LoopReport};

/// Runs one paced session; records the handle trace to `record` when given.
pub fn run(args: &RunArgs) -> Result<()> {
    let outputs = SessionOutputs::reserve(args)?;
    let LiveSession {
        assets,
        viewer: _viewer,
        setup,
        bridge,
        signals,
    } = prepare(args)?.go_live(args.view)?;
    let report: LoopReport = run_loop(assets.tree.clone(), assets.classed_shell(), setup)?;
    finish(
        args,
        outputs,
        &signals,
        &assets,
        &report,
        bridge.as_ref(),
        None::<&()>,
    )
}

/// `vps record -o FILE ...`: [`run`] with `--record FILE`.
pub fn record(args: &RecordArgs) -> Result<()> {
    if args.session.record.is_some() {
        bail!("vps record: give the trace file once, as -o FILE (or use vps run --record FILE)");
    }
    run(&RunArgs {
        record: Some(args.output.clone()),
        ..args.session.clone()
    })
}

/// `vps replay TRACE ...`: [`run`] with `--device replay:TRACE`.
pub fn replay(args: &ReplayArgs) -> Result<()> {
    if args.session.device.is_some() {
        bail!("vps replay: the device is the trace; --device cannot be given");
    }
    run(&RunArgs {
        device: Some(format!("replay:{}", args.trace.display())),
        ..args.session.clone()
    })
}

/// `vps devices`: the HID devices this machine sees and which of them vps can drive.
pub fn devices(json: bool) -> Result<()> {
    let list = vps_input::list_devices()?;
    if json {
        return print_json(&list);
    }
    if list.is_empty() {
        crate::output::outln!(
            "no HID devices found on this machine (none attached, or /dev/hidraw* not readable)"
        )?;
    }
    for d in &list {
        crate::output::outln!("{d}")?;
    }
    Ok(())
}
