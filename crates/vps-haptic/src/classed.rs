//! The point shell split cyclically into classes
//! (docs/architecture.md#exact-sums-and-the-cluster): the shell's points, in order, are dealt out
//! in runs of [`run_length`] consecutive points, run `j` to class `j mod C`, so point
//! `i` belongs to class `(i / R) mod C`. Each class is stored contiguously as structure-of-arrays
//! f32, so sampling a class is one linear scan over six arrays.
//!
//! Why runs: a shell in Morton order has neighbouring points next to each other, and a shell
//! finer than the voxmap has many points per voxel; a run keeps such neighbours together in one
//! class, so the kernel's blocks of points mostly repeat the previous point's voxel and skip its
//! lookup. Runs are short enough that every class still samples the whole shell evenly (at least
//! [`MIN_RUNS_PER_CLASS`] runs each, so class sizes differ by at most one run).

use vps_voxmap::PointShell;

/// The longest run of consecutive shell points dealt to one class (16 points: two blocks of the
/// kernel's 8 lanes).
pub const MAX_RUN_LENGTH: usize = 16;

/// Runs shorter than [`MAX_RUN_LENGTH`] are used where needed so that every class gets at least
/// this many runs (a shell of fewer than `C` times this many points is dealt point by point).
pub const MIN_RUNS_PER_CLASS: usize = 16;

/// The run length `R` for `points` points in `classes` classes: the longest up to
/// [`MAX_RUN_LENGTH`] that still gives every class [`MIN_RUNS_PER_CLASS`] runs, at least 1.
pub fn run_length(points: usize, classes: u32) -> usize {
    let classes = (classes.max(1) as usize).saturating_mul(MIN_RUNS_PER_CLASS);
    (points / classes).clamp(1, MAX_RUN_LENGTH)
}

/// A [`PointShell`] reordered by class. Within a class, points keep their shell order (ascending
/// index), which is Morton order when the shell is.
///
/// Invariants: the six arrays have `len()` entries; class `c` occupies
/// `offsets[c]..offsets[c + 1]`; `class_count() ≥ 1`.
#[derive(Clone, Debug, PartialEq)]
pub struct ClassedShell {
    pub(crate) px: Vec<f32>,
    pub(crate) py: Vec<f32>,
    pub(crate) pz: Vec<f32>,
    pub(crate) nx: Vec<f32>,
    pub(crate) ny: Vec<f32>,
    pub(crate) nz: Vec<f32>,
    offsets: Vec<usize>,
    max_radius: f64,
    max_normal: f64,
    /// Every point is finite (normals: see [`ClassedShell::max_normal`]).
    finite: bool,
}

/// The largest length among `vectors` (0 for none); infinite if any is not finite, so that the
/// kernel's bound on contributions then asks for clamping (see `crate::kernel`).
fn largest_length(vectors: &[glam::Vec3]) -> f64 {
    vectors
        .iter()
        .map(|v| {
            let length = f64::from(v.length());
            if length.is_finite() {
                length
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max)
}

impl ClassedShell {
    /// Splits `shell` into `class_count` classes (a `class_count` of 0 is taken as 1), in runs of
    /// [`run_length`]`(shell.len(), class_count)` points. Classes may be empty when
    /// `class_count > shell.len()`. Allocates; not for the frame path.
    pub fn new(shell: &PointShell, class_count: u32) -> ClassedShell {
        let classes = class_count.max(1) as usize;
        let n = shell.points.len().min(shell.normals.len());
        let mut out = ClassedShell {
            px: Vec::with_capacity(n),
            py: Vec::with_capacity(n),
            pz: Vec::with_capacity(n),
            nx: Vec::with_capacity(n),
            ny: Vec::with_capacity(n),
            nz: Vec::with_capacity(n),
            offsets: Vec::with_capacity(classes + 1),
            max_radius: shell.max_radius(),
            max_normal: largest_length(&shell.normals),
            finite: shell.points.iter().all(|p| p.is_finite()),
        };
        out.offsets.push(0);
        let run = run_length(n, classes as u32);
        for class in 0..classes {
            let runs = (class * run..n).step_by(classes * run);
            for i in runs.flat_map(|start| start..(start + run).min(n)) {
                let (p, nrm) = (shell.points[i], shell.normals[i]);
                out.px.push(p.x);
                out.py.push(p.y);
                out.pz.push(p.z);
                out.nx.push(nrm.x);
                out.ny.push(nrm.y);
                out.nz.push(nrm.z);
            }
            out.offsets.push(out.px.len());
        }
        out
    }

    /// Number of classes `C` (≥ 1).
    pub fn class_count(&self) -> u32 {
        (self.offsets.len() - 1) as u32
    }

    /// Total number of points.
    pub fn len(&self) -> usize {
        self.px.len()
    }

    /// True when the shell has no points.
    pub fn is_empty(&self) -> bool {
        self.px.is_empty()
    }

    /// Number of points in class `class`; 0 for a class that does not exist.
    pub fn class_len(&self, class: u32) -> usize {
        self.class_range(class).map_or(0, |r| r.len())
    }

    /// Whether every point is finite; a shell that is not makes the kernel clamp each
    /// contribution (see `crate::kernel`), so that every copy of its block loop gives the same
    /// bits even then.
    pub(crate) fn points_finite(&self) -> bool {
        self.finite
    }

    /// Largest distance of a point from the body origin (m): `r_max` of the tunnelling guard.
    pub fn max_radius(&self) -> f64 {
        self.max_radius
    }

    /// Largest length of a body-frame normal (1 for unit normals; infinite if some normal is not
    /// finite; bounds the kernel's contributions, see `crate::kernel`).
    pub fn max_normal(&self) -> f64 {
        self.max_normal
    }

    /// The index range of class `class` in the SoA arrays, `None` if it does not exist.
    #[inline]
    pub(crate) fn class_range(&self, class: u32) -> Option<std::ops::Range<usize>> {
        let c = class as usize;
        (c + 1 < self.offsets.len()).then(|| self.offsets[c]..self.offsets[c + 1])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A shell whose point `i` has x = i, so a class's points name their indices.
    fn numbered(n: usize) -> PointShell {
        let mut shell = vps_testkit::shell::sphere_shell(n);
        for (i, p) in shell.points.iter_mut().enumerate() {
            p.x = i as f32;
        }
        shell
    }

    #[test]
    fn run_lengths_keep_sixteen_runs_per_class() {
        assert_eq!(run_length(106_861, 64), 16);
        assert_eq!(run_length(16_384, 64), 16);
        assert_eq!(run_length(16_383, 64), 15);
        assert_eq!(run_length(10_000, 64), 9);
        assert_eq!(run_length(386, 64), 1);
        assert_eq!(run_length(0, 64), 1);
        assert_eq!(run_length(1_000, 0), 16, "a class count of 0 is taken as 1");
    }

    #[test]
    fn classes_deal_runs_cyclically_and_partition_the_shell() {
        for (n, classes) in [
            (106_861, 64),
            (10_000, 64),
            (1_000, 7),
            (386, 64),
            (5, 8),
            (0, 3),
        ] {
            let shell = ClassedShell::new(&numbered(n), classes);
            let run = run_length(n, classes);
            let mut seen = vec![false; n];
            let mut sizes = Vec::new();
            for class in 0..shell.class_count() {
                let range = shell.class_range(class).unwrap();
                sizes.push(range.len());
                for i in range.map(|k| shell.px[k] as usize) {
                    assert_eq!(
                        (i / run) % classes as usize,
                        class as usize,
                        "n {n}, point {i}"
                    );
                    assert!(!seen[i], "point {i} in two classes");
                    seen[i] = true;
                }
            }
            assert!(seen.iter().all(|&s| s), "n {n}: every point in a class");
            let (small, large) = (sizes.iter().min().unwrap(), sizes.iter().max().unwrap());
            assert!(
                large - small <= run,
                "n {n}: class sizes {small}..{large}, run {run}"
            );
        }
    }
}
