//! A mesh's health: whether it is a closed, consistently oriented surface (so it bounds a solid)
//! and, when it is not, what is wrong with it: boundary edges (open seams, missing caps),
//! non-manifold edges (three or more triangles on one edge), edges whose two triangles disagree
//! on orientation, and how many separate shells it has.
//!
//! Topology is taken from positions, not vertex indices: vertices at exactly the same position
//! (bit for bit) are one vertex here, so a file that repeats a vertex per face (common in OBJ and
//! PLY exports) is not reported open for that. Vertices that differ by rounding are different:
//! such a seam is reported open, as it is one.

use crate::union_find::{find, union};
use crate::TriMesh;
use serde::Serialize;
use std::collections::HashMap;

/// What [`mesh_health`] finds. Counts are of edges and triangles of the mesh as loaded (after the
/// loader dropped its degenerate triangles).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MeshHealth {
    /// Triangles.
    pub triangles: usize,
    /// Distinct vertex positions used by the triangles.
    pub vertices: usize,
    /// Connected pieces (triangles sharing a vertex position).
    pub shells: usize,
    /// Shells that are closed and consistently oriented.
    pub closed_shells: usize,
    /// Edges with one triangle: open seams, holes, missing caps.
    pub boundary_edges: usize,
    /// Edges with three or more triangles.
    pub non_manifold_edges: usize,
    /// Edges with two triangles that run the edge the same way: the two faces disagree about
    /// which side is outside.
    pub inconsistent_edges: usize,
    /// Signed volume (m³) by the divergence theorem: the solid's volume for a closed mesh facing
    /// outward, negative when it faces inward, meaningless when the mesh is open.
    pub signed_volume_m3: f64,
}

impl MeshHealth {
    /// Every edge has exactly two triangles running it in opposite directions: the mesh bounds a
    /// solid (possibly several).
    pub fn closed(&self) -> bool {
        self.boundary_edges == 0 && self.non_manifold_edges == 0 && self.inconsistent_edges == 0
    }

    /// One line for a person: "closed", or what is wrong ("not closed: 12 boundary edges, 2
    /// non-manifold edges").
    pub fn summary(&self) -> String {
        let shells = if self.shells == 1 {
            "1 shell".to_string()
        } else {
            format!("{} shells", self.shells)
        };
        if self.closed() {
            let facing = if self.signed_volume_m3 < 0.0 {
                ", facing inward"
            } else {
                ""
            };
            return format!("closed ({shells}{facing})");
        }
        let mut faults = Vec::new();
        for (n, what) in [
            (self.boundary_edges, "boundary edges"),
            (self.non_manifold_edges, "non-manifold edges"),
            (self.inconsistent_edges, "inconsistently oriented edges"),
        ] {
            if n > 0 {
                faults.push(format!("{n} {what}"));
            }
        }
        format!(
            "not closed: {} ({shells}, {} closed)",
            faults.join(", "),
            self.closed_shells
        )
    }
}

/// The health of `mesh` (vertex indices must be in range, as a validated mesh's are). Allocates
/// maps sized by the triangle count; O(triangles).
pub fn mesh_health(mesh: &TriMesh) -> MeshHealth {
    // One id per distinct position.
    let mut ids: HashMap<[u64; 3], u32> = HashMap::with_capacity(mesh.vertices.len());
    let id_of: Vec<u32> = mesh
        .vertices
        .iter()
        .map(|v| {
            let key = v.to_array().map(|c| (c + 0.0).to_bits());
            let next = ids.len() as u32;
            *ids.entry(key).or_insert(next)
        })
        .collect();
    let mut used = vec![false; ids.len()];
    let mut parent: Vec<u32> = (0..ids.len() as u32).collect();
    // Per undirected edge (low id, high id): triangles on it, and the sum of +1 (runs low → high)
    // and −1 (high → low).
    let mut edges: HashMap<(u32, u32), (u32, i32)> =
        HashMap::with_capacity(mesh.triangles.len() * 2);
    let mut signed_volume_m3 = 0.0;
    for (i, t) in mesh.triangles.iter().enumerate() {
        let [a, b, c] = mesh.triangle(i);
        signed_volume_m3 += a.dot(b.cross(c)) / 6.0;
        let corner = t.map(|v| id_of[v as usize]);
        // Corners at one position have no area (a validated mesh has none) and no edges.
        if corner[0] == corner[1] || corner[1] == corner[2] || corner[0] == corner[2] {
            continue;
        }
        for k in 0..3 {
            let (from, to) = (corner[k], corner[(k + 1) % 3]);
            used[from as usize] = true;
            let entry = edges.entry((from.min(to), from.max(to))).or_insert((0, 0));
            entry.0 += 1;
            entry.1 += if from < to { 1 } else { -1 };
        }
        union(&mut parent, corner[0], corner[1]);
        union(&mut parent, corner[0], corner[2]);
    }
    let (mut boundary_edges, mut non_manifold_edges, mut inconsistent_edges) = (0, 0, 0);
    // A shell is closed when none of its edges is at fault.
    let mut faulty_shell: HashMap<u32, bool> = HashMap::new();
    for (&(low, _), &(count, direction)) in &edges {
        let fault = match count {
            1 => {
                boundary_edges += 1;
                true
            }
            2 if direction != 0 => {
                inconsistent_edges += 1;
                true
            }
            2 => false,
            _ => {
                non_manifold_edges += 1;
                true
            }
        };
        let root = find(&mut parent, low);
        *faulty_shell.entry(root).or_insert(false) |= fault;
    }
    MeshHealth {
        triangles: mesh.triangles.len(),
        vertices: used.iter().filter(|&&u| u).count(),
        shells: faulty_shell.len(),
        closed_shells: faulty_shell.values().filter(|&&f| !f).count(),
        boundary_edges,
        non_manifold_edges,
        inconsistent_edges,
        signed_volume_m3,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::builtin::{cuboid, uv_sphere};
    use glam::{DQuat, DVec3};

    #[test]
    fn a_box_is_closed_with_its_volume() {
        let h = mesh_health(&cuboid(DVec3::splat(0.1)));
        assert!(h.closed(), "{h:?}");
        assert_eq!(
            (h.triangles, h.vertices, h.shells, h.closed_shells),
            (12, 8, 1, 1)
        );
        assert!((h.signed_volume_m3 - 8e-3).abs() < 1e-15, "{h:?}"); // half extents 0.1 m
        assert_eq!(h.summary(), "closed (1 shell)");
    }

    #[test]
    fn a_missing_face_leaves_four_boundary_edges() {
        let mut m = cuboid(DVec3::splat(0.1));
        m.triangles.truncate(10);
        let h = mesh_health(&m);
        assert!(!h.closed());
        assert_eq!(h.boundary_edges, 4, "{h:?}");
        assert_eq!((h.shells, h.closed_shells), (1, 0));
        assert_eq!(
            h.summary(),
            "not closed: 4 boundary edges (1 shell, 0 closed)"
        );
    }

    #[test]
    fn a_flipped_triangle_is_inconsistent_and_a_fin_non_manifold() {
        let mut m = cuboid(DVec3::splat(0.1));
        let t = &mut m.triangles[0];
        t.swap(1, 2);
        let h = mesh_health(&m);
        assert_eq!((h.boundary_edges, h.inconsistent_edges), (0, 3), "{h:?}");
        let mut fin = cuboid(DVec3::splat(0.1));
        let [a, b] = [fin.triangles[0][0], fin.triangles[0][1]];
        fin.vertices.push(DVec3::new(5.0, 5.0, 5.0));
        let far = fin.vertices.len() as u32 - 1;
        fin.triangles.push([a, b, far]);
        let h = mesh_health(&fin);
        assert_eq!(h.non_manifold_edges, 1, "{h:?}");
        assert_eq!(h.boundary_edges, 2, "{h:?}");
    }

    #[test]
    fn repeated_vertices_are_one_position_and_shells_are_counted() {
        // Every triangle with its own three vertices, as a per-face OBJ export writes it.
        let boxed = cuboid(DVec3::splat(0.1));
        let mut split = TriMesh {
            vertices: Vec::new(),
            triangles: Vec::new(),
        };
        for i in 0..boxed.triangles.len() {
            let base = split.vertices.len() as u32;
            split.vertices.extend(boxed.triangle(i));
            split.triangles.push([base, base + 1, base + 2]);
        }
        let mut two = split.clone();
        two.append(&uv_sphere(0.05, 12, 6).transformed(1.0, DQuat::IDENTITY, DVec3::X));
        let h = mesh_health(&two);
        assert!(h.closed(), "{h:?}");
        assert_eq!((h.shells, h.closed_shells), (2, 2));
        let mut flipped = split;
        flipped.flip_winding();
        let h = mesh_health(&flipped);
        assert!(h.closed() && h.signed_volume_m3 < 0.0);
        assert_eq!(h.summary(), "closed (1 shell, facing inward)");
    }

    #[test]
    fn a_single_triangle_is_an_open_sheet() {
        let m = TriMesh {
            vertices: vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            triangles: vec![[0, 1, 2]],
        };
        let h = mesh_health(&m);
        assert_eq!((h.boundary_edges, h.shells, h.closed_shells), (3, 1, 0));
        assert_eq!(h.signed_volume_m3, 0.0);
    }

    /// What the built-in meshes are (printed; the sphere, box and cylinder must be closed).
    #[test]
    fn builtin_meshes_report() {
        for name in crate::builtin::BUILTIN_NAMES {
            let h = mesh_health(&crate::builtin::by_name(name).unwrap());
            eprintln!("builtin:{name}: {} {h:?}", h.summary());
            if ["box", "sphere", "cylinder"].contains(name) {
                assert!(h.closed(), "builtin:{name}: {h:?}");
            }
        }
    }

    /// What the health report costs at scene load, on the largest built-in mesh (the aircraft
    /// bay, 596,032 triangles): a measurement, not a check (timing varies with the machine).
    /// `cargo test --release -p vps-mesh --lib health_cost -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn health_cost_on_the_aircraft_bay() {
        let bay = crate::builtin::by_name("aircraft-bay").unwrap();
        for _ in 0..3 {
            let t = std::time::Instant::now();
            let h = mesh_health(&bay);
            println!(
                "mesh_health on the aircraft bay: {} triangles, {:.0} ms",
                h.triangles,
                t.elapsed().as_secs_f64() * 1e3
            );
        }
    }
}
