//! What the coordinator's network tasks ([`crate::coordinator`]) hand the frame thread
//! ([`crate::shares`]) over crossbeam channels: joins and departures, and workers' datagrams
//! stamped on arrival. Its own module so that neither side imports the other.

use bytes::Bytes;
use std::time::Instant;

/// Connection-level events for the frame thread.
pub(crate) enum Control {
    /// A worker finished joining and can be given work; `scene_sent`: it was sent the voxmap or shell file.
    Joined {
        id: u32,
        conn: quinn::Connection,
        scene_sent: bool,
    },
    /// A worker's connection ended.
    Closed { id: u32 },
}

/// One datagram from worker `id`, stamped on arrival.
pub(crate) struct Datagram {
    pub id: u32,
    pub bytes: Bytes,
    pub at: Instant,
}
