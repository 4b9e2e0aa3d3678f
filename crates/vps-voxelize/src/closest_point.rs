//! Closest point on a triangle to a point (Ericson, "Real-Time Collision Detection", §5.1.5).

use glam::DVec3;

/// The point of the closed triangle `abc` nearest to `p`. Works for degenerate triangles (returns a
/// point of the degenerate segment or point). Pure, no allocation.
pub(crate) fn closest_point_on_triangle(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
    let ab = b - a;
    let ac = c - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        // Degenerate triangle reaching this branch: fall back to the nearest vertex.
        return [a, b, c]
            .into_iter()
            .min_by(|x, y| x.distance_squared(p).total_cmp(&y.distance_squared(p)))
            .unwrap_or(a);
    }
    let v = vb / denom;
    let w = vc / denom;
    a + ab * v + ac * w
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regions_and_brute_force() {
        use rand::{Rng, SeedableRng};
        let tri = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        assert_eq!(
            closest_point_on_triangle(DVec3::new(0.5, 0.25, 3.0), tri),
            DVec3::new(0.5, 0.25, 0.0)
        );
        assert_eq!(
            closest_point_on_triangle(DVec3::new(-1.0, -1.0, 0.0), tri),
            DVec3::ZERO
        );
        assert_eq!(
            closest_point_on_triangle(DVec3::new(1.0, -1.0, 1.0), tri),
            DVec3::new(1.0, 0.0, 0.0)
        );
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
            let q = closest_point_on_triangle(p, t);
            // No sampled point of the triangle is closer.
            let d = q.distance(p);
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
