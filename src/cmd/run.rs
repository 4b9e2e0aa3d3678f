//! `vps run`, `vps record`, `vps replay` and `vps devices`: one paced 1 kHz session on a scene
//! (`--scene`, default the built-in bay) with a chosen device, parameters from a TOML file, and
//! handle traces to and from files.

use super::output::print_json;
use crate::cli::RunArgs;
use anyhow::{anyhow, bail, Context, Result};
use serde::Serialize;
use std::path::Path;
use vps_device::trace::save_trace;
use vps_haptic::HapticParams;
use vps_runtime::{run_loop, LoopConfig, LoopReport, SessionSetup, StatsSummary};
use vps_session::{DeviceChoice, Session, SessionPlan};

#[derive(Serialize)]
struct RunReport {
    device: String,
    shell_points: usize,
    realtime_granted: bool,
    end: String,
    final_position_m: [f64; 3],
    stats: StatsSummary,
    #[serde(skip_serializing_if = "Option::is_none")]
    cluster: Option<serde_json::Value>,
}

/// Everything a session needs, opened from the command line.
pub struct PreparedSession {
    /// Scene, voxmap, shell and meshes.
    pub session: Session,
    /// Parameters, opened device, initial state and loop settings.
    pub plan: SessionPlan,
}

/// A prepared session made ready to run: its scene, the live viewer when one was asked for (keep
/// it alive for the session), and the loop's setup, publishing to that viewer.
pub struct LiveSession {
    /// Scene, voxmap, shell and meshes.
    pub session: Session,
    /// The viewer serving this session, if any.
    pub viewer: Option<super::view::LiveViewer>,
    /// What the frame loop runs.
    pub setup: SessionSetup,
}

impl PreparedSession {
    /// Attaches the viewer at `view` (when given) and builds the loop's setup, with a stop flag
    /// nobody raises (the session ends by its frame count, or its device).
    pub fn go_live(self, view: Option<std::net::SocketAddr>) -> Result<LiveSession> {
        let PreparedSession { session, plan } = self;
        let viewer = super::view::attach(view, &session)?;
        let setup = plan.into_setup(viewer.as_ref().map(|v| v.feed()));
        Ok(LiveSession {
            session,
            viewer,
            setup,
        })
    }
}

/// The device of `--device`, else the scene's.
pub fn device_choice(text: Option<&str>, session: &Session) -> Result<DeviceChoice> {
    match text {
        Some(t) => DeviceChoice::parse(t).map_err(|m| anyhow!("--device {m}")),
        None => Ok(session.device.clone()),
    }
}

/// Builds the scene, loads parameters and opens the device of `args`.
pub fn prepare(args: &RunArgs) -> Result<PreparedSession> {
    let mut session = Session::open(
        &args.scene.scene,
        &args.scene.build_options(args.voxel_size),
    )?;
    let choice = device_choice(args.device.as_deref(), &session)?;
    if let Some(path) = &args.config {
        session.params = HapticParams::from_file(path)?
            .with_scene(session.voxel_size, session.shell.max_radius())?;
    }
    let frames = choice.frames(args.seconds, session.params.dt)?;
    let config = LoopConfig {
        frames: Some(frames),
        threads: args.threads.max(1),
        realtime: true,
        record_trace: args.record.is_some(),
        ..LoopConfig::default()
    };
    let plan = session.plan(&choice, session.script()?, config)?;
    Ok(PreparedSession { session, plan })
}

/// Runs one paced session; records the handle trace to `record` when given.
pub fn run(args: &RunArgs) -> Result<()> {
    let LiveSession {
        session,
        viewer: _viewer,
        setup,
    } = prepare(args)?.go_live(args.view)?;
    let report: LoopReport = run_loop(session.tree.clone(), session.classed_shell(), setup)?;
    finish(args, session.shell.len(), &report, None::<&()>)
}

/// Saves the recording, prints the session's figures (and `cluster`, when given, as JSON), and
/// fails when the device failed.
pub fn finish<C: Serialize>(
    args: &RunArgs,
    shell_points: usize,
    report: &LoopReport,
    cluster: Option<&C>,
) -> Result<()> {
    if let Some(path) = &args.record {
        save_recording(report, path)?;
    }
    let end = match &report.device_error {
        Some(err) => format!("device failed: {err}"),
        None => format!("{:?}", report.end),
    };
    let out = RunReport {
        device: report.device_name.clone(),
        shell_points,
        realtime_granted: report.rt.fifo,
        end,
        final_position_m: report.final_state.position.to_array(),
        stats: report.stats.clone(),
        cluster: cluster.map(serde_json::to_value).transpose()?,
    };
    if args.json {
        print_json(&out)?;
    } else {
        println!(
            "device: {}, {} shell points, session end: {}",
            out.device, out.shell_points, out.end
        );
        crate::demo::print_summary("session", &out.stats, None);
        println!("final part position (m): {:?}", out.final_position_m);
        if let Some(cluster) = &out.cluster {
            println!("cluster: {}", serde_json::to_string_pretty(cluster)?);
        }
    }
    if report.device_error.is_some() {
        bail!("the session stopped because the device failed (the device was sent zero force)");
    }
    Ok(())
}

fn save_recording(report: &LoopReport, path: &Path) -> Result<()> {
    if let Some(why) = &report.trace_error {
        bail!("trace recording stopped early: {why}");
    }
    let trace = report
        .trace
        .as_ref()
        .context("the loop returned no trace")?;
    save_trace(path, trace)?;
    eprintln!(
        "recorded {} frames to {}",
        trace.frames.len(),
        path.display()
    );
    Ok(())
}

/// `vps devices`: the HID devices this machine sees and which of them vps can drive.
pub fn devices(json: bool) -> Result<()> {
    let list = vps_input::list_devices()?;
    if json {
        return print_json(&list);
    }
    if list.is_empty() {
        super::output::outln!(
            "no HID devices found on this machine (none attached, or /dev/hidraw* not readable)"
        )?;
    }
    for d in &list {
        super::output::outln!("{d}")?;
    }
    Ok(())
}
