//! The vps real-time shell around the sans-IO haptic core: the 1 kHz frame thread, a local worker
//! pool, frame timing, best-effort real-time scheduling, statistics, watchdog and a state feed.
//!
//! Module map:
//! - [`haptic_loop`]: [`run_loop`] / [`spawn_loop`], [`LoopConfig`], [`LoopReport`].
//! - [`parts`]: several moving parts in one session ([`PartsSetup`]), their pairs.
//! - [`pool`]: [`ClassPool`], cyclic class shares on local threads, exact merge; its class
//!   cursor is module `cursor` (lock-free, with a loom model test).
//! - [`clock`]: [`FrameClock`], absolute deadlines, sleep-then-spin, missed-tick accounting.
//! - [`rt`]: [`request_realtime`] (SCHED_FIFO, core pinning), [`RtGrant`].
//! - [`stats`]: [`FrameStats`], [`StatsSummary`] (HDR histograms, penetration ratio).
//! - [`feed`]: [`state_feed`], a lock-free latest-value slot for viewers.
//! - [`stop`]: [`SignalStop`] (SIGINT, SIGTERM, SIGHUP set a session's stop flag), exit codes.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod clock;
mod cursor;
pub mod feed;
pub mod haptic_loop;
pub mod parts;
pub mod pool;
mod recording;
pub mod rt;
pub mod stats;
pub mod stop;

pub use clock::{schedule, FrameClock, Schedule, Tick};
pub use feed::{
    state_feed, FeedFrame, OtherPartFrame, PartPose, RecentMax, StateFeedReceiver, StateFeedSender,
    MAX_OTHER_PARTS,
};
pub use haptic_loop::{
    run_loop, spawn_loop, spawn_loop_with, LoopConfig, LoopHandle, LoopReport, SessionEnd,
    SessionSetup,
};
pub use parts::{MovingPart, PartBody, PartReport, PartsSetup};
pub use pool::{ClassPool, FrameSampler, PoolResult};
pub use rt::{pin_current_thread, request_realtime, KeepOffFrameCore, Placement, RtGrant};
pub use stats::{FrameRecord, FrameStats, Percentiles, StatsSummary};
pub use stop::{SignalStop, StopSignal};
pub use vps_haptic::pair::{BodyVoxmap, PairCounts};

/// Why a session could not start or finish.
#[derive(Debug, thiserror::Error)]
pub enum RuntimeError {
    /// A [`LoopConfig`] field is invalid.
    #[error("loop config `{field}`: {message}")]
    Config {
        /// The field.
        field: &'static str,
        /// What is wrong.
        message: String,
    },
    /// The haptic parameters are invalid.
    #[error(transparent)]
    Params(#[from] vps_haptic::ParamsError),
    /// A thread could not be spawned.
    #[error("cannot spawn a thread: {0}")]
    Spawn(std::io::Error),
    /// The frame thread panicked outside a frame's work (a bug: the frame path is written not
    /// to panic, and a panic within a frame is caught and ends the session as
    /// [`SessionEnd::Panicked`]).
    #[error("the frame thread panicked")]
    FramePanicked,
    /// A signal handler could not be installed.
    #[error("cannot install the {signal} handler: {message}")]
    Signal {
        /// The signal's name.
        signal: &'static str,
        /// The system's message.
        message: String,
    },
}
