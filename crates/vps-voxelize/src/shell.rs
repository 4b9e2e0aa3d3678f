//! The point shell of the dynamic object (docs/architecture.md#voxmaps-and-point-shells): one point per Surface voxel of the object's own
//! voxelization (offset 0), with an inward unit normal from the mesh, in the body frame (origin at
//! the centre of mass), Morton ordered.

use crate::mass::{is_closed_and_oriented, mass_properties, voxel_mass_properties};
use crate::pipeline::{
    check_objects, check_voxel_size, grid_for, plane_at, voxelize_planes, VoxelizeOptions,
};
use crate::scan_convert::{overlap_pairs, Window};
use crate::stats::VoxelizeStats;
use crate::VoxelizeError;
use glam::{DVec3, IVec3, Vec3};
use rayon::prelude::*;
use vps_mesh::closest_point::closest_point;
use vps_mesh::TriMesh;
use vps_reference::orient::outward_flips;
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{GridSpec, PointShell};

/// Steps (in voxels) along a candidate normal at which the object's voxelization is probed to decide
/// which side is inside.
const PROBE_STEPS: [f64; 3] = [1.5, 2.5, 3.5];

/// Morton (Z-order) key of a non-negative voxel index: the low 21 bits of x, y, z interleaved,
/// x in the lowest bit.
pub fn morton_key(ijk: [u32; 3]) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut x = (v as u64) & 0x1f_ffff;
        x = (x | x << 32) & 0x1f_0000_0000_ffff;
        x = (x | x << 16) & 0x1f_0000_ff00_00ff;
        x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
        x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
        x = (x | x << 2) & 0x1249_2492_4924_9249;
        x
    }
    spread(ijk[0]) | spread(ijk[1]) << 1 | spread(ijk[2]) << 2
}

/// The point shell of `mesh` (its own frame, m) sampled at `voxel_size` (m).
///
/// The mesh is voxelized alone with no offset; every Surface voxel (a voxel its triangles overlap)
/// gives one point: its centre ([`ShellMethod::VoxelCentres`], the paper's method) or the point of
/// the mesh nearest to its centre among the triangles overlapping it
/// ([`ShellMethod::ExactSurface`]).
///
/// Normal rule: the area-weighted average of the inward normals of the triangles of that voxel
/// nearest to its centre (within 1e-6 voxel of the nearest: several at an edge or vertex), unit
/// length. Each triangle's inward side is decided once, by the object's flood-filled voxelization and
/// not by the winding: from the triangle's centroid (then from the midpoints between centroid and
/// each corner) probe 1.5, 2.5, then 3.5 voxels along ± its normal; a side scores Interior above
/// Surface above Free, and the normal points to the side that scores higher at the first probe where they differ.
/// Only when every probe ties (a sheet with no interior, or a part thinner than the probes resolve)
/// does the winding decide: inward = minus the counter-clockwise normal of the triangle turned to
/// face outward ([`vps_reference::orient::outward_flips`]; a flat sheet as written). So badly
/// oriented meshes such as tessellated Bezier teapots still get inward normals.
///
/// Mass properties: [`mass_properties`] when the mesh is closed and consistently oriented
/// ([`is_closed_and_oriented`]); otherwise estimated from the voxelization (Interior voxels plus half
/// of the Surface voxels), since the divergence theorem needs a consistent orientation. Points are
/// stored relative to that centre of mass, as f32, in Morton order of their voxel index.
///
/// Errors: invalid voxel size, an empty or invalid mesh, a grid over [`crate::MAX_VOXELS`].
/// Blocking, parallel, allocates.
pub fn point_shell(
    mesh: &TriMesh,
    voxel_size: f64,
    method: ShellMethod,
) -> Result<PointShell, VoxelizeError> {
    point_shell_within(
        mesh,
        voxel_size,
        method,
        crate::memory::default_memory_budget(),
    )
}

/// [`point_shell`] under a working-memory budget (bytes): the dense grid's estimate is checked
/// against it before any voxel is computed ([`VoxelizeError::OverMemoryBudget`]).
pub fn point_shell_within(
    mesh: &TriMesh,
    voxel_size: f64,
    method: ShellMethod,
    max_memory_bytes: u64,
) -> Result<PointShell, VoxelizeError> {
    check_voxel_size(voxel_size)?;
    let objects = std::slice::from_ref(mesh);
    check_objects(objects)?;
    let opts = VoxelizeOptions {
        voxel_size,
        offset_layers: 0,
        padding_voxels: 0,
        ..VoxelizeOptions::default()
    };
    let spec = grid_for(&mesh.bounds(), &opts)?;
    crate::memory::check_budget(
        crate::memory::estimate_dense(&spec),
        &spec,
        max_memory_bytes,
    )?;
    let layers = voxelize_planes(
        objects,
        &spec,
        0,
        false,
        false,
        &mut VoxelizeStats::default(),
    );
    let mass = if is_closed_and_oriented(mesh) {
        mass_properties(mesh)
    } else {
        voxel_mass_properties(&layers.interior, &layers.surface, &spec, mesh)
    };
    let window = Window::whole(&spec);
    let pairs = overlap_pairs(mesh, &spec, &window);
    // One group of (voxel, triangle) pairs per Surface voxel.
    let mut groups: Vec<&[(u64, u32)]> = pairs.chunk_by(|a, b| a.0 == b.0).collect();
    groups.retain(|g| {
        let ijk = unlinear(&spec, g[0].0);
        plane_at(&layers.surface, ijk)
    });
    let classify = |p: DVec3| -> i8 {
        let ijk = spec.index_of(p);
        if plane_at(&layers.interior, ijk) {
            1
        } else if plane_at(&layers.surface, ijk) {
            0
        } else {
            -1
        }
    };
    let probed: Vec<Option<DVec3>> = (0..mesh.triangle_count())
        .into_par_iter()
        .map(|t| triangle_inward_normal(mesh.triangle(t), spec.voxel_size, classify))
        .collect();
    // Where no probe tells, the winding decides, of the triangles turned to face outward (so a
    // mesh written clockwise or in mixed order gets the normals of one written outward).
    let flips = if probed.iter().any(Option::is_none) {
        outward_flips(mesh)
    } else {
        Vec::new()
    };
    let inward: Vec<DVec3> = probed
        .iter()
        .enumerate()
        .map(|(t, n)| {
            n.unwrap_or_else(|| {
                let wound = wound_inward(mesh.triangle(t));
                if flips[t] {
                    -wound
                } else {
                    wound
                }
            })
        })
        .collect();
    let mut samples: Vec<(u64, Vec3, Vec3)> = groups
        .par_iter()
        .map(|group| {
            let ijk = unlinear(&spec, group[0].0);
            let centre = spec.center_of(ijk);
            let (surface_point, inward) = nearest_and_normal(mesh, &inward, group, centre, &spec);
            let point = match method {
                ShellMethod::VoxelCentres => centre,
                ShellMethod::ExactSurface => surface_point,
            };
            let key = morton_key([ijk.x as u32, ijk.y as u32, ijk.z as u32]);
            let body = (point - mass.center_of_mass).as_vec3();
            (key, body, inward.as_vec3().normalize_or(Vec3::Z))
        })
        .collect();
    samples.par_sort_unstable_by_key(|s| s.0);
    Ok(PointShell {
        points: samples.iter().map(|s| s.1).collect(),
        normals: samples.iter().map(|s| s.2).collect(),
        voxel_size,
        method,
        mass,
    })
}

/// Grid index of a whole-grid linear index.
fn unlinear(spec: &GridSpec, i: u64) -> IVec3 {
    let (nx, ny) = (spec.dims[0] as u64, spec.dims[1] as u64);
    IVec3::new(
        (i % nx) as i32,
        (i / nx % ny) as i32,
        (i / (nx * ny)) as i32,
    )
}

/// The mesh point nearest to `centre` among the group's triangles, and the inward unit normal there:
/// the sum of the area-weighted inward normals `inward` of the triangles within 1e-6 voxel of the
/// nearest (the nearest triangle's alone if they cancel).
fn nearest_and_normal(
    mesh: &TriMesh,
    inward: &[DVec3],
    group: &[(u64, u32)],
    centre: DVec3,
    spec: &GridSpec,
) -> (DVec3, DVec3) {
    let candidates: Vec<(f64, DVec3, DVec3)> = group
        .iter()
        .map(|&(_, t)| {
            let q = closest_point(centre, &mesh.triangle(t as usize)).0;
            (q.distance(centre), q, inward[t as usize])
        })
        .collect();
    let best = candidates
        .iter()
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .copied()
        .unwrap_or((0.0, centre, DVec3::Z));
    let tol = best.0 + 1e-6 * spec.voxel_size;
    let sum: DVec3 = candidates.iter().filter(|c| c.0 <= tol).map(|c| c.2).sum();
    let normal = if sum.length_squared() > 1e-6 * best.2.length_squared() {
        sum
    } else {
        best.2
    };
    (best.1, normal.normalize_or(DVec3::Z))
}

/// The inward normal of triangle `tri`, scaled by twice its area, oriented by probing the object's
/// voxelization (`classify`: Interior 1, Surface 0, Free -1) as described at [`point_shell`];
/// `None` when no probe tells the sides apart.
fn triangle_inward_normal(
    tri: [DVec3; 3],
    s: f64,
    classify: impl Fn(DVec3) -> i8,
) -> Option<DVec3> {
    let wound = wound_inward(tri);
    let unit = wound.normalize_or_zero();
    let centroid = (tri[0] + tri[1] + tri[2]) / 3.0;
    let origins = [
        centroid,
        0.5 * (centroid + tri[0]),
        0.5 * (centroid + tri[1]),
        0.5 * (centroid + tri[2]),
    ];
    for origin in origins {
        match probe_side(origin, unit, s, &classify) {
            Some(true) => return Some(wound),
            Some(false) => return Some(-wound),
            None => {}
        }
    }
    None
}

/// Minus the counter-clockwise normal of `tri`, scaled by twice its area: inward if the triangle
/// is wound counter-clockwise seen from outside.
fn wound_inward(tri: [DVec3; 3]) -> DVec3 {
    -(tri[1] - tri[0]).cross(tri[2] - tri[0])
}

/// Whether `normal` at `point` points inside (`Some(true)`), outside (`Some(false)`) or cannot be
/// told (`None`) from the voxelization, probing [`PROBE_STEPS`] voxels of size `s` on both sides.
fn probe_side(point: DVec3, normal: DVec3, s: f64, classify: impl Fn(DVec3) -> i8) -> Option<bool> {
    for step in PROBE_STEPS {
        let ahead = classify(point + normal * (step * s));
        let behind = classify(point - normal * (step * s));
        if ahead != behind {
            return Some(ahead > behind);
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn morton_interleaves() {
        assert_eq!(morton_key([1, 0, 0]), 1);
        assert_eq!(morton_key([0, 1, 0]), 2);
        assert_eq!(morton_key([0, 0, 1]), 4);
        assert_eq!(morton_key([3, 3, 3]), 63);
        assert_eq!(morton_key([0x1f_ffff; 3]), (1u64 << 63) - 1);
        // Z order: all of the first 2x2x2 block precede (2, 0, 0).
        assert!(morton_key([1, 1, 1]) < morton_key([2, 0, 0]));
    }

    #[test]
    fn orientation_rule_prefers_interior_side() {
        // Inside is x < 0: probes at +x are Free, -x Interior.
        let classify = |p: DVec3| if p.x < 0.0 { 1 } else { -1 };
        assert_eq!(
            probe_side(DVec3::ZERO, DVec3::X, 1.0, classify),
            Some(false)
        );
        assert_eq!(
            probe_side(DVec3::ZERO, -DVec3::X, 1.0, classify),
            Some(true)
        );
        assert_eq!(probe_side(DVec3::ZERO, DVec3::Y, 1.0, |_| -1), None);
        // A triangle in the plane x = 0 wound with outward normal -x (wrong): the probes fix it.
        let tri = [DVec3::ZERO, DVec3::Z, DVec3::Y];
        assert_eq!((tri[1] - tri[0]).cross(tri[2] - tri[0]), -DVec3::X);
        assert_eq!(triangle_inward_normal(tri, 0.1, classify), Some(-DVec3::X));
        // Undecidable: left to the winding.
        assert_eq!(triangle_inward_normal(tri, 0.1, |_| -1), None);
    }
}
