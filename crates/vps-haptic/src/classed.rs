//! The point shell split cyclically into classes (docs/architecture.md#exact-sums-and-the-cluster): point `i` belongs to class
//! `i mod C`. Each class is stored contiguously as structure-of-arrays f32, so sampling a class is
//! one linear scan over six arrays.

use vps_voxmap::PointShell;

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
    /// Splits `shell` into `class_count` classes (a `class_count` of 0 is taken as 1). Classes may be
    /// empty when `class_count > shell.len()`. Allocates; not for the frame path.
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
        for class in 0..classes {
            for i in (class..n).step_by(classes) {
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
