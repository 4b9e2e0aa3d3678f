//! One frame's sampling work as a list of jobs: a session of several moving parts samples every
//! part's shell in the static scene's voxmap and, for each pair that may touch, each part's shell
//! in the other's body voxmap. Each such sampling is a [`SampleJob`]: which shell, which voxmap,
//! at which pose. Jobs are independent and their sums exact, so any party (a local thread, a
//! cluster worker) may compute any class of any job and the merged sums are the same bits.
//!
//! Numbering, fixed for a session: shell `k` is moving part `k`'s point shell (0 the session's
//! first part); voxmap 0 is the static scene's ([`SCENE_MAP`]), voxmap `1 + k` is part `k`'s body
//! voxmap ([`body_map`]).

use crate::KernelPose;

/// Most jobs one frame may hold: every one of up to 8 parts in the scene and every ordered pair
/// of them (8 + 8·7 = 64), so a job set is a 64-bit mask.
pub const MAX_JOBS: usize = 64;

/// Most moving parts a job list can name (shells 0..8, body voxmaps 1..=8).
pub const MAX_JOB_PARTS: usize = 8;

/// The voxmap index of the static scene.
pub const SCENE_MAP: u8 = 0;

/// The voxmap index of part `part`'s body voxmap.
pub const fn body_map(part: u8) -> u8 {
    part + 1
}

/// What a job samples: shell `shell` (a part index) in voxmap `map` (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct JobTarget {
    /// The moving part whose point shell is sampled.
    pub shell: u8,
    /// The voxmap it is sampled in: [`SCENE_MAP`] or [`body_map`]`(part)`.
    pub map: u8,
}

impl JobTarget {
    /// The session's first part in the static scene: the job of a one-part session.
    pub const FIRST: JobTarget = JobTarget {
        shell: 0,
        map: SCENE_MAP,
    };
}

/// One sampling job of a frame: every class (or the classes a party is given) of shell
/// `target.shell` in voxmap `target.map` at `pose` (the shell's pose in that voxmap's frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleJob {
    /// What is sampled.
    pub target: JobTarget,
    /// The shell's pose and velocities in the voxmap's frame (f32, as the kernel uses them).
    pub pose: KernelPose,
}
