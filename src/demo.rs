//! `vps demo`: the main job on a scene, by default the built-in scene file `bay-teapot`: the
//! teapot's point shell threads the aircraft bay (voxelized at 5 mm) in the hands of a simulated
//! user, on the 1 kHz loop; then the same scripted session again with pre-contact braking off, for
//! the penetration ratio of both.

use crate::cli::DemoArgs;
use crate::cmd::exit::{outcome, SessionExit};
use crate::cmd::output::print_json;
use anyhow::Result;
use serde::Serialize;
use vps_haptic::HapticParams;
use vps_runtime::{run_loop, LoopConfig, LoopReport, SignalStop, StateFeedSender, StatsSummary};
use vps_session::{stop_on_signals, DeviceChoice, Session};

/// The paper's penetration ratios (Table 2): braking on and off.
const PAPER_PR_BRAKING: f64 = 6e-5;
const PAPER_PR_NO_BRAKING: f64 = 1.0e-3;

#[derive(Serialize)]
struct DemoReport {
    scene_triangles: usize,
    voxel_size_m: f64,
    voxelize_ms: f64,
    tree_bytes: usize,
    /// The lookup directory derived from the tree (not part of `tree_bytes`).
    directory_bytes: usize,
    shell_points: usize,
    session_seconds: f64,
    threads: usize,
    realtime_granted: bool,
    pinned_core: Option<usize>,
    braking_on: StatsSummary,
    braking_off: StatsSummary,
}

/// Runs one session; `paced` runs at 1 kHz on the wall clock, otherwise frames run back to back
/// (the physics is identical: the device is given the scheduled tick time either way). Every frame
/// is published to `feed` when given (a viewer). Ended early (the device written zero) once one of
/// `signals` comes, when given.
pub fn run_session_until(
    scene: &Session,
    params: HapticParams,
    seconds: f64,
    threads: usize,
    paced: bool,
    feed: Option<StateFeedSender>,
    signals: Option<&SignalStop>,
) -> Result<LoopReport> {
    let script = scene.script()?;
    let frames = ((seconds.min(script.duration()) / params.dt).round() as u64).max(1);
    let config = LoopConfig {
        frames: Some(frames),
        threads,
        realtime: paced,
        free_running: !paced,
        ..LoopConfig::default()
    };
    let mut plan = scene.plan(&DeviceChoice::Simulated, script, config)?;
    plan.params = params;
    let report = run_loop(
        scene.tree.clone(),
        scene.classed_shell(),
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
    let us = |ns: u64| ns as f64 / 1e3;
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
    println!(
        "  compute µs  p50 {:.1}  p99 {:.1}  p99.9 {:.1}  max {:.1}",
        us(s.compute_ns.p50),
        us(s.compute_ns.p99),
        us(s.compute_ns.p999),
        us(s.compute_ns.max)
    );
    if s.period_error_ns.max > 0 || s.missed_deadlines > 0 {
        println!(
            "  period error µs  p50 {:.1}  p99 {:.1}  p99.9 {:.1}  max {:.1}",
            us(s.period_error_ns.p50),
            us(s.period_error_ns.p99),
            us(s.period_error_ns.p999),
            us(s.period_error_ns.max)
        );
    }
    println!(
        "  contact frames {}, touching {}, penetrating {}, penetration ratio {}{}",
        s.contact_frames,
        s.touching_frames,
        s.penetrating_frames,
        s.penetration_ratio
            .map_or("n/a (no contact)".into(), |r| format!("{r:.2e}")),
        paper.map_or(String::new(), |p| format!(" (paper: {p:.1e})"))
    );
}

/// Runs the demo.
pub fn run(args: &DemoArgs) -> Result<()> {
    let scene = Session::open(
        &args.scene.scene,
        &args.scene.build_options(args.voxel_size),
    )?;
    // Braking on for the first run whatever the scene says: the demo compares on with off.
    let params = HapticParams {
        braking: true,
        ..scene.params
    };
    let threads = args.threads.max(1);
    // One set of handlers for both sessions, installed before the scene is announced: a signal
    // from then on ends the demo (a session started after it stops at its first frame).
    let signals = stop_on_signals()?;
    if !args.json {
        println!(
            "scene: {} ({}), {} triangles, voxelized at {} m in {:.0} ms, tree {:.2} MiB \
             (+ {:.2} MiB lookup directory)",
            scene.name,
            scene.label,
            scene.scene_triangles,
            scene.voxel_size,
            scene.voxelize_ms,
            scene.tree.memory_bytes() as f64 / 1048576.0,
            scene.tree.directory_bytes() as f64 / 1048576.0
        );
        println!(
            "part: {} shell points; {} thread(s)",
            scene.shell.len(),
            threads
        );
    }
    let viewer = crate::cmd::view::attach(args.view, &scene)?;
    let feed = || viewer.as_ref().map(|v| v.feed());
    let session = |params: HapticParams, paced: bool| {
        let report = run_session_until(
            &scene,
            params,
            args.seconds,
            threads,
            paced,
            feed(),
            Some(&signals),
        )?;
        let (reason, code) = outcome(&report.end, Some(&signals));
        if code != 0 {
            print_summary(&format!("partial session ({reason})"), &report.stats, None);
            return Err(anyhow::Error::new(SessionExit {
                code,
                reason: format!(
                    "the session ended early ({reason}); the device was sent zero force"
                ),
            }));
        }
        Ok(report)
    };
    let on = session(params, true)?;
    let off_params = HapticParams {
        braking: false,
        ..params
    };
    let off = session(off_params, false)?;
    if args.json {
        return print_json(&DemoReport {
            scene_triangles: scene.scene_triangles,
            voxel_size_m: scene.voxel_size,
            voxelize_ms: scene.voxelize_ms,
            tree_bytes: scene.tree.memory_bytes(),
            directory_bytes: scene.tree.directory_bytes(),
            shell_points: scene.shell.len(),
            session_seconds: on.stats.frames as f64 * params.dt,
            threads,
            realtime_granted: on.rt.fifo,
            pinned_core: on.rt.pinned_core,
            braking_on: on.stats,
            braking_off: off.stats,
        });
    }
    let rt = if on.rt.fifo {
        "SCHED_FIFO granted"
    } else {
        "SCHED_FIFO not granted"
    };
    print_summary(
        &format!("braking on, 1 kHz paced ({rt})"),
        &on.stats,
        Some(PAPER_PR_BRAKING),
    );
    print_summary(
        "braking off, same script, frames back to back",
        &off.stats,
        Some(PAPER_PR_NO_BRAKING),
    );
    Ok(())
}
