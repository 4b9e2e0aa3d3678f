//! The assembly study of a session (the `vps-study` crate), made after it has ended and its
//! device has been written zero, never on the frame thread: for `--study DIR` on the session
//! commands and for `vps study` (`crate::cmd::study`). Prints the verdict for a person.

use crate::output::print_json;
use anyhow::{bail, Context, Result};
use serde_json::{json, Value};
use std::path::Path;
use vps_device::trace::Trace;
use vps_device::SimulatedHand;
use vps_haptic::{HapticParams, PartState};
use vps_runtime::LoopReport;
use vps_session::SessionAssets;
use vps_study::{run_study, Study, StudyInputs, Target};

/// The clearance series holds every this many frames (10 ms at 1 kHz); the minimum is over every
/// frame.
pub const SERIES_EVERY_FRAMES: usize = 10;

/// Makes and writes the study (`--study DIR`, path table every `every` frames) of the session
/// that produced `report` on `assets` with `params`, its part starting where the trace says the
/// loop started it, and prints its verdict. `stale_shares`: shares a cluster stood in for with an
/// earlier frame's sums (0 for a session on one host), said in the study since it recomputes
/// them. Blocking, parallel; called once the session's device has been written zero.
pub fn write_session_study(
    dir: &Path,
    every: usize,
    assets: &SessionAssets,
    params: HapticParams,
    report: &LoopReport,
    stale_shares: u64,
    json: bool,
) -> Result<()> {
    if let Some(why) = &report.trace_error {
        bail!("--study: the session's trace stopped early ({why}); no study written");
    }
    let trace = report
        .trace
        .as_ref()
        .context("--study: the loop returned no trace")?;
    let start = trace
        .part_start
        .context("--study: the loop's trace does not say where the part started")?;
    let initial = PartState::at_rest(start.position, start.orientation);
    let source = format!("the session ({})", report.device_name);
    let run = StudyRun {
        assets,
        params,
        trace,
        initial,
        source: &source,
        swept_voxel_size: None,
        stale_shares,
    };
    // With --json, stdout holds the session's report alone: the study's words go to stderr.
    let print = if json {
        Print::TextToStderr
    } else {
        Print::Text
    };
    write_study(&run, dir, every, print)
}

/// Where the hand was taking the part: the end of the scene's path when the trace is the
/// simulated hand's (or a replay of one), else `None` (the hand's last position).
fn target(assets: &SessionAssets, trace: &Trace) -> Result<Option<Target>> {
    let hand = SimulatedHand::NAME;
    let replayed = vps_device::trace::replayed_device(&trace.device) == Some(hand);
    if trace.device != hand && !replayed {
        return Ok(None);
    }
    let script = assets.script()?;
    let end = script.duration();
    Ok(Some(Target {
        position_m: script.sample(end).0,
        what: "the last waypoint".into(),
        path_end_s: Some(end),
    }))
}

/// What the study was made with, for `study.json`.
fn settings(run: &StudyRun<'_>) -> Value {
    let (assets, trace) = (run.assets, run.trace);
    let band = vps_voxmap::VoxelLookup::distance_band(&*assets.tree);
    json!({
        "scene": assets.label,
        "scene_name": assets.name,
        "voxel_size_m": assets.voxel_size,
        "force_model": if band.is_some() { "distance" } else { "tangent-plane" },
        "standoff_m": band.map(|b| b.standoff_m()),
        "shell_points": assets.shell.len(),
        "braking": run.params.braking,
        "device": trace.device,
        "frames": trace.frames.len(),
        "made_from": run.source,
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "clearance_series_every_frames": SERIES_EVERY_FRAMES,
        "cluster_stale_shares": run.stale_shares,
    })
}

/// A session to study: what it ran on and with, and its trace.
pub struct StudyRun<'a> {
    /// The scene the session ran on.
    pub assets: &'a SessionAssets,
    /// Its haptic parameters.
    pub params: HapticParams,
    /// Its handle trace.
    pub trace: &'a Trace,
    /// The part's state at its first frame.
    pub initial: PartState,
    /// "the session (device)" or "the trace FILE", for messages and study.json.
    pub source: &'a str,
    /// The swept volume's voxel size (m); `None`: the scene's.
    pub swept_voxel_size: Option<f64>,
    /// Shares the session's cluster stood in for with an earlier frame's sums
    /// (`--max-stale-frames`); the study computes every share, so with any its path may differ
    /// from the session's. 0 for a session on one host or a trace.
    pub stale_shares: u64,
}

/// Where a study's report goes.
#[derive(Clone, Copy, PartialEq)]
pub enum Print {
    /// Words on stdout.
    Text,
    /// Words on stderr (stdout carries a session's JSON report).
    TextToStderr,
    /// study.json's content on stdout.
    Json,
}

/// Makes the study of `run`, writes its files into `dir` (path table every `every` frames) and
/// prints its report as `print` says. Blocking, parallel.
pub fn write_study(run: &StudyRun<'_>, dir: &Path, every: usize, print: Print) -> Result<()> {
    let StudyRun {
        assets,
        trace,
        initial,
        source,
        ..
    } = *run;
    let classed = assets.classed_shell();
    let inputs = StudyInputs {
        map: &*assets.tree,
        shell: &classed,
        params: &run.params,
        limits: assets.bridge.limits,
        initial,
        trace,
        part_mesh: &assets.part_mesh,
        objects: &assets.static_meshes,
        object_names: &assets.static_names,
        target: target(assets, trace)?,
        clearance_every: SERIES_EVERY_FRAMES,
        reach_tolerance_m: assets.voxel_size,
        swept_voxel_size_m: Some(run.swept_voxel_size.unwrap_or(assets.voxel_size)),
    };
    let mut study = run_study(&inputs).with_context(|| format!("the study of {source}"))?;
    let settings = settings(run);
    let started = std::time::Instant::now();
    let view = crate::study_view::report_view(assets, &study);
    study.timings.report_view_ms = started.elapsed().as_secs_f64() * 1e3;
    let written = vps_study::files::write_study(
        dir,
        &study,
        &assets.part_mesh,
        &settings,
        every,
        Some(&view),
    )
    .with_context(|| format!("writing the study into {}", dir.display()))?;
    if print == Print::Json {
        return print_json(&vps_study::files::study_json(&study, &settings, every));
    }
    let mut lines = text_report(&study);
    if run.stale_shares > 0 {
        lines.push(format!(
            "  caution: the session's cluster stood in for {} late shares with an earlier \
             frame's sums (--max-stale-frames); the study computed every share exactly, so its \
             path can differ from the session's",
            run.stale_shares
        ));
    }
    lines.push(format!(
        "study: {} files in {} (open report.html; study.json, path.csv, clearance.csv, \
         contacts.csv, part.obj, swept.stl, swept.vmap; docs/study.md)",
        written.len(),
        dir.display()
    ));
    for line in lines {
        match print {
            Print::TextToStderr => eprintln!("{line}"),
            _ => crate::output::outln!("{line}")?,
        }
    }
    Ok(())
}

/// The study in words: the verdict, each object's least clearance, the contact events.
fn text_report(study: &Study) -> Vec<String> {
    let mm = |m: f64| format!("{:.2} mm", m * 1e3);
    let mut lines = vec![format!("verdict: {}", study.verdict.line)];
    for (name, c) in study.object_names.iter().zip(&study.clearance.objects) {
        if let Some(m) = c.minimum {
            let [x, y, z] = m.closest.on_object_m.to_array().map(|v| format!("{v:.4}"));
            lines.push(format!(
                "  clearance to {name}: least {} at t = {:.3} s (frame {}), nearest point of \
                 {name} ({x}, {y}, {z}) m",
                mm(m.closest.distance_m),
                m.time_s,
                m.frame
            ));
        }
    }
    match &study.swept {
        Some(Ok(s)) => lines.push(format!(
            "  swept volume: {:.1} cm³ ({} voxels of {} mm), its surface swept.stl ({} triangles)",
            s.volume_m3 * 1e6,
            crate::output::grouped(s.voxels),
            s.spec.voxel_size * 1e3,
            crate::output::grouped(s.mesh.triangle_count() as u64)
        )),
        Some(Err(e)) => lines.push(format!("  swept volume: not made: {e}")),
        None => {}
    }
    let names = &study.object_names;
    match study.contacts.len() {
        0 => lines.push("  contact events: none (the scene never pushed on the part)".into()),
        n => {
            lines.push(format!(
                "  contact events: {n} (spans with the scene pushing on the part)"
            ));
            for c in study.contacts.iter().take(10) {
                let object = c
                    .object
                    .and_then(|o| names.get(o))
                    .map_or("?", String::as_str);
                lines.push(format!(
                    "    {:.3}–{:.3} s against {object}, peak {:.2} N",
                    c.start_s, c.end_s, c.peak_force_n
                ));
            }
            if n > 10 {
                lines.push(format!("    … {} more in contacts.csv", n - 10));
            }
        }
    }
    lines
}
