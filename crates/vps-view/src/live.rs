//! A viewer attached to a running session: the server plus the loop's end of its state feed.

use crate::{ViewError, ViewerContent, ViewerHandle, ViewerServer};
use std::net::SocketAddr;
use vps_runtime::{state_feed, StateFeedSender};

/// A viewer serving one session's state feed. Dropping it stops the server (see
/// [`ViewerHandle`]); keep it alive for the session.
#[derive(Debug)]
pub struct LiveViewer {
    server: ViewerHandle,
    feed: StateFeedSender,
}

impl LiveViewer {
    /// Starts a viewer of `scene` on `addr` (port 0 picks a free one) fed by a new state feed,
    /// whose sending end [`LiveViewer::feed`] hands to the loop. Errors as [`ViewerServer::start`].
    pub fn start(addr: SocketAddr, scene: ViewerContent) -> Result<LiveViewer, ViewError> {
        let (feed, receiver) = state_feed();
        let server = ViewerServer::start(addr, scene, Some(receiver))?;
        Ok(LiveViewer { server, feed })
    }

    /// The loop's end of the viewer's feed (pass it to the session; cloning is cheap).
    pub fn feed(&self) -> StateFeedSender {
        self.feed.clone()
    }

    /// The address the viewer listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.server.local_addr()
    }

    /// The page's URL.
    pub fn url(&self) -> String {
        self.server.url()
    }
}
