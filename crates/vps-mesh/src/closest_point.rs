//! Closest point on a triangle (Ericson, Real-Time Collision Detection §5.1.5) and the feature of
//! the triangle it lies on (the exact reference uses it to pick the pseudo-normal for the sign; the
//! exact-surface point shell uses the point alone). Pure, no allocation.

use glam::DVec3;

/// The part of a triangle `[a, b, c]` a closest point lies on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Feature {
    /// Corner `k` (0 = a, 1 = b, 2 = c).
    Vertex(u8),
    /// Edge `k` from corner `k` to corner `(k + 1) % 3`.
    Edge(u8),
    /// The interior of the face.
    Face,
}

/// The point of triangle `t` nearest to `p` and the feature it lies on. Degenerate triangles, and
/// slivers whose angle at the first corner has a sine under 1e-8 (their plane is mostly
/// rounding, and the region tests below can then pick the wrong edge), give the nearest point of
/// their three edges (at most 1e-8 of their size from the exact answer).
pub fn closest_point(p: DVec3, t: &[DVec3; 3]) -> (DVec3, Feature) {
    let [a, b, c] = *t;
    let ab = b - a;
    let ac = c - a;
    if ab.cross(ac).length_squared() <= 1e-16 * ab.length_squared() * ac.length_squared() {
        return nearest_edge_point(p, t);
    }
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (a, Feature::Vertex(0));
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (b, Feature::Vertex(1));
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (a + ab * v, Feature::Edge(0));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (c, Feature::Vertex(2));
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (a + ac * w, Feature::Edge(2));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (b + (c - b) * w, Feature::Edge(1));
    }
    let denom = va + vb + vc;
    if denom.abs() <= f64::MIN_POSITIVE || !denom.is_finite() {
        // Degenerate (zero-area) triangle that fell through: nearest of its three edges.
        return nearest_edge_point(p, t);
    }
    let v = vb / denom;
    let w = vc / denom;
    (a + ab * v + ac * w, Feature::Face)
}

/// Nearest point on the three edges of `t` (for degenerate triangles).
fn nearest_edge_point(p: DVec3, t: &[DVec3; 3]) -> (DVec3, Feature) {
    (0..3u8)
        .map(|k| {
            let (a, b) = (t[k as usize], t[(k as usize + 1) % 3]);
            let ab = b - a;
            let len_sq = ab.length_squared();
            let s = if len_sq > 0.0 {
                ((p - a).dot(ab) / len_sq).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (a + ab * s, Feature::Edge(k))
        })
        .min_by(|x, y| x.0.distance_squared(p).total_cmp(&y.0.distance_squared(p)))
        .expect("three edges")
}

#[cfg(test)]
mod tests {
    use super::*;

    const T: [DVec3; 3] = [
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
    ];

    #[test]
    fn regions() {
        let cases = [
            (
                DVec3::new(0.2, 0.2, 1.0),
                DVec3::new(0.2, 0.2, 0.0),
                Feature::Face,
            ),
            (DVec3::new(-1.0, -1.0, 0.5), T[0], Feature::Vertex(0)),
            (DVec3::new(2.0, -0.1, 0.0), T[1], Feature::Vertex(1)),
            (DVec3::new(-0.1, 3.0, 0.0), T[2], Feature::Vertex(2)),
            (
                DVec3::new(0.5, -1.0, 0.0),
                DVec3::new(0.5, 0.0, 0.0),
                Feature::Edge(0),
            ),
            (
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.5, 0.5, 0.0),
                Feature::Edge(1),
            ),
            (
                DVec3::new(-2.0, 0.5, 0.3),
                DVec3::new(0.0, 0.5, 0.0),
                Feature::Edge(2),
            ),
        ];
        for (p, q, f) in cases {
            let (got, feature) = closest_point(p, &T);
            assert!(got.distance(q) < 1e-12, "{p}: {got} != {q}");
            assert_eq!(feature, f, "{p}");
        }
    }

    #[test]
    fn degenerate_triangle_gives_a_point_on_it() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        let (q, _) = closest_point(DVec3::new(1.5, 1.0, 0.0), &t);
        assert!(q.distance(DVec3::new(1.5, 0.0, 0.0)) < 1e-12);
    }

    /// A nearly collinear triangle (its third corner on the line of the first two, up to
    /// rounding): the point is on its longest edge, as far as the exact answer. Ericson's region
    /// tests alone took a point 1.5e-7 m too far here (found by the band builder's row test).
    #[test]
    fn a_nearly_collinear_triangle_gives_its_nearest_edge_point() {
        let t = [
            DVec3::new(
                -0.0037758233236668427,
                0.008639226885069374,
                0.0017712684234451413,
            ),
            DVec3::new(
                -0.002309511434553357,
                0.007391831436921464,
                -0.008562242787077175,
            ),
            DVec3::new(
                -0.0008431995454398714,
                0.0061444359887735545,
                -0.01889575399759949,
            ),
        ];
        let p = DVec3::new(0.035, -0.0026812370720094153, -0.0004155002841900665);
        let ac = t[2] - t[0];
        let along = ((p - t[0]).dot(ac) / ac.length_squared()).clamp(0.0, 1.0);
        let exact = (t[0] + ac * along).distance(p);
        let (q, feature) = closest_point(p, &t);
        assert!(
            (q.distance(p) - exact).abs() < 1e-12,
            "{} against {exact}",
            q.distance(p)
        );
        assert!(matches!(feature, Feature::Edge(_)), "{feature:?}");
    }

    /// No sampled point of a random triangle is closer than the returned one.
    #[test]
    fn no_sampled_point_is_closer() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut r = || {
            DVec3::new(
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
                rng.gen_range(-2.0..2.0),
            )
        };
        for _ in 0..200 {
            let t = [r(), r(), r()];
            let p = r();
            let d = closest_point(p, &t).0.distance(p);
            for i in 0..=20 {
                for j in 0..=(20 - i) {
                    let (u, v) = (i as f64 / 20.0, j as f64 / 20.0);
                    let s = t[0] + (t[1] - t[0]) * u + (t[2] - t[0]) * v;
                    assert!(s.distance(p) >= d - 1e-12);
                }
            }
        }
    }
}
