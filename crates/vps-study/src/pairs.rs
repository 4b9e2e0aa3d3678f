//! Exact clearance between two moving parts of one session: the distance between their meshes at
//! every `every`-th frame and the least over every frame, with where it was.
//!
//! Both parts move, so the pair is measured in part A's own frame, where A stands still: each
//! frame, B's pose relative to A (`R_a^T (x_b − x_a)`, `R_a^T R_b`) is a path of one rigid part
//! past one fixed object, and [`crate::clearance::track`] finds its series and its exact minimum
//! as it does for a static object (the motion bound holds for the relative motion). The nearest
//! points are then put back in the world with A's pose at that frame.

use crate::clearance::{track, MinimumClearance};
use crate::path::PathFrame;
use crate::StudyError;
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
    let minimum = object.minimum.map(|mut m| {
        let fa = &path_a[m.frame];
        let to_world = |p| fa.part_orientation.normalize() * p + fa.part_position_m;
        m.closest.on_part_m = to_world(m.closest.on_part_m);
        m.closest.on_object_m = to_world(m.closest.on_object_m);
        m
    });
    Ok(PairClearance {
        a,
        b,
        minimum,
        series_m: object.series_m,
        series_frames: measured.series_frames,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3};
    use vps_mesh::builtin::cuboid;

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
