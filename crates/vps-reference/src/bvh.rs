//! A bounding-volume hierarchy of axis-aligned boxes: median split on the longest axis of the
//! centroids, at most [`LEAF_SIZE`] primitives per leaf, nodes in depth-first order.

use glam::DVec3;
use vps_mesh::Aabb;

/// Most primitives in one leaf.
pub const LEAF_SIZE: usize = 4;

/// One node: its bounds and either two children or a run of primitives.
#[derive(Clone, Debug)]
struct Node {
    bounds: Aabb,
    /// Leaf: first index into `order`. Internal: index of the right child (the left child is the
    /// next node).
    start_or_right: u32,
    /// Leaf: number of primitives (≥ 1). Internal: 0.
    count: u32,
}

/// The hierarchy over primitives `0..n`, given by their boxes. Immutable after [`Bvh::build`];
/// queries do not allocate beyond a small stack.
#[derive(Clone, Debug)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    boxes: Vec<Aabb>,
}

/// Squared distance (m²) from `p` to the box (0 inside).
pub fn box_distance_sq(b: &Aabb, p: DVec3) -> f64 {
    let d = (b.min - p).max(p - b.max).max(DVec3::ZERO);
    d.length_squared()
}

/// Squared distance (m²) between two boxes (0 when they overlap).
pub fn box_box_distance_sq(a: &Aabb, b: &Aabb) -> f64 {
    let d = (a.min - b.max).max(b.min - a.max).max(DVec3::ZERO);
    d.length_squared()
}

impl Bvh {
    /// Builds the tree over `boxes` (one per primitive; primitive `i` is `boxes[i]`). An empty
    /// slice gives an empty tree whose queries find nothing. Allocates; O(n log n).
    pub fn build(boxes: &[Aabb]) -> Bvh {
        let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
        let centres: Vec<DVec3> = boxes.iter().map(Aabb::center).collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len() / LEAF_SIZE + 1);
        if !boxes.is_empty() {
            build_node(&mut nodes, &mut order, 0, boxes, &centres);
        }
        Bvh {
            nodes,
            order,
            boxes: boxes.to_vec(),
        }
    }

    /// The primitive nearest to `p` by `distance_sq(primitive, best_sq)` (squared metres), among
    /// those whose box lies within `max_sq` of `p`; `None` when no primitive is that close.
    /// `distance_sq` may return any value ≥ `best_sq` when it can tell early that the primitive is
    /// not nearer. Branch and bound: nearer children first, boxes beyond the best are skipped.
    pub fn nearest(
        &self,
        p: DVec3,
        max_sq: f64,
        mut distance_sq: impl FnMut(u32, f64) -> f64,
    ) -> Option<(u32, f64)> {
        let mut best: Option<(u32, f64)> = None;
        let mut best_sq = max_sq;
        let mut stack: Vec<(u32, f64)> = Vec::with_capacity(64);
        if let Some(root) = self.nodes.first() {
            stack.push((0, box_distance_sq(&root.bounds, p)));
        }
        while let Some((i, d)) = stack.pop() {
            if d > best_sq {
                continue;
            }
            let node = &self.nodes[i as usize];
            if node.count > 0 {
                let start = node.start_or_right as usize;
                for &prim in &self.order[start..start + node.count as usize] {
                    let dp = distance_sq(prim, best_sq);
                    if dp <= best_sq {
                        best_sq = dp;
                        best = Some((prim, dp));
                    }
                }
                continue;
            }
            let (l, r) = (i + 1, node.start_or_right);
            let dl = box_distance_sq(&self.nodes[l as usize].bounds, p);
            let dr = box_distance_sq(&self.nodes[r as usize].bounds, p);
            // Push the farther child first so the nearer one is searched first.
            if dl <= dr {
                stack.push((r, dr));
                stack.push((l, dl));
            } else {
                stack.push((l, dl));
                stack.push((r, dr));
            }
        }
        best
    }

    /// Calls `visit` for every primitive whose box lies within `max_sq` (squared metres) of `p`.
    pub fn within(&self, p: DVec3, max_sq: f64, mut visit: impl FnMut(u32)) {
        let mut stack: Vec<u32> = Vec::with_capacity(64);
        if !self.nodes.is_empty() {
            stack.push(0);
        }
        while let Some(i) = stack.pop() {
            let node = &self.nodes[i as usize];
            if box_distance_sq(&node.bounds, p) > max_sq {
                continue;
            }
            if node.count > 0 {
                let start = node.start_or_right as usize;
                self.order[start..start + node.count as usize]
                    .iter()
                    .filter(|&&prim| box_distance_sq(&self.boxes[prim as usize], p) <= max_sq)
                    .for_each(|&prim| visit(prim));
            } else {
                stack.push(node.start_or_right);
                stack.push(i + 1);
            }
        }
    }

    /// The pair (primitive of `self`, primitive of `other`) nearest by `distance_sq(a, b,
    /// best_sq)` (squared metres), among pairs whose boxes lie within `max_sq` of each other;
    /// `None` when no pair is that close. `other` may move: `place` maps a box of `other`'s frame
    /// to a box of `self`'s frame that contains everything the first box contained (for a rigid
    /// motion, the box of the moved box). `distance_sq` may return any value ≥ `best_sq` when it
    /// can tell early that the pair is not nearer. Branch and bound over both trees, the larger
    /// node split first, nearer pairs searched first. Allocates a small stack.
    pub fn nearest_pair(
        &self,
        other: &Bvh,
        place: impl Fn(&Aabb) -> Aabb,
        max_sq: f64,
        mut distance_sq: impl FnMut(u32, u32, f64) -> f64,
    ) -> Option<(u32, u32, f64)> {
        let (Some(a_root), Some(b_root)) = (self.nodes.first(), other.nodes.first()) else {
            return None;
        };
        let mut best: Option<(u32, u32, f64)> = None;
        let mut best_sq = max_sq;
        let mut stack: Vec<(u32, u32, Aabb, f64)> = Vec::with_capacity(128);
        let b_box = place(&b_root.bounds);
        stack.push((0, 0, b_box, box_box_distance_sq(&a_root.bounds, &b_box)));
        let mut children: [(u32, u32, Aabb, f64); 2] = [(0, 0, Aabb::EMPTY, 0.0); 2];
        while let Some((i, j, j_box, d)) = stack.pop() {
            if d > best_sq {
                continue;
            }
            let (a, b) = (&self.nodes[i as usize], &other.nodes[j as usize]);
            if a.count > 0 && b.count > 0 {
                let (sa, sb) = (a.start_or_right as usize, b.start_or_right as usize);
                for &pb in &other.order[sb..sb + b.count as usize] {
                    let pb_box = place(&other.boxes[pb as usize]);
                    for &pa in &self.order[sa..sa + a.count as usize] {
                        if box_box_distance_sq(&self.boxes[pa as usize], &pb_box) > best_sq {
                            continue;
                        }
                        let dp = distance_sq(pa, pb, best_sq);
                        if dp <= best_sq {
                            best_sq = dp;
                            best = Some((pa, pb, dp));
                        }
                    }
                }
                continue;
            }
            let split_a =
                b.count > 0 || (a.count == 0 && a.bounds.size().length() >= j_box.size().length());
            if split_a {
                for (slot, child) in children.iter_mut().zip([i + 1, a.start_or_right]) {
                    let bounds = &self.nodes[child as usize].bounds;
                    *slot = (child, j, j_box, box_box_distance_sq(bounds, &j_box));
                }
            } else {
                for (slot, child) in children.iter_mut().zip([j + 1, b.start_or_right]) {
                    let placed = place(&other.nodes[child as usize].bounds);
                    *slot = (i, child, placed, box_box_distance_sq(&a.bounds, &placed));
                }
            }
            // Push the farther pair first so the nearer one is searched first.
            if children[0].3 <= children[1].3 {
                stack.push(children[1]);
                stack.push(children[0]);
            } else {
                stack.push(children[0]);
                stack.push(children[1]);
            }
        }
        best
    }

    /// Bounds of everything in the tree (empty for an empty tree).
    pub fn bounds(&self) -> Aabb {
        self.nodes.first().map_or(Aabb::EMPTY, |n| n.bounds)
    }
}

/// Builds the node for `order[first..]` (a slice of it) and returns its index.
fn build_node(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    first: usize,
    boxes: &[Aabb],
    centres: &[DVec3],
) -> u32 {
    let bounds = order
        .iter()
        .fold(Aabb::EMPTY, |b, &i| b.union(&boxes[i as usize]));
    let index = nodes.len() as u32;
    nodes.push(Node {
        bounds,
        start_or_right: first as u32,
        count: order.len() as u32,
    });
    if order.len() <= LEAF_SIZE {
        return index;
    }
    let spread = order.iter().fold(Aabb::EMPTY, |mut b, &i| {
        b.grow(centres[i as usize]);
        b
    });
    let size = spread.size();
    let axis = if size.x >= size.y && size.x >= size.z {
        0
    } else if size.y >= size.z {
        1
    } else {
        2
    };
    let mid = order.len() / 2;
    order.select_nth_unstable_by(mid, |&a, &b| {
        centres[a as usize][axis].total_cmp(&centres[b as usize][axis])
    });
    let (left, right) = order.split_at_mut(mid);
    build_node(nodes, left, first, boxes, centres);
    let right_index = build_node(nodes, right, first + mid, boxes, centres);
    nodes[index as usize].start_or_right = right_index;
    nodes[index as usize].count = 0;
    index
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point_boxes(points: &[DVec3]) -> Vec<Aabb> {
        points.iter().map(|&p| Aabb { min: p, max: p }).collect()
    }

    #[test]
    fn nearest_matches_brute_force() {
        // A deterministic scatter of points on a twisted lattice.
        let points: Vec<DVec3> = (0..500)
            .map(|i| {
                let t = i as f64;
                DVec3::new((t * 0.37).sin(), (t * 0.91).cos(), (t * 0.13).sin() * 2.0)
            })
            .collect();
        let bvh = Bvh::build(&point_boxes(&points));
        for q in 0..50 {
            let p = DVec3::new(q as f64 * 0.05 - 1.2, 0.3, (q as f64).cos());
            let (found, d) = bvh
                .nearest(p, f64::INFINITY, |i, _| {
                    points[i as usize].distance_squared(p)
                })
                .unwrap();
            let brute = points
                .iter()
                .map(|x| x.distance_squared(p))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(d, brute);
            assert_eq!(points[found as usize].distance_squared(p), brute);
            let mut near = Vec::new();
            bvh.within(p, 0.25, |i| near.push(i));
            let expected = points
                .iter()
                .filter(|x| x.distance_squared(p) <= 0.25)
                .count();
            assert_eq!(near.len(), expected);
        }
        assert!(bvh.nearest(DVec3::splat(10.0), 1.0, |_, _| 0.0).is_none());
        assert!(Bvh::build(&[])
            .nearest(DVec3::ZERO, 1.0, |_, _| 0.0)
            .is_none());
    }

    #[test]
    fn nearest_pair_matches_brute_force_for_a_moved_set() {
        let scatter = |n: usize, k: f64| -> Vec<DVec3> {
            (0..n)
                .map(|i| {
                    let t = i as f64 * k;
                    DVec3::new((t * 0.37).sin(), (t * 0.91).cos(), (t * 0.13).sin() * 2.0)
                })
                .collect()
        };
        let a = scatter(300, 1.0);
        let b = scatter(200, 1.7);
        let (ta, tb) = (Bvh::build(&point_boxes(&a)), Bvh::build(&point_boxes(&b)));
        for shift in [0.0, 0.5, 3.0] {
            let offset = DVec3::new(shift, -shift * 0.5, 0.25);
            let place = |bx: &Aabb| Aabb {
                min: bx.min + offset,
                max: bx.max + offset,
            };
            let (pa, pb, d) = ta
                .nearest_pair(&tb, place, f64::INFINITY, |i, j, _| {
                    a[i as usize].distance_squared(b[j as usize] + offset)
                })
                .unwrap();
            let brute = a
                .iter()
                .flat_map(|p| b.iter().map(move |q| p.distance_squared(*q + offset)))
                .fold(f64::INFINITY, f64::min);
            assert_eq!(d, brute);
            assert_eq!(
                a[pa as usize].distance_squared(b[pb as usize] + offset),
                brute
            );
        }
        let far = |bx: &Aabb| Aabb {
            min: bx.min + 100.0,
            max: bx.max + 100.0,
        };
        assert!(ta.nearest_pair(&tb, far, 1.0, |_, _, _| 0.0).is_none());
    }
}
