//! Point shells and mass properties of dynamic objects.

use glam::{DQuat, DVec3};
use vps_mesh::builtin::{cuboid, uv_sphere};
use vps_mesh::TriMesh;
use vps_voxelize::shell::morton_key;
use vps_voxelize::{
    grid_for, is_closed_and_oriented, mass_properties, point_shell, ShellMethod, VoxelizeOptions,
};
use vps_voxmap::PointShell;

const S: f64 = 0.005;

/// The Morton key of the voxel (of `voxel_size`, on the unpadded grid of `mesh`) holding each
/// point of `shell`, in shell order.
fn voxel_keys(mesh: &TriMesh, shell: &PointShell, voxel_size: f64) -> Vec<u64> {
    let opts = VoxelizeOptions {
        voxel_size,
        offset_layers: 0,
        padding_voxels: 0,
        ..VoxelizeOptions::default()
    };
    let spec = grid_for(&mesh.bounds(), &opts).unwrap();
    shell
        .points
        .iter()
        .map(|p| {
            let ijk = spec.index_of(p.as_dvec3() + shell.mass.center_of_mass);
            morton_key([ijk.x as u32, ijk.y as u32, ijk.z as u32])
        })
        .collect()
}

#[test]
fn sphere_shell_normals_point_to_the_centre() {
    let r = 0.05;
    let c = DVec3::new(0.2, -0.1, 0.05);
    let sphere = uv_sphere(r, 64, 32).transformed(1.0, DQuat::IDENTITY, c);
    for method in [ShellMethod::VoxelCentres, ShellMethod::ExactSurface] {
        let shell = point_shell(&sphere, S, method).unwrap();
        assert_eq!(shell.method, method);
        assert!(shell.mass.center_of_mass.distance(c) < 1e-9);
        assert!(shell.len() > 1000);
        for (p, n) in shell.points.iter().zip(&shell.normals) {
            assert!((n.length() - 1.0).abs() < 1e-5);
            let towards_centre = -p.normalize();
            assert!(n.dot(towards_centre) > 0.9, "{p} {n}");
            let d = p.length() as f64;
            match method {
                // Centres of voxels overlapping the surface: within half a voxel diagonal.
                ShellMethod::VoxelCentres => assert!((d - r).abs() <= S * 0.87, "{d}"),
                // On the facetted surface: within the chord error of the tessellation.
                ShellMethod::ExactSurface => assert!((d - r).abs() < 5e-4, "{d}"),
            }
        }
    }
}

#[test]
fn sphere_volume_within_two_percent() {
    let r = 0.04;
    let m = mass_properties(&uv_sphere(r, 64, 32));
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!(
        (m.volume / exact - 1.0).abs() < 0.02,
        "{} vs {exact}",
        m.volume
    );
    assert!(m.center_of_mass.length() < 1e-12);
    assert!((m.bounding_radius - r).abs() < 1e-12);
}

#[test]
fn cube_shell_count_and_offset_com() {
    // 20-voxel cube placed off the lattice: one voxel layer per face, about 6 (L/s)^2 points.
    let l = 20.0 * S;
    let c = DVec3::new(0.3017, -0.2009, 0.1023);
    let cube = cuboid(DVec3::splat(l / 2.0)).transformed(1.0, DQuat::IDENTITY, c);
    assert!(is_closed_and_oriented(&cube));
    let shell = point_shell(&cube, S, ShellMethod::VoxelCentres).unwrap();
    let ideal = 6.0 * (l / S).powi(2);
    let n = shell.len() as f64;
    assert!(n >= ideal && n <= 1.1 * ideal, "{n} vs {ideal}");
    assert!(shell.mass.center_of_mass.distance(c) < 1e-12);
    assert!((shell.mass.volume - l.powi(3)).abs() < 1e-15);
    // Body frame: the points are centred on the centre of mass.
    let mean = shell.points.iter().map(|p| p.as_dvec3()).sum::<DVec3>() / n;
    assert!(mean.length() < S / 2.0, "{mean}");
    // Points away from edges have their face's inward axis as normal.
    let mut face_points = 0;
    for (p, nrm) in shell.points.iter().zip(&shell.normals) {
        let a = p.as_dvec3().abs().to_array();
        let near: Vec<usize> = (0..3).filter(|&i| a[i] > l / 2.0 - 2.0 * S).collect();
        if let [axis] = near[..] {
            assert!((nrm[axis] + p[axis].signum()).abs() < 1e-5, "{p} {nrm}");
            face_points += 1;
        }
    }
    assert!(face_points as f64 > 0.5 * n, "{face_points}");
}

#[test]
fn shell_is_morton_ordered() {
    let sphere = uv_sphere(0.03, 32, 16);
    let shell = point_shell(&sphere, S, ShellMethod::VoxelCentres).unwrap();
    let keys = voxel_keys(&sphere, &shell, S);
    assert!(keys.windows(2).all(|w| w[0] < w[1]));
}

#[test]
fn shell_of_tetrahedron_is_morton_ordered_and_inward() {
    let m = TriMesh::new(
        vec![DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z],
        vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    );
    let shell = point_shell(&m, 0.05, ShellMethod::VoxelCentres).unwrap();
    let keys = voxel_keys(&m, &shell, 0.05);
    assert!(keys.windows(2).all(|w| w[0] < w[1]), "strict Morton order");
    // Normals point into the tetrahedron: from any point, a small step along the normal lands
    // nearer the centroid than a step against it.
    for (p, n) in shell.points.iter().zip(&shell.normals) {
        assert!((n.length() - 1.0).abs() < 1e-5);
        let p = p.as_dvec3();
        let n = n.as_dvec3();
        assert!((p + 0.01 * n).length() < (p - 0.01 * n).length(), "{p} {n}");
    }
}

#[test]
fn inconsistent_winding_still_gives_inward_normals() {
    // Flip every other triangle of a sphere, like a badly oriented tessellation.
    let r = 0.04;
    let mut sphere = uv_sphere(r, 48, 24);
    for t in sphere.triangles.iter_mut().step_by(2) {
        t.swap(1, 2);
    }
    assert!(!is_closed_and_oriented(&sphere));
    let shell = point_shell(&sphere, S, ShellMethod::ExactSurface).unwrap();
    for (p, n) in shell.points.iter().zip(&shell.normals) {
        assert!(n.dot(-p.normalize()) > 0.9, "{p} {n}");
    }
    // Mass from the voxelization: close to the true values.
    let exact = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!(
        (shell.mass.volume / exact - 1.0).abs() < 0.05,
        "{}",
        shell.mass.volume
    );
    assert!(shell.mass.center_of_mass.length() < S / 4.0);
}

#[test]
fn bad_inputs_are_errors() {
    let sphere = uv_sphere(0.03, 16, 8);
    assert!(point_shell(&sphere, 0.0, ShellMethod::VoxelCentres).is_err());
    assert!(point_shell(&vps_mesh::TriMesh::default(), S, ShellMethod::VoxelCentres).is_err());
}
