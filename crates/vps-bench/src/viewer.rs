//! `vps bench viewer`: the viewer's cost on the loop. The demo's paced 1 kHz session (braking on,
//! one compute thread) runs in rounds on the same scene: without a viewer, then with a viewer and
//! one WebSocket client in this process reading every state message. Prints every run's frame
//! figures and the with/without ratios of the compute percentiles, per round and their medians
//! (JSON). SIGINT, SIGTERM or SIGHUP stop the running session (the simulated device is written
//! zero first); nothing is printed and the status is 128 + N, as for every benchmark.

use anyhow::{Context, Result};
use serde::Serialize;
use std::time::Duration;
use vps_app::exit::require_complete;
use vps_app::output::print_report;
use vps_app::scene_view::attach_viewer;
use vps_app::scripted::{run_scripted, Scripted};
use vps_haptic::HapticParams;
use vps_runtime::SignalStop;
use vps_runtime::{Percentiles, StatsSummary};
use vps_session::{stop_on_signals, BuildOptions, SessionAssets};
use vps_view::client::WsClient;

/// Voxel size of the benchmark's scene (m): the demo's.
const VOXEL_SIZE: f64 = 0.005;

#[derive(Serialize)]
struct ViewerBench {
    session_seconds: f64,
    shell_points: usize,
    /// with / without per compute percentile, the median over the rounds.
    median_compute_ratio: Ratios,
    rounds: Vec<Round>,
}

/// One session without a viewer, then one with.
#[derive(Serialize)]
struct Round {
    without_viewer: StatsSummary,
    with_viewer: StatsSummary,
    /// State messages the client read during the second run, and their total size.
    messages_read: u64,
    message_bytes: u64,
    /// CPU time of the viewer's threads (`vps-view-*`) over the second run (s), from
    /// /proc/self/task (Linux; `null` elsewhere).
    viewer_cpu_s: Option<f64>,
    /// with / without, per compute percentile.
    compute_ratio: Ratios,
}

#[derive(Serialize, Clone, Copy)]
struct Ratios {
    p50: f64,
    p99: f64,
    p999: f64,
    max: f64,
}

impl Ratios {
    fn of(with: &Percentiles, without: &Percentiles) -> Ratios {
        let r = |a: u64, b: u64| a as f64 / b.max(1) as f64;
        Ratios {
            p50: r(with.p50, without.p50),
            p99: r(with.p99, without.p99),
            p999: r(with.p999, without.p999),
            max: r(with.max, without.max),
        }
    }

    fn median(all: &[Ratios]) -> Ratios {
        let median = |f: fn(&Ratios) -> f64| {
            let mut v: Vec<f64> = all.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
        };
        Ratios {
            p50: median(|r| r.p50),
            p99: median(|r| r.p99),
            p999: median(|r| r.p999),
            max: median(|r| r.max),
        }
    }
}

/// Runs `rounds` pairs of sessions of `seconds` each (without, then with a viewer) and prints
/// JSON. Alternating spreads slow drifts of the machine's load over both kinds of run.
pub fn run(seconds: f64, rounds: u32, json: bool) -> Result<()> {
    // Installed before the scene is built: a signal during the build stops the first session at
    // its first frame.
    let signals = stop_on_signals()?;
    let scene = SessionAssets::open(
        vps_session::DEFAULT_SCENE,
        &BuildOptions {
            voxel_size: Some(VOXEL_SIZE),
            ..BuildOptions::default()
        },
    )?;
    let params = scene.params;
    let mut results = Vec::new();
    for _ in 0..rounds.max(1) {
        let without = run_scripted(
            &scene,
            params,
            seconds,
            1,
            Scripted::paced(true),
            None,
            Some(&signals),
        )?;
        require_complete(&without.end, Some(&signals))?;
        results.push(round_with_viewer(
            &scene,
            params,
            seconds,
            without.stats,
            &signals,
        )?);
    }
    let ratios: Vec<Ratios> = results.iter().map(|r| r.compute_ratio).collect();
    print_report(
        "bench viewer: frame compute of the paced demo session without and with a viewer",
        &ViewerBench {
            session_seconds: results[0].without_viewer.frames as f64 * params.dt,
            shell_points: scene.shell.len(),
            median_compute_ratio: Ratios::median(&ratios),
            rounds: results,
        },
        json,
    )
}

/// The session with a viewer and one WebSocket client reading every message.
fn round_with_viewer(
    scene: &SessionAssets,
    params: HapticParams,
    seconds: f64,
    without_viewer: StatsSummary,
    signals: &SignalStop,
) -> Result<Round> {
    let viewer = attach_viewer(Some("127.0.0.1:0".parse()?), scene)?.context("the viewer")?;
    let mut client = WsClient::connect(viewer.local_addr(), "/ws", Duration::from_secs(5))
        .context("connecting to the viewer's WebSocket")?;
    let reader = std::thread::spawn(move || {
        let (mut messages, mut bytes) = (0u64, 0u64);
        while let Ok(Some(text)) = client.read_text() {
            messages += 1;
            bytes += text.len() as u64;
        }
        (messages, bytes)
    });
    let cpu_before = viewer_threads_cpu_s();
    let with = run_scripted(
        scene,
        params,
        seconds,
        1,
        Scripted::paced(true),
        Some(viewer.feed()),
        Some(signals),
    )?;
    let viewer_cpu_s = cpu_before.zip(viewer_threads_cpu_s()).map(|(a, b)| b - a);
    drop(viewer);
    let (messages_read, message_bytes) = reader
        .join()
        .map_err(|_| anyhow::anyhow!("the WebSocket reader panicked"))?;
    require_complete(&with.end, Some(signals))?;
    Ok(Round {
        compute_ratio: Ratios::of(&with.stats.compute_ns, &without_viewer.compute_ns),
        without_viewer,
        with_viewer: with.stats,
        messages_read,
        message_bytes,
        viewer_cpu_s,
    })
}

/// User + system CPU time of this process's threads named `vps-view-*` (s), from
/// `/proc/self/task/*/stat` (10 ms resolution); `None` where that cannot be read.
fn viewer_threads_cpu_s() -> Option<f64> {
    let mut total = 0u64;
    for task in std::fs::read_dir("/proc/self/task").ok()?.flatten() {
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else {
            continue;
        };
        // "tid (name) state ...": utime and stime are fields 14 and 15, i.e. the 12th and 13th
        // after the closing parenthesis.
        let Some((head, rest)) = stat.rsplit_once(')') else {
            continue;
        };
        if !head.contains("(vps-view-") {
            continue;
        }
        let fields: Vec<&str> = rest.split_whitespace().collect();
        let ticks_of = |i: usize| fields.get(i).and_then(|f| f.parse::<u64>().ok());
        total += ticks_of(11)? + ticks_of(12)?;
    }
    Some(total as f64 / USER_HZ)
}

/// Clock ticks per second of `/proc/*/stat` times (Linux's fixed `USER_HZ`).
const USER_HZ: f64 = 100.0;
