//! Mass properties of the dynamic object from its mesh (docs/architecture.md#voxmaps-and-point-shells): volume, centre of mass and the
//! bounding radius about the centre of mass.

use crate::bitgrid::BitGrid;
use glam::DVec3;
use std::collections::HashMap;
use vps_mesh::TriMesh;
use vps_voxmap::{GridSpec, MassProperties};

/// Volume (m³), centre of mass (m, mesh frame, uniform density) and bounding radius (m) of `mesh` by
/// the divergence theorem: a sum of signed tetrahedra from a reference point to every triangle.
///
/// Exact for a closed, consistently oriented mesh (either orientation: an inside-out mesh gives the
/// same result). For an open or inconsistently oriented mesh the signed sum is not a volume; the
/// absolute value is returned as-is and the centre of mass is only an estimate (check with
/// [`is_closed_and_oriented`]). A mesh of zero volume (flat, or cancelling) gets the area-weighted
/// centroid of its triangles as centre of mass. Allocation-free; the mesh must have valid indices.
pub fn mass_properties(mesh: &TriMesh) -> MassProperties {
    let reference = mesh.bounds().center();
    let reference = if reference.is_finite() {
        reference
    } else {
        DVec3::ZERO
    };
    let mut volume6 = 0.0;
    let mut moment = DVec3::ZERO; // sum of 6 V_i * 4 centroid_i relative to the reference
    let mut area2 = 0.0;
    let mut area_moment = DVec3::ZERO;
    for i in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(i).map(|p| p - reference);
        let v6 = a.dot(b.cross(c));
        volume6 += v6;
        moment += v6 * (a + b + c);
        let a2 = (b - a).cross(c - a).length();
        area2 += a2;
        area_moment += a2 * (a + b + c) / 3.0;
    }
    let extent = mesh.bounds().size().max_element();
    let center_of_mass = if volume6.abs() > 1e-12 * extent.powi(3) * 6.0 && volume6.is_finite() {
        reference + moment / (4.0 * volume6)
    } else if area2 > 0.0 {
        reference + area_moment / area2
    } else {
        reference
    };
    MassProperties {
        volume: (volume6 / 6.0).abs(),
        center_of_mass,
        bounding_radius: bounding_radius(mesh, center_of_mass),
    }
}

/// Largest distance of a vertex used by a triangle from `center` (m).
pub(crate) fn bounding_radius(mesh: &TriMesh, center: DVec3) -> f64 {
    mesh.triangles
        .iter()
        .flatten()
        .map(|&v| mesh.vertices[v as usize].distance(center))
        .fold(0.0, f64::max)
}

/// True when `mesh` is closed and consistently oriented: after welding vertices with identical
/// coordinates, every directed edge is used by exactly one triangle and its reverse by exactly one
/// other. Then [`mass_properties`] is exact. Allocates a hash map of edges.
pub fn is_closed_and_oriented(mesh: &TriMesh) -> bool {
    let mut weld: HashMap<[u64; 3], u32> = HashMap::new();
    let ids: Vec<u32> = mesh
        .vertices
        .iter()
        .map(|p| {
            let key = [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()];
            let next = weld.len() as u32;
            *weld.entry(key).or_insert(next)
        })
        .collect();
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in &mesh.triangles {
        let v = t.map(|i| ids[i as usize]);
        if v[0] == v[1] || v[1] == v[2] || v[2] == v[0] {
            return false;
        }
        for k in 0..3 {
            *edges.entry((v[k], v[(k + 1) % 3])).or_insert(0) += 1;
        }
    }
    !edges.is_empty()
        && edges
            .iter()
            .all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
}

/// Volume and centre of mass from a voxelization of the object (offset 0): Interior voxels count
/// fully, Surface voxels half (the surface passes through them). Used for meshes that are not closed
/// and consistently oriented, where the divergence theorem fails; error is of order
/// `area × voxel_size / 2` in volume. Bounding radius from the mesh's vertices.
pub(crate) fn voxel_mass_properties(
    interior: &BitGrid,
    surface: &BitGrid,
    spec: &GridSpec,
    mesh: &TriMesh,
) -> MassProperties {
    let mut weight = 0.0;
    let mut moment = DVec3::ZERO;
    let [_, ny, nz] = interior.dims;
    let rw = interior.row_words;
    for z in 0..nz {
        for y in 0..ny {
            for w in 0..rw {
                let i = (y + ny * z) * rw + w;
                for (plane, wgt) in [(interior, 1.0), (surface, 0.5)] {
                    let mut bits = plane.words[i];
                    while bits != 0 {
                        let x = 64 * w + bits.trailing_zeros() as usize;
                        bits &= bits - 1;
                        let c = spec.center_of(glam::IVec3::new(x as i32, y as i32, z as i32));
                        weight += wgt;
                        moment += wgt * c;
                    }
                }
            }
        }
    }
    let center_of_mass = if weight > 0.0 {
        moment / weight
    } else {
        mesh.bounds().center()
    };
    MassProperties {
        volume: weight * spec.voxel_size.powi(3),
        center_of_mass,
        bounding_radius: bounding_radius(mesh, center_of_mass),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit tetrahedron, outward CCW.
    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn tetrahedron_volume_and_centroid() {
        let m = tetra().transformed(2.0, glam::DQuat::IDENTITY, DVec3::new(5.0, -1.0, 3.0));
        let p = mass_properties(&m);
        assert!((p.volume - 8.0 / 6.0).abs() < 1e-12);
        assert!(p.center_of_mass.distance(DVec3::new(5.5, -0.5, 3.5)) < 1e-12);
        assert!(is_closed_and_oriented(&m));
        // Inside-out gives the same.
        let mut flipped = m.clone();
        for t in &mut flipped.triangles {
            t.swap(1, 2);
        }
        let q = mass_properties(&flipped);
        assert!((q.volume - p.volume).abs() < 1e-12);
        assert!(q.center_of_mass.distance(p.center_of_mass) < 1e-12);
        assert!(is_closed_and_oriented(&flipped));
        // One flipped face: closed but not oriented.
        let mut bad = m.clone();
        bad.triangles[0].swap(1, 2);
        assert!(!is_closed_and_oriented(&bad));
        // Open.
        let mut open = m;
        open.triangles.pop();
        assert!(!is_closed_and_oriented(&open));
    }

    #[test]
    fn bounding_radius_about_com() {
        let p = mass_properties(&tetra());
        let far = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z]
            .iter()
            .map(|v| v.distance(p.center_of_mass))
            .fold(0.0, f64::max);
        assert!((p.bounding_radius - far).abs() < 1e-12);
    }
}
