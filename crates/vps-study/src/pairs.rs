//! Exact clearance between two moving parts of one session: the distance between their meshes at
//! every `every`-th frame and the least over every frame, with where it was.
//!
//! Both parts move, so the pair is measured in part A's own frame, where A stands still: each
//! frame, B's pose relative to A (`R_a^T (x_b − x_a)`, `R_a^T R_b`) is a path of one rigid part
//! past one fixed object, and [`crate::clearance::track`] finds its series and its exact minimum
//! as it does for a static object (the motion bound holds for the relative motion). The nearest
//! points are then put back in the world with A's pose at that frame.

use crate::clearance::{track, MinimumClearance};
use crate::contacts::{contact_spans, peak_of};
use crate::path::PathFrame;
use crate::StudyError;
use glam::DVec3;
use vps_mesh::TriMesh;
use vps_reference::RigidClearance;

/// The clearance between moving parts `a` and `b` (indices into the session's parts, `a < b`)
/// along their paths.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PairClearance {
    /// The lower-numbered part.
    pub a: usize,
    /// The other part.
    pub b: usize,
    /// The least distance over every frame: its frame and time, the distance, `on_part_m` the
    /// nearest point of B and `on_object_m` that of A, in the world (m); `None` when a mesh has
    /// no triangles.
    pub minimum: Option<MinimumClearance>,
    /// The distance (m) at the series frames ([`PairClearance::series_frames`]).
    pub series_m: Vec<f64>,
    /// The frames of the series: every `every`-th and the last.
    pub series_frames: Vec<usize>,
    /// The spans during which the two parts were in contact, in time order.
    pub contacts: Vec<PairContactEvent>,
}

/// A span of frames during which two moving parts were in contact: either part's shell reached a
/// non-free voxel of the other's voxmap (the frame loop's pair contact;
/// [`PathFrame::in_contact_with`]).
/// Spans closer together than [`crate::contacts::MERGE_GAP_FRAMES`] frames are one event.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PairContactEvent {
    /// First frame in contact.
    pub start_frame: usize,
    /// Last frame in contact.
    pub end_frame: usize,
    /// Time of the first frame (s).
    pub start_s: f64,
    /// Time of the last frame (s).
    pub end_s: f64,
    /// The largest force the other moving parts put on A during the event (N): B's push on A
    /// when no third part touched A at the same time.
    pub peak_force_on_a_n: f64,
    /// The frame of the peak.
    pub peak_frame: usize,
    /// Time of the peak (s).
    pub peak_s: f64,
    /// The exact distance between the two meshes at the peak (m; 0 when they touch or cross).
    pub distance_at_peak_m: f64,
    /// A's point nearest B at the peak, in the world (m).
    pub on_a_m: DVec3,
    /// B's point nearest A at the peak, in the world (m).
    pub on_b_m: DVec3,
}

/// The clearance between part `a` (mesh `mesh_a` in its grip frame, path `path_a`) and part `b`
/// along their paths of one session (as long as each other), a series every `every` frames.
/// Errors when a mesh cannot be measured. Blocking, parallel, allocates.
pub fn pair_clearance(
    (a, mesh_a, path_a): (usize, &TriMesh, &[PathFrame]),
    (b, mesh_b, path_b): (usize, &TriMesh, &[PathFrame]),
    every: usize,
) -> Result<PairClearance, StudyError> {
    let relative: Vec<PathFrame> = path_a
        .iter()
        .zip(path_b)
        .map(|(fa, fb)| {
            let to_a = fa.part_orientation.normalize().inverse();
            PathFrame::at_pose(
                fa.frame,
                fa.time_s,
                to_a * (fb.part_position_m - fa.part_position_m),
                (to_a * fb.part_orientation.normalize()).normalize(),
            )
        })
        .collect();
    let measure = RigidClearance::new(mesh_b, std::slice::from_ref(mesh_a))?;
    let mut measured = track(&measure, &relative, every);
    let object = measured.objects.remove(0);
    // A's frame to the world at frame `i`.
    let to_world = |i: usize, p: DVec3| {
        let fa = &path_a[i];
        fa.part_orientation.normalize() * p + fa.part_position_m
    };
    let minimum = object.minimum.map(|mut m| {
        m.closest.on_part_m = to_world(m.frame, m.closest.on_part_m);
        m.closest.on_object_m = to_world(m.frame, m.closest.on_object_m);
        m
    });
    let contacts = contact_spans(path_a.iter().map(|f| f.in_contact_with(b)))
        .into_iter()
        .filter_map(|(start, end)| {
            let (peak_frame, peak_force_on_a_n) =
                peak_of(start, end, |i| path_a[i].other_parts_force_n.length());
            let r = &relative[peak_frame];
            let closest =
                measure.closest(0, r.part_position_m, r.part_orientation, f64::INFINITY)?;
            Some(PairContactEvent {
                start_frame: start,
                end_frame: end,
                start_s: path_a[start].time_s,
                end_s: path_a[end].time_s,
                peak_force_on_a_n,
                peak_frame,
                peak_s: path_a[peak_frame].time_s,
                distance_at_peak_m: closest.distance_m,
                on_a_m: to_world(peak_frame, closest.on_object_m),
                on_b_m: to_world(peak_frame, closest.on_part_m),
            })
        })
        .collect();
    Ok(PairClearance {
        a,
        b,
        minimum,
        series_m: object.series_m,
        series_frames: measured.series_frames,
        contacts,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;
    use vps_mesh::builtin::cuboid;

    /// The pair's contact events are the spans of frames A's path marks B in contact with
    /// (gaps of up to 20 frames merged), each with its peak of the other parts' force on A and
    /// the exact gap and nearest points (in the world) at that peak; frames that mark another
    /// part only are not B's.
    #[test]
    fn the_pair_s_contact_events_are_its_contact_spans() {
        let cube = cuboid(DVec3::splat(0.01));
        // A still at the origin; B 25 mm off in x (a 5 mm gap), then 21 mm (1 mm) from frame 100.
        let mut path_a: Vec<PathFrame> = (0..200)
            .map(|i| PathFrame::at_pose(i, i as f64 * 1e-3, DVec3::ZERO, DQuat::IDENTITY))
            .collect();
        let path_b: Vec<PathFrame> = (0..200)
            .map(|i| {
                let x = if i < 100 { 0.025 } else { 0.021 };
                PathFrame::at_pose(i, i as f64 * 1e-3, DVec3::new(x, 0.0, 0.0), DQuat::IDENTITY)
            })
            .collect();
        for i in (10..=30).chain(45..=50).chain(120..=130) {
            path_a[i].parts_in_contact = 0b10;
            path_a[i].other_parts_force_n = DVec3::new(-(i as f64), 0.0, 0.0);
        }
        // Part 2 touching A is not B's contact.
        path_a[160].parts_in_contact = 0b100;
        let c = pair_clearance((0, &cube, &path_a), (1, &cube, &path_b), 10).unwrap();
        let spans: Vec<_> = c
            .contacts
            .iter()
            .map(|e| (e.start_frame, e.end_frame))
            .collect();
        assert_eq!(spans, [(10, 50), (120, 130)]);
        let last = &c.contacts[1];
        assert_eq!((last.peak_frame, last.peak_force_on_a_n), (130, 130.0));
        assert_eq!((last.start_s, last.end_s), (0.12, 0.13));
        assert!((last.distance_at_peak_m - 0.001).abs() < 1e-12, "{last:?}");
        assert!((last.on_a_m.x - 0.01).abs() < 1e-12, "{last:?}");
        assert!((last.on_b_m.x - 0.011).abs() < 1e-12, "{last:?}");
        assert!((c.contacts[0].distance_at_peak_m - 0.005).abs() < 1e-12);
    }

    /// Two 20 mm cubes sliding past each other along x, 10 mm apart in y at their nearest, the
    /// first turning about z: the least clearance is the analytic gap, at the frame where the
    /// second passes the first, and its points are in the world.
    #[test]
    fn two_moving_cubes_come_as_close_as_their_faces() {
        let cube = cuboid(DVec3::splat(0.01));
        let frames = 201;
        let path = |f: &dyn Fn(f64) -> (DVec3, DQuat)| -> Vec<PathFrame> {
            (0..frames)
                .map(|i| {
                    let t = i as f64 * 1e-3;
                    let (p, q) = f(t);
                    PathFrame::at_pose(i as u64, t, p, q)
                })
                .collect()
        };
        // A moves along +x at 0.1 m/s without turning; B comes the other way 30 mm off in y.
        let path_a = path(&|t| (DVec3::new(-0.01 + 0.1 * t, 0.0, 0.0), DQuat::IDENTITY));
        let path_b = path(&|t| (DVec3::new(0.01 - 0.1 * t, 0.03, 0.0), DQuat::IDENTITY));
        let c = pair_clearance((0, &cube, &path_a), (1, &cube, &path_b), 10).unwrap();
        let m = c.minimum.unwrap();
        assert!((m.closest.distance_m - 0.01).abs() < 1e-12, "{m:?}");
        // Nearest where their x ranges overlap (from 0 to 0.2 s): the earliest such frame.
        assert_eq!(m.frame, 0, "{m:?}");
        // The points are on B's bottom face and A's top face, in the world.
        assert!((m.closest.on_part_m.y - 0.02).abs() < 1e-12, "{m:?}");
        assert!((m.closest.on_object_m.y - 0.01).abs() < 1e-12, "{m:?}");
        assert_eq!(c.series_frames.len(), 21);
        // B turned by A's rotation: A spins a quarter turn about z; B stays put 40 mm above
        // (in z, along the axis): the gap never changes.
        let spin = path(&|t| {
            (
                DVec3::ZERO,
                DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2 * t / 0.2),
            )
        });
        let above = path(&|_| (DVec3::new(0.0, 0.0, 0.04), DQuat::IDENTITY));
        let c = pair_clearance((0, &cube, &spin), (1, &cube, &above), 7).unwrap();
        assert!(
            c.series_m.iter().all(|d| (d - 0.02).abs() < 1e-12),
            "{:?}",
            c.series_m
        );
    }
}
