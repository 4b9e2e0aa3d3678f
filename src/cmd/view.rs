//! `vps view FILE.vmap` or `vps view --scene FILE [--study DIR]`: the viewer offline, with no loop. (`--view
//! ADDR` on the session commands attaches it to a session: `vps_app::scene_view::attach_viewer`.)

use crate::cli::ViewArgs;
use anyhow::{Context, Result};
use std::sync::Arc;
use vps_app::scene_view::viewer_content;
use vps_app::study_view::{track_from_folder, StudyFolder};
use vps_session::{CachePolicy, SessionAssets};
use vps_view::{SceneLimits, ViewerContent, ViewerServer};
use vps_voxmap::file::{load_shell, load_voxmap};

/// `vps view FILE.vmap [--shell FILE.vshell]` or `vps view --scene FILE`: serves the scene with
/// no loop until interrupted.
pub fn run(args: &ViewArgs) -> Result<()> {
    let (scene, what) = match (&args.scene, &args.voxmap) {
        (Some(scene), _) => {
            let options = vps_session::BuildOptions {
                cache: if args.no_cache {
                    CachePolicy::Off
                } else {
                    CachePolicy::from_env()
                },
                viewer: true,
                max_memory_bytes: args.max_memory,
                ..vps_session::BuildOptions::default()
            };
            let assets = SessionAssets::open(scene, &options)?;
            let mut content = viewer_content(&assets, SceneLimits::default());
            if let Some(dir) = &args.study {
                let StudyFolder {
                    track,
                    swept,
                    scene: studied,
                    part,
                } = track_from_folder(dir)?;
                // A study of one of several moving parts: that part on the slider, alone.
                if let Some(name) = part {
                    let part = (0..)
                        .map_while(|k| assets.part(k))
                        .find(|p| p.name == name)
                        .with_context(|| {
                            format!(
                                "the study in {} is of part '{name}', which {} does not have",
                                dir.display(),
                                assets.label
                            )
                        })?;
                    content =
                        vps_app::scene_view::part_content(&assets, part, SceneLimits::default());
                }
                if !studied.is_empty() && studied != assets.label {
                    eprintln!(
                        "vps: warning: the study in {} was made on {studied}, not on {} (the \
                         part's mesh drawn is this scene's)",
                        dir.display(),
                        assets.label
                    );
                }
                eprintln!(
                    "study: {} frames of {} to scrub; {}",
                    track.time_s.len(),
                    dir.display(),
                    track.verdict
                );
                content = content.with_study(track, swept.as_ref());
            }
            (content, scene.clone())
        }
        (None, Some(voxmap)) => {
            let tree =
                load_voxmap(voxmap).with_context(|| format!("reading {}", voxmap.display()))?;
            let shell = match &args.shell {
                Some(path) => Some(Arc::new(
                    load_shell(path).with_context(|| format!("reading {}", path.display()))?,
                )),
                None => None,
            };
            let label = voxmap.file_name().map_or_else(
                || voxmap.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            );
            let scene = ViewerContent::new(label, Arc::new(tree), shell, SceneLimits::default());
            (scene, voxmap.display().to_string())
        }
        (None, None) => anyhow::bail!("give a voxmap file or --scene FILE"),
    };
    let server =
        ViewerServer::start(args.addr, scene, None).with_context(|| format!("serving {what}"))?;
    eprintln!("viewer: {} (Ctrl-C to stop)", server.url());
    loop {
        std::thread::park();
    }
}
