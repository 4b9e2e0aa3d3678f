//! Exact clearance along a path: for each static object, the distance between the part's mesh and
//! the object's mesh at every `every`-th frame (the series), and the least distance over *every*
//! frame with the frame it happens at (the minimum), found without measuring every frame.
//!
//! How the minimum is exact: the distance between two point sets changes by no more than the
//! farthest any point of the part moves. Between frames `i` and `j` no point of the part moves more
//! than `|x_j − x_i| + 2 sin(θ/2) r`, with θ the rotation between the two orientations and `r` the
//! part's radius about its grip. So a frame whose bound from its measured neighbours (the series
//! frames on either side) is not below the best distance found cannot hold the minimum; the others
//! are measured, nearest bound first, until none is left below the best. Ties go to the earliest
//! frame. Frames run in parallel on rayon's pool.

use crate::path::PathFrame;
use glam::DQuat;
use rayon::prelude::*;
use vps_reference::{Closest, RigidClearance};

/// Where the part came closest to one object over the whole path.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MinimumClearance {
    /// The frame (index into the path).
    pub frame: usize,
    /// Its time (s).
    pub time_s: f64,
    /// The two nearest points and their distance.
    pub closest: Closest,
}

/// One object's clearance along a path.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ObjectClearance {
    /// The least distance over every frame (`None` when the object has no triangles).
    pub minimum: Option<MinimumClearance>,
    /// The distance (m) at the series frames, in the order of [`ClearanceTrack::series_frames`].
    pub series_m: Vec<f64>,
    /// Frames measured exactly to find the minimum besides the series.
    pub searched_frames: usize,
}

/// Every object's clearance along a path.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ClearanceTrack {
    /// The frames of the series (indices into the path): every `every`-th and the last.
    pub series_frames: Vec<usize>,
    /// One per object, in the scene's order.
    pub objects: Vec<ObjectClearance>,
}

impl ClearanceTrack {
    /// The least clearance to any object (m) at the `k`-th series frame; `None` when no object
    /// has triangles.
    pub fn least_at(&self, k: usize) -> Option<f64> {
        self.objects
            .iter()
            .map(|o| o.series_m[k])
            .filter(|d| d.is_finite())
            .reduce(f64::min)
    }
}

/// The frames of a series of `len` frames, every `every`-th (at least 1) and the last.
pub fn series_frames(len: usize, every: usize) -> Vec<usize> {
    let mut frames: Vec<usize> = (0..len).step_by(every.max(1)).collect();
    if len > 0 && frames.last() != Some(&(len - 1)) {
        frames.push(len - 1);
    }
    frames
}

/// The farthest any point of a part of radius `radius` (m) moves between poses `a` and `b` (m).
pub fn motion_bound(a: &PathFrame, b: &PathFrame, radius: f64) -> f64 {
    let turn = rotation_angle(a.part_orientation, b.part_orientation);
    a.part_position_m.distance(b.part_position_m) + 2.0 * (turn * 0.5).sin() * radius
}

/// The angle (rad, in [0, π]) of the rotation from `a` to `b`.
fn rotation_angle(a: DQuat, b: DQuat) -> f64 {
    let w = a.dot(b).abs().min(1.0);
    2.0 * w.acos()
}

/// The clearance of the part along `path` to every object of `clearance`, with a series every
/// `every` frames. Blocking, parallel, allocates.
pub fn track(clearance: &RigidClearance, path: &[PathFrame], every: usize) -> ClearanceTrack {
    let series = series_frames(path.len(), every);
    let objects = (0..clearance.object_count())
        .map(|object| object_track(clearance, object, path, &series))
        .collect();
    ClearanceTrack {
        series_frames: series,
        objects,
    }
}

fn measure(clearance: &RigidClearance, object: usize, f: &PathFrame, max: f64) -> Option<Closest> {
    clearance.closest(object, f.part_position_m, f.part_orientation, max)
}

fn object_track(
    clearance: &RigidClearance,
    object: usize,
    path: &[PathFrame],
    series: &[usize],
) -> ObjectClearance {
    // Contiguous runs of the series in parallel; within a run each frame starts from the nearest
    // pair of the frame before (the same answer, found faster).
    let run = series
        .len()
        .div_ceil(4 * rayon::current_num_threads())
        .max(1);
    let measured: Vec<Option<Closest>> = series
        .par_chunks(run)
        .flat_map_iter(|frames| {
            let mut hint: Option<Closest> = None;
            frames
                .iter()
                .map(|&i| {
                    let f = &path[i];
                    let c = clearance.nearest_from(
                        object,
                        f.part_position_m,
                        f.part_orientation,
                        hint.as_ref(),
                    );
                    hint = c;
                    c
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let series_m: Vec<f64> = measured
        .iter()
        .map(|c| c.map_or(f64::INFINITY, |c| c.distance_m))
        .collect();
    let Some((mut best_frame, mut best)) = series
        .iter()
        .zip(&measured)
        .filter_map(|(&i, c)| Some((i, (*c)?)))
        .min_by(|a, b| {
            a.1.distance_m
                .total_cmp(&b.1.distance_m)
                .then(a.0.cmp(&b.0))
        })
    else {
        return ObjectClearance {
            minimum: None,
            series_m,
            searched_frames: 0,
        };
    };
    // Lower bounds of the frames between series frames, from the measured frame on each side.
    let radius = clearance.part_radius_m();
    let mut candidates: Vec<(f64, usize)> = Vec::new();
    for (k, pair) in series.windows(2).enumerate() {
        let (left, right) = (pair[0], pair[1]);
        for j in left + 1..right {
            let from_left = series_m[k] - motion_bound(&path[left], &path[j], radius);
            let from_right = series_m[k + 1] - motion_bound(&path[right], &path[j], radius);
            let bound = from_left.max(from_right);
            if bound <= best.distance_m {
                candidates.push((bound, j));
            }
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut searched = 0;
    for chunk in candidates.chunks(64) {
        if chunk[0].0 > best.distance_m {
            break;
        }
        let limit = best.distance_m;
        let found: Vec<(usize, Closest)> = chunk
            .par_iter()
            .filter(|(bound, _)| *bound <= limit)
            .filter_map(|&(_, j)| Some((j, measure(clearance, object, &path[j], limit)?)))
            .collect();
        searched += chunk.iter().filter(|(bound, _)| *bound <= limit).count();
        for (j, c) in found {
            let better = c.distance_m < best.distance_m
                || (c.distance_m == best.distance_m && j < best_frame);
            if better {
                best = c;
                best_frame = j;
            }
        }
    }
    ObjectClearance {
        minimum: Some(MinimumClearance {
            frame: best_frame,
            time_s: path[best_frame].time_s,
            closest: best,
        }),
        series_m,
        searched_frames: searched,
    }
}

/// The object nearest the part at frame `f` and where (`None` when no object has triangles).
pub fn nearest_object(clearance: &RigidClearance, f: &PathFrame) -> Option<(usize, Closest)> {
    (0..clearance.object_count())
        .filter_map(|o| Some((o, measure(clearance, o, f, f64::INFINITY)?)))
        .min_by(|a, b| a.1.distance_m.total_cmp(&b.1.distance_m))
}
