//! The state message the page receives (`/ws` text messages and `/state`), as JSON.

use crate::contacts::ContactSample;
use glam::{DQuat, DVec3};
use serde::Serialize;
use vps_runtime::FeedFrame;

/// Where the feed stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ViewStatus {
    /// No loop: the viewer shows a scene only (`vps view`).
    Offline,
    /// A loop is attached but has not published yet.
    Waiting,
    /// Frames are arriving.
    Live,
    /// No new frame for [`STALE_AFTER_S`] (the session ended or stalled): the last one is shown.
    Stale,
}

/// Seconds without a new frame after which the feed is [`ViewStatus::Stale`].
pub const STALE_AFTER_S: f64 = 1.0;

/// One state message: the status and, once a frame was published, that frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ViewState {
    /// Where the feed stands.
    pub status: ViewStatus,
    /// The newest frame; `None` before the first.
    pub frame: Option<FrameView>,
}

/// A pose as the page reads it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct PoseView {
    /// Position (m).
    pub position_m: [f64; 3],
    /// Orientation, body → world, as `[x, y, z, w]`.
    pub orientation_xyzw: [f64; 4],
}

impl PoseView {
    fn new(position: DVec3, orientation: DQuat) -> Self {
        Self {
            position_m: position.to_array(),
            orientation_xyzw: orientation.to_array(),
        }
    }
}

/// One frame of the loop as the page draws it. Times in µs for the charts.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FrameView {
    /// Frame index.
    pub frame: u64,
    /// Scheduled time since the session started (s).
    pub time_s: f64,
    /// The part's pose (its centre of mass).
    pub part: PoseView,
    /// The handle's pose (the ghost).
    pub handle: PoseView,
    /// Force sent to the device (N).
    pub force_n: [f64; 3],
    /// Torque sent to the device (N·m).
    pub torque_nm: [f64; 3],
    /// Contact count the loop computed this frame.
    pub contacts: u32,
    /// ≥ 1 point in Surface or Interior.
    pub touching: bool,
    /// ≥ 1 point in Interior.
    pub penetrating: bool,
    /// Missed deadlines so far.
    pub missed_deadlines: u64,
    /// Watchdog trips so far.
    pub watchdog_trips: u64,
    /// This frame's compute time (µs).
    pub compute_us: f64,
    /// Largest compute time over the last 32 to 64 frames (µs).
    pub recent_max_compute_us: f64,
    /// This frame's lateness (µs).
    pub period_error_us: f64,
    /// Largest lateness over the last 32 to 64 frames (µs).
    pub recent_max_period_error_us: f64,
    /// Contact points found by the viewer's re-sampling: `[x, y, z, depth]` (m), deepest kept.
    pub contact_points: Vec<[f32; 4]>,
    /// Shell points in Interior voxels: `[x, y, z]` (m).
    pub interior_points: Vec<[f32; 3]>,
    /// The other moving parts, in the order of the scene's `other_parts` (empty for one part).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub others: Vec<OtherPartView>,
}

/// Another moving part in a frame: its pose (`position_m`, `orientation_xyzw` at the top level,
/// as [`FrameView::part`]), its handle (the ghost) and what its own device was sent.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct OtherPartView {
    /// The part's pose (its grip frame).
    #[serde(flatten)]
    pub part: PoseView,
    /// Its handle's pose (its ghost).
    pub handle: PoseView,
    /// Force sent to its device (N).
    pub force_n: [f64; 3],
    /// Torque sent to its device (N·m).
    pub torque_nm: [f64; 3],
}

impl FrameView {
    /// The view of `frame` with the viewer's `contacts` (from [`crate::sample_contacts`]).
    pub fn new(frame: &FeedFrame, contacts: &[ContactSample]) -> Self {
        let us = |ns: u64| ns as f64 * 1e-3;
        let (interior, surface): (Vec<&ContactSample>, Vec<&ContactSample>) =
            contacts.iter().partition(|c| c.interior);
        Self {
            frame: frame.frame,
            time_s: frame.time,
            part: PoseView::new(frame.part.position, frame.part.orientation),
            handle: PoseView::new(frame.handle.position, frame.handle.orientation),
            force_n: frame.device_wrench.force.to_array(),
            torque_nm: frame.device_wrench.torque.to_array(),
            contacts: frame.contacts,
            touching: frame.touching,
            penetrating: frame.penetrating,
            missed_deadlines: frame.missed_deadlines,
            watchdog_trips: frame.watchdog_trips,
            compute_us: us(frame.compute_ns),
            recent_max_compute_us: us(frame.recent_max_compute_ns),
            period_error_us: us(frame.period_error_ns),
            recent_max_period_error_us: us(frame.recent_max_period_error_ns),
            contact_points: surface
                .iter()
                .map(|c| [c.position.x, c.position.y, c.position.z, c.depth])
                .collect(),
            interior_points: interior.iter().map(|c| c.position.to_array()).collect(),
            others: frame
                .others()
                .iter()
                .map(|o| OtherPartView {
                    part: PoseView::new(o.part.position, o.part.orientation),
                    handle: PoseView::new(o.handle.position, o.handle.orientation),
                    force_n: o.device_wrench.force.to_array(),
                    torque_nm: o.device_wrench.torque.to_array(),
                })
                .collect(),
        }
    }
}

impl ViewState {
    /// The JSON text of the message. Serialising these plain structs cannot fail (serde_json
    /// writes non-finite numbers as `null`); should it ever, the text is `{}`.
    pub fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_else(|_| "{}".into())
    }
}
