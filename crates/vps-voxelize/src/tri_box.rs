//! Exact triangle / axis-aligned box overlap by the separating axis theorem (Akenine-Möller 2001):
//! the 3 box face normals, the triangle normal and the 9 cross products of box and triangle edges.

use glam::DVec3;

/// True when the closed triangle `tri` and the closed box `center ± half` share at least one point.
///
/// Touching counts as overlap (a triangle lying exactly in a box face overlaps the box), so a surface
/// lying on a voxel boundary marks the voxels on both sides: conservative, never leaky. Degenerate
/// triangles (zero area) are handled: parallel edges give a zero axis, which never separates.
/// Units: metres, any consistent unit works. Pure function, no allocation. To test one triangle
/// against many boxes of one size, [`PreparedTriangle`] does the per-triangle work once.
pub fn triangle_box_overlap(tri: &[DVec3; 3], center: DVec3, half: DVec3) -> bool {
    PreparedTriangle::new(tri, half).overlaps(center)
}

/// A triangle made ready for separating-axis tests against many boxes of one size. Per axis it keeps
/// the interval of box-centre projections that do not separate: `[min - r, max + r]` with the
/// triangle's projection `[min, max]` and the box's projected radius `r`. The 9 edge-cross axes come
/// first (they reject most near misses), then the triangle normal (zero axes dropped); the 3 box
/// normals are checked last as plain coordinate intervals.
#[derive(Clone, Debug)]
pub struct PreparedTriangle {
    axes: [DVec3; 10],
    /// Per axis: the non-separating interval of `centre · axis`.
    keep: [(f64, f64); 10],
    count: usize,
    /// Non-separating interval of the centre along x, y, z.
    box_lo: DVec3,
    box_hi: DVec3,
}

impl PreparedTriangle {
    /// Prepares `tri` for boxes of half extents `half` (same units). No allocation.
    pub fn new(tri: &[DVec3; 3], half: DVec3) -> Self {
        let edges = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]];
        let mut axes = [DVec3::ZERO; 10];
        let mut keep = [(0.0, 0.0); 10];
        let mut count = 0;
        let mut add = |axis: DVec3| {
            if axis == DVec3::ZERO {
                return;
            }
            let p = [tri[0].dot(axis), tri[1].dot(axis), tri[2].dot(axis)];
            let r = half.dot(axis.abs());
            axes[count] = axis;
            keep[count] = (p[0].min(p[1]).min(p[2]) - r, p[0].max(p[1]).max(p[2]) + r);
            count += 1;
        };
        for e in edges {
            for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                add(axis.cross(e));
            }
        }
        add(edges[0].cross(edges[1]));
        Self {
            axes,
            keep,
            count,
            box_lo: tri[0].min(tri[1]).min(tri[2]) - half,
            box_hi: tri[0].max(tri[1]).max(tri[2]) + half,
        }
    }

    /// True when the triangle and the closed box `center ± half` overlap (touching counts).
    #[inline]
    pub fn overlaps(&self, center: DVec3) -> bool {
        for (axis, &(lo, hi)) in self.axes[..self.count].iter().zip(&self.keep) {
            let c = center.dot(*axis);
            if c < lo || c > hi {
                return false;
            }
        }
        center.cmpge(self.box_lo).all() && center.cmple(self.box_hi).all()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const C: DVec3 = DVec3::ZERO;
    const H: DVec3 = DVec3::splat(1.0);

    fn t(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
        [DVec3::from(a), DVec3::from(b), DVec3::from(c)]
    }

    #[test]
    fn triangle_fully_inside_box() {
        let tri = t([0.1, 0.1, 0.1], [0.5, 0.1, 0.2], [0.2, 0.4, -0.3]);
        assert!(triangle_box_overlap(&tri, C, H));
    }

    #[test]
    fn box_fully_inside_large_triangle() {
        let tri = t([-10.0, -10.0, 0.3], [10.0, -10.0, 0.3], [0.0, 10.0, 0.3]);
        assert!(triangle_box_overlap(&tri, C, H));
    }

    #[test]
    fn touching_face_vertex_and_edge_count() {
        // Triangle lying in the face x = 1.
        let face = t([1.0, -0.5, -0.5], [1.0, 0.5, -0.5], [1.0, 0.0, 0.5]);
        assert!(triangle_box_overlap(&face, C, H));
        // Only a vertex touches the corner (1, 1, 1).
        let vertex = t([1.0, 1.0, 1.0], [2.0, 3.0, 1.5], [3.0, 1.5, 2.0]);
        assert!(triangle_box_overlap(&vertex, C, H));
        // An edge touching the box edge x = 1, y = 1.
        let edge = t([1.0, 1.0, -3.0], [1.0, 1.0, 3.0], [3.0, 3.0, 0.0]);
        assert!(triangle_box_overlap(&edge, C, H));
    }

    #[test]
    fn separated_along_each_box_axis() {
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                let mut o = DVec3::ZERO;
                o[axis] = sign * 1.01;
                let d1 = DVec3::new(0.3, 0.2, 0.1);
                let mut d1 = d1;
                d1[axis] = 0.0;
                let mut d2 = DVec3::new(-0.2, 0.4, 0.3);
                d2[axis] = sign * 0.5;
                let tri = [o, o + d1, o + d2];
                assert!(!triangle_box_overlap(&tri, C, H), "axis {axis} sign {sign}");
                // Moving it to touch makes it overlap.
                let back = {
                    let mut b = DVec3::ZERO;
                    b[axis] = -sign * 0.01;
                    b
                };
                let touching = [tri[0] + back, tri[1] + back, tri[2] + back];
                assert!(
                    triangle_box_overlap(&touching, C, H),
                    "axis {axis} sign {sign}"
                );
            }
        }
    }

    #[test]
    fn separated_by_triangle_normal_only() {
        // Plane x + y + z = 3.01 misses the box (corner at 3) though the AABBs overlap.
        let d = 3.01;
        let tri = t([d, 0.0, 0.0], [0.0, d, 0.0], [0.0, 0.0, d]);
        assert!(!triangle_box_overlap(&tri, C, H));
        let d = 2.99;
        let tri = t([d, 0.0, 0.0], [0.0, d, 0.0], [0.0, 0.0, d]);
        assert!(triangle_box_overlap(&tri, C, H));
    }

    #[test]
    fn separated_by_edge_cross_axis_only() {
        // A triangle passing diagonally beside the box edge x = 1, y = 1 (parallel to z): the AABB
        // and plane tests both pass (plane offset 1.836 < radius 2); only Z x edge separates it.
        let e = 0.02;
        let tri2 = t(
            [0.5 + e, 1.5 + e, -0.5],
            [1.5 + e, 0.5 + e, 0.5],
            [1.6 + e, 0.6 + e, -0.4],
        );
        // The segment from (0.52,1.52) to (1.52,0.52) lies on x + y = 2.04 > 2 = max of box.
        assert!(!triangle_box_overlap(&tri2, C, H));
        let e = -0.02;
        let tri3 = t(
            [0.5 + e, 1.5 + e, -0.5],
            [1.5 + e, 0.5 + e, 0.5],
            [1.6 + e, 0.6 + e, -0.4],
        );
        assert!(triangle_box_overlap(&tri3, C, H));
    }

    #[test]
    fn edge_cross_axis_with_x_edges() {
        // Skew segment near the box edge y = 1, z = 1 (parallel to x).
        let e = 0.01;
        let tri = t(
            [-0.5, 0.5 + e, 1.5 + e],
            [0.5, 1.5 + e, 0.5 + e],
            [0.4, 1.5 + e, 0.6 + e],
        );
        assert!(!triangle_box_overlap(&tri, C, H));
        let e = -0.01;
        let tri = t(
            [-0.5, 0.5 + e, 1.5 + e],
            [0.5, 1.5 + e, 0.5 + e],
            [0.4, 1.5 + e, 0.6 + e],
        );
        assert!(triangle_box_overlap(&tri, C, H));
    }

    #[test]
    fn degenerate_triangles() {
        // A segment crossing the box.
        let seg = t([-2.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 0.0]);
        assert!(triangle_box_overlap(&seg, C, H));
        // A point outside.
        let p = t([1.5, 0.0, 0.0], [1.5, 0.0, 0.0], [1.5, 0.0, 0.0]);
        assert!(!triangle_box_overlap(&p, C, H));
        // A segment passing diagonally outside the corner.
        let seg = t([2.1, 0.0, 0.0], [0.0, 2.1, 0.0], [0.0, 2.1, 0.0]);
        assert!(!triangle_box_overlap(&seg, C, H));
    }

    /// Exact oracle: clip the triangle by the six closed half-spaces of the box (Sutherland-Hodgman)
    /// and report whether anything is left.
    fn clip_overlap(tri: &[DVec3; 3], c: DVec3, h: DVec3) -> bool {
        let mut poly: Vec<DVec3> = tri.to_vec();
        for axis in 0..3 {
            for sign in [-1.0, 1.0] {
                // Keep points with sign * (p - c)[axis] <= h[axis].
                let f = |p: DVec3| sign * (p - c)[axis] - h[axis];
                let mut out = Vec::new();
                for i in 0..poly.len() {
                    let a = poly[i];
                    let b = poly[(i + 1) % poly.len()];
                    let (fa, fb) = (f(a), f(b));
                    if fa <= 0.0 {
                        out.push(a);
                    }
                    if (fa < 0.0 && fb > 0.0) || (fa > 0.0 && fb < 0.0) {
                        out.push(a + (b - a) * (fa / (fa - fb)));
                    }
                }
                poly = out;
                if poly.is_empty() {
                    return false;
                }
            }
        }
        true
    }

    #[test]
    fn agrees_with_clipping_oracle_on_random_triangles() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut hits = 0;
        for _ in 0..20_000 {
            let centre = DVec3::new(
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
            );
            let scale = rng.gen_range(0.05..3.0);
            let mut p = || {
                centre
                    + scale
                        * DVec3::new(
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(-1.0..1.0),
                            rng.gen_range(-1.0..1.0),
                        )
            };
            let tri = [p(), p(), p()];
            let expect = clip_overlap(&tri, C, H);
            hits += expect as u32;
            assert_eq!(triangle_box_overlap(&tri, C, H), expect, "{tri:?}");
        }
        // Both outcomes are well represented.
        assert!(hits > 3000 && hits < 17000, "{hits}");
    }

    #[test]
    fn non_cubic_offset_box() {
        let c = DVec3::new(10.0, -5.0, 2.0);
        let h = DVec3::new(0.5, 2.0, 0.1);
        let tri = t([10.4, -6.9, 2.05], [10.4, -6.9, 3.0], [11.0, -7.5, 2.0]);
        assert!(triangle_box_overlap(&tri, c, h));
        let tri = t([10.4, -7.1, 2.05], [10.4, -7.1, 3.0], [11.0, -7.5, 2.0]);
        assert!(!triangle_box_overlap(&tri, c, h));
    }
}
