//! The distance between two triangles and the two points that realise it: 0 when they touch or
//! cross, else the least of the six corner-to-face and nine edge-to-edge distances (for two
//! disjoint triangles the nearest pair lies on one of those features). Segment closest points
//! after Ericson, Real-Time Collision Detection §5.1.9. Pure, no allocation; metres.

use crate::closest_point::closest_point;
use glam::DVec3;

/// The nearest pair of points of two triangles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrianglePair {
    /// Distance between the two triangles (m, ≥ 0; 0 when they touch or cross).
    pub distance: f64,
    /// The point of the first triangle nearest to the second (m).
    pub on_first: DVec3,
    /// The point of the second triangle nearest to the first (m; equal to `on_first` when they
    /// cross).
    pub on_second: DVec3,
}

/// The nearest points of segments `p0 p1` and `q0 q1` (either may be a single point).
pub fn segment_closest_points(p0: DVec3, p1: DVec3, q0: DVec3, q1: DVec3) -> (DVec3, DVec3) {
    let d1 = p1 - p0;
    let d2 = q1 - q0;
    let r = p0 - q0;
    let a = d1.length_squared();
    let e = d2.length_squared();
    let f = d2.dot(r);
    let tiny = f64::MIN_POSITIVE;
    let (s, t) = if a <= tiny && e <= tiny {
        (0.0, 0.0)
    } else if a <= tiny {
        (0.0, (f / e).clamp(0.0, 1.0))
    } else {
        let c = d1.dot(r);
        if e <= tiny {
            ((-c / a).clamp(0.0, 1.0), 0.0)
        } else {
            let b = d1.dot(d2);
            let denom = a * e - b * b;
            let mut s = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let mut t = (b * s + f) / e;
            if t < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            }
            (s, t)
        }
    };
    (p0 + d1 * s, q0 + d2 * t)
}

/// Where segment `p0 p1` meets triangle `t` (its plane crossed between the ends, or the segment
/// lying in the plane and touching the triangle is left to the edge–edge test), if it does.
fn segment_hits_triangle(p0: DVec3, p1: DVec3, t: &[DVec3; 3]) -> Option<DVec3> {
    let [a, b, c] = *t;
    let n = (b - a).cross(c - a);
    if n.length_squared() <= f64::MIN_POSITIVE {
        return None;
    }
    let s0 = n.dot(p0 - a);
    let s1 = n.dot(p1 - a);
    if (s0 > 0.0 && s1 > 0.0) || (s0 < 0.0 && s1 < 0.0) || s0 == s1 {
        return None;
    }
    let x = p0 + (p1 - p0) * (s0 / (s0 - s1));
    // Inside test by the signs of the three sub-triangle normals along n.
    let inside = [(a, b), (b, c), (c, a)]
        .iter()
        .all(|&(u, v)| (v - u).cross(x - u).dot(n) >= 0.0);
    inside.then_some(x)
}

/// The distance between triangles `s` and `t` and the points realising it. Degenerate triangles
/// (segments, points) are handled as the point sets they are.
pub fn triangle_distance(s: &[DVec3; 3], t: &[DVec3; 3]) -> TrianglePair {
    for (first, second) in [(s, t), (t, s)] {
        for k in 0..3 {
            if let Some(x) = segment_hits_triangle(first[k], first[(k + 1) % 3], second) {
                return TrianglePair {
                    distance: 0.0,
                    on_first: x,
                    on_second: x,
                };
            }
        }
    }
    let mut best = TrianglePair {
        distance: f64::INFINITY,
        on_first: s[0],
        on_second: t[0],
    };
    let mut consider = |on_first: DVec3, on_second: DVec3| {
        let d = on_first.distance(on_second);
        if d < best.distance {
            best = TrianglePair {
                distance: d,
                on_first,
                on_second,
            };
        }
    };
    for &p in s {
        consider(p, closest_point(p, t).0);
    }
    for &q in t {
        consider(closest_point(q, s).0, q);
    }
    for i in 0..3 {
        for j in 0..3 {
            let (a, b) = segment_closest_points(s[i], s[(i + 1) % 3], t[j], t[(j + 1) % 3]);
            consider(a, b);
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the least distance between dense samples of the two triangles (an upper
    /// bound on the true distance, close to it for fine sampling).
    fn sampled(s: &[DVec3; 3], t: &[DVec3; 3], n: usize) -> f64 {
        let points = |tri: &[DVec3; 3]| {
            let mut v = Vec::new();
            for i in 0..=n {
                for j in 0..=(n - i) {
                    let (u, w) = (i as f64 / n as f64, j as f64 / n as f64);
                    v.push(tri[0] + (tri[1] - tri[0]) * u + (tri[2] - tri[0]) * w);
                }
            }
            v
        };
        let (ps, pt) = (points(s), points(t));
        let mut best = f64::INFINITY;
        for p in &ps {
            for q in &pt {
                best = best.min(p.distance(*q));
            }
        }
        best
    }

    fn tri(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [DVec3; 3] {
        [a.into(), b.into(), c.into()]
    }

    #[test]
    fn parallel_faces_are_their_gap_apart() {
        let s = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let t = tri([0.1, 0.1, 0.25], [0.6, 0.1, 0.25], [0.1, 0.6, 0.25]);
        let pair = triangle_distance(&s, &t);
        assert!((pair.distance - 0.25).abs() < 1e-15, "{pair:?}");
        assert!((pair.on_first.distance(pair.on_second) - pair.distance).abs() < 1e-15);
    }

    #[test]
    fn crossing_triangles_are_zero_apart() {
        let s = tri([0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let t = tri([0.2, 0.2, -0.5], [0.2, 0.2, 0.5], [0.3, 0.25, 0.5]);
        let pair = triangle_distance(&s, &t);
        assert_eq!(pair.distance, 0.0);
        assert!(pair.on_first.z.abs() < 1e-15);
    }

    #[test]
    fn skew_edges_meet_at_their_common_perpendicular() {
        // Edge along x at z = 0, edge along y at z = 0.3: distance 0.3 between the edges.
        let s = tri([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, -1.0]);
        let t = tri([0.0, -1.0, 0.3], [0.0, 1.0, 0.3], [1.0, 0.0, 1.3]);
        let pair = triangle_distance(&s, &t);
        assert!((pair.distance - 0.3).abs() < 1e-12, "{pair:?}");
    }

    #[test]
    fn agrees_with_dense_sampling_on_a_scatter_of_pairs() {
        let mut x = 0.123_f64;
        let mut next = move || {
            x = (x * 997.0 + 0.377).fract();
            x * 2.0 - 1.0
        };
        for _ in 0..200 {
            let mut v = [[0.0; 3]; 6];
            for p in &mut v {
                *p = [next(), next(), next()];
            }
            let s = tri(v[0], v[1], v[2]);
            let mut t = tri(v[3], v[4], v[5]);
            let shift = DVec3::new(next(), next(), next()) * 0.8;
            t.iter_mut().for_each(|p| *p += shift);
            let exact = triangle_distance(&s, &t);
            let brute = sampled(&s, &t, 40);
            assert!(exact.distance <= brute + 1e-12, "{exact:?} vs {brute}");
            // Samples 1/40 of each edge apart are within that spacing of any point.
            let spacing = s
                .iter()
                .chain(t.iter())
                .map(|p| p.length())
                .fold(0.0, f64::max)
                * 2.0
                / 40.0;
            assert!(
                brute - exact.distance <= 2.0 * spacing,
                "{exact:?} vs {brute}"
            );
            assert!(
                (exact.on_first.distance(exact.on_second) - exact.distance).abs() < 1e-12,
                "{exact:?}"
            );
        }
    }

    #[test]
    fn degenerate_triangles_are_their_point_sets() {
        let point = tri([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]);
        let face = tri([-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [0.0, 1.0, 0.0]);
        assert!((triangle_distance(&point, &face).distance - 1.0).abs() < 1e-15);
        let segment = tri([2.0, 0.0, 0.0], [3.0, 0.0, 0.0], [2.5, 0.0, 0.0]);
        // (2, 0) to the edge from (1, −1) to (0, 1): 3/√5.
        let expected = 3.0 / 5f64.sqrt();
        assert!((triangle_distance(&segment, &face).distance - expected).abs() < 1e-12);
    }
}
