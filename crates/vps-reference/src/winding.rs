//! The generalized winding number of a triangle soup (Jacobson, Kavan and Sorkine-Hornung 2013):
//! `w(p) = Σ Ω_t(p) / 4π`, the signed solid angles `Ω_t` that the triangles subtend at `p`
//! (Van Oosterom and Strackee's formula). For a closed, consistently oriented (counter-clockwise
//! seen from outside) surface `w` is 1 inside and 0 outside; for an open or leaky one it blends
//! smoothly between them across the holes, so `w ≥ 0.5` is a robust inside test.
//!
//! [`WindingTree`] is the fast hierarchical approximation of Barill et al. 2018: a median-split
//! tree over the triangles whose nodes keep their area-weighted normal sum (the dipole moment
//! `Σ area_t · n_t`, m²) and area-weighted centroid; a node whose centroid is farther from `p` than
//! `β ×` its radius contributes its far-field expansion about the centroid, nearer nodes recurse
//! down to exact triangles. The expansion keeps the dipole term `A · r / (4π |r|³)` (`r = c − p`)
//! and the next (second-order) term from the moment `M = Σ area_t n_t ⊗ (x_t − c)` over triangle
//! centroids `x_t`. Error behaviour: the dropped terms of a far node are of relative size
//! `O((r_node / d)²) ≤ 1/β²` of that node's own contribution; near the point every triangle is
//! exact, so the error is largest at mid distances and shrinks with `β`. [`BETA`] = 2 (Barill et al.'s value);
//! the measured error against [`winding_number`] is in the tests below and `docs/voxelize.md`.
//!
//! Crates evaluated before writing this (2026-12): no maintained Rust crate offers a hierarchical
//! fast winding number on its own; the exact sum appears inside large, unrelated toolkits
//! (three.js and mesh-processing ports), so this module is self-contained.

use glam::{DMat3, DVec3};
use std::f64::consts::PI;
use vps_mesh::TriMesh;

/// Default accuracy parameter β of [`WindingTree`]: a node is far when its centroid is more than
/// `β ×` its radius from the query point.
pub const BETA: f64 = 2.0;

/// Where the inside test does not trust the approximation: a value within this of ½ is computed
/// again at [`REFINED_BETA`] ([`WindingTree::refined_winding_number`]).
pub const NEAR_HALF: f64 = 0.05;

/// The accuracy parameter of the second evaluation near ½: far terms' dropped parts are at most
/// 1/64 of their own contribution (1/4 at [`BETA`]).
pub const REFINED_BETA: f64 = 8.0;

/// Most triangles in one leaf of [`WindingTree`].
const LEAF_SIZE: usize = 8;

/// Signed solid angle (steradians, in `[-2π, 2π]`) that triangle `a b c` (m) subtends at `p`:
/// positive when `p` sees the triangle's back (the side its counter-clockwise normal points away
/// from). Zero for a degenerate triangle or when `p` lies on one of its vertices.
pub fn solid_angle(p: DVec3, [a, b, c]: [DVec3; 3]) -> f64 {
    let (a, b, c) = (a - p, b - p, c - p);
    let (la, lb, lc) = (a.length(), b.length(), c.length());
    let num = a.dot(b.cross(c));
    let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    if num == 0.0 && den <= 0.0 {
        return 0.0; // p on the triangle's plane, inside or on its edges: no defined value
    }
    2.0 * num.atan2(den)
}

/// The exact generalized winding number of `mesh` (m) at `p`: the sum of [`solid_angle`] over all
/// triangles divided by 4π. O(triangles). Vertex indices must be in range.
pub fn winding_number(mesh: &TriMesh, p: DVec3) -> f64 {
    (0..mesh.triangle_count())
        .map(|t| solid_angle(p, mesh.triangle(t)))
        .sum::<f64>()
        / (4.0 * PI)
}

/// One node of the tree.
#[derive(Clone, Debug)]
struct Node {
    /// Area-weighted centroid of its triangles (m).
    centre: DVec3,
    /// Largest distance from `centre` to a vertex of its triangles (m).
    radius: f64,
    /// Sum of area × unit normal of its triangles (m²).
    dipole: DVec3,
    /// Second-order moment `Σ area_t n_t ⊗ (x_t − centre)` over its triangles' centroids `x_t`
    /// (m³; column j holds the `j` components of the offsets).
    moment: DMat3,
    /// Leaf: first index into `tris`. Internal: index of the right child (left is the next node).
    start_or_right: u32,
    /// Leaf: number of triangles (≥ 1). Internal: 0.
    count: u32,
}

/// The fast approximate winding number of one triangle soup (see the module doc). Immutable after
/// [`WindingTree::new`]; queries allocate only a small stack and are deterministic (the same
/// mesh and point give bit-identical values).
#[derive(Clone, Debug)]
pub struct WindingTree {
    nodes: Vec<Node>,
    tris: Vec<[DVec3; 3]>,
    beta: f64,
}

impl WindingTree {
    /// Bytes a tree of `triangles` triangles holds: each triangle's corners and the nodes (their
    /// number depends on the count alone: the tree splits at the median). For memory estimates
    /// made before a tree is built; [`WindingTree::memory_bytes`] of the built tree is the same.
    pub fn estimated_bytes(triangles: usize) -> u64 {
        let tris = std::mem::size_of::<[DVec3; 3]>() as u64;
        let nodes = node_count(triangles) as u64 * std::mem::size_of::<Node>() as u64;
        (triangles as u64)
            .saturating_mul(tris)
            .saturating_add(nodes)
    }

    /// Bytes the tree holds (its vectors' capacities).
    pub fn memory_bytes(&self) -> u64 {
        (self.nodes.capacity() * std::mem::size_of::<Node>()
            + self.tris.capacity() * std::mem::size_of::<[DVec3; 3]>()) as u64
    }

    /// The tree of `mesh` with accuracy `beta` (clamped to at least 1; [`BETA`] is the default).
    /// Vertex indices must be in range. O(n log n); an empty mesh gives w = 0 everywhere.
    pub fn new(mesh: &TriMesh, beta: f64) -> WindingTree {
        let mut tris: Vec<[DVec3; 3]> = (0..mesh.triangle_count())
            .map(|t| mesh.triangle(t))
            .collect();
        let mut nodes = Vec::with_capacity(node_count(tris.len()));
        if !tris.is_empty() {
            let n = tris.len();
            build(&mut nodes, &mut tris, 0, n);
        }
        let beta = if beta.is_finite() {
            beta.max(1.0)
        } else {
            BETA
        };
        WindingTree { nodes, tris, beta }
    }

    /// The approximate winding number at `p` (m): exact for triangles in near nodes, dipole terms
    /// for far ones.
    pub fn winding_number(&self, p: DVec3) -> f64 {
        self.winding_number_at_beta(p, self.beta)
    }

    /// [`Self::winding_number`], evaluated again at [`REFINED_BETA`] when it lies within
    /// [`NEAR_HALF`] of ½: what the inside test uses, so a point is not classified by the
    /// approximation's error where the value is close to the threshold (a crack or hole of an open
    /// mesh seen from afar).
    pub fn refined_winding_number(&self, p: DVec3) -> f64 {
        let w = self.winding_number(p);
        if (w - 0.5).abs() < NEAR_HALF && self.beta < REFINED_BETA {
            self.winding_number_at_beta(p, REFINED_BETA)
        } else {
            w
        }
    }

    fn winding_number_at_beta(&self, p: DVec3, beta: f64) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let mut sum = 0.0;
        let mut stack = [0u32; 64];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            let d = node.centre - p;
            let dist_sq = d.length_squared();
            if dist_sq > (beta * node.radius).powi(2) {
                let d3 = dist_sq * dist_sq.sqrt();
                let m = &node.moment;
                let trace = m.x_axis.x + m.y_axis.y + m.z_axis.z;
                sum += (node.dipole.dot(d) + trace) / d3 - 3.0 * d.dot(*m * d) / (d3 * dist_sq);
            } else if node.count > 0 {
                let s = node.start_or_right as usize;
                for tri in &self.tris[s..s + node.count as usize] {
                    sum += solid_angle(p, *tri);
                }
            } else if top + 2 <= stack.len() {
                let i = stack[top];
                stack[top] = node.start_or_right;
                stack[top + 1] = i + 1;
                top += 2;
            }
        }
        sum / (4.0 * PI)
    }

    /// `refined_winding_number(p) >= 0.5`: `p` is inside the (possibly leaky) solid.
    pub fn inside(&self, p: DVec3) -> bool {
        self.refined_winding_number(p) >= 0.5
    }
}

/// Builds the subtree over `tris[lo..hi]` (reordering them), returns nothing; nodes depth-first.
/// Nodes of the tree of `triangles` triangles: [`build`] splits a range of more than
/// [`LEAF_SIZE`] at its median, so a level holds ranges of at most two sizes. O(log n).
fn node_count(triangles: usize) -> usize {
    if triangles == 0 {
        return 0;
    }
    let mut total = 0;
    // (range size, how many ranges of that size) on the current level: at most two entries.
    let mut level: Vec<(usize, usize)> = vec![(triangles, 1)];
    while !level.is_empty() {
        let mut next: Vec<(usize, usize)> = Vec::with_capacity(4);
        for &(size, count) in &level {
            total += count;
            if size > LEAF_SIZE {
                for half in [size / 2, size - size / 2] {
                    match next.iter_mut().find(|(s, _)| *s == half) {
                        Some(entry) => entry.1 += count,
                        None => next.push((half, count)),
                    }
                }
            }
        }
        level = next;
    }
    total
}

fn build(nodes: &mut Vec<Node>, tris: &mut [[DVec3; 3]], lo: usize, hi: usize) {
    let part = &tris[lo..hi];
    let mut dipole = DVec3::ZERO;
    let mut weighted = DVec3::ZERO;
    let mut area_sum = 0.0;
    let mut cmin = DVec3::splat(f64::INFINITY);
    let mut cmax = DVec3::splat(f64::NEG_INFINITY);
    for [a, b, c] in part {
        let n2 = (*b - *a).cross(*c - *a); // twice the area vector
        let area = 0.5 * n2.length();
        let centroid = (*a + *b + *c) / 3.0;
        dipole += 0.5 * n2;
        weighted += area * centroid;
        area_sum += area;
        cmin = cmin.min(centroid);
        cmax = cmax.max(centroid);
    }
    let centre = if area_sum > 0.0 {
        weighted / area_sum
    } else {
        0.5 * (cmin + cmax)
    };
    let radius = part
        .iter()
        .flat_map(|t| t.iter())
        .map(|v| v.distance(centre))
        .fold(0.0, f64::max);
    let moment = part.iter().fold(DMat3::ZERO, |m, [a, b, c]| {
        let area_vec = 0.5 * (*b - *a).cross(*c - *a);
        let off = (*a + *b + *c) / 3.0 - centre;
        m + DMat3::from_cols(area_vec * off.x, area_vec * off.y, area_vec * off.z)
    });
    let me = nodes.len();
    nodes.push(Node {
        centre,
        radius,
        dipole,
        moment,
        start_or_right: lo as u32,
        count: (hi - lo) as u32,
    });
    if hi - lo <= LEAF_SIZE {
        return;
    }
    let axis = (cmax - cmin).max_position();
    let mid = (hi - lo) / 2;
    let key = |t: &[DVec3; 3]| (t[0][axis] + t[1][axis] + t[2][axis]) / 3.0;
    tris[lo..hi].select_nth_unstable_by(mid, |x, y| key(x).total_cmp(&key(y)));
    nodes[me].count = 0;
    build(nodes, tris, lo, lo + mid);
    nodes[me].start_or_right = nodes.len() as u32;
    build(nodes, tris, lo + mid, hi);
}

#[cfg(test)]
mod tests {
    use vps_mesh::builtin;

    /// The estimate made before a tree is built is what the built tree holds, to the byte.
    #[test]
    fn the_estimate_bounds_a_built_trees_memory() {
        for name in ["teapot", "sphere", "box", "aircraft-bay"] {
            let mesh = builtin::by_name(name).unwrap();
            let built = WindingTree::new(&mesh, BETA).memory_bytes();
            let estimated = WindingTree::estimated_bytes(mesh.triangle_count());
            assert_eq!(built, estimated, "{name}");
        }
    }

    use super::*;
    use vps_mesh::builtin::{cuboid, uv_sphere};

    /// A box of half extent 1 with its +z face removed.
    fn open_box() -> TriMesh {
        let mut m = cuboid(DVec3::ONE);
        m.triangles
            .retain(|t| !t.iter().all(|&v| m.vertices[v as usize].z == 1.0));
        m
    }

    fn points(n: usize, half: f64) -> Vec<DVec3> {
        // A deterministic low-discrepancy-ish sequence (no rand dependency needed).
        (0..n)
            .map(|i| {
                let f = |k: f64| ((i as f64 + 0.5) * k).fract() * 2.0 * half - half;
                DVec3::new(f(0.754_877_666), f(0.569_840_29), f(0.362_182_6))
            })
            .collect()
    }

    #[test]
    fn closed_box_is_one_inside_zero_outside() {
        let m = cuboid(DVec3::ONE);
        assert!((winding_number(&m, DVec3::new(0.1, 0.2, -0.3)) - 1.0).abs() < 1e-12);
        assert!(winding_number(&m, DVec3::new(1.5, 0.2, -0.3)).abs() < 1e-12);
        let t = WindingTree::new(&m, BETA);
        assert!(t.inside(DVec3::new(0.1, 0.2, -0.3)));
        assert!(!t.inside(DVec3::new(1.5, 0.2, -0.3)));
        assert_eq!(
            WindingTree::new(&TriMesh::default(), BETA).winding_number(DVec3::ZERO),
            0.0
        );
    }

    #[test]
    fn open_box_is_still_inside() {
        let m = open_box();
        let w = winding_number(&m, DVec3::new(0.0, 0.0, -0.5));
        assert!(w > 0.75 && w < 1.0, "{w}");
        assert!(winding_number(&m, DVec3::new(0.0, 0.0, 3.0)) < 0.1);
    }

    /// Mean and largest |tree − exact| over `pts`.
    fn errors(m: &TriMesh, beta: f64, pts: &[DVec3]) -> (f64, f64) {
        let tree = WindingTree::new(m, beta);
        let errs: Vec<f64> = pts
            .iter()
            .map(|&p| (tree.winding_number(p) - winding_number(m, p)).abs())
            .collect();
        let mean = errs.iter().sum::<f64>() / errs.len() as f64;
        (mean, errs.iter().copied().fold(0.0, f64::max))
    }

    #[test]
    fn tree_error_against_exact_sum_is_small() {
        // A fine sphere (many far nodes) with its top cap cut away, and the teapot (open, 9120
        // triangles), 2000 points each in a box 1.6 × their size.
        let mut sphere = uv_sphere(1.0, 48, 96);
        sphere.triangles.retain(|t| {
            t.iter()
                .map(|&v| sphere.vertices[v as usize].z)
                .sum::<f64>()
                / 3.0
                < 0.7
        });
        let pot = vps_mesh::builtin::teapot();
        let c = pot.bounds().center();
        let h = pot.bounds().size().max_element() * 0.8;
        let pot_pts: Vec<DVec3> = points(2000, h).into_iter().map(|p| p + c).collect();
        for (name, m, pts) in [
            ("open sphere", &sphere, points(2000, 1.6)),
            ("teapot", &pot, pot_pts),
        ] {
            for beta in [2.0, 3.0] {
                let (mean, worst) = errors(m, beta, &pts);
                println!("{name}: beta {beta}: mean error {mean:.5}, largest {worst:.4}");
                if beta == BETA {
                    assert!(mean < 0.01 && worst < 0.1, "{name}: {mean} {worst}");
                }
            }
        }
    }
}
