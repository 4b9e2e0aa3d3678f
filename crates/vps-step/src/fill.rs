//! Faces truck's tessellator leaves empty, laid out by vps: a face whose boundary is a rectangle
//! in its surface's parameters.
//!
//! truck-meshalgo 0.4 returns no triangles for some faces it cannot lay out: a cone running to its
//! apex, a whole torus, some spherical patches. Those faces are usually the simplest of a B-rep:
//! bounded by seam edges and whole circles, their boundary in (u, v) is a rectangle, one side of
//! which may shrink to a point (the apex). [`rectangle_face`] lays such a face out from the
//! polylines truck already made of its edges (so its triangles meet the neighbouring faces' at
//! the same points and the shell stays closed): the boundary's points are placed in (u, v)
//! (periodic parameters unwrapped along the loop; a point where the surface is singular, like an
//! apex, taken twice, at its two neighbours' free parameter); two opposite sides whose points lie
//! at the same levels give the rows, every other row is the surface sampled at those levels and
//! at the parameters of the denser of the two other sides, and consecutive rows are zipped into
//! triangles. A face whose boundary is not such a rectangle is left empty (and the solid refused
//! as before).

use glam::DVec3;
use truck_meshalgo::prelude::*;

/// Points of a boundary loop closer than this fraction of a side's parameter range to it lie on
/// it; levels of opposite sides closer than this are the same.
const SIDE_EPS: f64 = 1e-6;

/// A point of the boundary (or of the layout) with its parameters.
#[derive(Clone, Copy, Debug)]
struct Placed {
    uv: [f64; 2],
    point: DVec3,
}

/// The triangles (counter-clockwise in (u, v); the caller orients them against the neighbouring
/// faces) of a face on `surface` whose boundary is `boundary` (one closed loop of points, the
/// last not repeating the first), or `None` when the boundary is not a rectangle in (u, v), a
/// point cannot be placed on the surface, or the layout would take more than `max_triangles`
/// triangles (counted before any is made). Evaluates the surface about once per triangle.
pub(crate) fn rectangle_face<S>(
    surface: &S,
    boundary: &[DVec3],
    max_triangles: usize,
) -> Option<Vec<[DVec3; 3]>>
where
    S: ParametricSurface3D + SearchNearestParameter<D2, Point = Point3>,
{
    let placed = place(surface, boundary)?;
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for p in &placed {
        for a in 0..2 {
            lo[a] = lo[a].min(p.uv[a]);
            hi[a] = hi[a].max(p.uv[a]);
        }
    }
    let range = [hi[0] - lo[0], hi[1] - lo[1]];
    if !(range[0] > 0.0 && range[1] > 0.0) {
        return None;
    }
    let on = |p: &Placed, axis: usize, high: bool| {
        let side = if high { hi[axis] } else { lo[axis] };
        (p.uv[axis] - side).abs() <= SIDE_EPS * range[axis]
    };
    if !runs_round_once(&placed, lo, hi) {
        return None;
    }
    // Rows across `axis`: the two sides at its ends; the other two sides must have their points
    // at the same levels of `axis`.
    for axis in 0..2 {
        let other = 1 - axis;
        let side = |high: bool, along: usize, across: usize| -> Vec<Placed> {
            let mut s: Vec<Placed> = placed
                .iter()
                .filter(|p| on(p, across, high))
                .copied()
                .collect();
            s.sort_by(|a, b| a.uv[along].total_cmp(&b.uv[along]));
            s
        };
        // The sides at the ends of `other` run along `axis`: their points are the levels.
        let first = side(false, axis, other);
        let last = side(true, axis, other);
        if first.len() != last.len()
            || first.len() < 2
            || first
                .iter()
                .zip(&last)
                .any(|(a, b)| (a.uv[axis] - b.uv[axis]).abs() > SIDE_EPS * range[axis])
        {
            continue;
        }
        // The rows: the sides at the ends of `axis`, running along `other`.
        let bottom = side(false, other, axis);
        let top = side(true, other, axis);
        if bottom.len() < 2 || top.len() < 2 {
            continue;
        }
        // Each strip between rows has at most as many triangles as its two rows have points.
        let widest = bottom.len().max(top.len()) as u64;
        if (first.len() as u64).saturating_mul(2 * widest) > max_triangles as u64 {
            return None;
        }
        let columns: Vec<f64> = if bottom.len() >= top.len() {
            bottom.iter().map(|p| p.uv[other]).collect()
        } else {
            top.iter().map(|p| p.uv[other]).collect()
        };
        let mut rows: Vec<Vec<Placed>> = vec![bottom];
        for level in 1..first.len() - 1 {
            let at = first[level].uv[axis];
            let mut row = vec![first[level]];
            for &c in &columns[1..columns.len() - 1] {
                let mut uv = [0.0; 2];
                uv[axis] = at;
                uv[other] = c;
                let p = surface.subs(uv[0], uv[1]);
                row.push(Placed {
                    uv,
                    point: DVec3::new(p.x, p.y, p.z),
                });
            }
            row.push(last[level]);
            rows.push(row);
        }
        rows.push(top);
        let mut triangles = Vec::new();
        for pair in rows.windows(2) {
            zip_rows(&pair[0], &pair[1], other, &mut triangles);
        }
        // Counter-clockwise in (u, v): the rows run along `other` and rise along `axis`, which is
        // clockwise when `other` is v.
        if other == 1 {
            for t in &mut triangles {
                t.swap(1, 2);
            }
        }
        return Some(triangles);
    }
    None
}

/// Whether every point of the loop `placed` lies on a side of the rectangle `lo`..`hi` and the
/// loop goes round the rectangle's perimeter once, in one direction, never turning back: only
/// then is the face the whole rectangle.
fn runs_round_once(placed: &[Placed], lo: [f64; 2], hi: [f64; 2]) -> bool {
    let range = [hi[0] - lo[0], hi[1] - lo[1]];
    let perimeter = 2.0 * (range[0] + range[1]);
    let near = |x: f64, side: f64, axis: usize| (x - side).abs() <= SIDE_EPS * range[axis];
    // Distance along the perimeter from (lo, lo), counter-clockwise in (u, v); `None` off the
    // sides.
    let at = |p: &Placed| {
        let [u, v] = p.uv;
        if near(v, lo[1], 1) {
            Some(u - lo[0])
        } else if near(u, hi[0], 0) {
            Some(range[0] + (v - lo[1]))
        } else if near(v, hi[1], 1) {
            Some(range[0] + range[1] + (hi[0] - u))
        } else if near(u, lo[0], 0) {
            Some(2.0 * range[0] + range[1] + (hi[1] - v))
        } else {
            None
        }
    };
    let Some(along) = placed.iter().map(at).collect::<Option<Vec<f64>>>() else {
        return false;
    };
    let (mut forward, mut backward) = (0.0, 0.0);
    for (i, s) in along.iter().enumerate() {
        let step = along[(i + 1) % along.len()] - s;
        forward += step.rem_euclid(perimeter);
        backward += (-step).rem_euclid(perimeter);
    }
    let once = |total: f64| (total - perimeter).abs() <= 1e-6 * perimeter;
    once(forward) || once(backward)
}

/// Triangles between row `a` and the next row `b` (both sorted along `along`), each point joined
/// to the nearest of the other row as the parameter advances.
fn zip_rows(a: &[Placed], b: &[Placed], along: usize, out: &mut Vec<[DVec3; 3]>) {
    let (mut i, mut j) = (0, 0);
    while i + 1 < a.len() || j + 1 < b.len() {
        let advance_a =
            j + 1 >= b.len() || (i + 1 < a.len() && a[i + 1].uv[along] <= b[j + 1].uv[along]);
        if advance_a {
            out.push([a[i].point, a[i + 1].point, b[j].point]);
            i += 1;
        } else {
            out.push([a[i].point, b[j + 1].point, b[j].point]);
            j += 1;
        }
    }
}

/// The boundary's points with their parameters: found on the surface, periodic ones unwrapped
/// along the loop, and a point where the surface is singular (one parameter free, like an apex)
/// taken twice, with the free parameter of the point before it and of the point after it.
fn place<S>(surface: &S, boundary: &[DVec3]) -> Option<Vec<Placed>>
where
    S: ParametricSurface3D + SearchNearestParameter<D2, Point = Point3>,
{
    let n = boundary.len();
    if n < 3 {
        return None;
    }
    let periods = [surface.u_period(), surface.v_period()];
    let scale = boundary
        .iter()
        .fold(0.0f64, |m, p| m.max((*p - boundary[0]).length()))
        .max(f64::MIN_POSITIVE);
    // Per point: its parameters, and which parameter is free there (None: regular).
    let mut found: Vec<([f64; 2], Option<usize>)> = Vec::with_capacity(n);
    let mut hint: Option<(f64, f64)> = None;
    for p in boundary {
        let point = Point3::new(p.x, p.y, p.z);
        let uv = match hint {
            Some(h) => surface
                .search_nearest_parameter(point, h, 100)
                .or_else(|| surface.search_nearest_parameter(point, SPHint2D::None, 100)),
            None => surface.search_nearest_parameter(point, SPHint2D::None, 100),
        }?;
        let at = surface.subs(uv.0, uv.1);
        if (DVec3::new(at.x, at.y, at.z) - *p).length() > 1e-6 * scale {
            return None;
        }
        let ders = [surface.uder(uv.0, uv.1), surface.vder(uv.0, uv.1)];
        let lengths = ders.map(|d| d.magnitude());
        let longest = lengths[0].max(lengths[1]);
        let free = (0..2).find(|&a| lengths[a] <= 1e-9 * longest.max(1e-300));
        let mut uv = [uv.0, uv.1];
        // Unwrap against the last regular point.
        if let Some(&(prev, _)) = found.iter().rev().find(|f| f.1.is_none()) {
            for a in 0..2 {
                if let Some(period) = periods[a] {
                    uv[a] += ((prev[a] - uv[a]) / period).round() * period;
                }
            }
        }
        hint = Some((uv[0], uv[1]));
        found.push((uv, free));
    }
    let regular: Vec<usize> = (0..n).filter(|&i| found[i].1.is_none()).collect();
    if regular.len() < 2 {
        return None;
    }
    let mut placed = Vec::with_capacity(n + 2);
    for i in 0..n {
        let (uv, free) = found[i];
        match free {
            None => placed.push(Placed {
                uv,
                point: boundary[i],
            }),
            Some(a) => {
                // The regular neighbours before and after it, cyclically.
                let before = (1..n)
                    .map(|k| (i + n - k) % n)
                    .find(|&k| found[k].1.is_none())?;
                let after = (1..n)
                    .map(|k| (i + k) % n)
                    .find(|&k| found[k].1.is_none())?;
                for k in [before, after] {
                    let mut at = uv;
                    at[a] = found[k].0[a];
                    placed.push(Placed {
                        uv: at,
                        point: boundary[i],
                    });
                }
            }
        }
    }
    Some(placed)
}

#[cfg(test)]
mod tests {
    use super::*;
    use truck_stepio::r#in::alias::re_exports::Plane;

    fn placed(t: f64, level: f64) -> Placed {
        Placed {
            uv: [t, level],
            point: DVec3::new(t, level, 0.0),
        }
    }

    /// Rows of 3 and 5 points give 3 + 5 − 2 = 6 triangles covering the strip, each
    /// counter-clockwise in (t, level), with no overlap: their areas add up to the strip's.
    #[test]
    fn zipped_rows_cover_the_strip_once() {
        let a: Vec<Placed> = [0.0, 0.5, 1.0].map(|t| placed(t, 0.0)).to_vec();
        let b: Vec<Placed> = [0.0, 0.2, 0.45, 0.8, 1.0].map(|t| placed(t, 1.0)).to_vec();
        let mut out = Vec::new();
        zip_rows(&a, &b, 0, &mut out);
        assert_eq!(out.len(), 6);
        let mut area = 0.0;
        for [p, q, r] in &out {
            let signed = 0.5 * (q - p).cross(r - p).z;
            assert!(signed > 0.0, "{signed}");
            area += signed;
        }
        assert!((area - 1.0).abs() < 1e-12, "{area}");
    }

    /// A square face on a plane is laid out and covers its area; a triangle is not a rectangle in
    /// (u, v) and is left to the caller.
    #[test]
    fn a_rectangle_is_laid_out_and_a_triangle_is_not() {
        let plane = Plane::new(
            Point3::new(0.0, 0.0, 0.0),
            Point3::new(1.0, 0.0, 0.0),
            Point3::new(0.0, 1.0, 0.0),
        );
        let square = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        let triangles = rectangle_face(&plane, &square, 100).expect("a rectangle");
        // Over the triangle limit: not laid out.
        assert!(rectangle_face(&plane, &square, 3).is_none());
        let area: f64 = triangles
            .iter()
            .map(|[p, q, r]| 0.5 * (*q - *p).cross(*r - *p).length())
            .sum();
        assert!((area - 1.0).abs() < 1e-9, "{area}");
        let triangle = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        assert!(rectangle_face(&plane, &triangle, 100).is_none());
        // Every point on a side of the unit square, but the loop turns back along the bottom:
        // not the whole rectangle.
        let folded = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.5, 0.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
        ];
        assert!(rectangle_face(&plane, &folded, 100).is_none());
    }
}
