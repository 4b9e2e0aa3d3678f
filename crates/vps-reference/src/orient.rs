//! Triangles turned to face outward, for the winding number of a mesh whose exporter wrote them
//! clockwise or in mixed order.
//!
//! The generalized winding number counts a triangle by the side it faces: inside a solid written
//! clockwise (every triangle facing inward, as some exporters write) it is −1, not +1, and where a
//! third of the triangles are flipped it falls to about 1/3. [`oriented_outward`] first makes the
//! triangles of each patch agree (a patch: triangles joined across manifold edges, those that
//! exactly two triangles share; neighbours must run their shared edge in opposite directions),
//! then turns each patch to face outward: a patch whose signed volume about its own area-weighted
//! centroid is negative is reversed. For a closed patch that volume is the solid's; for an open
//! one (a housing with a hole, a box without its lid) it is the volume of the cone from the
//! centroid, positive when the patch faces away from it. A flat patch (volume 0) is left as
//! written. libigl's `bfs_orient` + `orient_outward` (which shoots rays instead) turned the same
//! patches on the 13 public open meshes of `docs/validation/leaky_corpus.py`.

use crate::winding::{WindingTree, BETA};
use glam::DVec3;
use std::collections::VecDeque;
use vps_mesh::TriMesh;

/// Bytes [`oriented_outward`] allocates at most for a mesh of `triangles` triangles (with at
/// most three vertices each), for memory estimates made before it runs.
pub fn estimated_bytes(triangles: usize) -> u64 {
    (triangles as u64)
        .saturating_mul(BYTES_PER_TRIANGLE)
        .saturating_add(WindingTree::estimated_bytes(triangles))
}

/// Peak bytes a triangle costs [`oriented_outward`] besides the winding tree of the patches with a
/// volume (built when some patch is flat): its three edges in the sorted list (48), its neighbours
/// (24), flags, order and queue (14), the copy the tree is built from and the result, each its
/// corners (12) and at most three vertices (72).
const BYTES_PER_TRIANGLE: u64 = 48 + 24 + 14 + 2 * (12 + 72);

/// `mesh` with each patch's triangles made to agree and face outward (module docs): the same
/// vertices, each triangle either as written or with its last two corners swapped. Vertex
/// indices must be in range. O(n log n) in the triangles; allocates at most
/// [`estimated_bytes`].
pub fn oriented_outward(mesh: &TriMesh) -> TriMesh {
    let flip = outward_flips(mesh);
    let triangles = mesh
        .triangles
        .iter()
        .zip(&flip)
        .map(|(&t, &f)| turned(t, f))
        .collect();
    TriMesh::new(mesh.vertices.clone(), triangles)
}

/// Per triangle, whether [`oriented_outward`] reverses it.
pub fn outward_flips(mesh: &TriMesh) -> Vec<bool> {
    let n = mesh.triangles.len();
    let neighbours = manifold_neighbours(mesh);
    let mut flip = vec![false; n];
    let mut seen = vec![false; n];
    // Triangles in patch order; each patch a range of it.
    let mut order: Vec<u32> = Vec::with_capacity(n);
    let mut patches: Vec<std::ops::Range<usize>> = Vec::new();
    let mut queue = VecDeque::new();
    for seed in 0..n {
        if seen[seed] {
            continue;
        }
        seen[seed] = true;
        let start = order.len();
        queue.push_back(seed as u32);
        while let Some(t) = queue.pop_front() {
            order.push(t);
            for &(u, same_way) in &neighbours[t as usize] {
                if u != NONE && !seen[u as usize] {
                    seen[u as usize] = true;
                    flip[u as usize] = flip[t as usize] ^ same_way;
                    queue.push_back(u);
                }
            }
        }
        patches.push(start..order.len());
    }
    drop(neighbours);
    // Patches with a volume of their own are turned by its sign; flat ones are left for below.
    let mut flat = Vec::new();
    for range in patches {
        let patch = &order[range];
        let (volume, area) = signed_volume_about_centroid(mesh, patch, &flip);
        if volume.abs() < FLAT * area.powf(1.5) {
            flat.push(patch);
        } else if volume < 0.0 {
            for &t in patch {
                flip[t as usize] = !flip[t as usize];
            }
        }
    }
    turn_flat_patches(mesh, &flat, &mut flip);
    flip
}

/// A patch whose signed volume about its centroid is under this fraction of its area^1.5 is flat:
/// its own shape does not say which side is out (a lone triangle, a planar panel). A sphere's
/// ratio is 0.09; a cap of a sphere of radius R and width L about L/(24 R).
const FLAT: f64 = 1e-3;

/// Turns each flat patch to face away from the inside of the other patches: the winding number
/// of the patches with a volume of their own, sampled a little in front of and behind the patch's
/// largest triangles, is higher on the inside. A patch with nothing around it (a free panel, a
/// single-triangle part) is left as written.
fn turn_flat_patches(mesh: &TriMesh, flat: &[&[u32]], flip: &mut [bool]) {
    if flat.is_empty() {
        return;
    }
    let mut is_flat = vec![false; mesh.triangles.len()];
    for &t in flat.iter().flat_map(|p| p.iter()) {
        is_flat[t as usize] = true;
    }
    let solid: Vec<[u32; 3]> = (0..mesh.triangles.len())
        .filter(|&t| !is_flat[t])
        .map(|t| turned(mesh.triangles[t], flip[t]))
        .collect();
    if solid.is_empty() {
        return;
    }
    let rest = WindingTree::new(&TriMesh::new(mesh.vertices.clone(), solid), BETA);
    for patch in flat {
        let mut largest: Vec<(f64, u32)> = patch
            .iter()
            .map(|&t| {
                let [a, b, c] = mesh.triangle(t as usize);
                ((b - a).cross(c - a).length(), t)
            })
            .collect();
        largest.sort_unstable_by(|x, y| y.0.total_cmp(&x.0));
        let (mut rise, mut weight) = (0.0, 0.0);
        for &(area2, t) in largest.iter().take(FLAT_SAMPLES) {
            let [a, b, c] = mesh.triangle(t as usize);
            let mut normal = (b - a).cross(c - a).normalize_or_zero();
            if flip[t as usize] {
                normal = -normal;
            }
            let centre = (a + b + c) / 3.0;
            let step = 0.5 * area2.sqrt();
            rise += area2
                * (rest.winding_number(centre + step * normal)
                    - rest.winding_number(centre - step * normal));
            weight += area2;
        }
        // Facing the inside (w rises along the normal): turn it.
        if weight > 0.0 && rise / weight > FLAT_RISE {
            for &t in patch.iter() {
                flip[t as usize] = !flip[t as usize];
            }
        }
    }
}

/// Triangles of a flat patch sampled (its largest).
const FLAT_SAMPLES: usize = 8;

/// Least mean rise of the winding number across a flat patch that turns it (a patch in free space
/// sees a rise of about 0).
const FLAT_RISE: f64 = 1e-3;

/// `t` as written, or with its last two corners swapped.
fn turned(t: [u32; 3], flip: bool) -> [u32; 3] {
    if flip {
        [t[0], t[2], t[1]]
    } else {
        t
    }
}

/// No neighbour across that edge.
const NONE: u32 = u32::MAX;

/// Per triangle, its neighbours across its manifold edges (edges exactly two triangles share;
/// [`NONE`] for the others), each with whether the two run the edge the same way (then one of
/// them must turn).
fn manifold_neighbours(mesh: &TriMesh) -> Vec<[(u32, bool); 3]> {
    // Every edge once per triangle, keyed by its undirected ends, with whether the triangle runs
    // it from the lower index to the higher.
    let mut edges: Vec<((u32, u32), u32, bool)> = Vec::with_capacity(3 * mesh.triangles.len());
    for (t, tri) in mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            edges.push(((a.min(b), a.max(b)), t as u32, a < b));
        }
    }
    edges.sort_unstable_by_key(|e| e.0);
    let mut neighbours = vec![[(NONE, false); 3]; mesh.triangles.len()];
    let mut add = |t: u32, u: u32, same_way: bool| {
        if let Some(slot) = neighbours[t as usize].iter_mut().find(|s| s.0 == NONE) {
            *slot = (u, same_way);
        }
    };
    for group in edges.chunk_by(|a, b| a.0 == b.0) {
        if let [s, t] = group {
            if s.1 != t.1 {
                let same_way = s.2 == t.2;
                add(s.1, t.1, same_way);
                add(t.1, s.1, same_way);
            }
        }
    }
    neighbours
}

/// Signed volume (m³) of the cones from the area-weighted centroid of `patch` to its triangles,
/// each triangle reversed where `flip` says, and the patch's area (m²).
fn signed_volume_about_centroid(mesh: &TriMesh, patch: &[u32], flip: &[bool]) -> (f64, f64) {
    let mut area = 0.0;
    let mut weighted = DVec3::ZERO;
    for &t in patch {
        let [a, b, c] = mesh.triangle(t as usize);
        let w = (b - a).cross(c - a).length();
        area += w;
        weighted += (a + b + c) * w;
    }
    if area <= 0.0 {
        return (0.0, 0.0);
    }
    let centre = weighted / (3.0 * area);
    let volume = patch
        .iter()
        .map(|&t| {
            let [a, b, c] = mesh.triangle(t as usize);
            let v = (a - centre).dot((b - centre).cross(c - centre)) / 6.0;
            if flip[t as usize] {
                -v
            } else {
                v
            }
        })
        .sum();
    (volume, 0.5 * area)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::components::components;
    use crate::winding::winding_number;
    use glam::DQuat;
    use vps_mesh::builtin::{cuboid, uv_sphere};

    /// A closed box and a sphere, written inward, with every third triangle flipped back: turned
    /// outward they are two closed, consistently oriented solids of positive volume, and w is 1
    /// inside each.
    #[test]
    fn scrambled_inward_solids_are_turned_outward() {
        let mut m = cuboid(DVec3::splat(0.1));
        m.append(&uv_sphere(0.1, 12, 6).transformed(1.0, DQuat::IDENTITY, DVec3::X));
        for (i, t) in m.triangles.iter_mut().enumerate() {
            if i % 3 != 0 {
                *t = turned(*t, true);
            }
        }
        let out = oriented_outward(&m);
        let comps = components(&out);
        assert_eq!(comps.len(), 2);
        for c in &comps {
            assert!(c.closed);
            assert_eq!(c.orientation, 1.0);
        }
        for p in [DVec3::ZERO, DVec3::X] {
            assert!((winding_number(&out, p) - 1.0).abs() < 1e-9);
        }
        // Written as it was, w inside is far from 1.
        assert!(winding_number(&m, DVec3::ZERO) < 0.5);
    }

    /// A box without its lid, written inward: turned to face outward, w inside is above ½ again;
    /// a mesh already outward is left as written.
    #[test]
    fn an_inward_open_box_is_turned_and_an_outward_one_is_kept() {
        let mut open = cuboid(DVec3::splat(0.1));
        open.triangles
            .retain(|t| !t.iter().all(|&v| open.vertices[v as usize].z == 0.1));
        assert!(outward_flips(&open).iter().all(|&f| !f));
        let mut inward = open.clone();
        for t in &mut inward.triangles {
            *t = turned(*t, true);
        }
        assert!(winding_number(&inward, DVec3::ZERO) < -0.5);
        assert!(outward_flips(&inward).iter().all(|&f| f));
        assert!(winding_number(&oriented_outward(&inward), DVec3::ZERO) > 0.5);
    }

    /// A box whose lid is a separate patch (its own vertices: not welded to the walls) written
    /// inward: the lid is flat, so its own shape cannot say which side is out; the winding number
    /// of the walls can, and it is turned. Written outward, it is kept.
    #[test]
    fn a_flat_lid_is_turned_by_the_winding_number_of_the_rest() {
        let h = 0.1;
        let mut walls = cuboid(DVec3::splat(h));
        walls
            .triangles
            .retain(|t| !t.iter().all(|&v| walls.vertices[v as usize].z == h));
        let lid = |inward: bool| {
            let tris = if inward {
                vec![[0, 2, 1], [0, 3, 2]]
            } else {
                vec![[0, 1, 2], [0, 2, 3]]
            };
            TriMesh::new(
                vec![
                    DVec3::new(-h, -h, h),
                    DVec3::new(h, -h, h),
                    DVec3::new(h, h, h),
                    DVec3::new(-h, h, h),
                ],
                tris,
            )
        };
        for inward in [true, false] {
            let mut m = walls.clone();
            m.append(&lid(inward));
            let flips = outward_flips(&m);
            assert!(flips[..10].iter().all(|&f| !f));
            assert_eq!(&flips[10..], &[inward, inward], "inward {inward}");
            let w = winding_number(&oriented_outward(&m), DVec3::ZERO);
            assert!((w - 1.0).abs() < 1e-9, "{w}");
        }
    }

    /// A flat patch has no outward side: it is left as written. Triangles joined only at a
    /// non-manifold edge (three sharing it) are separate patches.
    #[test]
    fn a_flat_patch_is_left_and_a_non_manifold_edge_separates_patches() {
        let flat = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y],
            vec![[0, 2, 1], [0, 3, 2]],
        );
        assert_eq!(outward_flips(&flat), vec![false, false]);
        // Three triangles on the edge 0–1, the third running it the same way as the first.
        let fan = TriMesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::Y,
                DVec3::Z,
                DVec3::new(0.5, -1.0, 0.2),
            ],
            vec![[0, 1, 2], [1, 0, 3], [0, 1, 4]],
        );
        assert_eq!(outward_flips(&fan), vec![false, false, false]);
    }
}
