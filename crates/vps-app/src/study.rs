//! The assembly study of a session (the `vps-study` crate), made after it has ended and its
//! device has been written zero, never on the frame thread: for `--study DIR` on the session
//! commands and for `vps study`. Prints the verdict for a person.
//!
//! A session of several moving parts is studied part by part: every part's path is recomputed
//! together (the pairs too), then each part's study is written into `DIR/<part>/`
//! ([`vps_study::files::part_file_names`]).

use crate::output::print_json;
use anyhow::{bail, Context, Result};
use serde_json::{json, Value};
use std::path::Path;
use vps_device::trace::Trace;
use vps_device::trace::Trace as HandleTrace;
use vps_device::SimulatedHand;
use vps_haptic::{HapticParams, PartState};
use vps_runtime::LoopReport;
use vps_session::{PartView, SessionAssets};
use vps_study::pairs::pair_clearance;
use vps_study::path::{recompute_paths, PathPart};
use vps_study::report::{parts_index_html, PartEntry};
use vps_study::{run_study, study_path, EvidenceInputs, Study, StudyInputs, Target};

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
    let mut others = Vec::with_capacity(report.other_parts.len());
    for part in &report.other_parts {
        if let Some(why) = &part.trace_error {
            bail!(
                "--study: part '{}''s trace stopped early ({why}); no study written",
                part.name
            );
        }
        let trace = part.trace.as_ref().with_context(|| {
            format!(
                "--study: the loop returned no trace of part '{}'",
                part.name
            )
        })?;
        let start = trace.part_start.with_context(|| {
            format!(
                "--study: part '{}''s trace does not say where it started",
                part.name
            )
        })?;
        others.push(OtherPartRun {
            trace,
            initial: PartState::at_rest(start.position, start.orientation),
        });
    }
    let source = format!("the session ({})", report.device_name);
    let run = StudyRun {
        assets,
        params,
        trace,
        initial,
        source: &source,
        swept_voxel_size: None,
        stale_shares,
        others,
    };
    // With --json, stdout holds the session's report alone: the study's words go to stderr.
    let print = if json {
        Print::TextToStderr
    } else {
        Print::Text
    };
    write_study(&run, dir, every, print)
}

/// Where the hand was taking part `part` (0 the first): the end of its path in the scene when
/// its trace is the simulated hand's (or a replay of one), else `None` (the hand's last
/// position).
fn target(run: &StudyRun<'_>, part: usize, trace: &Trace) -> Result<Option<Target>> {
    let hand = SimulatedHand::NAME;
    let replayed = vps_device::trace::replayed_device(&trace.device) == Some(hand);
    if trace.device != hand && !replayed {
        return Ok(None);
    }
    let script = run.part(part)?.hand.script(&run.assets.tree)?;
    let end = script.duration();
    Ok(Some(Target {
        position_m: script.sample(end).0,
        what: "the last waypoint".into(),
        path_end_s: Some(end),
    }))
}

/// What the study of part `part` (0 the first) was made with, for `study.json`; `trace` is that
/// part's.
fn settings(run: &StudyRun<'_>, part: usize, trace: &Trace) -> Result<Value> {
    let assets = run.assets;
    let band = vps_voxmap::VoxelLookup::distance_band(&*assets.tree);
    let (shell_points, braking) = (run.part(part)?.shell.len(), run.params_of(part)?.braking);
    let mut settings = json!({
        "scene": assets.label,
        "scene_name": assets.name,
        "voxel_size_m": assets.voxel_size,
        "force_model": if band.is_some() { "distance" } else { "tangent-plane" },
        "standoff_m": band.map(|b| b.standoff_m()),
        "shell_points": shell_points,
        "braking": braking,
        "device": trace.device,
        "frames": trace.frames.len(),
        "made_from": run.source,
        "command": std::env::args().collect::<Vec<_>>().join(" "),
        "clearance_series_every_frames": SERIES_EVERY_FRAMES,
        "cluster_stale_shares": run.stale_shares,
    });
    if !run.others.is_empty() {
        settings["part"] = json!(run.part(part)?.name);
        settings["parts"] = json!(assets.part_names());
        settings["pair_margin_m"] = json!(assets.pair_margin);
    }
    Ok(settings)
}

/// One of the other moving parts of a session to study: its trace and its state at the first
/// frame.
pub struct OtherPartRun<'a> {
    /// Its handle trace, recorded with the first part's.
    pub trace: &'a HandleTrace,
    /// Its state at the first frame.
    pub initial: PartState,
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
    /// The other moving parts, in the scene's order (empty: a one-part session).
    pub others: Vec<OtherPartRun<'a>>,
}

impl<'a> StudyRun<'a> {
    /// Moving part `k` of the session's scene (0 the first).
    fn part(&self, k: usize) -> Result<PartView<'a>> {
        self.assets
            .part(k)
            .with_context(|| format!("{} has no moving part {k}", self.assets.label))
    }

    /// Part `k`'s haptic parameters in the session: the first part's are the run's own (a demo
    /// turns braking on, `--haptic` replaces them), the others' the scene's.
    fn params_of(&self, k: usize) -> Result<&HapticParams> {
        match k {
            0 => Ok(&self.params),
            k => Ok(self.part(k)?.params),
        }
    }
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
/// prints its report as `print` says; a session of several parts gets one study per part in
/// `dir/<part>/`. Blocking, parallel.
pub fn write_study(run: &StudyRun<'_>, dir: &Path, every: usize, print: Print) -> Result<()> {
    if !run.others.is_empty() {
        return write_parts_study(run, dir, every, print);
    }
    let classed = run.assets.classed_shell();
    let inputs = StudyInputs {
        map: &*run.assets.tree,
        shell: &classed,
        params: &run.params,
        limits: run.assets.bridge.limits,
        initial: run.initial,
        trace: run.trace,
        evidence: evidence(run, 0, run.trace)?,
    };
    let study = run_study(&inputs).with_context(|| format!("the study of {}", run.source))?;
    let written = write_part_study(run, 0, run.trace, study, dir, every)?;
    if print == Print::Json {
        return print_json(&written.json);
    }
    let mut lines = written.lines;
    lines.push(format!(
        "study: {} files in {} (open report.html; study.json, path.csv, clearance.csv, \
         contacts.csv, part.obj, swept.stl, swept.vmap; docs/study.md)",
        written.files,
        dir.display()
    ));
    print_lines(&lines, print)
}

/// The study of a session of several parts: every part's path recomputed together, then each
/// part's study in `dir/<part>/`.
fn write_parts_study(run: &StudyRun<'_>, dir: &Path, every: usize, print: Print) -> Result<()> {
    let assets = run.assets;
    if run.others.len() != assets.more_parts.len() {
        bail!(
            "the study of {}: {} traces for a scene of {} moving parts",
            run.source,
            run.others.len() + 1,
            assets.more_parts.len() + 1
        );
    }
    let names = assets.part_names();
    let folders = vps_study::files::part_file_names(&names);
    let traces: Vec<&Trace> = std::iter::once(run.trace)
        .chain(run.others.iter().map(|o| o.trace))
        .collect();
    vps_study::check_traces(&traces).with_context(|| format!("the study of {}", run.source))?;
    let first_body = assets
        .part_body
        .as_ref()
        .context("the scene's first part has no voxmap of its own")?;
    let shells: Vec<_> = std::iter::once(assets.classed_shell())
        .chain(assets.more_parts.iter().map(|p| p.shell.classed()))
        .collect();
    let mut parts = vec![PathPart {
        shell: &shells[0],
        params: &run.params,
        limits: assets.bridge.limits,
        initial: run.initial,
        trace: run.trace,
        body: &**first_body,
        radius: vps_session::parts::body_radius(&assets.part_mesh, assets.shell.points()),
    }];
    for ((p, other), shell) in assets.more_parts.iter().zip(&run.others).zip(&shells[1..]) {
        parts.push(PathPart {
            shell,
            params: &p.params,
            limits: p.bridge.limits,
            initial: other.initial,
            trace: other.trace,
            body: &*p.body,
            radius: p.radius,
        });
    }
    let started = std::time::Instant::now();
    let paths = recompute_paths(&*assets.tree, &parts, assets.pair_margin);
    let path_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut made = Vec::with_capacity(names.len());
    for (k, (path, final_state)) in paths.into_iter().enumerate() {
        let what = || format!("the study of part '{}' of {}", names[k], run.source);
        let mut study =
            study_path(&evidence(run, k, traces[k])?, path, final_state).with_context(what)?;
        study.timings.path_ms = path_ms;
        made.push(study);
    }
    // The exact clearance between each pair of moving parts along their paths.
    let mut pairs = Vec::new();
    for i in 0..made.len() {
        for j in i + 1..made.len() {
            let clearance = pair_clearance(
                (i, run.part(i)?.mesh, &made[i].path),
                (j, run.part(j)?.mesh, &made[j].path),
                SERIES_EVERY_FRAMES,
            )
            .with_context(|| {
                format!(
                    "the clearance between parts '{}' and '{}'",
                    names[i], names[j]
                )
            })?;
            pairs.push(clearance);
        }
    }
    let times: Vec<f64> = made[0].path.iter().map(|f| f.time_s).collect();
    let entries: Vec<PartEntry<'_>> = made
        .iter()
        .enumerate()
        .map(|(k, s)| PartEntry {
            name: &names[k],
            folder: &folders[k],
            verdict: &s.verdict.line,
        })
        .collect();
    let index = parts_index_html(&assets.name, &entries, &names, &pairs);
    vps_study::files::write_pairs(dir, &names, &pairs, &times, SERIES_EVERY_FRAMES, &index)
        .with_context(|| format!("writing the pairs' clearance into {}", dir.display()))?;
    let mut lines = Vec::new();
    let mut studies = Vec::with_capacity(names.len());
    for (k, study) in made.into_iter().enumerate() {
        let folder = dir.join(&folders[k]);
        let written = write_part_study(run, k, traces[k], study, &folder, every)?;
        lines.push(format!("part '{}' ({}):", names[k], folder.display()));
        lines.extend(written.lines.into_iter().map(|l| format!("  {l}")));
        studies.push(json!({"name": names[k], "folder": folders[k], "study": written.json}));
    }
    if print == Print::Json {
        return print_json(&json!({
            "parts": studies,
            "pairs": vps_study::files::pairs_json(&names, &pairs, SERIES_EVERY_FRAMES)["pairs"],
        }));
    }
    for p in &pairs {
        match &p.minimum {
            Some(m) if m.closest.distance_m == 0.0 => lines.push(format!(
                "between parts '{}' and '{}': their meshes touched or crossed at t = {:.3} s \
                 (frame {})",
                names[p.a], names[p.b], m.time_s, m.frame
            )),
            Some(m) => lines.push(format!(
                "between parts '{}' and '{}': least exact clearance {:.2} mm at t = {:.3} s \
                 (frame {})",
                names[p.a],
                names[p.b],
                m.closest.distance_m * 1e3,
                m.time_s,
                m.frame
            )),
            None => {}
        }
        if let Some(peak) = p
            .contacts
            .iter()
            .max_by(|x, y| x.peak_force_on_a_n.total_cmp(&y.peak_force_on_a_n))
        {
            let first = &p.contacts[0];
            lines.push(format!(
                "  in contact {} time(s), the first from t = {:.3} to {:.3} s; the hardest push on \
                 '{}' {:.2} N at t = {:.3} s (exact gap then {:.2} mm)",
                p.contacts.len(),
                first.start_s,
                first.end_s,
                names[p.a],
                peak.peak_force_on_a_n,
                peak.peak_s,
                peak.distance_at_peak_m * 1e3
            ));
        }
    }
    lines.push(format!(
        "study: {} parts in {} (open its report.html: every part's verdict, linked to its own \
         study, and the clearance between the parts; pairs.json, pair_clearance.csv; \
         docs/study.md); the other parts' force on each part is in its path.csv",
        names.len(),
        dir.display()
    ));
    print_lines(&lines, print)
}

/// What the study of part `part`'s path (0 the first; `trace` its trace) needs.
fn evidence<'a>(run: &StudyRun<'a>, part: usize, trace: &Trace) -> Result<EvidenceInputs<'a>> {
    let assets = run.assets;
    Ok(EvidenceInputs {
        part_mesh: run.part(part)?.mesh,
        objects: &assets.static_meshes,
        object_names: &assets.static_names,
        target: target(run, part, trace)?,
        clearance_every: SERIES_EVERY_FRAMES,
        reach_tolerance_m: assets.voxel_size,
        swept_voxel_size_m: Some(run.swept_voxel_size.unwrap_or(assets.voxel_size)),
    })
}

/// One part's study, written.
struct WrittenStudy {
    /// Its report in words.
    lines: Vec<String>,
    /// Its `study.json`.
    json: Value,
    /// Files written.
    files: usize,
}

/// Writes `study` (of part `part`, from `trace`) into `dir` with its report's 3D view. Blocking.
fn write_part_study(
    run: &StudyRun<'_>,
    part: usize,
    trace: &Trace,
    mut study: Study,
    dir: &Path,
    every: usize,
) -> Result<WrittenStudy> {
    let settings = settings(run, part, trace)?;
    let started = std::time::Instant::now();
    let view = crate::study_view::report_view(run.assets, run.part(part)?, &study);
    study.timings.report_view_ms = started.elapsed().as_secs_f64() * 1e3;
    let mesh = run.part(part)?.mesh;
    let written = vps_study::files::write_study(dir, &study, mesh, &settings, every, Some(&view))
        .with_context(|| format!("writing the study into {}", dir.display()))?;
    let mut lines = text_report(&study);
    if run.stale_shares > 0 {
        lines.push(format!(
            "  caution: the session's cluster stood in for {} late shares with an earlier \
             frame's sums (--max-stale-frames); the study computed every share exactly, so its \
             path can differ from the session's",
            run.stale_shares
        ));
    }
    Ok(WrittenStudy {
        lines,
        json: vps_study::files::study_json(&study, &settings, every),
        files: written.len(),
    })
}

/// Prints `lines` as `print` says (never [`Print::Json`]).
fn print_lines(lines: &[String], print: Print) -> Result<()> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scripted::{run_scripted, Scripted};
    use vps_session::{BuildOptions, CachePolicy, LoadedScene};

    /// The study of a session whose cluster stood in for late shares says how many: the count in
    /// `study.json`'s `settings.cluster_stale_shares` and a caution naming it on `report.html`;
    /// with none, 0 and no caution. (A real session's count reaches this through `finish`, from
    /// the cluster report's `stale_shares`: `tests/study.rs` checks that they agree.)
    #[test]
    fn a_study_says_how_many_shares_its_session_s_cluster_stood_in_for() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("scene.toml");
        std::fs::write(
            &scene,
            "[part]\nsource = \"builtin:box\"\nscale = 0.2\n[[static]]\nsource = \"builtin:box\"\n\
             translate = [0.0, 0.0, -0.1]\n[voxels]\nvoxel_size = \"5 mm\"\n\
             [hand]\nwaypoints = [[0.0, 0.0, 0.05], [0.0, 0.0, 0.02]]\n",
        )
        .unwrap();
        let options = BuildOptions {
            cache: CachePolicy::Off,
            progress: false,
            ..BuildOptions::default()
        };
        let assets = LoadedScene::load(&scene.display().to_string())
            .unwrap()
            .build(&options)
            .unwrap();
        let how = Scripted {
            paced: false,
            record_trace: true,
        };
        let report = run_scripted(&assets, assets.params, 0.2, 1, how, None, None).unwrap();
        for stood_in in [7u64, 0] {
            let out = dir.path().join(format!("study-{stood_in}"));
            write_session_study(&out, 10, &assets, assets.params, &report, stood_in, true).unwrap();
            let study: Value =
                serde_json::from_str(&std::fs::read_to_string(out.join("study.json")).unwrap())
                    .unwrap();
            assert_eq!(study["settings"]["cluster_stale_shares"], stood_in);
            let page = std::fs::read_to_string(out.join("report.html")).unwrap();
            let caution = "<p id=\"caution\">Caution: the session's cluster stood in for 7 late \
                           shares";
            assert_eq!(page.contains(caution), stood_in == 7, "{page}");
            assert_eq!(page.contains("id=\"caution\""), stood_in > 0);
        }
    }
}
