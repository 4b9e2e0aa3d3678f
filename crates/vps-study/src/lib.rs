//! Evidence for an assembly study: given a session's handle trace and its scene, the part's path
//! (recomputed frame by frame with the 1 kHz loop's own core), the exact clearance between the
//! part's mesh and each static object's mesh over the path, the contact events, and a verdict
//! ("reached the last waypoint" / "held back at …, N mm short, by OBJECT"; "minimum clearance
//! X mm at t = … s near OBJECT"), and the swept volume (voxels and a closed mesh), written as
//! CSV, JSON, STL and voxmap files a colleague can open.
//!
//! Everything here runs after a session, never on its frame thread: a study is a pure function of
//! the trace, the voxmap, the shell, the parameters and the meshes, so it can be regenerated or
//! compared after a change.
//!
//! A session of several moving parts is studied part by part: [`recompute_paths`](path::recompute_paths)
//! runs every part's path again together (the pairs too), then [`study_path`] makes each part's
//! study of its own path against the static objects, and [`pairs::pair_clearance`] measures the
//! exact clearance between each pair of moving parts along their paths.
//!
//! Module map: [`path`] (the part's path from a trace), [`pairs`] (clearance between two moving
//! parts), [`clearance`] (exact clearance series and
//! minimum), [`contacts`] (contact events), [`swept`] (the swept volume as voxels and a closed
//! mesh), [`verdict`](mod@verdict) (the verdict line), [`report`] (the one-page HTML report),
//! [`files`] (the study's files).
//!
//! Units: metres, seconds, newtons, newton-metres; CSV columns name theirs.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod clearance;
pub mod contacts;
pub mod files;
pub mod pairs;
pub mod path;
pub mod report;
pub mod swept;
pub mod verdict;

pub use clearance::{ClearanceTrack, MinimumClearance, ObjectClearance};
pub use contacts::ContactEvent;
pub use path::{PathFrame, PathPart};
pub use verdict::{Target, Verdict};

use std::time::Instant;
use vps_device::trace::Trace;
use vps_device::DeviceLimits;
use vps_haptic::{ClassedShell, HapticParams, PartState};
use vps_mesh::TriMesh;
use vps_reference::{ReferenceError, RigidClearance};
use vps_voxmap::VoxelLookup;

/// Most frames a study covers, over all its parts together: 66 min of one part at 1 kHz, about
/// 0.9 GiB of recomputed path ([`PathFrame`] is 232 bytes) besides the traces themselves.
pub const MAX_STUDY_FRAMES: usize = 4_000_000;

/// Why a study cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum StudyError {
    /// The trace is longer than a study covers.
    #[error(
        "the trace holds {frames} frames; a study covers at most {MAX_STUDY_FRAMES} (66 min at \
         1 kHz): study a shorter session"
    )]
    TooLong {
        /// Frames in the trace.
        frames: usize,
    },
    /// The trace has no frames.
    #[error("the trace has no frames: there is no path to study")]
    EmptyTrace,
    /// The traces of a session of several parts cover too many frames together.
    #[error(
        "the {parts} parts' traces hold {frames} frames each, {total} together; a study covers \
         at most {MAX_STUDY_FRAMES} (66 min of one part at 1 kHz): study a shorter session"
    )]
    TooLongTogether {
        /// Parts.
        parts: usize,
        /// Frames in each trace.
        frames: usize,
        /// Frames of all parts together.
        total: usize,
    },
    /// Two parts' traces of one session differ in length (they were not recorded together).
    #[error(
        "part {part}'s trace holds {frames} frames but the first part's {first}: the traces of \
         a session of several parts are recorded together, one frame each per frame"
    )]
    TracesDiffer {
        /// The part (0 the first).
        part: usize,
        /// Frames in its trace.
        frames: usize,
        /// Frames in the first part's trace.
        first: usize,
    },
    /// The part's or an object's mesh cannot be measured.
    #[error("the exact clearance cannot be measured: {0}")]
    Mesh(#[from] ReferenceError),
}

/// What a study is made from.
pub struct StudyInputs<'a, L: VoxelLookup> {
    /// The static scene's voxmap the session ran on.
    pub map: &'a L,
    /// The part's point shell, in classes.
    pub shell: &'a ClassedShell,
    /// The session's haptic parameters.
    pub params: &'a HapticParams,
    /// The device's limits (the wrench sent is saturated to them, as in the session).
    pub limits: DeviceLimits,
    /// The part's state at the first frame.
    pub initial: PartState,
    /// The handle trace of the session.
    pub trace: &'a Trace,
    /// What the study of the recomputed path needs.
    pub evidence: EvidenceInputs<'a>,
}

/// What the study of a part's path needs besides the path: the meshes to measure, the goal, and
/// the series and swept volume's settings.
pub struct EvidenceInputs<'a> {
    /// The part's mesh in its grip frame (m).
    pub part_mesh: &'a TriMesh,
    /// The static objects' meshes, placed (m).
    pub objects: &'a [TriMesh],
    /// The static objects' names, for the verdict and the files.
    pub object_names: &'a [String],
    /// Where the hand was taking the part; `None`: the hand's last position in the trace.
    pub target: Option<Target>,
    /// A clearance sample every this many frames (≥ 1) for the series; the minimum is over every
    /// frame whatever this is.
    pub clearance_every: usize,
    /// How near the goal the grip must end to have reached it (m).
    pub reach_tolerance_m: f64,
    /// The swept volume's voxel size (m); `None`: no swept volume.
    pub swept_voxel_size_m: Option<f64>,
}

/// Wall time of each stage of a study (ms).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StudyTimings {
    /// Recomputing the path.
    pub path_ms: f64,
    /// Preparing the meshes' trees.
    pub trees_ms: f64,
    /// The clearance series and minimum.
    pub clearance_ms: f64,
    /// Contact events.
    pub contacts_ms: f64,
    /// The swept volume.
    pub swept_ms: f64,
    /// The report's 3D view (made by the caller, which sets this; 0 without one).
    pub report_view_ms: f64,
}

/// A finished study.
#[derive(Clone, Debug)]
pub struct Study {
    /// One frame per trace frame.
    pub path: Vec<PathFrame>,
    /// The part's state after the last frame.
    pub final_state: PartState,
    /// Clearance to each object.
    pub clearance: ClearanceTrack,
    /// Contact events, in time order.
    pub contacts: Vec<ContactEvent>,
    /// The verdict.
    pub verdict: Verdict,
    /// The swept volume, when asked for: made, or why not.
    pub swept: Option<Result<swept::SweptVolume, swept::SweptError>>,
    /// The static objects' names.
    pub object_names: Vec<String>,
    /// Where the time went.
    pub timings: StudyTimings,
}

fn ms_since(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

/// Makes the study of `inputs`: its path recomputed from the trace, then [`study_path`].
/// Blocking, parallel (rayon), allocates.
pub fn run_study<L: VoxelLookup>(inputs: &StudyInputs<'_, L>) -> Result<Study, StudyError> {
    check_traces(&[inputs.trace])?;
    let t = Instant::now();
    let (path, final_state) = path::recompute_path(
        inputs.map,
        inputs.shell,
        inputs.params,
        &inputs.limits,
        inputs.initial,
        inputs.trace,
    );
    let path_ms = ms_since(t);
    let mut study = study_path(&inputs.evidence, path, final_state)?;
    study.timings.path_ms = path_ms;
    Ok(study)
}

/// Checks the traces of one session (one per part) before its paths are recomputed: none empty,
/// all as long as the first, and at most [`MAX_STUDY_FRAMES`] frames together. Arithmetic only.
pub fn check_traces(traces: &[&Trace]) -> Result<(), StudyError> {
    let first = traces.first().map_or(0, |t| t.frames.len());
    if first == 0 {
        return Err(StudyError::EmptyTrace);
    }
    if let Some((part, t)) = traces
        .iter()
        .enumerate()
        .find(|(_, t)| t.frames.len() != first)
    {
        return Err(StudyError::TracesDiffer {
            part,
            frames: t.frames.len(),
            first,
        });
    }
    if traces.len() == 1 && first > MAX_STUDY_FRAMES {
        return Err(StudyError::TooLong { frames: first });
    }
    let total = first.saturating_mul(traces.len());
    if total > MAX_STUDY_FRAMES {
        return Err(StudyError::TooLongTogether {
            parts: traces.len(),
            frames: first,
            total,
        });
    }
    Ok(())
}

/// The study of a part's recomputed `path` (one frame per trace frame, not empty) ending in
/// `final_state`: exact clearance to the static objects, contact events, verdict, swept volume.
/// `timings.path_ms` is left 0 for the caller. Blocking, parallel (rayon), allocates.
pub fn study_path(
    inputs: &EvidenceInputs<'_>,
    path: Vec<PathFrame>,
    final_state: PartState,
) -> Result<Study, StudyError> {
    let last_hand = path.last().ok_or(StudyError::EmptyTrace)?.handle_position_m;
    let mut timings = StudyTimings::default();
    let t = Instant::now();
    let measure = RigidClearance::new(inputs.part_mesh, inputs.objects)?;
    timings.trees_ms = ms_since(t);
    let t = Instant::now();
    let clearance = clearance::track(&measure, &path, inputs.clearance_every);
    timings.clearance_ms = ms_since(t);
    let t = Instant::now();
    let contacts = contacts::contact_events(&measure, &path);
    timings.contacts_ms = ms_since(t);
    let held_by = path
        .last()
        .filter(|f| f.contacts > 0)
        .and_then(|f| clearance::nearest_object(&measure, f))
        .map(|(object, _)| object);
    let target = inputs.target.clone().unwrap_or_else(|| Target {
        position_m: last_hand,
        what: "the hand's last position".into(),
        path_end_s: None,
    });
    let verdict = verdict::verdict(
        &path,
        final_state.position,
        target,
        inputs.reach_tolerance_m,
        &clearance,
        held_by,
        inputs.object_names,
    );
    let t = Instant::now();
    let swept = inputs
        .swept_voxel_size_m
        .map(|h| swept::swept_volume(inputs.part_mesh, &path, h, swept::SweptLimits::default()));
    timings.swept_ms = ms_since(t);
    Ok(Study {
        path,
        final_state,
        clearance,
        contacts,
        verdict,
        swept,
        object_names: inputs.object_names.to_vec(),
        timings,
    })
}
