//! Sessions on the command line, shared by `vps run`, `record`, `replay`, `demo`, `coordinator`,
//! `cluster` and the benchmarks that run sessions: opening one from the command line
//! ([`prepare`]), attaching the viewer and the signal handlers ([`PreparedSession::go_live`]),
//! writing its files and figures at its end ([`finish`]), and the scripted simulated session of
//! `vps demo` and `vps bench viewer` ([`run_scripted`]).
//!
//! Words (one meaning each): a *session* is one run of the 1 kHz loop, start to stop.
//! [`SessionAssets`] (vps-session) is what is built once from a scene file and sessions run with.
//! A [`PreparedSession`] is those assets plus the session's plan (parameters, the opened device,
//! loop settings), made by [`prepare`] from the command line. A [`LiveSession`] is a prepared
//! session with its viewer, loop setup and signal handlers, ready for `run_loop` (made by
//! [`PreparedSession::go_live`]). [`finish`] reports a session that has run. A *coordinated*
//! session runs with workers (`crate::cluster_session`).

use crate::cli::{BridgeArgs, RunArgs};
use crate::exit::{outcome, SessionExit};
use crate::output::{check_outputs, print_json, write_file};
use anyhow::{anyhow, bail, Context, Result};
use glam::DVec3;
use serde::Serialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use vps_device::trace::save_trace;
use vps_haptic::HapticParams;
use vps_input::{BridgeCounters, BridgeMonitor};
use vps_runtime::{
    run_loop, LoopConfig, LoopReport, Percentiles, SessionSetup, SignalStop, StateFeedSender,
    StatsSummary,
};
use vps_session::{BridgeSettings, DeviceChoice, LoadedScene, SessionAssets, SessionPlan};
use vps_view::{LiveViewer, SceneLimits};

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
    /// The process's exit status (src/exit.rs; README, "Units, limits and safety").
    exit_code: i32,
    final_position_m: [f64; 3],
    /// Where the hand (the device's handle) was in the last frame (m): a part held back by an
    /// obstacle stays away from it. `None` when no frame ran.
    #[serde(skip_serializing_if = "Option::is_none")]
    final_hand_position_m: Option<[f64; 3]>,
    stats: StatsSummary,
    /// The device's own counters (e.g. the bridge's datagram counts), when it keeps any.
    #[serde(skip_serializing_if = "Option::is_none")]
    device_counters: Option<serde_json::Value>,
    #[serde(skip_serializing_if = "Option::is_none")]
    cluster: Option<serde_json::Value>,
    /// The bridge device's counters, when the device was the bridge.
    #[serde(skip_serializing_if = "Option::is_none")]
    bridge: Option<BridgeCounters>,
    /// Every moving part, the first first (absent in a one-part scene).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    parts: Vec<crate::parts_report::PartSummary>,
    /// The pairs of parts, counted (absent in a one-part scene).
    #[serde(skip_serializing_if = "Option::is_none")]
    pairs: Option<vps_runtime::PairCounts>,
}

/// The files a session writes at its end, checked before the session starts so that a bad path
/// fails before any work ([`check_outputs`]: each a regular file or a new path in a directory that
/// takes new files, none of them an input the command line names or another output), and again
/// against the scene's mesh files once the scene file is read ([`prepare`]); written atomically
/// at the end.
#[derive(Default)]
pub struct SessionOutputs {
    /// `--report FILE`.
    report: Option<PathBuf>,
    /// `--record FILE`.
    record: Option<PathBuf>,
    /// `--study DIR`.
    pub study: Option<PathBuf>,
}

/// Every file a session of `args` writes, with the flag that named it (a study's folder: each
/// file the study writes into it). `part_files`: with several moving parts, each part's file name
/// ([`vps_study::files::part_file_names`]): `--record` writes one trace per part
/// ([`part_trace_path`]) and `--study` one folder per part.
fn named_outputs(args: &RunArgs, part_files: &[String]) -> Vec<(&'static str, PathBuf)> {
    let mut outputs: Vec<(&'static str, PathBuf)> = [
        ("--report", &args.report),
        ("--record", &args.record),
        ("--log-wrenches", &args.bridge.log_wrenches),
    ]
    .into_iter()
    .filter_map(|(flag, path)| Some((flag, path.clone()?)))
    .collect();
    if let (Some(dir), true) = (&args.study, part_files.len() <= 1) {
        outputs.extend(
            vps_study::files::study_paths(dir)
                .into_iter()
                .map(|p| ("--study", p)),
        );
    }
    if part_files.len() > 1 {
        if let Some(record) = &args.record {
            outputs.extend(
                part_files[1..]
                    .iter()
                    .map(|f| ("--record", part_trace_path(record, f))),
            );
        }
        if let Some(dir) = &args.study {
            for f in part_files {
                outputs.extend(
                    vps_study::files::study_paths(&dir.join(f))
                        .into_iter()
                        .map(|p| ("--study", p)),
                );
            }
            outputs.extend(
                vps_study::files::pair_paths(dir)
                    .into_iter()
                    .map(|p| ("--study", p)),
            );
        }
    }
    outputs
}

/// Where the trace of a session's moving part `part_file` (its file name,
/// [`vps_study::files::part_file_names`]) is written beside the first part's trace `record`
/// (`--record`), and read back from by `vps study`: `record`'s stem, a dot, the part's file
/// name, then `record`'s extension (`s.trace` → `s.peg.trace`).
pub fn part_trace_path(record: &Path, part_file: &str) -> PathBuf {
    let stem = record.file_stem().map_or_else(
        || std::ffi::OsString::from("trace"),
        std::ffi::OsStr::to_os_string,
    );
    let mut name = stem;
    name.push(".");
    name.push(part_file);
    if let Some(ext) = record.extension() {
        name.push(".");
        name.push(ext);
    }
    record.with_file_name(name)
}

/// The files a session of `args` reads that its command line names: the scene file, the haptic
/// parameter file and a replayed trace (`--device replay:FILE`).
fn command_line_inputs(args: &RunArgs) -> Vec<PathBuf> {
    let mut inputs = Vec::new();
    if !args.scene.scene.starts_with("builtin:") {
        inputs.push(PathBuf::from(&args.scene.scene));
    }
    inputs.extend(args.haptic.clone());
    if let Some(trace) = args
        .device
        .as_deref()
        .and_then(|d| d.strip_prefix("replay:"))
    {
        inputs.push(PathBuf::from(trace));
    }
    inputs
}

/// Checks every output of `args` against `inputs` and each other ([`check_outputs`]), making the
/// study's folder (and with several parts each part's in it) first when missing.
fn check_session_outputs(args: &RunArgs, inputs: &[PathBuf], part_files: &[String]) -> Result<()> {
    if let Some(dir) = &args.study {
        make_study_dir(dir)?;
        if part_files.len() > 1 {
            for f in part_files {
                make_study_dir(&dir.join(f))?;
            }
        }
    }
    let inputs: Vec<&Path> = inputs.iter().map(PathBuf::as_path).collect();
    let outputs = named_outputs(args, part_files);
    let outputs: Vec<(&str, &Path)> = outputs.iter().map(|(f, p)| (*f, p.as_path())).collect();
    check_outputs(&outputs, &inputs)
}

/// Makes the study folder `dir` when missing and checks the files a study writes into it
/// against `inputs` ([`check_outputs`]).
pub fn reserve_study_dir(dir: &Path, inputs: &[&Path]) -> Result<()> {
    make_study_dir(dir)?;
    let paths = vps_study::files::study_paths(dir);
    let outputs: Vec<(&str, &Path)> = paths.iter().map(|p| ("--study", p.as_path())).collect();
    check_outputs(&outputs, inputs)
}

/// Makes `dir` (and its parents) unless it is a folder already; fails, naming it, when it is
/// something else.
fn make_study_dir(dir: &Path) -> Result<()> {
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Ok(_) => bail!(
            "--study {}: exists and is not a folder; give a folder (made when missing)",
            dir.display()
        ),
        Err(_) => std::fs::create_dir_all(dir)
            .with_context(|| format!("--study {}: cannot make the folder", dir.display())),
    }
}

impl SessionOutputs {
    /// Checks `--report`, `--record` and `--log-wrenches` of `args` (against the inputs its
    /// command line names and each other).
    pub fn reserve(args: &RunArgs) -> Result<SessionOutputs> {
        check_session_outputs(args, &command_line_inputs(args), &[])?;
        Ok(SessionOutputs {
            report: args.report.clone(),
            record: args.record.clone(),
            study: args.study.clone(),
        })
    }
}

/// Everything a session needs, opened from the command line.
pub struct PreparedSession {
    /// What was built once from the scene file: voxmap, shell, parameters, meshes.
    pub assets: SessionAssets,
    /// Parameters, opened device, initial state and loop settings.
    pub plan: SessionPlan,
    /// The device it was opened from (a replay's trace, read once, is shared from here).
    pub device: DeviceChoice,
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
}

impl PreparedSession {
    /// Attaches the viewer at `view` (when given) and builds the loop's setup, with a stop flag
    /// set by SIGINT, SIGTERM and SIGHUP (installed here: the device is open from now on).
    pub fn go_live(self, view: Option<std::net::SocketAddr>) -> Result<LiveSession> {
        let PreparedSession { assets, plan, .. } = self;
        let viewer = attach_viewer(view, &assets)?;
        let bridge = plan.bridge.clone();
        let (setup, signals) = plan.into_live_setup(viewer.as_ref().map(|v| v.feed()))?;
        Ok(LiveSession {
            assets,
            viewer,
            setup,
            bridge,
            signals,
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
    flags: &BridgeArgs,
    choice: &DeviceChoice,
    scene: BridgeSettings,
    frames: u64,
) -> Result<BridgeSettings> {
    if *flags == BridgeArgs::default() {
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
pub fn prepare(args: &RunArgs) -> Result<PreparedSession> {
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
    Ok(PreparedSession {
        assets,
        plan,
        device: choice,
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

/// Once the device has been written zero: saves the recording (and the bridge's wrench log when
/// asked), writes the report file and the study (`--study`, of the session run on `assets`), prints the session's figures (with the bridge's counters when
/// `bridge` is given, and `cluster`, when given, as JSON), and fails with a [`SessionExit`] (its
/// exit status) when the session did not run to its end.
pub fn finish<C: Serialize>(
    args: &RunArgs,
    outputs: SessionOutputs,
    signals: &SignalStop,
    assets: &SessionAssets,
    report: &LoopReport,
    bridge: Option<&BridgeMonitor>,
    cluster: Option<&C>,
) -> Result<()> {
    if let (Some(monitor), Some(path)) = (bridge, &args.bridge.log_wrenches) {
        let mut n = 0;
        vps_voxmap::atomic::write_atomically(
            path,
            |w| {
                n = monitor.write_wrench_log(w)?;
                Ok(())
            },
            |stage, e| std::io::Error::new(e.kind(), format!("{}: {e}", stage.name())),
        )
        .with_context(|| format!("--log-wrenches: writing the wrench log {}", path.display()))?;
        eprintln!("logged {n} wrenches sent to {}", path.display());
    }
    if let Some(c) = bridge.map(|m| m.counters()) {
        if c.stale > 0 || c.restarts > 0 {
            eprintln!(
                "bridge: {} pose(s) dropped as stale (a sequence number not above the sender's \
                 newest accepted one); {} time(s) a sender was taken back counting from below its \
                 old sequence, after its poses had timed out (a restarted client)",
                c.stale, c.restarts
            );
        }
    }
    let (end, exit_code) = outcome(&report.end, Some(signals));
    let out = RunReport {
        device: report.device_name.clone(),
        shell_points: assets.shell.len(),
        realtime_granted: report.rt.fifo,
        end,
        complete: report.end.is_complete(),
        exit_code,
        final_position_m: report.final_state.position.to_array(),
        final_hand_position_m: report.final_handle.map(|h| h.position.to_array()),
        stats: report.stats.clone(),
        // A bridge's counters are `bridge` below (read through its monitor): given once.
        device_counters: report.device_counters.clone().filter(|_| bridge.is_none()),
        cluster: cluster.map(serde_json::to_value).transpose()?,
        bridge: bridge.map(|m| m.counters()),
        parts: crate::parts_report::part_summaries(assets, report),
        pairs: (!report.other_parts.is_empty()).then_some(report.pairs),
    };
    if let Some(path) = &outputs.report {
        let text = serde_json::to_string_pretty(&out)? + "\n";
        write_file(path, text.as_bytes())?;
    }
    if let Some(path) = &outputs.record {
        save_recording(assets, report, path)?;
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
        print_summary("session", &out.stats, None);
        if cfg!(debug_assertions) {
            println!(
                "  (this vps was built without --release (debug assertions on): its frames are no \
                 guide to a release build's, and frames past the watchdog budget send zero force; \
                 run target/release/vps for a real session)"
            );
        }
        let [x, y, z] = out.final_position_m.map(crate::output::metres_4);
        println!("final part position (m): [{x}, {y}, {z}]");
        if let Some(hand) = out.final_hand_position_m {
            let gap = (DVec3::from_array(hand) - DVec3::from_array(out.final_position_m)).length();
            let [x, y, z] = hand.map(crate::output::metres_4);
            println!(
                "final hand position (m): [{x}, {y}, {z}]; the part's grip is {} m from it \
                 (a part held back by an obstacle stays away from the hand)",
                crate::output::metres_4(gap)
            );
        }
        if let Some(pairs) = &out.pairs {
            crate::parts_report::print_parts(&out.parts, pairs);
        }
        if let Some(c) = &out.bridge {
            println!(
                "bridge: poses received {}, bad datagrams {} (+{} wrong token, {} stale), \
                 sender restarts {}, timeouts {}, clutch presses {}, zeroed frames {}, wrenches \
                 sent {} ({} failed)",
                c.accepted,
                c.garbage,
                c.unauthorized,
                c.stale,
                c.restarts,
                c.timeouts,
                c.clutch_presses,
                c.zeroed_frames,
                c.sent,
                c.send_failed
            );
        }
        if let Some(cluster) = &out.cluster {
            // The figures of `vps_cluster::ClusterReport` (plus `placement`) in words; every
            // figure is in `--json`.
            match serde_json::from_value::<vps_cluster::ClusterReport>(cluster.clone()) {
                Ok(report) => {
                    for line in cluster_lines(&report) {
                        println!("{line}");
                    }
                }
                Err(_) => println!("cluster: figures with --json"),
            }
        }
    }
    if let Some(dir) = &outputs.study {
        let study = crate::session_study::write_session_study(
            dir,
            args.study_every,
            assets,
            assets.params,
            report,
            out.cluster
                .as_ref()
                .and_then(|c| c["stale_shares"].as_u64())
                .unwrap_or(0),
            args.json,
        );
        match study {
            Err(e) if exit_code != 0 => eprintln!("vps: --study: {e:#}"),
            other => other?,
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

/// µs from ns, one decimal.
fn us(ns: u64) -> String {
    format!("{:.1} µs", ns as f64 / 1e3)
}

/// A coordinated session's cluster figures in words for a person: how the frames were split
/// between the coordinator and its workers and why, what was recomputed or stood in for, and one
/// line per worker. Every figure is in the `--json` report's `cluster`.
pub fn cluster_lines(r: &vps_cluster::ClusterReport) -> Vec<String> {
    use crate::output::grouped;
    let mut lines = Vec::new();
    let sp = &r.split;
    let frames = grouped(r.frames);
    let predicted = sp.split_frames + sp.kept_local_frames > 0;
    lines.push(format!(
        "cluster: {} worker(s), {frames} frames gathered",
        r.peers.len()
    ));
    if !predicted {
        // `--split always` (no prediction): every frame is split between the workers.
        let shared = r.frames.saturating_sub(r.local_only_frames);
        lines.push(format!(
            "  {} frames split between the coordinator and its workers (--split always), {} \
             computed wholly here because no worker was able to take work",
            grouped(shared),
            grouped(r.local_only_frames)
        ));
    } else if sp.split_frames == 0 {
        let why = if sp.worker_base_ns == 0 {
            "no worker's round trip was measured yet, and a share is sent only to a measured \
             worker"
                .to_string()
        } else {
            format!(
                "the shell is small enough that a worker's round trip costs more than it saves \
                 (a worker's round trip about {}, the whole frame computed here about {})",
                us(sp.worker_base_ns),
                us(sp.predicted_local_ns)
            )
        };
        lines.push(format!("  all {frames} frames kept local: {why}"));
    } else {
        lines.push(format!(
            "  {} frames split between the coordinator and its workers (predicted faster: about \
             {} split against {} wholly here, latest frame), {} kept local (a split predicted no \
             faster)",
            grouped(sp.split_frames),
            us(sp.predicted_split_ns),
            us(sp.predicted_local_ns),
            grouped(sp.kept_local_frames)
        ));
    }
    if sp.probes > 0 {
        lines.push(format!(
            "  round trips measured by {} probes (no frame waits for one): {} answered, {} failed",
            grouped(sp.probes),
            grouped(sp.probe_replies),
            grouped(sp.probes_failed)
        ));
    }
    if r.fallback_shares > 0 || r.stale_shares > 0 {
        lines.push(format!(
            "  {} worker share(s) recomputed here (a reply late, lost or invalid); {} stood in \
             for by an earlier frame's sums (degraded accuracy)",
            grouped(r.fallback_shares),
            grouped(r.stale_shares)
        ));
    } else {
        lines.push("  no worker share was late or lost".into());
    }
    for p in &r.peers {
        let state = match (p.connected, p.sidelined) {
            (false, _) if p.disconnected_for_bad_replies => "disconnected for bad replies",
            (false, _) => "gone",
            (true, true) => "connected, sidelined",
            (true, false) => "connected",
        };
        let rtt = if p.rtt_samples > 0 {
            format!(
                ", round trip p50 {} p99 {}",
                us(p.rtt_ns.p50),
                us(p.rtt_ns.p99)
            )
        } else {
            String::new()
        };
        lines.push(format!(
            "  worker {}: {state}; {} requests, {} shares merged, {} late, {} lost{rtt}",
            p.id,
            grouped(p.requests),
            grouped(p.merged),
            grouped(p.late),
            grouped(p.lost)
        ));
    }
    lines.push("  (every figure, per worker too: --json)".into());
    lines
}

/// Saves the first part's trace to `path` and, with several moving parts, every other part's
/// beside it ([`part_trace_path`]).
fn save_recording(assets: &SessionAssets, report: &LoopReport, path: &Path) -> Result<()> {
    if let Some(why) = &report.trace_error {
        bail!("trace recording stopped early: {why}");
    }
    let trace = report
        .trace
        .as_ref()
        .context("the loop returned no trace")?;
    let frames = trace.frames.len();
    save_trace(path, trace)?;
    eprintln!("recorded {frames} frames to {}", path.display());
    if report.other_parts.is_empty() {
        return Ok(());
    }
    let files = vps_study::files::part_file_names(&assets.part_names());
    for (part, file) in report.other_parts.iter().zip(&files[1..]) {
        if let Some(why) = &part.trace_error {
            bail!("part '{}': trace recording stopped early: {why}", part.name);
        }
        let trace = part
            .trace
            .as_ref()
            .with_context(|| format!("the loop returned no trace of part '{}'", part.name))?;
        let beside = part_trace_path(path, file);
        save_trace(&beside, trace)?;
        eprintln!(
            "recorded part '{}': {} frames to {}",
            part.name,
            trace.frames.len(),
            beside.display()
        );
    }
    Ok(())
}

/// Starts a viewer of `assets` on `addr` when `--view` was given and prints its URL on stderr.
pub fn attach_viewer(
    addr: Option<SocketAddr>,
    assets: &SessionAssets,
) -> Result<Option<LiveViewer>> {
    let Some(addr) = addr else {
        return Ok(None);
    };
    let viewer = LiveViewer::start(
        addr,
        crate::scene_view::viewer_content(assets, SceneLimits::default()),
    )?;
    eprintln!("viewer: {}", viewer.url());
    Ok(Some(viewer))
}

/// How [`run_scripted`] runs its session.
#[derive(Clone, Copy, Debug, Default)]
pub struct Scripted {
    /// At 1 kHz on the wall clock; otherwise frames back to back (the same physics).
    pub paced: bool,
    /// Keep the handle trace (for a study).
    pub record_trace: bool,
}

impl Scripted {
    /// Paced at 1 kHz (`true`) or back to back, no trace kept.
    pub fn paced(paced: bool) -> Scripted {
        Scripted {
            paced,
            record_trace: false,
        }
    }
}

/// Runs one session of the scene's simulated hand (its script) on `assets` with `params`, for
/// at most `seconds` (the script's length at most); `paced` runs at 1 kHz on the wall clock,
/// otherwise frames run back to back (the physics is identical: the device is given the scheduled
/// tick time either way). Every frame is published to `feed` when given (a viewer). When `signals`
/// are given, one of them ends the session early (the device written zero first).
pub fn run_scripted(
    assets: &SessionAssets,
    params: HapticParams,
    seconds: f64,
    threads: usize,
    how: Scripted,
    feed: Option<StateFeedSender>,
    signals: Option<&SignalStop>,
) -> Result<LoopReport> {
    let script = assets.script()?;
    let frames = ((seconds.min(script.duration()) / params.dt).round() as u64).max(1);
    let config = LoopConfig {
        frames: Some(frames),
        threads,
        realtime: how.paced,
        free_running: !how.paced,
        record_trace: how.record_trace,
        ..LoopConfig::default()
    };
    let mut plan = assets.plan(&DeviceChoice::Simulated, script, config)?;
    plan.setup.params = params;
    let report = run_loop(
        assets.tree.clone(),
        assets.classed_shell(),
        match signals {
            Some(signals) => plan.into_stopped_setup(feed, signals),
            None => plan.into_setup(feed),
        },
    )?;
    if let Some(err) = &report.device_error {
        anyhow::bail!("the device failed: {err}");
    }
    Ok(report)
}

/// Prints a session's frame figures; `paper` is the paper's penetration ratio to show beside ours.
pub fn print_summary(label: &str, s: &StatsSummary, paper: Option<f64>) {
    // "  NAME µs  p50 ..  p99 ..  p99.9 ..  max .." from nanoseconds.
    let line_us = |name: &str, p: &Percentiles| {
        let us = |ns: u64| ns as f64 / 1e3;
        println!(
            "  {name} µs  p50 {:.1}  p99 {:.1}  p99.9 {:.1}  max {:.1}",
            us(p.p50),
            us(p.p99),
            us(p.p999),
            us(p.max)
        );
    };
    println!("{label}:");
    println!(
        "  frames {}, missed deadlines {}, watchdog trips {}, local fallbacks {}",
        s.frames, s.missed_deadlines, s.watchdog_trips, s.fallback_shares
    );
    if s.missed_deadlines > 0 {
        println!(
            "  missed after a late start {} (the thread was not run in time), after a long frame {}",
            s.missed_after_late_start, s.missed_after_long_frame
        );
    }
    line_us("compute", &s.compute_ns);
    if s.period_error_ns.max > 0 || s.missed_deadlines > 0 {
        line_us("period error", &s.period_error_ns);
    }
    println!(
        "  contact frames {}, touching {}, penetrating {}, penetration ratio {}{}",
        s.contact_frames,
        s.touching_frames,
        s.penetrating_frames,
        s.penetration_ratio
            .map_or("n/a (no contact)".into(), |r| format!("{r:.2e}")),
        paper.map_or(String::new(), |p| format!(" (the paper's: {p:.1e})"))
    );
}

/// What each figure of [`print_summary`] means, one line each (`vps demo` prints it under its
/// figures).
pub const SESSION_LEGEND: &[&str] = &[
    "what the figures mean:",
    "  frames: 1 ms loop iterations run (one force sent to the device each)",
    "  missed deadlines: 1 ms ticks skipped because a frame started or finished too late",
    "  watchdog trips: frames whose compute overran the budget; the device got zero force for them",
    "  local fallbacks: worker shares the frame thread computed itself because a worker's reply \
     missed its deadline (always 0 without workers)",
    "  compute: time from reading the device to writing its force, per frame (µs percentiles)",
    "  period error: how far a frame started from its scheduled 1 ms tick (paced sessions only)",
    "  contact frames: frames in which at least one shell point pushed (a point in an obstacle's \
     force layer, past its tangent plane)",
    "  touching: frames with at least one shell point in an obstacle's force layer or inside it \
     (pushing or not)",
    "  penetrating: frames with at least one shell point inside an obstacle (past the force layer)",
    "  penetration ratio: penetrating / touching frames, lower is better; the paper's: McNeely et \
     al. 1999, Table 2 (6.0e-5 with braking, 1.0e-3 without)",
    "  braking: pre-contact braking slows the part as it nears a surface (the paper's); the \
     second session turns it off to show what it prevents",
];
