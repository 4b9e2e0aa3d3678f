//! Exact clearance between a moving rigid part and static objects: the least distance between the
//! part's triangle mesh, placed at a pose, and each object's triangle mesh (not the voxmap, not the
//! point shell), with the two points that realise it. Two bounding-volume hierarchies, one per
//! mesh, searched together ([`Bvh::nearest_pair`]); the part's tree stays in the part's frame and
//! its boxes are moved with the pose. All lengths are metres.
//!
//! What 0 means: the two surfaces touch or cross. A part wholly inside a closed object without
//! touching its surface has a positive clearance; [`ExactScene`](crate::ExactScene)'s signed
//! distance tells the two apart.

use crate::bvh::Bvh;
use crate::ReferenceError;
use glam::{DMat3, DQuat, DVec3};
use vps_mesh::triangle_distance::triangle_distance;
use vps_mesh::{Aabb, TriMesh};

/// One mesh's triangles and their tree.
#[derive(Debug)]
struct MeshTree {
    triangles: Vec<[DVec3; 3]>,
    tree: Bvh,
}

impl MeshTree {
    fn new(index: usize, mesh: &TriMesh) -> Result<MeshTree, ReferenceError> {
        crate::scene::check_mesh(index, mesh)?;
        let triangles: Vec<[DVec3; 3]> = (0..mesh.triangle_count())
            .map(|t| mesh.triangle(t))
            .collect();
        let boxes: Vec<Aabb> = triangles
            .iter()
            .map(crate::scene::triangle_bounds)
            .collect();
        Ok(MeshTree {
            tree: Bvh::build(&boxes),
            triangles,
        })
    }
}

/// Where a part came nearest to one object at one pose.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Closest {
    /// The exact distance between the two meshes (m, ≥ 0; 0 when they touch or cross).
    pub distance_m: f64,
    /// The part's nearest point, in the world (m).
    pub on_part_m: DVec3,
    /// The same point in the part's own frame (m): where on the part.
    pub on_part_local_m: DVec3,
    /// The object's nearest point, in the world (m).
    pub on_object_m: DVec3,
    /// The part's triangle holding `on_part_m` (index into the part's mesh).
    pub part_triangle: u32,
    /// The object's triangle holding `on_object_m` (index into the object's mesh).
    pub object_triangle: u32,
}

/// A part's mesh and the static objects' meshes, prepared for clearance queries. Immutable;
/// queries allocate only a small search stack and may run on many threads at once.
#[derive(Debug)]
pub struct RigidClearance {
    part: MeshTree,
    part_radius_m: f64,
    objects: Vec<MeshTree>,
}

impl RigidClearance {
    /// Prepares `part` (in its own frame: the pose's position is this frame's origin, m) and
    /// `objects` (world frame, m). An object without triangles is never near anything.
    ///
    /// Errors: a vertex index out of range or a non-finite vertex (mesh 0 is the part, mesh
    /// `k + 1` is object `k`); a part without triangles ([`ReferenceError::Empty`]).
    /// Allocates; O(n log n) in the triangles.
    pub fn new(part: &TriMesh, objects: &[TriMesh]) -> Result<RigidClearance, ReferenceError> {
        let part_tree = MeshTree::new(0, part)?;
        if part_tree.triangles.is_empty() {
            return Err(ReferenceError::Empty);
        }
        let part_radius_m = part_tree
            .triangles
            .iter()
            .flatten()
            .map(|v| v.length())
            .fold(0.0, f64::max);
        let objects = objects
            .iter()
            .enumerate()
            .map(|(k, mesh)| MeshTree::new(k + 1, mesh))
            .collect::<Result<_, _>>()?;
        Ok(RigidClearance {
            part: part_tree,
            part_radius_m,
            objects,
        })
    }

    /// The number of objects.
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// The farthest any vertex of the part lies from the part frame's origin (m): a rotation by
    /// θ radians moves no point of the part more than θ times this.
    pub fn part_radius_m(&self) -> f64 {
        self.part_radius_m
    }

    /// The nearest points of the part at pose (`position` m, unit `orientation`) and object
    /// `object`, when they are at most `max_m` apart; `None` when farther (or the object has no
    /// triangles). Panics when `object` is out of range.
    pub fn closest(
        &self,
        object: usize,
        position: DVec3,
        orientation: DQuat,
        max_m: f64,
    ) -> Option<Closest> {
        let target = &self.objects[object];
        let rotation = DMat3::from_quat(orientation);
        let spread = DMat3::from_cols(
            rotation.x_axis.abs(),
            rotation.y_axis.abs(),
            rotation.z_axis.abs(),
        );
        let place = |b: &Aabb| {
            let centre = rotation * b.center() + position;
            let half = spread * (b.size() * 0.5);
            Aabb {
                min: centre - half,
                max: centre + half,
            }
        };
        let moved = |t: u32| self.part.triangles[t as usize].map(|v| rotation * v + position);
        let max_sq = if max_m.is_finite() {
            max_m.max(0.0).powi(2)
        } else {
            f64::INFINITY
        };
        let (on_object, on_part, _) =
            target
                .tree
                .nearest_pair(&self.part.tree, place, max_sq, |o, p, _| {
                    let pair = triangle_distance(&target.triangles[o as usize], &moved(p));
                    pair.distance * pair.distance
                })?;
        let pair = triangle_distance(&target.triangles[on_object as usize], &moved(on_part));
        Some(Closest {
            distance_m: pair.distance,
            on_part_m: pair.on_second,
            on_part_local_m: rotation.transpose() * (pair.on_second - position),
            on_object_m: pair.on_first,
            part_triangle: on_part,
            object_triangle: on_object,
        })
    }

    /// [`RigidClearance::nearest`] started from a guess: the triangle pair of `hint` (the nearest
    /// pair at a pose close to this one, e.g. the frame before) bounds the search from the
    /// start, so far branches are cut at once. The same answer as without the hint; faster when
    /// the hint is good.
    pub fn nearest_from(
        &self,
        object: usize,
        position: DVec3,
        orientation: DQuat,
        hint: Option<&Closest>,
    ) -> Option<Closest> {
        let target = &self.objects[object];
        let bound = hint
            .filter(|h| {
                (h.object_triangle as usize) < target.triangles.len()
                    && (h.part_triangle as usize) < self.part.triangles.len()
            })
            .map(|h| {
                let moved = self.part.triangles[h.part_triangle as usize]
                    .map(|v| orientation * v + position);
                triangle_distance(&target.triangles[h.object_triangle as usize], &moved).distance
            });
        match bound {
            // A hair over the hint's own distance: the hint's pair is always within it.
            Some(d) => self
                .closest(object, position, orientation, d * (1.0 + 1e-9) + 1e-15)
                .or_else(|| self.nearest(object, position, orientation)),
            None => self.nearest(object, position, orientation),
        }
    }

    /// [`RigidClearance::closest`] without a limit: always `Some` unless the object has no
    /// triangles.
    pub fn nearest(&self, object: usize, position: DVec3, orientation: DQuat) -> Option<Closest> {
        self.closest(object, position, orientation, f64::INFINITY)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use vps_mesh::builtin::{cuboid, cuboid_between, uv_sphere};

    /// A faceted sphere's distance to a floor is its lowest vertex's height: the mesh distance,
    /// not the ideal sphere's.
    #[test]
    fn a_sphere_above_a_floor_is_its_lowest_vertex_away() {
        let sphere = uv_sphere(0.05, 24, 12);
        let floor = cuboid_between(DVec3::new(-1.0, -1.0, -0.1), DVec3::new(1.0, 1.0, 0.0));
        let clearance = RigidClearance::new(&sphere, &[floor]).unwrap();
        for (height, tilt) in [(0.2, 0.0), (0.0731, 0.3), (0.06, 1.1)] {
            let orientation = DQuat::from_rotation_x(tilt);
            let position = DVec3::new(0.1, -0.2, height);
            let lowest = sphere
                .vertices
                .iter()
                .map(|&v| (orientation * v + position).z)
                .fold(f64::INFINITY, f64::min);
            let c = clearance.nearest(0, position, orientation).unwrap();
            assert!((c.distance_m - lowest).abs() < 1e-12, "{c:?} vs {lowest}");
            assert!(c.on_object_m.z.abs() < 1e-12);
            let back = orientation * c.on_part_local_m + position;
            assert!(back.distance(c.on_part_m) < 1e-12);
        }
        // Sunk into the floor: the surfaces cross.
        let c = clearance
            .nearest(0, DVec3::new(0.0, 0.0, 0.01), DQuat::IDENTITY)
            .unwrap();
        assert_eq!(c.distance_m, 0.0);
        // Started from the answer at a nearby pose: the same answer.
        let here = DVec3::new(0.1, -0.2, 0.0731);
        let hint = clearance.nearest(0, here + DVec3::X * 0.01, DQuat::IDENTITY);
        assert_eq!(
            clearance.nearest_from(0, here, DQuat::IDENTITY, hint.as_ref()),
            clearance.nearest(0, here, DQuat::IDENTITY)
        );
        // Beyond the limit: nothing.
        assert!(clearance
            .closest(0, DVec3::new(0.0, 0.0, 0.5), DQuat::IDENTITY, 0.1)
            .is_none());
    }

    #[test]
    fn two_boxes_side_by_side_are_their_gap_apart_at_any_spin_about_the_gap_axis() {
        let part = cuboid(DVec3::splat(0.01));
        let wall = cuboid_between(DVec3::new(0.05, -0.5, -0.5), DVec3::new(0.1, 0.5, 0.5));
        let clearance = RigidClearance::new(&part, &[wall]).unwrap();
        assert!((clearance.part_radius_m() - 0.01 * 3f64.sqrt()).abs() < 1e-15);
        for spin in [0.0, 0.4, 1.3] {
            let c = clearance
                .nearest(0, DVec3::ZERO, DQuat::from_rotation_x(spin))
                .unwrap();
            assert!((c.distance_m - 0.04).abs() < 1e-12, "{c:?}");
        }
        // Turned 45° about z, a vertical edge leads: 0.05 − 0.01·√2.
        let c = clearance
            .nearest(
                0,
                DVec3::ZERO,
                DQuat::from_rotation_z(std::f64::consts::FRAC_PI_4),
            )
            .unwrap();
        assert!((c.distance_m - (0.05 - 0.01 * 2f64.sqrt())).abs() < 1e-12);
    }

    #[test]
    fn bad_meshes_are_named() {
        let part = cuboid(DVec3::splat(0.01));
        let mut bad = part.clone();
        bad.triangles[0][1] = 99;
        assert!(matches!(
            RigidClearance::new(&part, &[bad]),
            Err(ReferenceError::VertexIndex { mesh: 1, .. })
        ));
        let empty = TriMesh::new(Vec::new(), Vec::new());
        assert_eq!(
            RigidClearance::new(&empty, std::slice::from_ref(&part)).unwrap_err(),
            ReferenceError::Empty
        );
        let c = RigidClearance::new(&part, &[empty]).unwrap();
        assert!(c.nearest(0, DVec3::ZERO, DQuat::IDENTITY).is_none());
    }
}
