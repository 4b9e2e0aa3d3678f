//! One frame of the gather as four events, in the order a driver meets them, so that a driver
//! makes one call per event instead of stepping [`GatherCore`] through its rules itself:
//!
//! 1. [`GatherCore::start_frame`]: the frame's jobs and reply window in, the [`Plan`] out (the
//!    coordinator's own classes, the probe class, and with [`GatherCore::requests`] what to send
//!    to whom); the driver reports each send with [`GatherCore::sent`].
//! 2. [`GatherCore::local_done`]: the coordinator's own share is computed (its time per class
//!    feeds the prediction and the fallback plan; the probe class's sums check probe replies).
//! 3. [`GatherCore::handle_datagram`] for each worker datagram before the deadline,
//!    [`GatherCore::handle_late_datagram`] after it: decoded and judged here; a
//!    [`Acceptance::Merged`] share's sums are [`GatherCore::merged_sums`].
//! 4. [`GatherCore::finish`]: at the deadline, the outcome per worker and the fallback for the
//!    missing shares ([`Outcome`]; stood-in sums are [`GatherCore::held_sums`]); then
//!    [`GatherCore::take_misbehaving`] names the workers to disconnect.
//!
//! Membership ([`GatherCore::join`], [`GatherCore::leave`]) changes between frames. Like the rest
//! of the core, nothing here reads a clock or does I/O: times come in as arguments.

use crate::gather::{Acceptance, Fallback, GatherCore, Transition};
use crate::protocol::{DecodeError, FrameReply};
use crate::ConfigError;
use std::time::{Duration, Instant};
use vps_haptic::job::JobTarget;
use vps_haptic::PartialSums;

/// What a frame samples and how long its replies are awaited.
#[derive(Clone, Copy, Debug)]
pub struct FrameStart<'a> {
    /// The frame's jobs ([`GatherCore::set_jobs`]: the first part in the scene first).
    pub jobs: &'a [JobTarget],
    /// From now (the requests) to the reply deadline: no frame waits longer for a worker.
    pub reply_window: Duration,
}

/// A frame's plan ([`GatherCore::start_frame`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Plan {
    /// The frame's sequence number (its requests carry it).
    pub seq: u64,
    /// The classes the coordinator computes itself, of every job.
    pub local: u64,
    /// Of those, the class an unawaited probe asks a worker for (0: none), to be computed on
    /// its own for [`GatherCore::local_done`].
    pub probe: u64,
}

/// One request of the frame: send worker `peer` the classes `classes` of the frame's first `jobs`
/// jobs, one datagram per job.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Request {
    /// The worker's join id.
    pub peer: u32,
    /// The classes asked for.
    pub classes: u64,
    /// How many of the frame's jobs (all of them for a work share, the first for a probe).
    pub jobs: usize,
}

/// What became of one worker datagram.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Handled {
    /// It did not decode; `known` when it came from a worker the core tracks (then it counts
    /// as a bad reply).
    Malformed {
        /// Why.
        error: DecodeError,
        /// From a tracked worker.
        known: bool,
    },
    /// It decoded and was judged.
    Judged(Acceptance),
}

/// A frame's outcome at its deadline ([`GatherCore::finish`]).
#[derive(Clone, Copy, Debug)]
pub struct Outcome<'a> {
    /// The workers whose standing changed (lost a share, sidelined, reinstated).
    pub transitions: &'a [(u32, Transition)],
    /// The missing shares: recomputed locally, or stood in for.
    pub fallback: &'a Fallback,
}

impl GatherCore {
    /// Event 1: a new frame of `start.jobs`; returns its plan. Errors (naming the jobs) when the
    /// jobs are not the assets' targets, before anything of the frame is decided. Allocates the
    /// split's masks (one small `Vec`).
    pub fn start_frame(&mut self, start: FrameStart<'_>) -> Result<Plan, ConfigError> {
        self.set_jobs(start.jobs)?;
        let seq = self.begin_frame();
        self.set_reply_window(start.reply_window);
        let local = self.assign();
        Ok(Plan {
            seq,
            local,
            probe: self.probe_classes(),
        })
    }

    /// This frame's requests, in join order (after [`GatherCore::start_frame`]). Does not
    /// allocate.
    pub fn frame_requests(&self) -> impl Iterator<Item = Request> + '_ {
        self.requests().map(|(peer, classes, _)| Request {
            peer,
            classes,
            jobs: self.jobs_asked(peer),
        })
    }

    /// Event 2: the coordinator's own share took `elapsed` for its `classes` classes of every job
    /// (its cost per class for the prediction and the fallback); `probe_sums` are its own sums of
    /// the plan's probe class of the first job (probe replies must equal them). Does not allocate.
    pub fn local_done(
        &mut self,
        classes: u32,
        elapsed: Duration,
        probe_sums: Option<&PartialSums>,
    ) -> Duration {
        if let Some(sums) = probe_sums {
            self.set_probe_result(sums);
        }
        if classes > 0 {
            self.set_local_cost(elapsed / classes);
        }
        self.local_cost()
    }

    /// Event 3: a datagram from worker `peer` that arrived at `at`, before the frame's deadline:
    /// decoded (strictly) and judged ([`GatherCore::accept`]). Does not allocate.
    pub fn handle_datagram(&mut self, peer: u32, bytes: &[u8], at: Instant) -> Handled {
        match FrameReply::decode(bytes) {
            Ok(reply) => Handled::Judged(self.accept(peer, &reply, at)),
            Err(error) => Handled::Malformed {
                error,
                known: self.malformed(peer),
            },
        }
    }

    /// Event 3, past the deadline: never merged; the answer to an outstanding unawaited probe is
    /// booked whenever it comes ([`Acceptance::Probed`]), anything else from a known worker is
    /// [`Acceptance::Late`] (not a bad reply, even undecodable: the share is settled already),
    /// from an unknown one [`Acceptance::Unknown`]. Does not allocate.
    pub fn handle_late_datagram(&mut self, peer: u32, bytes: &[u8], at: Instant) -> Acceptance {
        if let Ok(reply) = FrameReply::decode(bytes) {
            if self.answers_probe(peer, reply.seq) {
                return self.accept(peer, &reply, at);
            }
        }
        if self.late(peer) {
            Acceptance::Late
        } else {
            Acceptance::Unknown
        }
    }

    /// Event 4: the reply `deadline` has passed and `left` remains until the device write is
    /// due: books every worker's outcome ([`GatherCore::settle`]) and plans the fallback for the
    /// missing shares at the coordinator's latest cost per class
    /// ([`GatherCore::plan_fallback`]). Allocates the plan only when shares are missing.
    pub fn finish(&mut self, deadline: Instant, left: Duration) -> Outcome<'_> {
        self.settle(deadline);
        let per_class = self.local_cost();
        self.plan_fallback(left, per_class);
        Outcome {
            transitions: self.transitions(),
            fallback: self.fallback(),
        }
    }
}
