//! A session prepared from a [`SessionRequest`]: the scene built once, the device opened, the
//! loop's settings fixed ([`prepare`] → [`Prepared`]); then made live with its viewer and signal
//! handlers ([`Prepared::go_live`] → [`LiveSession`]). A missing device or a bad output path is
//! reported before the voxmap is built (that can take minutes).

use crate::request::{BridgeOverrides, SessionRequest};
use crate::scene_view::attach_viewer;
use crate::session_files::{
    check_session_outputs, command_line_inputs, part_trace_path, SessionOutputs,
};
use anyhow::{anyhow, bail, Context, Result};
use std::path::PathBuf;
use vps_haptic::HapticParams;
use vps_input::BridgeMonitor;
use vps_runtime::{LoopConfig, SessionSetup, SignalStop};
use vps_session::{BridgeSettings, DeviceChoice, LoadedScene, SessionAssets, SessionPlan};
use vps_view::LiveViewer;

/// Everything a session needs, made by [`prepare`] from a [`SessionRequest`]; run it with
/// [`Prepared::run`] (or make it live yourself with [`Prepared::go_live`]).
pub struct Prepared {
    /// What was built once from the scene file: voxmap, shell, parameters, meshes.
    pub assets: SessionAssets,
    /// Parameters, opened device, initial state and loop settings.
    pub plan: SessionPlan,
    /// The device it was opened from (a replay's trace, read once, is shared from here).
    pub device: DeviceChoice,
    /// What was asked for (the viewer's address, the outputs, printing).
    pub request: SessionRequest,
    /// The files the session writes at its end, checked.
    pub outputs: SessionOutputs,
}

/// A prepared session made ready to run: its scene, the live viewer when one was asked for (keep
/// it alive for the session), the loop's setup, publishing to that viewer, and the signal
/// handlers that stop it.
pub struct LiveSession {
    /// What was built once from the scene file: voxmap, shell, parameters, meshes.
    pub assets: SessionAssets,
    /// The viewer serving this session, if any.
    pub viewer: Option<LiveViewer>,
    /// What the frame loop runs.
    pub setup: SessionSetup,
    /// The bridge's counters and wrench log, when the device is the UDP bridge (for the report).
    pub bridge: Option<BridgeMonitor>,
    /// SIGINT, SIGTERM and SIGHUP set `setup.stop` (the device is then written zero and the
    /// report says which signal came).
    pub signals: SignalStop,
    /// What was asked for.
    pub request: SessionRequest,
    /// The files the session writes at its end, checked.
    pub outputs: SessionOutputs,
}

impl Prepared {
    /// A session of `assets` with a plan made by its caller (a benchmark's resampled shell or
    /// repeated script) instead of [`prepare`]'s; `request` gives the threads, viewer and outputs
    /// (checked here against each other, as [`prepare`] does first).
    pub fn from_plan(
        assets: SessionAssets,
        plan: SessionPlan,
        device: DeviceChoice,
        request: SessionRequest,
    ) -> Result<Prepared> {
        let outputs = SessionOutputs::reserve(&request)?;
        Ok(Prepared {
            assets,
            plan,
            device,
            request,
            outputs,
        })
    }

    /// Attaches the viewer at the request's `view` (when given) and builds the loop's setup, with
    /// a stop flag set by SIGINT, SIGTERM and SIGHUP (installed here: the device is open from now
    /// on).
    pub fn go_live(self) -> Result<LiveSession> {
        let Prepared {
            assets,
            plan,
            request,
            outputs,
            ..
        } = self;
        let viewer = attach_viewer(request.view, &assets)?;
        let bridge = plan.bridge.clone();
        let (setup, signals) = plan.into_live_setup(viewer.as_ref().map(|v| v.feed()))?;
        Ok(LiveSession {
            assets,
            viewer,
            setup,
            bridge,
            signals,
            request,
            outputs,
        })
    }
}

/// The device of `--device`, else the scene file's (`scene_device`).
pub fn device_choice(text: Option<&str>, scene_device: &DeviceChoice) -> Result<DeviceChoice> {
    match text {
        Some(t) => DeviceChoice::parse(t).map_err(|m| anyhow!("--device {m}")),
        None => Ok(scene_device.clone()),
    }
}

/// The bridge settings of a session: the scene's (`[device]` `mapping`, `pose_timeout_ms`) with
/// each flag of `flags` that was given in their place; the wrench log holds one wrench per frame
/// plus the loop's final zero when `--log-wrenches` is given. The flags need the bridge device.
fn bridge_settings(
    flags: &BridgeOverrides,
    choice: &DeviceChoice,
    scene: BridgeSettings,
    frames: u64,
) -> Result<BridgeSettings> {
    if *flags == BridgeOverrides::default() {
        return Ok(scene);
    }
    if !matches!(choice, DeviceChoice::Bridge(_)) {
        bail!("--map-*, --force-scale, --pose-timeout-ms and --log-wrenches need --device bridge[:ADDR]");
    }
    let mut settings = scene;
    let m = &mut settings.mapping;
    m.scale = flags.map_scale.unwrap_or(m.scale);
    m.offset = flags.map_offset.unwrap_or(m.offset);
    m.rotate_deg = flags.map_rotate_deg.unwrap_or(m.rotate_deg);
    m.force_scale = flags.force_scale.unwrap_or(m.force_scale);
    if let Some(ms) = flags.pose_timeout_ms {
        settings.pose_timeout = ms / 1e3;
    }
    if flags.log_wrenches.is_some() {
        // The loop writes one zero wrench after its last frame.
        settings.wrench_log_frames = usize::try_from(frames)
            .unwrap_or(usize::MAX)
            .saturating_add(1);
    }
    Ok(settings)
}

/// Checks that the device of `args` is there, builds the scene, loads parameters and opens the
/// device. A missing device is reported before the voxmap is built (that can take minutes).
pub fn prepare(args: &SessionRequest) -> Result<Prepared> {
    // Output paths first: a bad one fails before the scene file is read.
    let outputs = SessionOutputs::reserve(args)?;
    let mut loaded = LoadedScene::load_within(&args.scene.scene, args.scene.memory_budget())?;
    let choice = device_choice(args.device.as_deref(), &loaded.device)?;
    let part_files = vps_study::files::part_file_names(&loaded.part_names());
    if args.replay_every_part {
        let DeviceChoice::Replay(first) = &choice else {
            bail!("every part replays its own trace only beside a replayed first part");
        };
        for (p, file) in loaded.more_parts.iter_mut().zip(&part_files[1..]) {
            let path = part_trace_path(&first.path, file);
            if !path.exists() {
                bail!(
                    "part '{}' of {}: its trace {} is missing (a session of several parts \
                     records each other part's trace beside the first's: --record {} wrote it)",
                    p.name,
                    loaded.label,
                    path.display(),
                    first.path.display()
                );
            }
            p.device = DeviceChoice::Replay(vps_session::ReplaySource::new(path));
        }
    }
    // Now that the scene file is read: no output may be one of its meshes (or the trace its
    // device replays).
    let mut inputs = command_line_inputs(args);
    inputs.extend(
        loaded
            .static_sources
            .iter()
            .chain([&loaded.part_source])
            .chain(loaded.more_parts.iter().map(|p| &p.source))
            .filter(|s| !s.starts_with("builtin:"))
            .map(PathBuf::from),
    );
    for device in std::iter::once(&choice).chain(loaded.more_parts.iter().map(|p| &p.device)) {
        if let DeviceChoice::Replay(source) = device {
            inputs.push(source.path.clone());
        }
    }
    check_session_outputs(args, &inputs, &part_files)?;
    if args.free_running {
        let paced = std::iter::once(&choice)
            .chain(loaded.more_parts.iter().map(|p| &p.device))
            .find(|d| !matches!(d, DeviceChoice::Simulated | DeviceChoice::Replay(_)));
        if let Some(device) = paced {
            bail!(
                "--free-running runs frames back to back: only for the simulated hand and \
                 replays, not for a person's device ({device:?})"
            );
        }
    }
    choice.check_available()?;
    for p in &loaded.more_parts {
        p.device
            .check_available()
            .with_context(|| format!("part '{}'", p.name))?;
    }
    // Read before the voxmap is built (that can take minutes), so a bad file is reported at once.
    let haptic_file = args
        .haptic
        .as_deref()
        .map(HapticParams::from_file)
        .transpose()?;
    let options = vps_session::BuildOptions {
        viewer: args.view.is_some(),
        ..args.scene.build_options(args.voxel_size)
    };
    let mut assets = SessionAssets::from_loaded(loaded, &options)?;
    if let Some(params) = haptic_file {
        assets.params = params.with_scene(assets.voxel_size, assets.shell.points().max_radius())?;
    }
    let source = match &args.haptic {
        Some(path) => path.display().to_string(),
        None => assets.label.clone(),
    };
    check_loop_period(&assets.params, &source)?;
    let script = assets.script()?;
    let seconds = session_seconds(args.seconds, &choice, assets.hands_duration(&script)?);
    if args.seconds.is_none() && choice == DeviceChoice::Simulated {
        eprintln!(
            "session: {seconds:.2} s, until the simulated hand's path ends (--seconds to change)"
        );
    }
    let frames = choice.frames(seconds, assets.params.dt)?;
    assets.bridge = bridge_settings(&args.bridge, &choice, assets.bridge, frames)?;
    let config = LoopConfig {
        frames: Some(frames),
        threads: args.threads.max(1),
        realtime: !args.free_running,
        free_running: args.free_running,
        // Back to back nobody holds a device: a slow frame (a loaded machine) must not zero the
        // simulated hand's force, or the session would depend on the machine's load.
        watchdog: if args.free_running {
            FREE_RUNNING_WATCHDOG
        } else {
            LoopConfig::default().watchdog
        },
        record_trace: args.record.is_some() || args.study.is_some(),
        ..LoopConfig::default()
    };
    if let Some(warning) = assets.start_overlap(&script).warning() {
        eprintln!(
            "{}: warning: {}",
            vps_files::printable(&assets.label),
            vps_files::printable(&warning)
        );
    }
    let plan = assets.plan(&choice, script, config)?;
    Ok(Prepared {
        assets,
        plan,
        device: choice,
        request: args.clone(),
        outputs,
    })
}

/// The watchdog of a `--free-running` session: long enough never to trip on a loaded machine.
const FREE_RUNNING_WATCHDOG: std::time::Duration = std::time::Duration::from_secs(10);

/// A session's length when `--seconds` is not given and the device is not a replay (whose trace
/// sets it).
pub const DEFAULT_SESSION_SECONDS: f64 = 30.0;

/// How long a session runs (s): `--seconds` when given; else, for the simulated hand, until its
/// path has ended (its last hold included: the last frame at or just past `path_seconds`, the
/// longest simulated hand's script, at most [`crate::limits::MAX_SESSION_SECONDS`]); else
/// [`DEFAULT_SESSION_SECONDS`].
pub fn session_seconds(given: Option<f64>, choice: &DeviceChoice, path_seconds: f64) -> f64 {
    match (given, choice) {
        (Some(s), _) => s,
        (None, DeviceChoice::Simulated) => {
            // Frames at 0, dt, 2 dt, ...: the last one at or past the path's end.
            let dt = LoopConfig::default().period.as_secs_f64();
            let ticks = (path_seconds / dt).ceil() + 1.0;
            (ticks * dt).min(crate::limits::MAX_SESSION_SECONDS)
        }
        (None, _) => DEFAULT_SESSION_SECONDS,
    }
}

/// Fails unless the haptic time step `dt` (s) of `params`, read from `source`, is the session
/// loop's period: the loop ticks at 1 kHz whatever the parameters say.
fn check_loop_period(params: &HapticParams, source: &str) -> Result<()> {
    let period = LoopConfig::default().period.as_secs_f64();
    if (params.dt - period).abs() > 1e-12 {
        bail!(
            "{source}: haptic parameter `dt` = {} s: the session loop runs at {} Hz, so `dt` \
             must be {period} s (or left out)",
            params.dt,
            1.0 / period
        );
    }
    Ok(())
}
