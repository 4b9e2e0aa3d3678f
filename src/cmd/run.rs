//! `vps run`, `vps record`, `vps replay` and `vps devices`: one paced 1 kHz session on the
//! built-in scene with a chosen device, parameters from a TOML file, and handle traces to and from
//! files.

use super::exit::{outcome, SessionExit};
use super::output::print_json;
use super::reserve::ReservedFile;
use crate::cli::RunArgs;
use crate::session::{builtin_scene, classed, standard_script, SessionScene};
use anyhow::{bail, Context, Result};
use glam::DQuat;
use serde::Serialize;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use vps_device::trace::{load_trace, save_trace, ReplayDevice};
use vps_device::{DeviceLimits, HandParams, HapticDevice, SimulatedHand};
use vps_haptic::{HapticParams, PartState};
use vps_input::{BridgeConfig, BridgeDevice, SpaceMouse, SpaceMouseConfig};
use vps_runtime::{run_loop, LoopConfig, LoopReport, SessionSetup, SignalStop, StatsSummary};
use vps_voxelize::ShellMethod;

/// The device a session is driven by, parsed from `--device`.
enum DeviceChoice {
    /// The simulated hand on the standard script.
    Simulated,
    /// The first SpaceMouse-family HID device found (input only).
    SpaceMouse,
    /// The UDP device bridge, bound to the address (loopback unless a token is given).
    Bridge(std::net::SocketAddr),
    /// A recorded handle trace, played back exactly.
    Replay(std::path::PathBuf),
}

fn parse_device(text: &str) -> Result<DeviceChoice> {
    Ok(match text.split_once(':') {
        None if text == "sim" => DeviceChoice::Simulated,
        None if text == "spacemouse" => DeviceChoice::SpaceMouse,
        None if text == "bridge" => DeviceChoice::Bridge("127.0.0.1:7700".parse()?),
        Some(("bridge", addr)) => DeviceChoice::Bridge(addr.parse().with_context(|| {
            format!("--device bridge:{addr}: not an address like 127.0.0.1:7700")
        })?),
        Some(("replay", path)) => DeviceChoice::Replay(path.into()),
        _ => bail!("--device {text}: expected sim, spacemouse, bridge[:ADDR] or replay:FILE"),
    })
}

/// Opens the device; the start pose is where the session begins (m).
fn open_device(
    choice: &DeviceChoice,
    scene: &SessionScene,
) -> Result<(Box<dyn HapticDevice>, PartState)> {
    let script = standard_script(&scene.tree, &scene.corridor, 0.8)?;
    let (start, orientation) = script.sample(0.0);
    let at_start = PartState::at_rest(start, orientation);
    Ok(match choice {
        DeviceChoice::Simulated => (
            Box::new(SimulatedHand::new(script, HandParams::default())?),
            at_start,
        ),
        DeviceChoice::SpaceMouse => {
            let config = SpaceMouseConfig {
                start_position: start,
                start_orientation: DQuat::IDENTITY,
                ..Default::default()
            };
            let device = SpaceMouse::open_first(config).context(
                "opening a SpaceMouse (`vps devices` lists what this machine sees; /dev/hidraw* must be readable)",
            )?;
            (Box::new(device), at_start)
        }
        DeviceChoice::Bridge(addr) => {
            let config = BridgeConfig {
                bind: *addr,
                initial_position: start,
                ..Default::default()
            };
            let device = BridgeDevice::bind(config)
                .with_context(|| format!("binding the device bridge on {addr}"))?;
            eprintln!("device bridge listening on {}", device.local_addr());
            (Box::new(device), at_start)
        }
        DeviceChoice::Replay(path) => {
            let trace = load_trace(path)?;
            let first = trace
                .frames
                .first()
                .with_context(|| format!("{}: the trace has no frames", path.display()))?;
            let state = PartState::at_rest(first.sample.position, first.sample.orientation);
            (
                Box::new(ReplayDevice::new(trace, DeviceLimits::PAPER)),
                state,
            )
        }
    })
}

/// The session report (`--json`, `--report FILE`).
#[derive(Serialize)]
struct RunReport {
    device: String,
    shell_points: usize,
    realtime_granted: bool,
    /// Why the session ended: "frames done", "stopped by SIGTERM", "device failed: ...",
    /// "panic: ...".
    end: String,
    /// False when the session did not run all its frames (the figures cover the frames run).
    complete: bool,
    /// The process's exit status (src/cmd/exit.rs; README, "Units, limits and safety").
    exit_code: i32,
    final_position_m: [f64; 3],
    stats: StatsSummary,
    /// The device's own counters (e.g. the bridge's datagram counts), when it keeps any.
    #[serde(skip_serializing_if = "Option::is_none")]
    device_counters: Option<serde_json::Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    cluster: Option<serde_json::Value>,
}

/// The files a session writes at its end, created (empty, beside their destinations) before the
/// session starts so that a bad path fails before any work.
#[derive(Default)]
pub struct SessionOutputs {
    /// `--report FILE`.
    report: Option<ReservedFile>,
    /// `--record FILE`.
    record: Option<ReservedFile>,
}

impl SessionOutputs {
    /// Reserves `--report` and `--record` of `args`.
    pub fn reserve(args: &RunArgs) -> Result<SessionOutputs> {
        Ok(SessionOutputs {
            report: args
                .report
                .as_deref()
                .map(ReservedFile::reserve)
                .transpose()?,
            record: args
                .record
                .as_deref()
                .map(ReservedFile::reserve)
                .transpose()?,
        })
    }
}

/// Everything a session needs, opened from the command line.
pub struct PreparedSession {
    /// Scene, voxmap and shell.
    pub scene: SessionScene,
    /// Validated haptic parameters.
    pub params: HapticParams,
    /// The opened device.
    pub device: Box<dyn HapticDevice>,
    /// The part's state at frame 0.
    pub initial: PartState,
    /// Frame loop settings.
    pub config: LoopConfig,
}

/// A prepared session made ready to run: its scene, the live viewer when one was asked for (keep
/// it alive for the session), the loop's setup, publishing to that viewer, and the signal
/// handlers that stop it.
pub struct LiveSession {
    /// Scene, voxmap and shell.
    pub scene: SessionScene,
    /// The viewer serving this session, if any.
    pub viewer: Option<super::view::LiveViewer>,
    /// What the frame loop runs.
    pub setup: SessionSetup,
    /// SIGINT, SIGTERM and SIGHUP set `setup.stop` (the device is then written zero and the
    /// report says which signal came).
    pub signals: SignalStop,
}

impl PreparedSession {
    /// Attaches the viewer at `view` (when given) and builds the loop's setup, with a stop flag
    /// set by SIGINT, SIGTERM and SIGHUP (installed here: the device is open from now on).
    pub fn go_live(self, view: Option<std::net::SocketAddr>) -> Result<LiveSession> {
        let PreparedSession {
            scene,
            params,
            device,
            initial,
            config,
        } = self;
        let stop = Arc::new(AtomicBool::new(false));
        let signals = SignalStop::install(&stop)?;
        let viewer = super::view::attach(view, &scene)?;
        let setup = SessionSetup {
            params,
            device,
            initial,
            config,
            feed: viewer.as_ref().map(|v| v.feed()),
            stop,
        };
        Ok(LiveSession {
            scene,
            viewer,
            setup,
            signals,
        })
    }
}

/// Builds the scene, loads parameters and opens the device of `args`.
pub fn prepare(args: &RunArgs) -> Result<PreparedSession> {
    let choice = parse_device(&args.device)?;
    let loaded = match &args.config {
        Some(path) => {
            let params = HapticParams::from_file(path)?;
            let period = LoopConfig::default().period.as_secs_f64();
            if (params.dt - period).abs() > 1e-12 {
                bail!(
                    "{}: haptic parameter `dt` = {} s: the session loop runs at {} Hz, so `dt` \
                     must be {period} s (or left out)",
                    path.display(),
                    params.dt,
                    1.0 / period
                );
            }
            params
        }
        None => HapticParams::default(),
    };
    let scene = builtin_scene(args.voxel_size, ShellMethod::VoxelCentres)?;
    let params = loaded.with_scene(args.voxel_size, scene.shell.max_radius())?;
    let (device, initial) = open_device(&choice, &scene)?;
    let frames = match &choice {
        DeviceChoice::Replay(path) => load_trace(path)?.frames.len() as u64,
        _ => (args.seconds / params.dt).round().max(1.0) as u64,
    };
    let config = LoopConfig {
        frames: Some(frames),
        threads: args.threads.max(1),
        realtime: true,
        record_trace: args.record.is_some(),
        ..LoopConfig::default()
    };
    Ok(PreparedSession {
        scene,
        params,
        device,
        initial,
        config,
    })
}

/// Runs one paced session; records the handle trace to `record` when given.
pub fn run(args: &RunArgs) -> Result<()> {
    let outputs = SessionOutputs::reserve(args)?;
    let LiveSession {
        scene,
        viewer: _viewer,
        setup,
        signals,
    } = prepare(args)?.go_live(args.view)?;
    let report: LoopReport = run_loop(scene.tree.clone(), classed(&scene.shell), setup)?;
    finish(
        args,
        outputs,
        &signals,
        scene.shell.len(),
        &report,
        None::<&()>,
    )
}

/// Once the device has been written zero: saves the recording, writes the report file, prints
/// the session's figures (and `cluster`, when given, as JSON), and fails with a [`SessionExit`]
/// (its exit status) when the session did not run to its end.
pub fn finish<C: Serialize>(
    args: &RunArgs,
    outputs: SessionOutputs,
    signals: &SignalStop,
    shell_points: usize,
    report: &LoopReport,
    cluster: Option<&C>,
) -> Result<()> {
    let (end, exit_code) = outcome(&report.end, Some(signals));
    let out = RunReport {
        device: report.device_name.clone(),
        shell_points,
        realtime_granted: report.rt.fifo,
        end,
        complete: report.end.is_complete(),
        exit_code,
        final_position_m: report.final_state.position.to_array(),
        stats: report.stats.clone(),
        device_counters: report.device_counters.clone(),
        cluster: cluster.map(serde_json::to_value).transpose()?,
    };
    if let Some(file) = outputs.report {
        file.commit(|path| {
            let text = serde_json::to_string_pretty(&out)?;
            std::fs::write(path, text + "\n")?;
            Ok(())
        })?;
    }
    if let Some(file) = outputs.record {
        save_recording(report, file)?;
    }
    if args.json {
        print_json(&out)?;
    } else {
        println!(
            "device: {}, {} shell points, session end: {}{}",
            out.device,
            out.shell_points,
            out.end,
            if out.complete { "" } else { " (partial)" }
        );
        crate::demo::print_summary("session", &out.stats, None);
        println!("final part position (m): {:?}", out.final_position_m);
        if let Some(cluster) = &out.cluster {
            println!("cluster: {}", serde_json::to_string_pretty(cluster)?);
        }
    }
    if exit_code != 0 {
        return Err(SessionExit {
            code: exit_code,
            reason: format!(
                "the session ended early ({}); the device was sent zero force",
                out.end
            ),
        }
        .into());
    }
    Ok(())
}

fn save_recording(report: &LoopReport, file: ReservedFile) -> Result<()> {
    if let Some(why) = &report.trace_error {
        bail!("trace recording stopped early: {why}");
    }
    let trace = report
        .trace
        .as_ref()
        .context("the loop returned no trace")?;
    let frames = trace.frames.len();
    let path = file.path().to_path_buf();
    file.commit(|temporary| Ok(save_trace(temporary, trace)?))?;
    eprintln!("recorded {frames} frames to {}", path.display());
    Ok(())
}

/// `vps devices`: the HID devices this machine sees and which of them vps can drive.
pub fn devices(json: bool) -> Result<()> {
    let list = vps_input::list_devices()?;
    if json {
        return print_json(&list);
    }
    if list.is_empty() {
        println!(
            "no HID devices found on this machine (none attached, or /dev/hidraw* not readable)"
        );
    }
    for d in &list {
        println!("{d}");
    }
    Ok(())
}
