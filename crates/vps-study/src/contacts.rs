//! Contact events: the spans of a path during which the scene pushed on the part (at least one
//! shell point in the force layer), each with its object, peak force and where on the part.
//! Spans closer together than [`MERGE_GAP_FRAMES`] frames are one event (a part sliding along a
//! surface flickers in and out of the force layer).

use crate::clearance::nearest_object;
use crate::path::PathFrame;
use glam::DVec3;
use rayon::prelude::*;
use vps_reference::RigidClearance;

/// Gaps of at most this many frames without contact do not end an event (20 ms at 1 kHz).
pub const MERGE_GAP_FRAMES: usize = 20;

/// The spans `(first, last)` of frames in contact (`in_contact`, one flag a frame), gaps of at
/// most [`MERGE_GAP_FRAMES`] frames merged. Allocates the result.
pub fn contact_spans(in_contact: impl IntoIterator<Item = bool>) -> Vec<(usize, usize)> {
    let mut spans: Vec<(usize, usize)> = Vec::new();
    for (i, touching) in in_contact.into_iter().enumerate() {
        if !touching {
            continue;
        }
        match spans.last_mut() {
            Some((_, end)) if i - *end <= MERGE_GAP_FRAMES + 1 => *end = i,
            _ => spans.push((i, i)),
        }
    }
    spans
}

/// The frame of `start..=end` with the largest `force(frame)` (the first of equals) and that
/// force.
pub(crate) fn peak_of(start: usize, end: usize, force: impl Fn(usize) -> f64) -> (usize, f64) {
    (start..=end)
        .map(|i| (i, force(i)))
        .fold((start, f64::NEG_INFINITY), |best, x| {
            if x.1 > best.1 {
                x
            } else {
                best
            }
        })
}

/// One contact event.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ContactEvent {
    /// First frame in contact.
    pub start_frame: usize,
    /// Last frame in contact.
    pub end_frame: usize,
    /// Time of the first frame (s).
    pub start_s: f64,
    /// Time of the last frame (s).
    pub end_s: f64,
    /// The largest contact force on the part during the event (N).
    pub peak_force_n: f64,
    /// The frame of the peak.
    pub peak_frame: usize,
    /// The object nearest the part at the peak (index into the scene's static objects; `None`
    /// when no object has triangles).
    pub object: Option<usize>,
    /// The exact distance to that object at the peak (m).
    pub distance_at_peak_m: Option<f64>,
    /// Where on the part, in the part's frame (m from the grip): its point nearest the object at
    /// the peak.
    pub on_part_local_m: Option<DVec3>,
    /// The same point in the world at the peak (m).
    pub on_part_m: Option<DVec3>,
}

/// The contact events of `path`, their objects found with `clearance`. Blocking, parallel over
/// events, allocates.
pub fn contact_events(clearance: &RigidClearance, path: &[PathFrame]) -> Vec<ContactEvent> {
    contact_spans(path.iter().map(|f| f.contacts > 0))
        .par_iter()
        .map(|&(start, end)| {
            let (peak_frame, peak_force_n) =
                peak_of(start, end, |i| path[i].contact_force_n.length());
            let nearest = nearest_object(clearance, &path[peak_frame]);
            ContactEvent {
                start_frame: start,
                end_frame: end,
                start_s: path[start].time_s,
                end_s: path[end].time_s,
                peak_force_n,
                peak_frame,
                object: nearest.map(|n| n.0),
                distance_at_peak_m: nearest.map(|n| n.1.distance_m),
                on_part_local_m: nearest.map(|n| n.1.on_part_local_m),
                on_part_m: nearest.map(|n| n.1.on_part_m),
            }
        })
        .collect()
}
