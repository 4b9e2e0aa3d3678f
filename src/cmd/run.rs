//! `vps run`, `vps record`, `vps replay` and `vps devices`: one paced 1 kHz session on a scene
//! (`--scene`, default the built-in bay) with a chosen device, parameters from a TOML file, and
//! handle traces to and from files.

use crate::cli::{RecordArgs, ReplayArgs, RunArgs};
use anyhow::{bail, Result};
use vps_app::output::print_json;
use vps_app::{prepare, Backend};

/// Runs one paced session; records the handle trace to `record` when given.
pub fn run(args: &RunArgs) -> Result<()> {
    prepare(&args.request())?.run(Backend::Local)
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
        vps_app::output::outln!(
            "no HID devices found on this machine (none attached, or /dev/hidraw* not readable)"
        )?;
    }
    for d in &list {
        vps_app::output::outln!("{d}")?;
    }
    Ok(())
}
