//! What the viewer draws of a session's scene ([`viewer_content`]): for the live viewer of a
//! session ([`attach_viewer`]), `vps view --scene` and a study's 3D view
//! (`crate::study_view`).

use anyhow::Result;
use glam::DVec3;
use std::net::SocketAddr;
use std::sync::Arc;
use vps_session::{PartView, SessionAssets};
use vps_view::{LiveViewer, SceneLimits, ViewerContent};

/// What the viewer draws of a session, within `limits`: its voxmap, shell and meshes, labelled
/// with the scene's name, its other moving parts at their start poses, and the simulated hand's
/// path with the part's start pose (when the scene's script can be made).
pub fn viewer_content(assets: &SessionAssets, limits: SceneLimits) -> ViewerContent {
    let content = part_content(assets, assets.first_part(), limits).with_other_parts(
        assets
            .more_parts
            .iter()
            .map(|p| {
                let start = p
                    .hand
                    .script(&assets.tree)
                    .map_or((DVec3::ZERO, glam::DQuat::IDENTITY), |s| s.sample(0.0));
                (p.name.clone(), p.mesh.clone(), start)
            })
            .collect(),
    );
    content
}

/// What a study's 3D view draws of moving part `p` of `assets`: the static scene's voxmap and
/// meshes, that part's mesh and shell, and its simulated hand's path with its start pose (when
/// its script can be made). The other moving parts are not drawn: the study is of this part's
/// path against the static objects.
pub fn part_content(assets: &SessionAssets, p: PartView<'_>, limits: SceneLimits) -> ViewerContent {
    let content = ViewerContent::new(
        assets.name.clone(),
        assets.tree.clone(),
        Some(Arc::new(p.shell.clone())),
        limits,
    )
    .with_meshes(assets.static_meshes.clone(), Some(p.mesh.clone()));
    match p.hand.script(&assets.tree) {
        Ok(script) => {
            // Every 10 ms of the path (the viewer thins it further when long).
            let steps = (script.duration() / 0.01).ceil().clamp(1.0, 1e6) as usize;
            let path: Vec<DVec3> = (0..=steps)
                .map(|k| script.sample(script.duration() * k as f64 / steps as f64).0)
                .collect();
            content.with_hand(&path, script.sample(0.0))
        }
        Err(_) => content,
    }
}
/// Starts a viewer of `assets` on `addr` when `--view` was given and prints its URL on stderr.
pub fn attach_viewer(
    addr: Option<SocketAddr>,
    assets: &SessionAssets,
) -> Result<Option<LiveViewer>> {
    let Some(addr) = addr else {
        return Ok(None);
    };
    let viewer = LiveViewer::start(addr, viewer_content(assets, SceneLimits::default()))?;
    eprintln!("viewer: {}", viewer.url());
    Ok(Some(viewer))
}
