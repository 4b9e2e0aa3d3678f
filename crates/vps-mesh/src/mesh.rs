//! The indexed triangle mesh and its axis-aligned bounds.

use glam::{DMat3, DQuat, DVec3};

/// An axis-aligned box in metres. Invariant for a non-empty box: `min <= max` component-wise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner (m).
    pub min: DVec3,
    /// Maximum corner (m).
    pub max: DVec3,
}

impl Aabb {
    /// The empty box: `min = +inf`, `max = -inf`, so that any `grow` makes it the point grown by.
    pub const EMPTY: Aabb = Aabb {
        min: DVec3::splat(f64::INFINITY),
        max: DVec3::splat(f64::NEG_INFINITY),
    };

    /// Extends the box to contain `p`.
    pub fn grow(&mut self, p: DVec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The smallest box containing both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// True when no point was ever added.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    /// Edge lengths (m).
    pub fn size(&self) -> DVec3 {
        self.max - self.min
    }

    /// Centre (m).
    pub fn center(&self) -> DVec3 {
        0.5 * (self.min + self.max)
    }
}

/// An indexed triangle mesh in metres.
///
/// Invariants after [`crate::validate::validate`] (the loaders and built-ins always validate): every
/// index is in range, every coordinate is finite, no triangle has zero area.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions (m).
    pub vertices: Vec<DVec3>,
    /// Triangles as vertex indices, counter-clockwise seen from outside where the source is consistent.
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    /// A mesh from raw parts; not validated.
    pub fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        Self {
            vertices,
            triangles,
        }
    }

    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corners of triangle `i` (m). Panics if `i` or its indices are out of range, which a
    /// validated mesh rules out.
    pub fn triangle(&self, i: usize) -> [DVec3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.vertices[a as usize],
            self.vertices[b as usize],
            self.vertices[c as usize],
        ]
    }

    /// Bounds of all vertices; [`Aabb::EMPTY`] for an empty mesh.
    pub fn bounds(&self) -> Aabb {
        let mut b = Aabb::EMPTY;
        for &v in &self.vertices {
            b.grow(v);
        }
        b
    }

    /// Appends `other`, re-indexing its triangles.
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.vertices.len() as u32;
        self.vertices.extend_from_slice(&other.vertices);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    /// Applies `p -> rotation * (scale * p) + translation` to every vertex (scale is uniform).
    pub fn transform(&mut self, scale: f64, rotation: DQuat, translation: DVec3) {
        let m = DMat3::from_quat(rotation) * scale;
        for v in &mut self.vertices {
            *v = m * *v + translation;
        }
    }

    /// Returns a transformed copy; see [`TriMesh::transform`].
    pub fn transformed(&self, scale: f64, rotation: DQuat, translation: DVec3) -> TriMesh {
        let mut m = self.clone();
        m.transform(scale, rotation, translation);
        m
    }

    /// Signed enclosed volume by the divergence theorem (m³): positive for a closed mesh whose
    /// triangles face outward, negative when they all face inward; only indicative for open meshes.
    pub fn signed_volume(&self) -> f64 {
        (0..self.triangles.len())
            .map(|i| {
                let [a, b, c] = self.triangle(i);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// Reverses the winding of every triangle (turns every normal around).
    pub fn flip_winding(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }

    /// Total surface area (m²).
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|i| {
                let [a, b, c] = self.triangle(i);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum()
    }
}
