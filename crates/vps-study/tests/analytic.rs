//! The study's clearance against answers worked out without its search: a faceted sphere moved
//! along a straight line (spinning as it goes) past a plane and past a box. The exact per-frame
//! mesh distance comes from a brute force over every pair of triangles (no tree, no motion
//! bound) and, for the plane, from the lowest vertex's height; the study's minimum must equal the
//! least of them to 1e-12 m (the issue asks 1e-6 m) at the same frame, after measuring fewer
//! frames than the path has.

use glam::{DQuat, DVec3};
use vps_mesh::builtin::{cuboid_between, uv_sphere};
use vps_mesh::triangle_distance::triangle_distance;
use vps_mesh::TriMesh;
use vps_reference::RigidClearance;
use vps_study::clearance::track;
use vps_study::{ClearanceTrack, PathFrame};

/// `frames` poses from `from` to `to` along a straight line, turning `turns` times about `axis`.
fn line_path(from: DVec3, to: DVec3, axis: DVec3, turns: f64, frames: usize) -> Vec<PathFrame> {
    (0..frames)
        .map(|i| {
            let s = i as f64 / (frames - 1) as f64;
            let orientation =
                DQuat::from_axis_angle(axis.normalize(), s * turns * std::f64::consts::TAU);
            PathFrame::at_pose(i as u64, i as f64 * 1e-3, from.lerp(to, s), orientation)
        })
        .collect()
}

/// The exact distance between `part` at `f`'s pose and `object`: every pair of triangles.
fn brute_force(part: &TriMesh, object: &TriMesh, f: &PathFrame) -> f64 {
    let moved = part.transformed(1.0, f.part_orientation, f.part_position_m);
    let mut best = f64::INFINITY;
    for a in 0..moved.triangle_count() {
        let ta = moved.triangle(a);
        for b in 0..object.triangle_count() {
            best = best.min(triangle_distance(&ta, &object.triangle(b)).distance);
        }
    }
    best
}

/// The first frame of the least value and the value.
fn least(values: &[f64]) -> (usize, f64) {
    values
        .iter()
        .copied()
        .enumerate()
        .fold(
            (0, f64::INFINITY),
            |best, (i, v)| if v < best.1 { (i, v) } else { best },
        )
}

/// Tracks the one object of `clearance` along `path` (a series every 10 frames) and checks its
/// minimum against `brute` (the exact distance at every frame): the same value to 1e-12 m at the
/// same frame, found after measuring fewer frames than the path has.
fn track_and_check(
    clearance: &RigidClearance,
    path: &[PathFrame],
    brute: &[f64],
) -> ClearanceTrack {
    let (frame, exact) = least(brute);
    let tracked = track(clearance, path, 10);
    let minimum = tracked.objects[0].minimum.unwrap();
    assert!(
        (minimum.closest.distance_m - exact).abs() < 1e-12,
        "{minimum:?} vs {exact} at {frame}"
    );
    assert_eq!(minimum.frame, frame);
    assert!(tracked.objects[0].searched_frames < path.len());
    tracked
}

#[test]
fn a_sphere_along_a_line_past_a_plane_finds_the_exact_minimum_at_its_frame() {
    let sphere = uv_sphere(0.02, 12, 6);
    let floor = cuboid_between(DVec3::new(-1.0, -1.0, -0.1), DVec3::new(1.0, 1.0, 0.0));
    let clearance = RigidClearance::new(&sphere, std::slice::from_ref(&floor)).unwrap();
    // Descending towards the floor while spinning: the lowest vertex changes along the way.
    let path = line_path(
        DVec3::new(-0.2, 0.0, 0.08),
        DVec3::new(0.2, 0.05, 0.0221),
        DVec3::new(1.0, 0.3, 0.2),
        1.7,
        601,
    );
    let lowest: Vec<f64> = path
        .iter()
        .map(|f| {
            sphere
                .vertices
                .iter()
                .map(|&v| (f.part_orientation * v + f.part_position_m).z)
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let brute: Vec<f64> = path
        .iter()
        .map(|f| brute_force(&sphere, &floor, f))
        .collect();
    for (a, b) in lowest.iter().zip(&brute) {
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
    let tracked = track_and_check(&clearance, &path, &brute);
    // The series is the exact distance at its frames.
    for (k, &i) in tracked.series_frames.iter().enumerate() {
        assert!((tracked.objects[0].series_m[k] - brute[i]).abs() < 1e-12);
    }
}

#[test]
fn a_sphere_along_a_line_past_a_box_finds_the_exact_minimum_at_its_frame() {
    let sphere = uv_sphere(0.02, 12, 6);
    // A box beside the line: the sphere passes its face, then its vertical edge, and leaves.
    let block = cuboid_between(DVec3::new(-0.1, 0.03, -0.1), DVec3::new(0.02, 0.2, 0.1));
    let clearance = RigidClearance::new(&sphere, std::slice::from_ref(&block)).unwrap();
    let path = line_path(
        DVec3::new(-0.2, -0.02, 0.0),
        DVec3::new(0.2, 0.01, 0.01),
        DVec3::new(0.2, 0.1, 1.0),
        0.9,
        601,
    );
    let brute: Vec<f64> = path
        .iter()
        .map(|f| brute_force(&sphere, &block, f))
        .collect();
    let (frame, _) = least(&brute);
    assert!(
        frame > 0 && frame < path.len() - 1,
        "the minimum is inside the path"
    );
    let tracked = track_and_check(&clearance, &path, &brute);
    // The two points returned are that far apart, one on the block's surface.
    let c = tracked.objects[0].minimum.unwrap().closest;
    assert!((c.on_part_m.distance(c.on_object_m) - c.distance_m).abs() < 1e-12);
}

/// The ideal sphere's answer: the faceted sphere is never nearer than the ideal one and at most
/// its facet sag (r (1 − cos(π/segments)) per direction, twice over) farther.
#[test]
fn a_fine_sphere_past_a_plane_is_within_its_facet_sag_of_the_ideal_sphere() {
    let (r, segments) = (0.02, 64);
    let sphere = uv_sphere(r, segments, segments / 2);
    let floor = cuboid_between(DVec3::new(-1.0, -1.0, -0.1), DVec3::new(1.0, 1.0, 0.0));
    let clearance = RigidClearance::new(&sphere, &[floor]).unwrap();
    let path = line_path(
        DVec3::new(-0.2, 0.0, 0.09),
        DVec3::new(0.2, 0.0, 0.03),
        DVec3::X,
        0.0,
        401,
    );
    let minimum = track(&clearance, &path, 10).objects[0].minimum.unwrap();
    let ideal = 0.03 - r;
    let sag = 2.0 * r * (1.0 - (std::f64::consts::PI / segments as f64).cos());
    let got = minimum.closest.distance_m;
    assert!(
        got >= ideal - 1e-12 && got <= ideal + sag,
        "{got} vs {ideal}"
    );
    assert_eq!(minimum.frame, 400);
}
