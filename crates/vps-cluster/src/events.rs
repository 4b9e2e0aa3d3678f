//! What the coordinator's network tasks ([`crate::coordinator`]) and the frame thread
//! ([`crate::shares`]) hand each other: joins and departures and workers' datagrams stamped on
//! arrival (crossbeam channels to the frame thread), and frame requests to send (one bounded
//! queue per worker to its network task, so the frame thread never takes quinn's connection lock
//! nor allocates to send). Its own module so that neither side imports the other.

use crate::protocol::REQUEST_LEN;
use bytes::Bytes;
use std::time::Instant;

/// One frame request datagram for a worker, as the frame thread encoded it.
pub(crate) type Outgoing = [u8; REQUEST_LEN];

/// Requests a worker's queue holds: two frames of the most jobs a frame may have. A frame thread
/// that finds it full counts the request as not sent (its share is recomputed locally).
pub(crate) const OUTGOING_QUEUE: usize = 2 * vps_haptic::job::MAX_JOBS;

/// Connection-level events for the frame thread.
pub(crate) enum Control {
    /// A worker finished joining and can be given work; `scene_sent`: it was sent the voxmap or
    /// shell file; `outgoing`: its requests' queue to its network task.
    Joined {
        id: u32,
        conn: quinn::Connection,
        outgoing: tokio::sync::mpsc::Sender<Outgoing>,
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
