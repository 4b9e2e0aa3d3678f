//! `vps bench parts`: what several moving parts cost a frame. On a scene of at least two
//! `[[part]]`s, in one process, alternating, `--rounds` times each, frames back to back (the
//! simulated hands, realtime off):
//! - `first alone`: the first part alone (its shell in the static scene);
//! - `second alone`: the second part alone, its hand moved 1 m away along +x from where the first
//!   part starts (as in `apart`);
//! - `apart`: both parts, the second 1 m away: the broad phase skips the pair every frame;
//! - `apart, every pair sampled`: the same with the broad phase's margin made infinite, so the pair
//!   is sampled both ways every frame (and finds nothing);
//! - `scene`: the scene's own session (its parts may touch).
//!
//! The figure the broad phase answers for: `apart` against `first alone + second alone` (the two
//! parts' own static sampling, which two parts need whatever the broad phase does).

use anyhow::{bail, Result};
use glam::DVec3;
use serde::Serialize;
use vps_app::output::print_report;
use vps_app::SceneRequest;
use vps_runtime::{run_loop, LoopConfig};
use vps_session::{DeviceChoice, HandPlan, SessionAssets};

/// One configuration's figures, its runs' medians.
#[derive(Serialize)]
struct Row {
    configuration: &'static str,
    /// Frame compute p50 (µs), the median over the rounds.
    compute_p50_us: f64,
    /// Frame compute p99.9 (µs), the median over the rounds.
    compute_p999_us: f64,
    /// Pairs sampled per frame.
    pairs_sampled_per_frame: f64,
}

#[derive(Serialize)]
struct PartsBench {
    scene: String,
    shell_points: Vec<usize>,
    frames: u64,
    rounds: u32,
    host_idle: crate::machine::HostIdle,
    rows: Vec<Row>,
    /// `apart` p50 ÷ (`first alone` p50 + `second alone` p50).
    apart_over_both_alone: f64,
    /// `apart` p50 ÷ `first alone` p50.
    apart_over_first_alone: f64,
}

/// The configurations, in the order they run each round.
const CONFIGURATIONS: [&str; 5] = [
    "first alone",
    "second alone",
    "apart",
    "apart, every pair sampled",
    "scene",
];

/// `assets` made into configuration `name`. Allocates.
fn configured(assets: &SessionAssets, name: &str) -> SessionAssets {
    let mut a = assets.clone();
    let far = {
        let start = a.hand.first_waypoint().unwrap_or(DVec3::ZERO);
        HandPlan::Path {
            waypoints: vec![start + DVec3::X],
            speed: 0.1,
            hold: 0.0,
        }
    };
    match name {
        "first alone" => {
            a.more_parts.clear();
            a.part_body = None;
        }
        "second alone" => {
            let second = a.more_parts.remove(0);
            a.more_parts.clear();
            a.part_body = None;
            a.shell = second.shell;
            a.params = second.params;
            a.part_mesh = second.mesh;
            a.hand = far;
        }
        "apart" | "apart, every pair sampled" => {
            a.more_parts.truncate(1);
            a.more_parts[0].hand = far;
            if name != "apart" {
                a.pair_margin = f64::MAX;
            }
        }
        _ => a.more_parts.truncate(1),
    }
    a
}

/// Runs the benchmark.
pub fn run(scene: &SceneRequest, frames: u64, rounds: u32, json: bool) -> Result<()> {
    let assets = SessionAssets::open(&scene.scene, &scene.build_options(None))?;
    if assets.more_parts.is_empty() {
        bail!(
            "{}: vps bench parts needs a scene of at least two [[part]]s (e.g. --scene \
             assets/scenes/two-hands.toml)",
            assets.label
        );
    }
    let host_idle = crate::machine::HostIdle::read();
    let mut samples: Vec<Vec<(f64, f64, f64)>> = vec![Vec::new(); CONFIGURATIONS.len()];
    for _ in 0..rounds.max(1) {
        for (k, name) in CONFIGURATIONS.iter().enumerate() {
            let a = configured(&assets, name);
            let config = LoopConfig {
                frames: Some(frames),
                free_running: true,
                watchdog: std::time::Duration::from_secs(10),
                ..LoopConfig::default()
            };
            let plan = a.plan(
                &DeviceChoice::Simulated,
                a.script_for_frames(frames)?,
                config,
            )?;
            let report = run_loop(a.tree.clone(), a.classed_shell(), plan.into_setup(None))?;
            vps_app::exit::require_complete(&report.end, None)?;
            let c = &report.stats.compute_ns;
            samples[k].push((
                c.p50 as f64 / 1e3,
                c.p999 as f64 / 1e3,
                report.pairs.sampled as f64 / frames as f64,
            ));
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let rows: Vec<Row> = CONFIGURATIONS
        .iter()
        .zip(samples)
        .map(|(name, s)| Row {
            configuration: name,
            compute_p50_us: median(s.iter().map(|x| x.0).collect()),
            compute_p999_us: median(s.iter().map(|x| x.1).collect()),
            pairs_sampled_per_frame: median(s.iter().map(|x| x.2).collect()),
        })
        .collect();
    let p50 = |k: usize| rows[k].compute_p50_us;
    let bench = PartsBench {
        scene: assets.label.clone(),
        shell_points: std::iter::once(assets.shell.len())
            .chain(assets.more_parts.iter().map(|p| p.shell.len()))
            .collect(),
        frames,
        rounds,
        host_idle,
        apart_over_both_alone: p50(2) / (p50(0) + p50(1)),
        apart_over_first_alone: p50(2) / p50(0),
        rows,
    };
    print_report(
        "bench parts: frame compute of several parts, apart and touching",
        &bench,
        json,
    )
}
