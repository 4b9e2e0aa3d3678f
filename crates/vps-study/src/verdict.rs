//! The study's verdict: did the part get where the hand was taking it, and if not, what held it
//! back; how close it came to the structure, and where. One line for a person, and its figures.

use crate::clearance::{ClearanceTrack, MinimumClearance};
use crate::path::PathFrame;
use glam::DVec3;

/// Where the hand was taking the part.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Target {
    /// The grip's goal (m).
    pub position_m: DVec3,
    /// What the goal is, in words: "the last waypoint" (a simulated hand's path) or "the hand's
    /// last position" (any other device).
    pub what: String,
    /// When the hand's path ends (s, its last hold included), when the device follows a path.
    pub path_end_s: Option<f64>,
}

/// The verdict and its figures.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Verdict {
    /// The verdict in one line.
    pub line: String,
    /// The part's grip ended within `tolerance_m` of the target.
    pub reached: bool,
    /// The goal.
    pub target: Target,
    /// The grip's position after the last frame (m).
    pub final_position_m: DVec3,
    /// How far the grip ended from the goal (m).
    pub short_m: f64,
    /// How near counts as reached (m).
    pub tolerance_m: f64,
    /// The object pushing on the part at the end (its index), when the part ended in contact.
    pub held_by: Option<usize>,
    /// Another moving part pushed on the part in the last frame (its force on the part,
    /// `PathFrame::other_parts_force_n`, was not zero); always false with one moving part.
    pub held_by_other_parts: bool,
    /// The session's last frame time (s).
    pub session_end_s: f64,
    /// The session ran to the end of the hand's path (`None` when the device follows no path).
    pub path_completed: Option<bool>,
    /// The least clearance to any object over the path, and the object (index).
    pub minimum_clearance: Option<(usize, MinimumClearance)>,
}

/// Millimetres with one decimal.
fn mm(m: f64) -> String {
    format!("{:.1} mm", m * 1e3)
}

/// The verdict for `path` (non-empty), the grip ending at `final_position`. `names` are the static
/// objects' names; `held_by` the object nearest the part in the last frame when that frame is in
/// contact.
pub fn verdict(
    path: &[PathFrame],
    final_position: DVec3,
    target: Target,
    tolerance_m: f64,
    clearance: &ClearanceTrack,
    held_by: Option<usize>,
    names: &[String],
) -> Verdict {
    let name = |o: usize| names.get(o).map_or("?", String::as_str).to_string();
    let session_end_s = path.last().map_or(0.0, |f| f.time_s);
    let short_m = final_position.distance(target.position_m);
    let reached = short_m <= tolerance_m;
    let path_completed = target.path_end_s.map(|end| session_end_s >= end);
    let minimum_clearance = clearance
        .objects
        .iter()
        .enumerate()
        .filter_map(|(o, c)| Some((o, c.minimum?)))
        .min_by(|a, b| {
            a.1.closest
                .distance_m
                .total_cmp(&b.1.closest.distance_m)
                .then(a.1.frame.cmp(&b.1.frame))
        });
    let held_by_other_parts = path
        .last()
        .is_some_and(|f| f.other_parts_force_n != DVec3::ZERO);
    let [x, y, z] = final_position.to_array().map(|v| format!("{v:.4}"));
    let mut line = if reached {
        format!("reached {} (within {} of it)", target.what, mm(short_m))
    } else if let Some(o) = held_by {
        format!(
            "held back at ({x}, {y}, {z}) m, {} short of {}, by {}",
            mm(short_m),
            target.what,
            name(o)
        )
    } else if held_by_other_parts {
        format!(
            "held back at ({x}, {y}, {z}) m, {} short of {}, by another moving part",
            mm(short_m),
            target.what
        )
    } else {
        format!(
            "did not reach {}: {} short at the end, not in contact",
            target.what,
            mm(short_m)
        )
    };
    match (path_completed, target.path_end_s) {
        (Some(false), Some(end)) => line.push_str(&format!(
            " (the session ended at {session_end_s:.2} s, before the hand's path ended at \
             {end:.2} s)"
        )),
        (Some(true), Some(end)) if !reached => {
            line.push_str(&format!(" (the hand's path ended at {end:.2} s)"))
        }
        _ => {}
    }
    match &minimum_clearance {
        Some((o, m)) if m.closest.distance_m == 0.0 => line.push_str(&format!(
            "; the part's mesh touched or crossed {} at t = {:.3} s",
            name(*o),
            m.time_s
        )),
        Some((o, m)) => line.push_str(&format!(
            "; minimum clearance {} at t = {:.3} s near {}",
            mm(m.closest.distance_m),
            m.time_s,
            name(*o)
        )),
        None => {}
    }
    Verdict {
        line,
        reached,
        target,
        final_position_m: final_position,
        short_m,
        tolerance_m,
        held_by,
        held_by_other_parts,
        session_end_s,
        path_completed,
        minimum_clearance,
    }
}
