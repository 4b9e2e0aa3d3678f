//! The live viewer of vps: a small HTTP + WebSocket server (axum on its own tokio runtime thread)
//! and a dependency-free WebGL page that shows the static scene, the part at its current pose, the
//! handle ghost, contact points coloured by depth, force and torque arrows and live strip charts.
//!
//! The frame loop is never touched: the viewer reads the loop's lock-free latest-value state feed
//! ([`vps_runtime::state_feed`]) from its own thread at [`STATE_RATE_HZ`], re-samples the point
//! shell at the published pose for the contact points (off the loop thread, bounded), and pushes
//! one JSON state message per tick to every WebSocket client. A slow client only ever misses
//! states: nothing queues up.
//!
//! Routes (see [`server`]): `/` the page, `/app.js` its script, `/scene` the viewer content's
//! metadata (JSON, [`content::SceneMeta`]: the static scene and the part),
//! `/scene/boxes` and `/scene/shell` (little-endian f32 xyz triples, m), `/scene/mesh`,
//! `/scene/part_mesh`, `/scene/swept_mesh` and `/scene/other_part_meshes` (little-endian f32
//! triangle corners, m), `/state` the latest state (JSON),
//! `/ws` the state stream (WebSocket, JSON text messages). Every request's `Host` and `Origin` are
//! checked ([`access`]), connections are capped and slow headers timed out ([`ServerLimits`]).
//!
//! What is drawn: the static scene's Surface voxels as boxes, decimated from the voxmap tree's
//! leaves and tiles with memory bounded by [`SceneLimits::max_boxes`] ([`content`]); with
//! [`ViewerContent::with_meshes`], the static meshes and the part's mesh shaded, decimated to
//! [`SceneLimits::max_static_triangles`] and [`SceneLimits::max_part_triangles`] ([`mesh`]), the
//! boxes then being an overlay the user turns on. With [`ViewerContent::with_study`], an assembly
//! study's path to scrub along, its closest approach and its swept volume ([`study`]). The same
//! page works with no server at all, its data inlined ([`standalone::standalone_page`]): the 3D
//! view of a study's `report.html`.
//!
//! Module map: [`content`] (what is drawn: decimated Surface voxels, the shell, meshes), [`mesh`]
//! (mesh decimation and encoding), [`study`] (a study's path as the page scrubs it),
//! [`standalone`] (the page with its data inlined, one file), [`contacts`] (contact points at a pose), [`live`] (a viewer
//! attached to a session's feed), [`state`] (the JSON
//! state message), [`sampler`] (the feed reader thread), [`server`] (routes, WebSocket, limits,
//! start and shutdown), [`access`] (Host and Origin checks), [`client`] (a minimal blocking
//! HTTP/WebSocket client for tests, benchmarks and tools), [`browser`] (headless Chromium over
//! DevTools, for browser tests).
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod access;
pub mod browser;
pub mod client;
pub mod contacts;
pub mod content;
pub mod live;
pub mod mesh;
pub mod sampler;
pub mod server;
pub mod standalone;
pub mod state;
pub mod study;

pub use contacts::{sample_contacts, ContactSample};
pub use content::{OtherPartMeta, SceneLimits, ViewerContent};
pub use live::LiveViewer;
pub use server::{ServerLimits, ViewerHandle, ViewerServer};
pub use state::{FrameView, OtherPartView, PoseView, ViewState, ViewStatus};
pub use study::{ClosestApproach, StudyTrack};

/// How often the viewer reads the feed and pushes a state to its clients (Hz).
pub const STATE_RATE_HZ: f64 = 30.0;

/// Why the viewer could not start.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// The listening socket could not be bound.
    #[error("viewer: cannot listen on {addr}: {source}")]
    Bind {
        /// The address asked for.
        addr: std::net::SocketAddr,
        /// The OS error.
        source: std::io::Error,
    },
    /// The tokio runtime or a viewer thread could not be started.
    #[error("viewer: cannot start {what}: {source}")]
    Start {
        /// What failed to start.
        what: &'static str,
        /// The OS error.
        source: std::io::Error,
    },
}
