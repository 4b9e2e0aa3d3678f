//! The live viewer on the command line: `--view ADDR` on `vps demo`, `vps run` and
//! `vps coordinator` ([`attach`]), and `vps view FILE.vmap` or `vps view --scene FILE` offline
//! ([`run`]).

use crate::cli::ViewArgs;
use anyhow::{Context, Result};
use std::net::SocketAddr;
use std::sync::Arc;
use vps_runtime::{state_feed, StateFeedSender};
use vps_session::{CachePolicy, Session};
use vps_view::{SceneLimits, ViewerContent, ViewerHandle, ViewerServer};
use vps_voxmap::file::{load_shell, load_voxmap};

/// A viewer serving a session's state feed. Dropping it stops the server.
pub struct LiveViewer {
    server: ViewerHandle,
    feed: StateFeedSender,
}

impl LiveViewer {
    /// The loop's end of the viewer's feed (pass it to the session; cloning is cheap).
    pub fn feed(&self) -> StateFeedSender {
        self.feed.clone()
    }

    /// The address the viewer listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.server.local_addr()
    }
}

/// What the viewer draws of a session: its voxmap and shell, labelled with the scene's name.
fn viewer_scene(session: &Session) -> ViewerContent {
    ViewerContent::new(
        session.name.clone(),
        session.tree.clone(),
        Some(Arc::new(session.shell.clone())),
        SceneLimits::default(),
    )
    .with_meshes(
        session.static_meshes.clone(),
        Some(session.part_mesh.clone()),
    )
}

/// Starts a viewer of `session` on `addr` when `--view` was given and prints its URL on stderr.
pub fn attach(addr: Option<SocketAddr>, session: &Session) -> Result<Option<LiveViewer>> {
    let Some(addr) = addr else {
        return Ok(None);
    };
    let (feed, receiver) = state_feed();
    let server = ViewerServer::start(addr, viewer_scene(session), Some(receiver))?;
    eprintln!("viewer: {}", server.url());
    Ok(Some(LiveViewer { server, feed }))
}

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
                ..vps_session::BuildOptions::default()
            };
            (
                viewer_scene(&Session::open(scene, &options)?),
                scene.clone(),
            )
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
