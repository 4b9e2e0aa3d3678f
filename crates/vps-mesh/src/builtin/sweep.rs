//! Tubes swept along a polyline centreline, and the centreline shapes the built-in scenes use.

use std::f64::consts::TAU;

use glam::DVec3;

use super::primitives::push_quad;
use crate::TriMesh;

/// A closed tube of `radius` (m) with `sides` facets (at least 3) swept along `path` (m), capped
/// at both ends by triangle fans. Rings are perpendicular to the averaged tangent and carried along
/// by parallel transport, so the tube does not twist. `path` needs at least two points and no two
/// consecutive equal points; bends should be gentle relative to `radius` (an arc's radius larger
/// than the tube's), or the tube self-intersects. Returns an empty mesh for a path that is too
/// short. Triangles: `2 sides (points - 1) + 2 sides`.
pub fn swept_tube(path: &[DVec3], radius: f64, sides: u32) -> TriMesh {
    let sides = sides.max(3);
    if path.len() < 2 {
        return TriMesh::default();
    }
    let last = path.len() - 1;
    let tangent =
        |i: usize| (path[(i + 1).min(last)] - path[i.saturating_sub(1)]).normalize_or_zero();

    let rings = path.len() as u32;
    let mut vertices = Vec::with_capacity((rings * sides + 2) as usize);
    let mut normal = tangent(0).any_orthonormal_vector();
    for (i, &centre) in path.iter().enumerate() {
        let t = tangent(i);
        // Parallel transport: remove the component along the new tangent.
        normal = (normal - normal.dot(t) * t).normalize_or(t.any_orthonormal_vector());
        let binormal = t.cross(normal);
        for j in 0..sides {
            let (s, c) = (TAU * f64::from(j) / f64::from(sides)).sin_cos();
            vertices.push(centre + radius * (c * normal + s * binormal));
        }
    }
    let start_centre = vertices.len() as u32;
    vertices.push(path[0]);
    vertices.push(path[last]);
    let end_centre = start_centre + 1;

    let ring = |i: u32, j: u32| i * sides + j % sides;
    let mut triangles = Vec::with_capacity((2 * sides * rings) as usize);
    for i in 0..rings - 1 {
        for j in 0..sides {
            push_quad(
                &mut triangles,
                ring(i + 1, j),
                ring(i + 1, j + 1),
                ring(i, j),
                ring(i, j + 1),
            );
        }
    }
    for j in 0..sides {
        triangles.push([start_centre, ring(0, j + 1), ring(0, j)]);
        triangles.push([end_centre, ring(rings - 1, j), ring(rings - 1, j + 1)]);
    }
    TriMesh::new(vertices, triangles)
}

/// Points of a pipe that runs from `start` along unit `first_dir` for `first_len` (m), bends
/// through 90° with centreline radius `bend_radius` (m) towards unit `second_dir` (perpendicular to
/// `first_dir`) in `arc_segments` steps, then runs `second_len` (m) along `second_dir`.
pub fn bent_pipe_path(
    start: DVec3,
    first_dir: DVec3,
    first_len: f64,
    second_dir: DVec3,
    second_len: f64,
    bend_radius: f64,
    arc_segments: u32,
) -> Vec<DVec3> {
    let arc_segments = arc_segments.max(1);
    let arc_start = start + first_dir * first_len;
    let arc_centre = arc_start + second_dir * bend_radius;
    let mut path = vec![start];
    for k in 0..=arc_segments {
        let a = std::f64::consts::FRAC_PI_2 * f64::from(k) / f64::from(arc_segments);
        let (s, c) = a.sin_cos();
        path.push(arc_centre - c * bend_radius * second_dir + s * bend_radius * first_dir);
    }
    let arc_end = arc_centre + first_dir * bend_radius;
    path.push(arc_end + second_dir * second_len);
    if first_len <= 0.0 {
        path.remove(0);
    }
    if second_len <= 0.0 {
        path.pop();
    }
    path
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::builtin::test_support::assert_closed;

    #[test]
    fn straight_tube_is_closed_with_cylinder_volume() {
        let path: Vec<DVec3> = (0..=10)
            .map(|i| DVec3::new(0.1 * f64::from(i), 0.2, 0.3))
            .collect();
        let m = swept_tube(&path, 0.01, 64);
        assert_eq!(m.triangle_count(), 2 * 64 * 10 + 2 * 64);
        assert_closed(&m);
        let v = PI * 0.01 * 0.01 * 1.0;
        assert!(
            (m.signed_volume() - v).abs() / v < 0.01,
            "{}",
            m.signed_volume()
        );
    }

    #[test]
    fn bent_pipe_is_closed_and_has_torus_volume() {
        let (r, bend) = (0.01, 0.1);
        let path = bent_pipe_path(DVec3::ZERO, DVec3::X, 0.2, DVec3::Z, 0.3, bend, 64);
        assert!((path.last().unwrap().distance(DVec3::new(0.3, 0.0, 0.4))).abs() < 1e-12);
        let m = swept_tube(&path, r, 48);
        assert_closed(&m);
        // Straight parts plus a quarter torus (Pappus).
        let v = PI * r * r * (0.2 + 0.3 + 0.5 * PI * bend);
        assert!(
            (m.signed_volume() - v).abs() / v < 0.01,
            "{} vs {v}",
            m.signed_volume()
        );
    }
}
