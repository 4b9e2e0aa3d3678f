//! QUIC application close codes of the cluster: why a connection ended, as the other side sees
//! it (`quinn::ConnectionError::ApplicationClosed`). A worker decides from them whether to wait
//! for the next coordinator (the coordinator went away) or to give up (it was refused for good).

use quinn::VarInt;

/// The coordinator's session ended normally (it is exiting).
pub const CLOSE_SESSION_DONE: u32 = 0;
/// The coordinator was stopped by a signal (SIGINT, SIGTERM, SIGHUP); workers may wait for the
/// next one.
pub const CLOSE_COORDINATOR_STOPPING: u32 = 1;
/// The join exchange failed (timeout, malformed message, protocol version).
pub const CLOSE_JOIN_FAILED: u32 = 2;
/// Another live connection already presents this worker's certificate. Sent by coordinators
/// before issue 36, which refused the newer connection; this one keeps the newest and closes the
/// older with [`CLOSE_REPLACED`]. Still a refusal when received.
pub const CLOSE_DUPLICATE_IDENTITY: u32 = 3;
/// The coordinator disconnected the worker for bad replies in a row
/// (`GatherConfig::disconnect_after`); it may join again.
pub const CLOSE_BAD_REPLIES: u32 = 4;
/// The close reason sent with [`CLOSE_DUPLICATE_IDENTITY`].
pub const DUPLICATE_IDENTITY_REASON: &str = "another worker with this certificate is connected";
/// A newer connection presenting this worker's certificate joined in its place (the coordinator
/// keeps one connection per pinned certificate, the newest, so that a worker restarted after a
/// crash replaces its dead connection at once). A refusal: the process replaced stops, rather
/// than taking turns with the other one.
pub const CLOSE_REPLACED: u32 = 5;
/// The close reason sent with [`CLOSE_REPLACED`].
pub const REPLACED_REASON: &str =
    "a newer connection with this worker's certificate joined in its \
                                   place (is a second worker running with the same certificate?)";
/// The worker is stopping (SIGINT, SIGTERM).
pub const CLOSE_WORKER_STOPPED: u32 = 0;

/// A close code as quinn takes it.
pub fn code(value: u32) -> VarInt {
    VarInt::from_u32(value)
}

/// True when a coordinator's close `code` refuses this worker for good (retrying cannot help
/// until an operator acts): a duplicate identity, a connection replaced by a newer one with the
/// same certificate, or a failed join.
pub fn is_refusal(code: u64) -> bool {
    [CLOSE_DUPLICATE_IDENTITY, CLOSE_JOIN_FAILED, CLOSE_REPLACED]
        .iter()
        .any(|c| u64::from(*c) == code)
}
