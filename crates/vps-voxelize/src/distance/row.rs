//! Squared distances from a row of samples (a line along x) to one triangle, written without
//! branches so that the compiler computes several samples per instruction: the band builder's
//! inner loop. The band takes its distances from the exact closest point of the triangle each
//! sample keeps ([`vps_mesh::closest_point`]); these only choose that triangle.

use glam::DVec3;

/// A triangle prepared for rows of samples. Pure, no allocation.
#[derive(Clone, Debug)]
pub(super) struct RowTriangle {
    /// Corners (m).
    corner: [DVec3; 3],
    /// Edge `k`, from corner `k` to corner `k + 1` (m).
    edge: [DVec3; 3],
    /// `1 / |edge k|²` (1/m²; 0 for a zero-length edge).
    inverse_length_sq: [f64; 3],
    /// `|edge k|²` (m²).
    length_sq: [f64; 3],
    /// Edge `k`'s in-plane normal pointing into the triangle (`n × edge k`, `n` the plane's
    /// unnormalised normal; zero for a degenerate triangle).
    inward: [DVec3; 3],
    /// The plane's unit normal (zero for a degenerate triangle).
    unit_normal: DVec3,
    /// Whether the triangle has no area, or so little that it counts as its edges (no inside:
    /// the nearest point is on an edge).
    degenerate: bool,
}

impl RowTriangle {
    /// The triangle `[a, b, c]` (m).
    pub(super) fn new(corner: [DVec3; 3]) -> RowTriangle {
        let edge = [0, 1, 2].map(|k| corner[(k + 1) % 3] - corner[k]);
        let normal = edge[0].cross(corner[2] - corner[0]);
        let length_sq = edge.map(|e| e.length_squared());
        // A sliver whose angle's sine is under 1e-8 counts as its three edges (at most 1e-8 of
        // its size away): its plane's direction would be mostly rounding.
        let degenerate = normal.length_squared() <= 1e-16 * length_sq[0] * length_sq[2];
        let unit_normal = if degenerate {
            DVec3::ZERO
        } else {
            normal.normalize_or_zero()
        };
        RowTriangle {
            corner,
            edge,
            inverse_length_sq: length_sq.map(|l| if l > 0.0 { 1.0 / l } else { 0.0 }),
            length_sq,
            inward: edge.map(|e| {
                if degenerate {
                    DVec3::ZERO
                } else {
                    normal.cross(e)
                }
            }),
            unit_normal,
            degenerate,
        }
    }

    /// The squared distance (m²) from each sample `(xs[i], y, z)` (m) to the triangle, into
    /// `out[i]`: the squared distance to its plane where the sample projects inside it, else to
    /// the nearest of its three edges. Agrees with the exact closest point's distance to within
    /// 2e-8 of the distance to the farthest corner (rounding, and slivers taken as their edges:
    /// a code is 1/64 of a voxel). The same bits whatever
    /// the instruction set it is compiled for (no fused multiply-add). Pure, no allocation.
    #[inline(always)]
    /// Only the groups of [`LANES`] samples that hold one of `first..=last` are computed (the
    /// others of `out` keep their values).
    pub(super) fn distances_sq(
        &self,
        y: f64,
        z: f64,
        xs: &[f64; ROW],
        (first, last): (usize, usize),
        out: &mut [f64; ROW],
    ) {
        // Everything that does not depend on x, per corner k: the rest of (p − corner k) · w for
        // the edge, the inward normal and (corner 0) the plane normal, and |p − corner k|² but x.
        let mut along = [0.0; 3];
        let mut across = [0.0; 3];
        let mut rest_sq = [0.0; 3];
        for k in 0..3 {
            let (dy, dz) = (y - self.corner[k].y, z - self.corner[k].z);
            along[k] = self.edge[k].y * dy + self.edge[k].z * dz;
            across[k] = self.inward[k].y * dy + self.inward[k].z * dz;
            rest_sq[k] = dy * dy + dz * dz;
        }
        if self.degenerate {
            // No inside: one side test always fails.
            across[0] = -1.0;
        }
        let height_rest = self.unit_normal.y * (y - self.corner[0].y)
            + self.unit_normal.z * (z - self.corner[0].z);
        // In groups of LANES samples, each step one operation on every lane.
        let groups = first / LANES..last / LANES + 1;
        for (xs, out) in xs
            .chunks_exact(LANES)
            .zip(out.chunks_exact_mut(LANES))
            .take(groups.end)
            .skip(groups.start)
        {
            let mut edge_sq = [f64::INFINITY; LANES];
            // The least of the three side tests: the sample projects inside when it is ≥ 0.
            let mut side = [f64::INFINITY; LANES];
            for k in 0..3 {
                for j in 0..LANES {
                    let dx = xs[j] - self.corner[k].x;
                    let q = self.edge[k].x * dx + along[k];
                    let t = clamp01(q * self.inverse_length_sq[k]);
                    let to_edge_sq = dx * dx + rest_sq[k] - t * (2.0 * q - t * self.length_sq[k]);
                    edge_sq[j] = min(edge_sq[j], to_edge_sq);
                    side[j] = min(side[j], self.inward[k].x * dx + across[k]);
                }
            }
            for j in 0..LANES {
                let height = self.unit_normal.x * (xs[j] - self.corner[0].x) + height_rest;
                let plane_sq = height * height;
                out[j] = max(if side[j] >= 0.0 { plane_sq } else { edge_sq[j] }, 0.0);
            }
        }
    }
}

/// Samples computed together: four `f64` lanes (one AVX2 register, two SSE2 registers).
const LANES: usize = 4;

/// Samples of a row, padded to whole groups of [`LANES`] (a band cube's row is 9 samples).
pub(super) const ROW: usize = 12;

/// `a.min(b)` for numbers that are not NaN, as one instruction.
#[inline(always)]
fn min(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// `a.max(b)` for numbers that are not NaN, as one instruction.
#[inline(always)]
fn max(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

/// `v` clamped to `0..=1` (not NaN).
#[inline(always)]
fn clamp01(v: f64) -> f64 {
    min(max(v, 0.0), 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use vps_mesh::closest_point::closest_point;

    /// The point of segment `a`–`b` nearest to `p`.
    fn nearest_on_segment(p: DVec3, a: DVec3, b: DVec3) -> DVec3 {
        let ab = b - a;
        let along = if ab == DVec3::ZERO {
            0.0
        } else {
            ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0)
        };
        a + ab * along
    }

    /// Against the exact closest point, on random triangles (slivers, zero-length edges and
    /// degenerate ones included) and rows of samples around them.
    #[test]
    fn the_row_distances_are_the_closest_points_distances() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut random = |scale: f64| {
            DVec3::new(
                rng.gen_range(-scale..scale),
                rng.gen_range(-scale..scale),
                rng.gen_range(-scale..scale),
            )
        };
        let mut checked = 0;
        for case in 0..3_000 {
            let a = random(0.01);
            let mut tri = [a, random(0.01), random(0.01)];
            match case % 6 {
                // A sliver, a repeated corner, three corners on a line.
                3 => tri[2] = tri[0] + (tri[1] - tri[0]) * 0.5 + random(1e-9),
                4 => tri[2] = tri[1],
                5 => tri[2] = tri[0] + (tri[1] - tri[0]) * 2.0,
                _ => {}
            }
            let row = RowTriangle::new(tri);
            let (y, z) = (random(0.02).y, random(0.02).z);
            let xs: [f64; ROW] = std::array::from_fn(|i| -0.02 + 0.005 * i as f64);
            let mut out = [0.0; ROW];
            row.distances_sq(y, z, &xs, (0, ROW - 1), &mut out);
            for (x, d_sq) in xs.iter().zip(out) {
                let p = DVec3::new(*x, y, z);
                // Ericson's closest point, or a nearer point of an edge: on a nearly degenerate
                // triangle its region tests can miss the nearest edge.
                let exact = (0..3)
                    .map(|k| nearest_on_segment(p, tri[k], tri[(k + 1) % 3]).distance_squared(p))
                    .fold(closest_point(p, &tri).0.distance_squared(p), f64::min);
                let scale = tri.iter().map(|c| c.distance(p)).fold(0.0, f64::max);
                assert!(
                    (d_sq.sqrt() - exact.sqrt()).abs() <= 2e-8 * scale,
                    "case {case}: triangle {tri:?}, p {p}: row {d_sq}, exact {exact}"
                );
                checked += 1;
            }
        }
        assert_eq!(checked, 3_000 * ROW);
    }
}
