//! [`StudyTrack`]: an assembly study's path as the page scrubs it (`vps view --scene FILE --study
//! DIR`, and the 3D view inside a study's `report.html`): the part's grip pose, the force sent to
//! the device and the least clearance at a bounded number of the study's frames, the closest
//! approach and the verdict. Built by the caller from a study (the `vps-study` crate) or its files;
//! this crate does not read studies.

use serde::Serialize;

/// Most frames a [`StudyTrack`] keeps: enough to scrub a long session smoothly (a 60 s session at
/// 1 kHz is thinned to one frame in 12), small enough for a page (about 0.6 MB of JSON).
pub const MAX_STUDY_TRACK_FRAMES: usize = 5000;

/// A study's path at a subset of its frames (see [`track_frames`]); every per-frame vector has
/// the same length, times increase. Lengths in m, forces in N.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct StudyTrack {
    /// The study's verdict line ("reached the last waypoint …").
    pub verdict: String,
    /// The study's frame number of each kept frame.
    pub frame: Vec<u64>,
    /// Time of each kept frame (s from the session's start).
    pub time_s: Vec<f64>,
    /// The part's grip position (m, world frame).
    pub position_m: Vec<[f64; 3]>,
    /// The part's orientation, quaternion `[x, y, z, w]`.
    pub orientation_xyzw: Vec<[f64; 4]>,
    /// The force sent to the device (N, within its limits).
    pub device_force_n: Vec<[f64; 3]>,
    /// The least exact clearance to any static object (m) where the study's series measured it,
    /// `None` (JSON `null`) elsewhere.
    pub clearance_m: Vec<Option<f64>>,
    /// The closest approach over the whole path; `None` when there were no static meshes.
    pub closest: Option<ClosestApproach>,
}

/// Where the part's mesh came nearest a static object's mesh.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ClosestApproach {
    /// When (s).
    pub time_s: f64,
    /// The exact mesh-to-mesh distance (m); 0 when they touched or crossed.
    pub distance_m: f64,
    /// The static object's name.
    pub object: String,
    /// The part's nearest point then (m, world frame).
    pub on_part_m: [f64; 3],
    /// The object's nearest point (m, world frame).
    pub on_object_m: [f64; 3],
}

/// Which of a study's `frames` frames a track keeps: evenly spaced, at most
/// [`MAX_STUDY_TRACK_FRAMES`], always the first, the last and `also` (the closest approach's
/// frame, when given and in range), in increasing order. Allocates the result only.
pub fn track_frames(frames: usize, also: Option<usize>) -> Vec<usize> {
    if frames == 0 {
        return Vec::new();
    }
    // Room for the last frame and `also` beside the evenly spaced ones.
    let stride = frames.div_ceil(MAX_STUDY_TRACK_FRAMES - 2).max(1);
    let mut kept: Vec<usize> = (0..frames).step_by(stride).collect();
    kept.push(frames - 1);
    if let Some(k) = also.filter(|&k| k < frames) {
        kept.push(k);
    }
    kept.sort_unstable();
    kept.dedup();
    kept
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_track_keeps_the_ends_and_the_closest_frame_within_the_bound() {
        assert!(track_frames(0, Some(3)).is_empty());
        assert_eq!(track_frames(3, None), vec![0, 1, 2]);
        for frames in [1, 2, 4999, 5000, 5001, 60_001, 4_000_000] {
            let closest = frames * 2 / 3 + 1;
            let kept = track_frames(frames, Some(closest));
            assert!(
                kept.len() <= MAX_STUDY_TRACK_FRAMES,
                "{frames}: {}",
                kept.len()
            );
            assert_eq!(kept[0], 0);
            assert_eq!(*kept.last().unwrap(), frames - 1);
            assert!(kept.windows(2).all(|w| w[0] < w[1]));
            if closest < frames {
                assert!(kept.contains(&closest), "{frames}");
            }
        }
        // A long study is thinned to near the bound, not far below it.
        assert!(track_frames(60_001, None).len() > MAX_STUDY_TRACK_FRAMES / 2);
    }
}
