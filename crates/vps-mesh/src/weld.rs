//! Vertex welding: merge vertices that coincide within a tolerance.

use std::collections::HashMap;

use crate::TriMesh;

/// Returns a copy of `mesh` in which vertices that round to the same cell of a grid of pitch
/// `tolerance` (m) are merged into the first of them, and unused vertices are removed. Triangles
/// keep their order and winding; triangles that become degenerate are kept (validation drops
/// them). Allocates; setup-time only.
///
/// Two points closer than `tolerance` that straddle a cell boundary are not merged; with a
/// tolerance far above the rounding noise of the source this is rare and harmless.
pub fn weld_vertices(mesh: &TriMesh, tolerance: f64) -> TriMesh {
    let inv = if tolerance > 0.0 {
        1.0 / tolerance
    } else {
        0.0
    };
    let mut cell_to_new: HashMap<[i64; 3], u32> = HashMap::with_capacity(mesh.vertices.len());
    let mut old_to_new = Vec::with_capacity(mesh.vertices.len());
    let mut vertices = Vec::new();
    for v in &mesh.vertices {
        let key = if inv > 0.0 {
            (*v * inv).round().to_array().map(|c| c as i64)
        } else {
            v.to_array().map(|c| c.to_bits() as i64)
        };
        let index = *cell_to_new.entry(key).or_insert_with(|| {
            vertices.push(*v);
            vertices.len() as u32 - 1
        });
        old_to_new.push(index);
    }
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| old_to_new[i as usize]))
        .collect();
    TriMesh::new(vertices, triangles)
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    #[test]
    fn merges_near_duplicates_and_keeps_winding() {
        let m = TriMesh::new(
            vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::Y,
                DVec3::X + DVec3::splat(1e-12),
                DVec3::ONE,
            ],
            vec![[0, 1, 2], [3, 4, 2]],
        );
        let w = weld_vertices(&m, 1e-9);
        assert_eq!(w.vertices.len(), 4);
        assert_eq!(w.triangles, vec![[0, 1, 2], [1, 3, 2]]);
    }
}
