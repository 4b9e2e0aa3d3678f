//! `vps demo`: the main job on a scene, by default the built-in scene file `bay-teapot`: the
//! teapot's point shell threads the aircraft bay (voxelized at 5 mm) in the hands of a simulated
//! user, on the 1 kHz loop; then the same scripted session again with pre-contact braking off, for
//! the penetration ratio of both.

use crate::exit::{outcome, SessionExit};
use crate::finish::print_summary;
use crate::output::print_json;
use crate::request::SessionRequest;
use crate::scripted::{run_scripted, Scripted};
use anyhow::Result;
use serde::Serialize;
use vps_haptic::HapticParams;
use vps_runtime::StatsSummary;
use vps_session::{stop_on_signals, SessionAssets};

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
    /// Every moving part of the braking-on session, in a scene of several (absent for one).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    parts: Vec<crate::parts_report::PartSummary>,
    /// The pairs of that session, counted (absent for one part).
    #[serde(skip_serializing_if = "Option::is_none")]
    pairs: Option<vps_runtime::PairCounts>,
}

/// Runs the demo on the request's scene (`scene`, `voxel_size`, `seconds`, `threads`, `view`,
/// `study`, `study_every`, `json`; its device, outputs and overrides are not used: the simulated
/// hand runs the scene's script). Blocks for both sessions.
pub fn run(args: &SessionRequest) -> Result<()> {
    if let Some(dir) = &args.study {
        crate::session_files::reserve_study_dir(dir, &[])?;
    }
    let scene = SessionAssets::open(
        &args.scene.scene,
        &vps_session::BuildOptions {
            viewer: args.view.is_some(),
            ..args.scene.build_options(args.voxel_size)
        },
    )?;
    // Braking on for the first run whatever the scene says: the demo compares on with off.
    let params = HapticParams {
        braking: true,
        ..scene.params
    };
    let threads = args.threads.max(1);
    // Without --seconds, each session follows the scene's hand path to its end.
    let seconds = crate::prepare::session_seconds(
        args.seconds,
        &vps_session::DeviceChoice::Simulated,
        scene.hands_duration(&scene.script()?)?,
    );
    // One set of handlers for both sessions, installed before the scene is announced: a signal
    // from then on ends the demo (a session started after it stops at its first frame).
    let signals = stop_on_signals()?;
    if !args.json {
        println!(
            "scene: {} ({}), {} triangles, voxelized at {} m in {:.0} ms, tree {:.2} MiB \
             (+ {:.2} MiB lookup directory)",
            scene.name,
            vps_files::printable(&scene.label),
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
    let viewer = crate::scene_view::attach_viewer(args.view, &scene)?;
    let feed = || viewer.as_ref().map(|v| v.feed());
    let session = |params: HapticParams, how: Scripted| {
        let report = run_scripted(
            &scene,
            params,
            seconds,
            threads,
            how,
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
    let on = session(
        params,
        Scripted {
            paced: true,
            record_trace: args.study.is_some(),
        },
    )?;
    let off_params = HapticParams {
        braking: false,
        ..params
    };
    let off = session(off_params, Scripted::paced(false))?;
    if let Some(dir) = &args.study {
        crate::study::write_session_study(
            dir,
            args.study_every,
            &scene,
            params,
            &on,
            0,
            args.json,
        )?;
    }
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
            parts: crate::parts_report::part_summaries(&scene, &on),
            pairs: (!on.other_parts.is_empty()).then_some(on.pairs),
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
    if !on.other_parts.is_empty() {
        println!("the parts in the braking-on session:");
        crate::parts_report::print_parts(
            &crate::parts_report::part_summaries(&scene, &on),
            &on.pairs,
        );
    }
    for line in crate::finish::SESSION_LEGEND {
        println!("{line}");
    }
    Ok(())
}
