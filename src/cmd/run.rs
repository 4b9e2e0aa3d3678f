//! `vps run`, `vps record`, `vps replay` and `vps devices`: one paced 1 kHz session on the
//! built-in scene with a chosen device, parameters from a TOML file, and handle traces to and from
//! files.

use super::output::print_json;
use crate::cli::{BridgeArgs, RunArgs};
use crate::session::{builtin_scene, classed, standard_script, SessionScene};
use anyhow::{bail, Context, Result};
use glam::DQuat;
use serde::Serialize;
use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use vps_device::trace::{load_trace, save_trace, ReplayDevice};
use vps_device::{DeviceLimits, HandParams, HapticDevice, SimulatedHand};
use vps_haptic::{HapticParams, PartState};
use vps_input::{
    BridgeConfig, BridgeCounters, BridgeDevice, BridgeMonitor, SpaceMouse, SpaceMouseConfig,
    WorkspaceMapping,
};
use vps_runtime::{run_loop, LoopConfig, LoopReport, SessionSetup, StatsSummary};
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

/// The bridge device this process's session opened: its counters and wrench log, read by
/// [`finish`] after the device itself has moved into the frame loop.
static BRIDGE_MONITOR: Mutex<Option<BridgeMonitor>> = Mutex::new(None);

/// The bridge's configuration from the command line; `frames` sizes the wrench log.
fn bridge_config(
    args: &BridgeArgs,
    bind: std::net::SocketAddr,
    start: glam::DVec3,
    frames: u64,
) -> BridgeConfig {
    BridgeConfig {
        bind,
        initial_position: start,
        pose_timeout: args.pose_timeout_ms / 1e3,
        mapping: WorkspaceMapping {
            scale: args.map_scale,
            rotate_deg: args.map_rotate_deg,
            offset: args.map_offset,
            force_scale: args.force_scale,
        },
        // The loop writes one zero wrench after its last frame.
        wrench_log_frames: if args.log_wrenches.is_some() {
            usize::try_from(frames)
                .unwrap_or(usize::MAX)
                .saturating_add(1)
        } else {
            0
        },
        ..Default::default()
    }
}

/// Opens the device; the start pose is where the session begins (m). `frames` is the session's
/// length (sizes the bridge's wrench log).
fn open_device(
    choice: &DeviceChoice,
    scene: &SessionScene,
    bridge: &BridgeArgs,
    frames: u64,
) -> Result<(Box<dyn HapticDevice>, PartState)> {
    if !matches!(choice, DeviceChoice::Bridge(_)) && *bridge != BridgeArgs::default() {
        bail!("--map-*, --force-scale, --pose-timeout-ms and --log-wrenches need --device bridge[:ADDR]");
    }
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
            let device = BridgeDevice::bind(bridge_config(bridge, *addr, start, frames))
                .with_context(|| format!("binding the device bridge on {addr}"))?;
            eprintln!("device bridge listening on {}", device.local_addr());
            *BRIDGE_MONITOR.lock().unwrap_or_else(|e| e.into_inner()) = Some(device.monitor());
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
    /// The bridge device's counters, when the device was the bridge.
    #[serde(skip_serializing_if = "Option::is_none")]
    bridge: Option<BridgeCounters>,
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
/// it alive for the session), and the loop's setup, publishing to that viewer.
pub struct LiveSession {
    /// Scene, voxmap and shell.
    pub scene: SessionScene,
    /// The viewer serving this session, if any.
    pub viewer: Option<super::view::LiveViewer>,
    /// What the frame loop runs.
    pub setup: SessionSetup,
}

impl PreparedSession {
    /// Attaches the viewer at `view` (when given) and builds the loop's setup, with a stop flag
    /// nobody raises (the session ends by its frame count, or its device).
    pub fn go_live(self, view: Option<std::net::SocketAddr>) -> Result<LiveSession> {
        let PreparedSession {
            scene,
            params,
            device,
            initial,
            config,
        } = self;
        let viewer = super::view::attach(view, &scene)?;
        let setup = SessionSetup {
            params,
            device,
            initial,
            config,
            feed: viewer.as_ref().map(|v| v.feed()),
            stop: Arc::new(AtomicBool::new(false)),
        };
        Ok(LiveSession {
            scene,
            viewer,
            setup,
        })
    }
}

/// Builds the scene, loads parameters and opens the device of `args`.
pub fn prepare(args: &RunArgs) -> Result<PreparedSession> {
    let choice = parse_device(&args.device)?;
    let scene = builtin_scene(args.voxel_size, ShellMethod::VoxelCentres)?;
    let params = match &args.config {
        Some(path) => HapticParams::from_file(path)?,
        None => HapticParams::default(),
    }
    .with_scene(args.voxel_size, scene.shell.max_radius())?;
    let frames = match &choice {
        DeviceChoice::Replay(path) => load_trace(path)?.frames.len() as u64,
        _ => (args.seconds / params.dt).round().max(1.0) as u64,
    };
    let (device, initial) = open_device(&choice, &scene, &args.bridge, frames)?;
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
    let LiveSession {
        scene,
        viewer: _viewer,
        setup,
    } = prepare(args)?.go_live(args.view)?;
    let report: LoopReport = run_loop(scene.tree.clone(), classed(&scene.shell), setup)?;
    finish(args, scene.shell.len(), &report, None::<&()>)
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
    let bridge = BRIDGE_MONITOR
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .take();
    if let (Some(monitor), Some(path)) = (&bridge, &args.bridge.log_wrenches) {
        let n = monitor
            .save_wrench_log(path)
            .with_context(|| format!("writing the wrench log {}", path.display()))?;
        eprintln!("logged {n} wrenches sent to {}", path.display());
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
        bridge: bridge.map(|m| m.counters()),
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
        if let Some(c) = &out.bridge {
            println!(
                "bridge: poses received {}, bad datagrams {} (+{} wrong token, {} stale), \
                 timeouts {}, clutch presses {}, zeroed frames {}, wrenches sent {} ({} failed)",
                c.accepted,
                c.garbage,
                c.unauthorized,
                c.stale,
                c.timeouts,
                c.clutch_presses,
                c.zeroed_frames,
                c.sent,
                c.send_failed
            );
        }
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
        println!(
            "no HID devices found on this machine (none attached, or /dev/hidraw* not readable)"
        );
    }
    for d in &list {
        println!("{d}");
    }
    Ok(())
}
