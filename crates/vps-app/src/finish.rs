//! A session's end, once the device has been written zero: its recording, wrench log, report
//! file, study and printed figures ([`finish`]), and the words for a person of its frame figures
//! ([`print_summary`], [`SESSION_LEGEND`]) and cluster figures ([`cluster_lines`]).

use crate::exit::{outcome, SessionExit};
use crate::output::{print_json, write_file};
use crate::request::SessionRequest;
use crate::session_files::{part_trace_path, SessionOutputs};
use anyhow::{bail, Context, Result};
use glam::DVec3;
use serde::Serialize;
use std::path::Path;
use vps_device::trace::save_trace;
use vps_input::{BridgeCounters, BridgeMonitor};
use vps_runtime::{LoopReport, Percentiles, SignalStop, StatsSummary};
use vps_session::SessionAssets;

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

/// Once the device has been written zero: saves the recording (and the bridge's wrench log when
/// asked), writes the report file and the study (`--study`, of the session run on `assets`), prints the session's figures (with the bridge's counters when
/// `bridge` is given, and `cluster`, when given, as JSON), and fails with a [`SessionExit`] (its
/// exit status) when the session did not run to its end.
pub fn finish<C: Serialize>(
    args: &SessionRequest,
    outputs: SessionOutputs,
    signals: &SignalStop,
    assets: &SessionAssets,
    report: &LoopReport,
    bridge: Option<&BridgeMonitor>,
    cluster: Option<&C>,
) -> Result<()> {
    if let (Some(monitor), Some(path)) = (bridge, &args.bridge.log_wrenches) {
        let mut n = 0;
        vps_files::atomic::write_atomically(
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
        let study = crate::study::write_session_study(
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
    "  contact frames: frames in which at least one shell point pushed (tangent-plane model: a \
     point in an obstacle's force layer, past its tangent plane; distance model: a point nearer \
     the exact surface than the stand-off)",
    "  touching: frames with at least one shell point in an obstacle's force layer or inside it, \
     pushing or not (distance model: nearer than the stand-off or inside)",
    "  penetrating: frames with at least one shell point inside an obstacle (tangent-plane model: \
     past the force layer; distance model: inside the exact surface)",
    "  penetration ratio: penetrating / touching frames, lower is better; the paper's: McNeely et \
     al. 1999, Table 2 (6.0e-5 with braking, 1.0e-3 without)",
    "  braking: pre-contact braking slows the part as it nears a surface (the paper's); the \
     second session turns it off to show what it prevents",
];
