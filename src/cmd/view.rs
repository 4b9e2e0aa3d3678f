//! The live viewer on the command line: `--view ADDR` on `vps demo`, `vps run` and
//! `vps coordinator` ([`attach`]), and `vps view FILE.vmap` for an offline voxmap ([`run`]).

use crate::cli::ViewArgs;
use crate::session::SessionScene;
use anyhow::{Context, Result};
use std::net::SocketAddr;
use std::sync::Arc;
use vps_runtime::{state_feed, StateFeedSender};
use vps_view::{SceneLimits, ViewerHandle, ViewerScene, ViewerServer};
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

/// Starts a viewer of `scene` on `addr` when `--view` was given and prints its URL on stderr.
pub fn attach(addr: Option<SocketAddr>, scene: &SessionScene) -> Result<Option<LiveViewer>> {
    let Some(addr) = addr else {
        return Ok(None);
    };
    let drawn = ViewerScene::new(
        "aircraft bay + Utah teapot",
        scene.tree.clone(),
        Some(Arc::new(scene.shell.clone())),
        SceneLimits::default(),
    );
    let (feed, receiver) = state_feed();
    let server = ViewerServer::start(addr, drawn, Some(receiver))?;
    eprintln!("viewer: {}", server.url());
    Ok(Some(LiveViewer { server, feed }))
}

/// `vps view FILE.vmap [--shell FILE.vshell]`: serves the scene with no loop until interrupted.
pub fn run(args: &ViewArgs) -> Result<()> {
    let tree =
        load_voxmap(&args.voxmap).with_context(|| format!("reading {}", args.voxmap.display()))?;
    let shell = match &args.shell {
        Some(path) => Some(Arc::new(
            load_shell(path).with_context(|| format!("reading {}", path.display()))?,
        )),
        None => None,
    };
    let label = args.voxmap.file_name().map_or_else(
        || args.voxmap.display().to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let scene = ViewerScene::new(label, Arc::new(tree), shell, SceneLimits::default());
    let server = ViewerServer::start(args.addr, scene, None)
        .with_context(|| format!("serving {}", args.voxmap.display()))?;
    eprintln!("viewer: {} (Ctrl-C to stop)", server.url());
    loop {
        std::thread::park();
    }
}
