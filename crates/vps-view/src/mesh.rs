//! Meshes the page draws: the static scene's meshes and the part's mesh, decimated to a triangle
//! budget by vertex clustering and served as triangle soup (three f32 corners per triangle).
//!
//! Vertex clustering: every vertex moves to the mean of the vertices in its cell of a cubic grid
//! of edge `c`; triangles whose corners fall in fewer than three cells vanish, and repeated
//! triangles are kept once. Large flat faces (a wall of two triangles) keep their shape; fine
//! detail (a pipe's tessellation) is merged down to about `c`. The cell edge is the smallest (to
//! about 5 %) for which the result fits the budget, found by doubling then bisection; each try
//! costs one pass over the mesh's vertices and triangles.

use glam::{DVec3, IVec3, Vec3};
use std::collections::{HashMap, HashSet};
use vps_mesh::TriMesh;

/// A mesh as the page draws it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DrawnMesh {
    /// Triangles as three corners each (m, the mesh's frame), at most the budget.
    pub triangles: Vec<[Vec3; 3]>,
    /// Triangles of the source mesh (before decimation).
    pub source_triangles: usize,
    /// Cell edge of the vertex clustering (m); 0 when the mesh fitted the budget as it was.
    pub cell_m: f64,
}

/// Bisection steps (in log scale) once a factor-2 bracket is found: the cell edge ends within a
/// factor `2^(1/2⁴)` ≈ 1.044 of the smallest fitting one (where the count falls as cells grow).
const BISECTION_STEPS: u32 = 4;

/// Most doublings of the cell edge while bracketing (from a 1 µm-scale start to kilometres).
const MAX_DOUBLINGS: u32 = 64;

/// `mesh` decimated to at most `max_triangles` triangles (see the module docs). Allocates about
/// the mesh's size again; never more than one clustering at a time.
pub fn decimate(mesh: &TriMesh, max_triangles: usize) -> DrawnMesh {
    let source_triangles = mesh.triangle_count();
    if source_triangles <= max_triangles {
        return DrawnMesh {
            triangles: soup(&mesh.vertices, mesh.triangles.iter().copied()),
            source_triangles,
            cell_m: 0.0,
        };
    }
    let bounds = mesh.bounds();
    let diagonal = bounds.size().length().max(1e-9);
    // Surface area over budget: roughly the cell at which a smooth surface has `max` triangles.
    let mut hi = (2.0 * mesh.area() / max_triangles.max(1) as f64)
        .sqrt()
        .clamp(diagonal * 1e-6, diagonal);
    let mut lo = 0.0;
    let mut best = None;
    for _ in 0..MAX_DOUBLINGS {
        let clustered = cluster(mesh, bounds.min, hi);
        if clustered.triangles.len() <= max_triangles {
            best = Some((hi, clustered));
            break;
        }
        lo = hi;
        hi *= 2.0;
    }
    let Some((mut cell, mut clustered)) = best else {
        // A cell larger than the whole mesh always fits (no triangle survives); unreachable in
        // practice, but never loop forever.
        return DrawnMesh {
            triangles: Vec::new(),
            source_triangles,
            cell_m: hi,
        };
    };
    if lo == 0.0 {
        lo = hi / 2.0;
        // The estimate may be far too coarse: step down while halving still fits.
        for _ in 0..MAX_DOUBLINGS {
            let finer = cluster(mesh, bounds.min, lo);
            if finer.triangles.len() > max_triangles {
                break;
            }
            (cell, clustered) = (lo, finer);
            lo /= 2.0;
        }
    }
    for _ in 0..BISECTION_STEPS {
        let mid = (lo * cell).sqrt();
        let tried = cluster(mesh, bounds.min, mid);
        if tried.triangles.len() <= max_triangles {
            (cell, clustered) = (mid, tried);
        } else {
            lo = mid;
        }
    }
    DrawnMesh {
        triangles: soup(&clustered.vertices, clustered.triangles.iter().copied()),
        source_triangles,
        cell_m: cell,
    }
}

/// The meshes merged into one, then [`decimate`]d to `max_triangles` in total.
pub fn decimate_all(meshes: &[TriMesh], max_triangles: usize) -> DrawnMesh {
    let mut merged = TriMesh::default();
    for m in meshes {
        merged.append(m);
    }
    decimate(&merged, max_triangles)
}

/// `mesh` with its vertices clustered in cells of edge `cell` (m) from `origin`.
fn cluster(mesh: &TriMesh, origin: DVec3, cell: f64) -> TriMesh {
    let mut cells: HashMap<IVec3, u32> = HashMap::new();
    let mut sums: Vec<(DVec3, u32)> = Vec::new();
    let rep: Vec<u32> = mesh
        .vertices
        .iter()
        .map(|&v| {
            let key = ((v - origin) / cell).floor().as_ivec3();
            let index = *cells.entry(key).or_insert_with(|| {
                sums.push((DVec3::ZERO, 0));
                (sums.len() - 1) as u32
            });
            let s = &mut sums[index as usize];
            s.0 += v;
            s.1 += 1;
            index
        })
        .collect();
    let vertices = sums.iter().map(|&(sum, n)| sum / n as f64).collect();
    let mut seen = HashSet::new();
    let triangles = mesh
        .triangles
        .iter()
        .map(|t| t.map(|i| rep[i as usize]))
        .filter(|&[a, b, c]| a != b && b != c && a != c)
        .filter(|t| {
            let mut key = *t;
            key.sort_unstable();
            seen.insert(key)
        })
        .collect();
    TriMesh::new(vertices, triangles)
}

/// Triangles as corner triples (f32).
fn soup(vertices: &[DVec3], triangles: impl Iterator<Item = [u32; 3]>) -> Vec<[Vec3; 3]> {
    triangles
        .map(|t| t.map(|i| vertices[i as usize].as_vec3()))
        .collect()
}

/// Little-endian f32 corners, 36 bytes per triangle (x, y, z of each corner in turn): the body of
/// `/scene/mesh` and `/scene/part_mesh`.
pub fn encode_triangles(triangles: &[[Vec3; 3]]) -> Vec<u8> {
    triangles
        .iter()
        .flatten()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use vps_mesh::builtin::{cuboid, uv_sphere};

    #[test]
    fn a_small_mesh_is_kept_as_it_is() {
        let cube = cuboid(DVec3::splat(0.05));
        let drawn = decimate(&cube, 1000);
        assert_eq!(drawn.triangles.len(), 12);
        assert_eq!((drawn.source_triangles, drawn.cell_m), (12, 0.0));
        assert_eq!(
            drawn.triangles[0][0],
            cube.vertices[cube.triangles[0][0] as usize].as_vec3()
        );
        assert_eq!(encode_triangles(&drawn.triangles).len(), 12 * 36);
    }

    #[test]
    fn a_large_mesh_fits_the_budget_and_keeps_its_shape() {
        let sphere = uv_sphere(0.05, 256, 128);
        let n = sphere.triangle_count();
        for budget in [20_000, 2_000, 200] {
            let drawn = decimate(&sphere, budget);
            assert!(drawn.triangles.len() <= budget, "{budget}");
            // Not thrown away: at least a fifth of the budget survives.
            assert!(
                drawn.triangles.len() > budget / 5,
                "{budget}: {}",
                drawn.triangles.len()
            );
            assert!(drawn.cell_m > 0.0 && drawn.source_triangles == n);
            // Every corner stays near the sphere (within a cell of it).
            for p in drawn.triangles.iter().flatten() {
                let r = p.length() as f64;
                assert!(
                    (r - 0.05).abs() < drawn.cell_m * 1.8,
                    "r {r}, cell {}",
                    drawn.cell_m
                );
            }
        }
    }

    #[test]
    fn several_meshes_share_one_budget() {
        let a = uv_sphere(0.05, 128, 64);
        let b = uv_sphere(0.05, 128, 64).transformed(1.0, glam::DQuat::IDENTITY, DVec3::X);
        let drawn = decimate_all(&[a, b], 4000);
        assert!(drawn.triangles.len() <= 4000 && drawn.triangles.len() > 800);
        let right = drawn.triangles.iter().filter(|t| t[0].x > 0.5).count();
        assert!(right > drawn.triangles.len() / 4 && right < drawn.triangles.len() * 3 / 4);
    }
}
