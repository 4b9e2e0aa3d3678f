//! A bound on the geometry kernel's surface subdivision, so that malformed B-spline geometry fails
//! fast instead of running for ever.
//!
//! truck lays a face's triangles out on a grid of its surface's parameters, refined until the
//! bilinear patch of every cell is within the chord tolerance of the surface
//! (`truck_geotrait::algo::surface::parameter_division`). The refinement has no limit: on a
//! B-spline or NURBS surface that is not smooth at the tolerance (a mutated knot vector, a weight
//! of 0, a jump between patches) it halves cells until the floating-point resolution, with the
//! grid and its memory growing at each pass. Every tessellation loop seen in fuzzing was this
//! refinement (12 of 12 looping inputs from 2,000 mutated STEP files, checked with a debugger).
//!
//! [`Guarded`] wraps each face's surface for the tessellator. For B-spline and NURBS surfaces it
//! runs the same refinement (the same operations in the same order, so the same grid: a unit test
//! compares it with truck's) but stops after [`MAX_PASSES`] passes or [`DivisionBudget`]'s points;
//! it also counts the face's surface evaluations. [`GuardedCurve`] bounds each B-spline edge's
//! polyline. Over any bound the budget records what ran over and unwinds out of truck
//! ([`OutOfEvaluations`]); the caller catches it and refuses the shell. Every other surface and
//! curve kind is truck's own division.
//!
//! The grid bound matters as much as the passes: a mutated control point far away makes a
//! surface legitimately huge against the tolerance, and truck's triangulator then spends time per
//! triangle per boundary point (one fuzzed input spent minutes there under a 10⁷-point grid).

use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};

use truck_meshalgo::prelude::*;
use truck_stepio::r#in::alias::{Curve3D, Surface};

/// Refinement passes allowed. A surface smooth at the tolerance needs about `log2(size / √(tol ·
/// r))` passes for curvature radius `r` (under 20 for a 10 m part at a micrometre, with `r` a
/// thousandth of the part); each pass halves the cells still too coarse, so 32 passes reach a
/// cell 2⁻³² of the face's parameter range.
pub const MAX_PASSES: usize = 32;

/// Grid points a face may have in the first tessellation pass of a shell (the coarse sizing pass,
/// at 1 % of the shell's size, or the only pass): a 500 × 500 grid. A face of a real part needs
/// a few thousand at that tolerance; a grid near this bound already takes the triangulator
/// seconds (its boundary test is per triangle), so a face that needs more is refused at once.
pub const FIRST_PASS_POINTS: usize = 250_000;

/// Surface evaluations (a point or a derivative) a face may make in a pass besides its grid's: its
/// boundary's points in the parameter plane, the searches for them, the trimming. A face of the
/// public test files makes a few thousand.
pub const FACE_EVALUATIONS: u64 = 200_000;

/// What a parameter search counts: with a hint, one Newton step's six evaluations (it takes at
/// most `trials` steps); without one, truck first evaluates a 51 × 51 grid over the surface.
fn search_cost(hinted: bool) -> u64 {
    if hinted {
        6
    } else {
        51 * 51 + 6
    }
}

/// Evaluations a face may make per point of its grid (the triangulation evaluates each grid point
/// and its normal).
pub const EVALUATIONS_PER_GRID_POINT: u64 = 4;

/// What one tessellation pass over a shell may spend per face: grid points, and surface
/// evaluations besides the grid's own (truck meshes the faces in parallel, so each face has its own
/// count). A face that runs out stops the whole pass at once (an unwind the caller catches) and
/// the shell is refused: truck's trimming tests every triangle against every boundary point, so a
/// boundary grown without bound would otherwise cost minutes.
#[derive(Debug)]
pub struct DivisionBudget {
    /// Grid points (u lines × v lines) one face may have.
    max_points: AtomicUsize,
    /// Evaluations left to each face in this pass.
    evaluations_left: Vec<AtomicU64>,
    /// Debug text of the first surface or curve that ran over a bound.
    first: Mutex<Option<String>>,
    /// Set when the read's deadline has passed: the next evaluation unwinds.
    cancelled: Arc<AtomicBool>,
}

impl DivisionBudget {
    /// For `faces` faces: at most `max_points` grid points per face (at least 4), [`MAX_PASSES`]
    /// passes, and [`FACE_EVALUATIONS`] evaluations a face plus
    /// [`EVALUATIONS_PER_GRID_POINT`] per point of its grids.
    /// `cancelled`, once set, stops the pass at the next evaluation or edge division (the read's
    /// deadline: its thread then ends instead of running on).
    pub fn new(faces: usize, max_points: usize, cancelled: Arc<AtomicBool>) -> Arc<Self> {
        Arc::new(Self {
            max_points: AtomicUsize::new(max_points.max(4)),
            evaluations_left: (0..faces)
                .map(|_| AtomicU64::new(FACE_EVALUATIONS))
                .collect(),
            first: Mutex::new(None),
            cancelled,
        })
    }

    /// A new pass with at most `max_points` grid points per face (set between passes).
    pub fn start_pass(&self, max_points: usize) {
        self.max_points.store(max_points.max(4), Ordering::Relaxed);
        for left in &self.evaluations_left {
            left.store(FACE_EVALUATIONS, Ordering::Relaxed);
        }
    }

    /// Takes `n` of face `face`'s evaluations; when they are not left, stops at `surface`.
    fn spend(&self, face: usize, surface: &Surface, n: u64) {
        unwind_if_cancelled(&self.cancelled);
        let Some(left) = self.evaluations_left.get(face) else {
            return;
        };
        if left
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |left| {
                left.checked_sub(n)
            })
            .is_err()
        {
            self.stop(surface);
        }
    }

    /// Gives face `face` the evaluations of a grid of `points` points.
    fn grant_grid(&self, face: usize, points: usize) {
        if let Some(left) = self.evaluations_left.get(face) {
            left.fetch_add(
                EVALUATIONS_PER_GRID_POINT.saturating_mul(points as u64),
                Ordering::Relaxed,
            );
        }
    }

    /// The debug text of the first surface or curve that ran over a bound, if any did (the
    /// caller names its kind).
    pub fn ran_over(&self) -> Option<String> {
        self.first.lock().ok().and_then(|first| first.clone())
    }

    /// Records `what` (unless something ran over first) and unwinds out of the tessellation with
    /// [`OutOfEvaluations`] (by `resume_unwind`: no panic hook, as this is no error of vps).
    fn stop(&self, what: &dyn std::fmt::Debug) -> ! {
        if let Ok(mut first) = self.first.lock() {
            if first.is_none() {
                *first = Some(format!("{what:?}"));
            }
        }
        std::panic::resume_unwind(Box::new(OutOfEvaluations))
    }
}

/// Points one edge's polyline may have: truck halves a B-spline edge's parameter range up to
/// 100 levels deep wherever the chord is off the curve by more than the tolerance, so a mutated
/// control point far away made one edge's polyline tens of megabytes (found by fuzzing). A real
/// edge needs hundreds at a fine tolerance.
pub const EDGE_POINTS: usize = 100_000;

/// An edge's curve whose division (for B-spline and NURBS curves) is bounded by [`EDGE_POINTS`];
/// every other operation is the curve's own.
#[derive(Clone, Debug)]
pub struct GuardedCurve {
    curve: Curve3D,
    budget: Arc<DivisionBudget>,
}

impl GuardedCurve {
    /// `curve` under `budget`.
    pub fn new(curve: Curve3D, budget: Arc<DivisionBudget>) -> Self {
        Self { curve, budget }
    }
}

impl ParametricCurve for GuardedCurve {
    type Point = Point3;
    type Vector = Vector3;
    fn subs(&self, t: f64) -> Point3 {
        self.curve.subs(t)
    }
    fn der(&self, t: f64) -> Vector3 {
        self.curve.der(t)
    }
    fn der2(&self, t: f64) -> Vector3 {
        self.curve.der2(t)
    }
    fn parameter_range(&self) -> ParameterRange {
        self.curve.parameter_range()
    }
    fn try_range_tuple(&self) -> Option<(f64, f64)> {
        self.curve.try_range_tuple()
    }
    fn period(&self) -> Option<f64> {
        self.curve.period()
    }
}

impl BoundedCurve for GuardedCurve {
    fn range_tuple(&self) -> (f64, f64) {
        self.curve.range_tuple()
    }
    fn front(&self) -> Point3 {
        self.curve.front()
    }
    fn back(&self) -> Point3 {
        self.curve.back()
    }
}

impl ParameterDivision1D for GuardedCurve {
    type Point = Point3;
    fn parameter_division(&self, range: (f64, f64), tol: f64) -> (Vec<f64>, Vec<Point3>) {
        unwind_if_cancelled(&self.budget.cancelled);
        let spline = matches!(
            self.curve,
            Curve3D::BSplineCurve(_) | Curve3D::NurbsCurve(_)
        );
        if !spline || tol < TOLERANCE {
            return self.curve.parameter_division(range, tol);
        }
        let ends = (self.curve.subs(range.0), self.curve.subs(range.1));
        let mut out = (Vec::new(), Vec::new());
        if bounded_curve_division(&self.curve, range, ends, tol, 100, &mut out).is_err() {
            self.budget.stop(&self.curve);
        }
        out
    }
}

/// truck's curve division (`truck_geotrait::algo::curve::parameter_division`: the same
/// operations in the same order, so the same points), appending to `out` and stopped with `Err`
/// when it would hold more than [`EDGE_POINTS`].
fn bounded_curve_division<C: ParametricCurve<Point = Point3>>(
    curve: &C,
    range: (f64, f64),
    ends: (Point3, Point3),
    tol: f64,
    trials: usize,
    out: &mut (Vec<f64>, Vec<Point3>),
) -> Result<(), ()> {
    let gen = ends.0.midpoint(ends.1);
    let p = 0.5 + (0.2 * HashGen::hash1(gen) - 0.1);
    let t = range.0 * (1.0 - p) + range.1 * p;
    let mid = ends.0 + (ends.1 - ends.0) * p;
    let dist2 = curve.subs(t).distance2(mid);
    if dist2 < tol * tol || trials == 0 {
        if out.0.len() >= EDGE_POINTS {
            return Err(());
        }
        // Each piece's end is the next piece's start: written once (truck pops and re-pushes it).
        if out.0.is_empty() {
            out.0.push(range.0);
            out.1.push(ends.0);
        }
        out.0.push(range.1);
        out.1.push(ends.1);
        return Ok(());
    }
    let mid_param = (range.0 + range.1) / 2.0;
    let mid_value = curve.subs(mid_param);
    bounded_curve_division(
        curve,
        (range.0, mid_param),
        (ends.0, mid_value),
        tol,
        trials - 1,
        out,
    )?;
    bounded_curve_division(
        curve,
        (mid_param, range.1),
        (mid_value, ends.1),
        tol,
        trials - 1,
        out,
    )
}

/// The unwind payload of a face or edge that ran over a bound of its [`DivisionBudget`].
#[derive(Debug)]
pub struct OutOfEvaluations;

/// The unwind payload of a pass stopped because the read's deadline passed.
#[derive(Debug)]
pub struct Cancelled;

/// Unwinds out of the tessellation with [`Cancelled`] once `cancelled` is set (by
/// `resume_unwind`: no panic hook).
pub(crate) fn unwind_if_cancelled(cancelled: &AtomicBool) {
    if cancelled.load(Ordering::Relaxed) {
        std::panic::resume_unwind(Box::new(Cancelled));
    }
}

/// Face `face`'s surface with its division and evaluations bounded by a shared
/// [`DivisionBudget`]; every other operation is the surface's own.
#[derive(Clone, Debug)]
pub struct Guarded {
    surface: Surface,
    face: usize,
    budget: Arc<DivisionBudget>,
}

impl Guarded {
    /// Face `face`'s `surface` under `budget`.
    pub fn new(surface: Surface, face: usize, budget: Arc<DivisionBudget>) -> Self {
        Self {
            surface,
            face,
            budget,
        }
    }

    /// The surface itself.
    pub fn surface(&self) -> &Surface {
        &self.surface
    }

    /// `f` of the surface, one evaluation spent.
    fn point(&self, f: impl FnOnce(&Surface) -> Point3) -> Point3 {
        self.budget.spend(self.face, &self.surface, 1);
        f(&self.surface)
    }

    /// `f` of the surface, one evaluation spent.
    fn vector(&self, f: impl FnOnce(&Surface) -> Vector3) -> Vector3 {
        self.budget.spend(self.face, &self.surface, 1);
        f(&self.surface)
    }

    /// Spends what a parameter search with `hint` costs ([`search_cost`]).
    fn spend_search(&self, hint: &SPHint2D) {
        let cost = search_cost(!matches!(hint, SPHint2D::None));
        self.budget.spend(self.face, &self.surface, cost);
    }
}

impl ParametricSurface for Guarded {
    type Point = Point3;
    type Vector = Vector3;
    fn subs(&self, u: f64, v: f64) -> Point3 {
        self.point(|s| s.subs(u, v))
    }
    fn uder(&self, u: f64, v: f64) -> Vector3 {
        self.vector(|s| s.uder(u, v))
    }
    fn vder(&self, u: f64, v: f64) -> Vector3 {
        self.vector(|s| s.vder(u, v))
    }
    fn uuder(&self, u: f64, v: f64) -> Vector3 {
        self.vector(|s| s.uuder(u, v))
    }
    fn uvder(&self, u: f64, v: f64) -> Vector3 {
        self.vector(|s| s.uvder(u, v))
    }
    fn vvder(&self, u: f64, v: f64) -> Vector3 {
        self.vector(|s| s.vvder(u, v))
    }
    fn parameter_range(&self) -> (ParameterRange, ParameterRange) {
        self.surface.parameter_range()
    }
    fn try_range_tuple(&self) -> (Option<(f64, f64)>, Option<(f64, f64)>) {
        self.surface.try_range_tuple()
    }
    fn u_period(&self) -> Option<f64> {
        self.surface.u_period()
    }
    fn v_period(&self) -> Option<f64> {
        self.surface.v_period()
    }
}

impl ParametricSurface3D for Guarded {
    fn normal(&self, u: f64, v: f64) -> Vector3 {
        self.vector(|s| s.normal(u, v))
    }
}

impl SearchParameter<D2> for Guarded {
    type Point = Point3;
    fn search_parameter<H: Into<SPHint2D>>(
        &self,
        point: Point3,
        hint: H,
        trials: usize,
    ) -> Option<(f64, f64)> {
        let hint = hint.into();
        self.spend_search(&hint);
        self.surface.search_parameter(point, hint, trials)
    }
}

impl SearchNearestParameter<D2> for Guarded {
    type Point = Point3;
    fn search_nearest_parameter<H: Into<SPHint2D>>(
        &self,
        point: Point3,
        hint: H,
        trials: usize,
    ) -> Option<(f64, f64)> {
        let hint = hint.into();
        self.spend_search(&hint);
        self.surface.search_nearest_parameter(point, hint, trials)
    }
}

impl ParameterDivision2D for Guarded {
    fn parameter_division(
        &self,
        range: ((f64, f64), (f64, f64)),
        tol: f64,
    ) -> (Vec<f64>, Vec<f64>) {
        let spline = matches!(
            self.surface,
            Surface::BSplineSurface(_) | Surface::NurbsSurface(_)
        );
        // A tolerance truck refuses goes to truck, which says so (a panic the caller catches).
        let division = if !spline || tol < TOLERANCE {
            self.surface.parameter_division(range, tol)
        } else {
            // The grid's own evaluations are bounded by its points and passes, not counted.
            let max_points = self.budget.max_points.load(Ordering::Relaxed);
            match bounded_division(&self.surface, range, tol, max_points) {
                Ok(division) => division,
                Err(()) => self.budget.stop(&self.surface),
            }
        };
        self.budget
            .grant_grid(self.face, division.0.len() * division.1.len());
        division
    }
}

/// truck's `parameter_division` for a surface (the same operations in the same order), stopped
/// with `Err` after [`MAX_PASSES`] refining passes or when the grid would pass `max_points`.
fn bounded_division<S>(
    surface: &S,
    (urange, vrange): ((f64, f64), (f64, f64)),
    tol: f64,
    max_points: usize,
) -> Result<(Vec<f64>, Vec<f64>), ()>
where
    S: ParametricSurface<Point = Point3>,
{
    let (mut udiv, mut vdiv) = (vec![urange.0, urange.1], vec![vrange.0, vrange.1]);
    for _ in 0..=MAX_PASSES {
        let mut divide_u = vec![false; udiv.len() - 1];
        let mut divide_v = vec![false; vdiv.len() - 1];
        for (u, ub) in udiv.windows(2).zip(&mut divide_u) {
            for (v, vb) in vdiv.windows(2).zip(&mut divide_v) {
                if *ub && *vb {
                    continue;
                }
                let (u_gen, v_gen) = ((u[0] + u[1]) / 2.0, (v[0] + v[1]) / 2.0);
                let gen = surface.subs(u_gen, v_gen);
                let p = 0.5 + (0.2 * HashGen::hash1(gen) - 0.1);
                let q = 0.5 + (0.2 * HashGen::hash1(gen) - 0.1);
                let u0 = u[0] * (1.0 - p) + u[1] * p;
                let v0 = v[0] * (1.0 - q) + v[1] * q;
                let p0 = surface.subs(u0, v0);
                let pt00 = surface.subs(u[0], v[0]);
                let pt01 = surface.subs(u[0], v[1]);
                let pt10 = surface.subs(u[1], v[0]);
                let pt11 = surface.subs(u[1], v[1]);
                let pt = Point3::from_vec(
                    pt00.to_vec() * (1.0 - p) * (1.0 - q)
                        + pt01.to_vec() * (1.0 - p) * q
                        + pt10.to_vec() * p * (1.0 - q)
                        + pt11.to_vec() * p * q,
                );
                let far = p0.distance2(pt) > tol * tol;
                *ub = *ub || far;
                *vb = *vb || far;
            }
        }
        let added_u = divide_u.iter().filter(|&&d| d).count();
        let added_v = divide_v.iter().filter(|&&d| d).count();
        if added_u == 0 && added_v == 0 {
            return Ok((udiv, vdiv));
        }
        let points = (udiv.len() + added_u).saturating_mul(vdiv.len() + added_v);
        if points > max_points {
            return Err(());
        }
        udiv = refined(&udiv, &divide_u);
        vdiv = refined(&vdiv, &divide_v);
    }
    Err(())
}

/// `division` with the midpoint of every interval marked in `divide` inserted.
fn refined(division: &[f64], divide: &[bool]) -> Vec<f64> {
    let mut out = Vec::with_capacity(division.len() + divide.len());
    out.push(division[0]);
    for (w, &d) in division.windows(2).zip(divide) {
        if d {
            out.push((w[0] + w[1]) / 2.0);
        }
        out.push(w[1]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use truck_stepio::r#in::alias::re_exports::{BSplineSurface, KnotVec};

    /// A bicubic B-spline patch with a bump: several refining passes at 1e-4.
    fn bumpy() -> BSplineSurface<Point3> {
        let knots = KnotVec::bezier_knot(3);
        let points = (0..4)
            .map(|i| {
                (0..4)
                    .map(|j| {
                        let z = if (1..3).contains(&i) && (1..3).contains(&j) {
                            0.7
                        } else {
                            0.0
                        };
                        Point3::new(i as f64, j as f64, z)
                    })
                    .collect()
            })
            .collect();
        BSplineSurface::new((knots.clone(), knots), points)
    }

    /// Once the read's deadline has set the flag, the next evaluation unwinds with `Cancelled`
    /// (before, a read given up on ran on to its end).
    #[test]
    fn a_cancelled_budget_stops_at_the_next_evaluation() {
        let cancelled = Arc::new(AtomicBool::new(false));
        let budget = DivisionBudget::new(1, 100, cancelled.clone());
        let surface = Guarded::new(Surface::BSplineSurface(Box::new(bumpy())), 0, budget);
        let _ = surface.subs(0.5, 0.5);
        cancelled.store(true, Ordering::Relaxed);
        let stopped =
            std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| surface.subs(0.5, 0.5)))
                .expect_err("unwinds");
        assert!(stopped.is::<Cancelled>());
    }

    #[test]
    fn the_bounded_division_is_trucks_own() {
        let surface = bumpy();
        let range = ((0.0, 1.0), (0.0, 1.0));
        for tol in [0.1, 0.01, 1e-4] {
            let theirs = surface.parameter_division(range, tol);
            let ours = bounded_division(&surface, range, tol, usize::MAX).expect("converges");
            assert_eq!(ours, theirs, "tolerance {tol}");
            assert!(ours.0.len() > 2 && ours.1.len() > 2);
        }
    }

    #[test]
    fn a_grid_over_its_points_or_passes_stops() {
        let surface = bumpy();
        let range = ((0.0, 1.0), (0.0, 1.0));
        let (u, v) = surface.parameter_division(range, 1e-4);
        assert_eq!(
            bounded_division(&surface, range, 1e-4, u.len() * v.len() - 1),
            Err(())
        );
        // A surface that is not smooth at any tolerance: a jump in the middle of its range.
        #[derive(Clone)]
        struct Step;
        impl ParametricSurface for Step {
            type Point = Point3;
            type Vector = Vector3;
            fn subs(&self, u: f64, v: f64) -> Point3 {
                Point3::new(u, v, if u < 0.5 { 0.0 } else { 1.0 })
            }
            fn uder(&self, _: f64, _: f64) -> Vector3 {
                Vector3::unit_x()
            }
            fn vder(&self, _: f64, _: f64) -> Vector3 {
                Vector3::unit_y()
            }
            fn uuder(&self, _: f64, _: f64) -> Vector3 {
                Vector3::zero()
            }
            fn uvder(&self, _: f64, _: f64) -> Vector3 {
                Vector3::zero()
            }
            fn vvder(&self, _: f64, _: f64) -> Vector3 {
                Vector3::zero()
            }
        }
        // Its grid doubles along the jump at every pass: the points bound stops it.
        assert_eq!(
            bounded_division(&Step, range, 1e-3, FIRST_PASS_POINTS),
            Err(())
        );
        assert_eq!(bounded_division(&Step, range, 1e-3, 1000), Err(()));
    }
}
