//! [`ExactScene`]: the static meshes prepared for signed-distance queries (two-level BVH: one tree
//! over the components' boxes, one tree per component over its triangles).

use crate::bvh::{box_distance_sq, Bvh};
use crate::components::components;
use crate::ReferenceError;
use glam::DVec3;
use rayon::prelude::*;
use rustc_hash::FxHashMap;
use vps_mesh::closest_point::{closest_point, Feature};
use vps_mesh::{Aabb, TriMesh};

/// The signed distance of a point to the scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SignedDistance {
    /// Signed distance (m): positive outside every solid, negative inside one (penetration depth
    /// = −distance_m). Never negative for unsigned (open) components.
    pub distance_m: f64,
    /// The nearest point of the scene's surface (m).
    pub closest: DVec3,
    /// Unit outward normal at `closest`: the direction that moves the point away from (out of)
    /// the surface fastest. From `closest` towards the point outside, away from it inside; the
    /// angle-weighted pseudo-normal when the point lies on the surface.
    pub normal: DVec3,
}

/// One connected component with its own triangle tree.
#[derive(Debug)]
struct Object {
    /// Global triangle indices; the tree's primitives index this list.
    triangles: Vec<u32>,
    tree: Bvh,
    bounds: Aabb,
    /// Closed and oriented: has an inside.
    closed: bool,
}

/// Static triangle meshes (world frame, m) ready for exact signed-distance queries. Immutable and
/// `Sync`: queries from many threads at once are fine. Building allocates (about 250 bytes per
/// triangle) and takes about a second for the 600k-triangle bay on one core.
#[derive(Debug)]
pub struct ExactScene {
    triangles: Vec<[DVec3; 3]>,
    /// Outward pseudo-normals per triangle: face, edges (edge k from corner k to k+1), corners.
    face_normals: Vec<DVec3>,
    edge_normals: Vec<[DVec3; 3]>,
    vertex_normals: Vec<[DVec3; 3]>,
    objects: Vec<Object>,
    /// Per triangle: its component's index in `objects`.
    triangle_component: Vec<u32>,
    top: Bvh,
}

impl ExactScene {
    /// Prepares `meshes` (world frame, m). Each mesh is split into connected components (triangles
    /// sharing vertex indices); a component that is closed and consistently oriented is a solid
    /// (either winding: inward-facing solids are flipped), any other is an unsigned sheet.
    ///
    /// Errors: no triangles at all, a vertex index out of range, a non-finite vertex.
    pub fn new(meshes: &[TriMesh]) -> Result<ExactScene, ReferenceError> {
        let mut scene = ExactScene {
            triangles: Vec::new(),
            face_normals: Vec::new(),
            edge_normals: Vec::new(),
            vertex_normals: Vec::new(),
            objects: Vec::new(),
            triangle_component: Vec::new(),
            top: Bvh::build(&[]),
        };
        for (index, mesh) in meshes.iter().enumerate() {
            check_mesh(index, mesh)?;
            scene.add_mesh(mesh);
        }
        if scene.triangles.is_empty() {
            return Err(ReferenceError::Empty);
        }
        let boxes: Vec<Aabb> = scene.objects.iter().map(|o| o.bounds).collect();
        scene.top = Bvh::build(&boxes);
        Ok(scene)
    }

    fn add_mesh(&mut self, mesh: &TriMesh) {
        let base = self.triangles.len() as u32;
        let parts = components(mesh);
        let mut orientation = vec![1.0; mesh.triangle_count()];
        for part in &parts {
            for &t in &part.triangles {
                orientation[t as usize] = part.orientation;
            }
        }
        // Per triangle, in parallel: its oriented unit normal and its three corner angles (the
        // sums below stay serial, in triangle order: the same bits on any number of threads).
        let (faces, angles): (Vec<DVec3>, Vec<[f64; 3]>) = (0..mesh.triangle_count())
            .into_par_iter()
            .map(|t| {
                let corners = mesh.triangle(t);
                let [a, b, c] = corners;
                let face = (b - a).cross(c - a).normalize_or_zero() * orientation[t];
                let angle = [0, 1, 2].map(|k| {
                    let e1 = corners[(k + 1) % 3] - corners[k];
                    let e2 = corners[(k + 2) % 3] - corners[k];
                    e1.angle_between(e2).max(0.0)
                });
                (face, angle)
            })
            .unzip();
        let mut at_vertex = vec![DVec3::ZERO; mesh.vertices.len()];
        // Each undirected edge's sum of its faces' normals (in triangle order), and per corner
        // `k` of triangle `t` the sum of its edge from corner k to k + 1 (`3 t + k`).
        let mut edge_index: FxHashMap<(u32, u32), u32> = FxHashMap::default();
        edge_index.reserve(mesh.triangles.len() * 3 / 2);
        let mut at_edge: Vec<DVec3> = Vec::with_capacity(mesh.triangles.len() * 3 / 2);
        let mut edge_of = Vec::with_capacity(mesh.triangles.len() * 3);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                at_vertex[tri[k] as usize] += faces[t] * angles[t][k];
                let next = at_edge.len() as u32;
                let slot = *edge_index
                    .entry(edge_key(tri[k], tri[(k + 1) % 3]))
                    .or_insert(next);
                if slot == next {
                    at_edge.push(DVec3::ZERO);
                }
                at_edge[slot as usize] += faces[t];
                edge_of.push(slot);
            }
        }
        for (t, tri) in mesh.triangles.iter().enumerate() {
            self.triangles.push(mesh.triangle(t));
            self.face_normals.push(faces[t]);
            self.vertex_normals
                .push(tri.map(|v| at_vertex[v as usize].normalize_or(faces[t])));
            self.edge_normals.push(
                [0, 1, 2].map(|k| at_edge[edge_of[3 * t + k] as usize].normalize_or(faces[t])),
            );
        }
        self.triangle_component.resize(self.triangles.len(), 0);
        // Each component's search tree, in parallel (each build is serial and deterministic).
        let all = &self.triangles;
        let objects: Vec<Object> = parts
            .into_par_iter()
            .map(|part| {
                let triangles: Vec<u32> = part.triangles.iter().map(|&t| t + base).collect();
                let boxes: Vec<Aabb> = triangles
                    .iter()
                    .map(|&t| triangle_bounds(&all[t as usize]))
                    .collect();
                let tree = Bvh::build(&boxes);
                Object {
                    bounds: tree.bounds(),
                    triangles,
                    tree,
                    closed: part.closed,
                }
            })
            .collect();
        for object in objects {
            let component = self.objects.len() as u32;
            for &t in &object.triangles {
                self.triangle_component[t as usize] = component;
            }
            self.objects.push(object);
        }
    }

    /// Triangle `t` (global index: the meshes given to [`ExactScene::new`] one after the other,
    /// each in its own order) as its three corners (m). Panics when `t` is out of range.
    pub fn triangle(&self, t: u32) -> [DVec3; 3] {
        self.triangles[t as usize]
    }

    /// The signed distance from `p` (m) to triangle `t` alone (global index, see
    /// [`ExactScene::triangle`]): the distance to its closest point, negative when `p` lies behind
    /// the angle-weighted pseudo-normal of that point's feature and the triangle's component is
    /// closed. For a `t` that is the nearest triangle of the scene to `p` this is the scene's
    /// signed distance wherever solids do not overlap. Panics when `t` is out of range. Pure.
    pub fn signed_to_triangle_at(&self, p: DVec3, t: u32) -> SignedDistance {
        let (closest, _) = closest_point(p, &self.triangles[t as usize]);
        let closed = self.objects[self.triangle_component[t as usize] as usize].closed;
        self.signed_to_triangle(p, t, closest.distance(p), closed)
    }

    /// [`ExactScene::signed_to_triangle_at`]'s distance alone (m): the same value, bit for bit,
    /// with one closest point and no normal. Panics when `t` is out of range. Pure.
    pub fn signed_distance_to_triangle(&self, p: DVec3, t: u32) -> f64 {
        let t = t as usize;
        let nearest = closest_point(p, &self.triangles[t]);
        let distance = nearest.0.distance(p);
        let closed = self.objects[self.triangle_component[t] as usize].closed;
        if self.is_behind(p, t, nearest, closed) {
            -distance
        } else {
            distance
        }
    }

    /// The connected component (index, `0..component_count()`) triangle `t` belongs to. The
    /// scene's signed distance is the minimum over components of the signed distance to each
    /// component's nearest triangle. Panics when `t` is out of range.
    pub fn component_of(&self, t: u32) -> u32 {
        self.triangle_component[t as usize]
    }

    /// Whether component `component` (`0..component_count()`) is a closed, consistently oriented
    /// solid, whose distance is signed (else it is open and its distance unsigned). Panics when
    /// `component` is out of range.
    pub fn is_closed(&self, component: u32) -> bool {
        self.objects[component as usize].closed
    }

    /// Triangles in the scene.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// Connected components (solids and sheets).
    pub fn component_count(&self) -> usize {
        self.objects.len()
    }

    /// Components that are open or inconsistently oriented, whose distance is unsigned.
    pub fn unsigned_components(&self) -> usize {
        self.objects.iter().filter(|o| !o.closed).count()
    }

    /// Bounds of the whole scene (m).
    pub fn bounds(&self) -> Aabb {
        self.top.bounds()
    }

    /// The exact signed distance from `p` (m) to the scene. Blocking, allocates a small stack.
    pub fn signed_distance(&self, p: DVec3) -> SignedDistance {
        let nearest_sq = self
            .top
            .nearest(p, f64::INFINITY, |o, best_sq| {
                self.object_nearest(&self.objects[o as usize], p, best_sq)
                    .map_or(f64::INFINITY, |(_, d)| d)
            })
            .map_or(f64::INFINITY, |(_, d)| d);
        let reach = nearest_sq.sqrt() * (1.0 + 1e-9) + 1e-12;
        self.signed_distance_within(p, reach)
            .expect("the nearest component is within its own distance")
    }

    /// The signed distance from `p` (m) when it is at most `max_m` (m); `None` when `p` is farther
    /// than `max_m` outside every component. Points inside a solid are always resolved, however
    /// deep. Cheaper than [`ExactScene::signed_distance`] for small `max_m`: only components whose
    /// box lies within `max_m` are searched.
    pub fn signed_distance_within(&self, p: DVec3, max_m: f64) -> Option<SignedDistance> {
        let max_sq = max_m * max_m;
        let mut best: Option<SignedDistance> = None;
        self.top.within(p, max_sq, |o| {
            let object = &self.objects[o as usize];
            let inside_box = box_distance_sq(&object.bounds, p) == 0.0;
            let cap = if inside_box && object.closed {
                f64::INFINITY
            } else {
                max_sq
            };
            let Some((t, d_sq)) = self.object_nearest(object, p, cap) else {
                return;
            };
            let found = self.signed_to_triangle(p, t, d_sq.sqrt(), object.closed);
            if found.distance_m <= max_m
                && best.is_none_or(|b: SignedDistance| found.distance_m < b.distance_m)
            {
                best = Some(found);
            }
        });
        best
    }

    /// Nearest triangle (global index) of `object` within `max_sq` and its squared distance.
    fn object_nearest(&self, object: &Object, p: DVec3, max_sq: f64) -> Option<(u32, f64)> {
        object
            .tree
            .nearest(p, max_sq, |i, _| {
                let t = &self.triangles[object.triangles[i as usize] as usize];
                closest_point(p, t).0.distance_squared(p)
            })
            .map(|(i, d)| (object.triangles[i as usize], d))
    }

    /// The angle-weighted pseudo-normal of `feature` of triangle `t`.
    fn pseudo_normal(&self, t: usize, feature: Feature) -> DVec3 {
        match feature {
            Feature::Face => self.face_normals[t],
            Feature::Edge(k) => self.edge_normals[t][k as usize],
            Feature::Vertex(k) => self.vertex_normals[t][k as usize],
        }
    }

    /// Whether `p` lies inside: behind the pseudo-normal at `closest`, the point of triangle `t`
    /// nearest to it (on `feature`), of a `solid` component.
    fn is_behind(
        &self,
        p: DVec3,
        t: usize,
        (closest, feature): (DVec3, Feature),
        solid: bool,
    ) -> bool {
        solid && (p - closest).dot(self.pseudo_normal(t, feature)) < 0.0
    }

    fn signed_to_triangle(&self, p: DVec3, t: u32, distance: f64, solid: bool) -> SignedDistance {
        let t = t as usize;
        let (closest, feature) = closest_point(p, &self.triangles[t]);
        let pseudo = self.pseudo_normal(t, feature);
        let away = p - closest;
        let sign = if self.is_behind(p, t, (closest, feature), solid) {
            -1.0
        } else {
            1.0
        };
        let normal = if distance > ON_SURFACE_M {
            away / distance * sign
        } else {
            pseudo
        };
        SignedDistance {
            distance_m: sign * distance,
            closest,
            normal: normal.normalize_or(pseudo),
        }
    }
}

/// Below this distance (m) a point counts as on the surface and takes the pseudo-normal.
const ON_SURFACE_M: f64 = 1e-12;

fn edge_key(a: u32, b: u32) -> (u32, u32) {
    (a.min(b), a.max(b))
}

pub(crate) fn triangle_bounds(t: &[DVec3; 3]) -> Aabb {
    Aabb {
        min: t[0].min(t[1]).min(t[2]),
        max: t[0].max(t[1]).max(t[2]),
    }
}

pub(crate) fn check_mesh(mesh_index: usize, mesh: &TriMesh) -> Result<(), ReferenceError> {
    if let Some((vertex, value)) = mesh
        .vertices
        .iter()
        .enumerate()
        .find(|(_, v)| !v.is_finite())
    {
        return Err(ReferenceError::NonFinite {
            mesh: mesh_index,
            vertex,
            value: *value,
        });
    }
    for (triangle, tri) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = tri.iter().find(|&&v| v as usize >= mesh.vertices.len()) {
            return Err(ReferenceError::VertexIndex {
                mesh: mesh_index,
                triangle,
                index,
                vertices: mesh.vertices.len(),
            });
        }
    }
    Ok(())
}
