//! Closed analytic primitives: box, UV sphere, capped cylinder.
//!
//! Every primitive is a closed 2-manifold (each edge shared by exactly two triangles), centred at the
//! origin, in metres, with counter-clockwise triangles seen from outside (outward normals by the
//! right-hand rule). They allocate and are meant for scene setup, not the haptic frame path.

use std::f64::consts::{PI, TAU};

use glam::DVec3;

use crate::TriMesh;

/// The axis-aligned box from corner `min` to corner `max` (m): [`cuboid`] centred between them.
pub fn cuboid_between(min: DVec3, max: DVec3) -> TriMesh {
    cuboid((max - min) * 0.5).transformed(1.0, glam::DQuat::IDENTITY, (max + min) * 0.5)
}

/// An axis-aligned box with the given half extents (m), 8 vertices and 12 triangles.
///
/// Half extents should be positive; a zero or negative component gives a degenerate box that
/// validation will reject.
pub fn cuboid(half_extents: DVec3) -> TriMesh {
    // Vertex index = bit 0 for +x, bit 1 for +y, bit 2 for +z.
    let vertices = (0..8u32)
        .map(|i| {
            let sign = |bit: u32| if i & (1 << bit) != 0 { 1.0 } else { -1.0 };
            DVec3::new(sign(0), sign(1), sign(2)) * half_extents
        })
        .collect();
    let corner =
        |s: [i32; 3]| -> u32 { (0..3).map(|k| if s[k] > 0 { 1u32 << k } else { 0 }).sum() };
    let mut triangles = Vec::with_capacity(12);
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in [-1, 1] {
            // Quad corners in (u, v) order CCW about +axis; reversed on the negative side.
            let mut quad = [(-1, -1), (1, -1), (1, 1), (-1, 1)].map(|(su, sv)| {
                let mut s = [0; 3];
                s[axis] = side;
                s[u] = su;
                s[v] = sv;
                corner(s)
            });
            if side < 0 {
                quad.reverse();
            }
            triangles.push([quad[0], quad[1], quad[2]]);
            triangles.push([quad[0], quad[2], quad[3]]);
        }
    }
    TriMesh::new(vertices, triangles)
}

/// A UV sphere of `radius` (m) with `segments` around the z axis (at least 3) and `rings` latitude
/// bands from pole to pole (at least 2). The poles are single vertices joined by triangle fans, so
/// there are no degenerate triangles: `2 * segments * (rings - 1)` triangles.
pub fn uv_sphere(radius: f64, segments: u32, rings: u32) -> TriMesh {
    let segments = segments.max(3);
    let rings = rings.max(2);
    let mut vertices = Vec::with_capacity((segments * (rings - 1) + 2) as usize);
    vertices.push(DVec3::new(0.0, 0.0, radius));
    for i in 1..rings {
        let theta = PI * f64::from(i) / f64::from(rings);
        let (st, ct) = theta.sin_cos();
        for j in 0..segments {
            let phi = TAU * f64::from(j) / f64::from(segments);
            let (sp, cp) = phi.sin_cos();
            vertices.push(radius * DVec3::new(st * cp, st * sp, ct));
        }
    }
    let south = vertices.len() as u32;
    vertices.push(DVec3::new(0.0, 0.0, -radius));

    let ring = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    let mut triangles = Vec::with_capacity((2 * segments * (rings - 1)) as usize);
    for j in 0..segments {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            push_quad(
                &mut triangles,
                ring(i, j),
                ring(i, j + 1),
                ring(i + 1, j),
                ring(i + 1, j + 1),
            );
        }
    }
    for j in 0..segments {
        triangles.push([south, ring(rings - 1, j + 1), ring(rings - 1, j)]);
    }
    TriMesh::new(vertices, triangles)
}

/// A capped cylinder along z of `radius` (m), from `z = -half_length` to `z = +half_length` (m), with
/// `segments` sides (at least 3). Caps are fans around a centre vertex: `4 * segments` triangles.
pub fn cylinder(radius: f64, half_length: f64, segments: u32) -> TriMesh {
    let segments = segments.max(3);
    let mut vertices = Vec::with_capacity((2 * segments + 2) as usize);
    for z in [half_length, -half_length] {
        for j in 0..segments {
            let phi = TAU * f64::from(j) / f64::from(segments);
            let (sp, cp) = phi.sin_cos();
            vertices.push(DVec3::new(radius * cp, radius * sp, z));
        }
    }
    let top_centre = vertices.len() as u32;
    vertices.push(DVec3::new(0.0, 0.0, half_length));
    vertices.push(DVec3::new(0.0, 0.0, -half_length));
    let bottom_centre = top_centre + 1;

    let top = |j: u32| j % segments;
    let bottom = |j: u32| segments + j % segments;
    let mut triangles = Vec::with_capacity((4 * segments) as usize);
    for j in 0..segments {
        push_quad(&mut triangles, top(j), top(j + 1), bottom(j), bottom(j + 1));
        triangles.push([top_centre, top(j), top(j + 1)]);
        triangles.push([bottom_centre, bottom(j + 1), bottom(j)]);
    }
    TriMesh::new(vertices, triangles)
}

/// Pushes the two triangles of a quad given as seen from outside: `a` upper-left, `b` upper-right,
/// `c` lower-left, `d` lower-right (counter-clockwise order a, c, d, b).
pub(crate) fn push_quad(triangles: &mut Vec<[u32; 3]>, a: u32, b: u32, c: u32, d: u32) {
    triangles.push([a, c, d]);
    triangles.push([a, d, b]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin::test_support::assert_closed;

    #[test]
    fn cuboid_is_closed_with_right_volume_and_area() {
        let m = cuboid(DVec3::new(0.1, 0.2, 0.3));
        assert_eq!(m.triangle_count(), 12);
        assert_closed(&m);
        assert!((m.signed_volume() - 0.2 * 0.4 * 0.6).abs() < 1e-12);
        let area = 2.0 * (0.2 * 0.4 + 0.4 * 0.6 + 0.2 * 0.6);
        assert!((m.area() - area).abs() < 1e-12);
        let between = cuboid_between(DVec3::new(-1.0, 0.5, 2.0), DVec3::new(1.0, 0.75, 2.5));
        assert_closed(&between);
        let b = between.bounds();
        assert_eq!(
            (b.min, b.max),
            (DVec3::new(-1.0, 0.5, 2.0), DVec3::new(1.0, 0.75, 2.5))
        );
    }

    #[test]
    fn sphere_is_closed_with_near_analytic_volume_and_area() {
        let r = 0.05;
        let m = uv_sphere(r, 64, 32);
        assert_eq!(m.triangle_count(), 2 * 64 * 31);
        assert_closed(&m);
        let v = 4.0 / 3.0 * PI * r.powi(3);
        let a = 4.0 * PI * r * r;
        assert!(
            (m.signed_volume() - v).abs() / v < 0.01,
            "volume {}",
            m.signed_volume()
        );
        assert!((m.area() - a).abs() / a < 0.01, "area {}", m.area());
        // Inscribed polyhedron: strictly smaller.
        assert!(m.signed_volume() < v);
    }

    #[test]
    fn sphere_has_no_degenerate_triangles() {
        let m = uv_sphere(1.0, 3, 2);
        for i in 0..m.triangle_count() {
            let [a, b, c] = m.triangle(i);
            assert!((b - a).cross(c - a).length() > 1e-6, "triangle {i}");
        }
    }

    #[test]
    fn cylinder_is_closed_with_near_analytic_volume_and_area() {
        let (r, h) = (0.02, 0.1);
        let m = cylinder(r, h, 128);
        assert_eq!(m.triangle_count(), 4 * 128);
        assert_closed(&m);
        let v = PI * r * r * 2.0 * h;
        let a = 2.0 * PI * r * 2.0 * h + 2.0 * PI * r * r;
        assert!((m.signed_volume() - v).abs() / v < 0.005);
        assert!((m.area() - a).abs() / a < 0.005);
        let b = m.bounds();
        assert!((b.min.z + h).abs() < 1e-15 && (b.max.z - h).abs() < 1e-15);
    }
}
