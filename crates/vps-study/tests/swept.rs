//! The swept volume against analytic shapes: a sphere moved along a straight line sweeps a capsule;
//! a box turned a full turn about an axis through its centre sweeps a cylinder (the circle of its
//! half-diagonal, its height). Checked: the mesh is closed, its vertices lie within one voxel of
//! the analytic surface and points of the analytic surface within one voxel of the mesh
//! (Hausdorff, both ways), and the voxel set's volume and the mesh's volume within 5 % of the
//! analytic volume.

use glam::{DQuat, DVec3};
use std::f64::consts::PI;
use vps_mesh::builtin::{cuboid, uv_sphere};
use vps_mesh::TriMesh;
use vps_study::swept::{swept_volume, SweptLimits, SweptVolume};
use vps_study::PathFrame;

/// Frame `i` of a 1 kHz path at a pose.
fn frame(i: usize, position: DVec3, orientation: DQuat) -> PathFrame {
    PathFrame::at_pose(i as u64, i as f64 * 1e-3, position, orientation)
}

/// Both halves of the Hausdorff distance between `mesh` and the surface whose signed distance is
/// `sdf`, the second over `surface_points`: (largest |sdf| at a mesh vertex, largest distance from
/// a surface point to the mesh).
fn hausdorff(mesh: &TriMesh, sdf: impl Fn(DVec3) -> f64, surface_points: &[DVec3]) -> (f64, f64) {
    let out = mesh
        .vertices
        .iter()
        .map(|&v| sdf(v).abs())
        .fold(0.0, f64::max);
    let exact = vps_reference::ExactScene::new(std::slice::from_ref(mesh)).unwrap();
    let back = surface_points
        .iter()
        .map(|&p| exact.signed_distance(p).distance_m.abs())
        .fold(0.0, f64::max);
    (out, back)
}

/// Checks `swept` against the analytic shape `what` (signed distance `sdf`, points
/// `surface_points` on it, volume `volume`, m³) at voxel size `h`: Hausdorff both ways within one
/// voxel, the voxel set's and the mesh's volumes within 5 %. Prints the figures.
fn check_against(
    what: &str,
    swept: &SweptVolume,
    sdf: impl Fn(DVec3) -> f64,
    surface_points: &[DVec3],
    volume: f64,
    h: f64,
) {
    let (out, back) = hausdorff(&swept.mesh, sdf, surface_points);
    let mesh_volume = swept.mesh.signed_volume();
    eprintln!(
        "{what}: Hausdorff {out:.2e} / {back:.2e} m, voxel volume {:+.2} %, mesh volume {:+.2} %",
        (swept.volume_m3 / volume - 1.0) * 100.0,
        (mesh_volume / volume - 1.0) * 100.0
    );
    assert!(
        out <= h && back <= h,
        "{what}: Hausdorff {out}, {back} against one voxel {h}"
    );
    assert!(
        (swept.volume_m3 - volume).abs() <= 0.05 * volume,
        "{what}: {} vs {volume}",
        swept.volume_m3
    );
    assert!(
        (mesh_volume - volume).abs() <= 0.05 * volume,
        "{what}: {mesh_volume} vs {volume}"
    );
}

fn assert_closed(mesh: &TriMesh) {
    let health = vps_mesh::mesh_health(mesh);
    assert_eq!(health.boundary_edges, 0, "{health:?}");
    assert!(mesh.signed_volume() > 0.0);
}

#[test]
fn a_sphere_along_a_line_sweeps_its_capsule() {
    let (r, length, h) = (0.02, 0.2, 0.004);
    let sphere = uv_sphere(r, 64, 32);
    let path: Vec<PathFrame> = (0..=1000)
        .map(|i| {
            frame(
                i,
                DVec3::new(length * i as f64 / 1000.0, 0.0, 0.0),
                DQuat::IDENTITY,
            )
        })
        .collect();
    let swept = swept_volume(&sphere, &path, h, SweptLimits::default()).unwrap();
    let capsule = |p: DVec3| {
        let x = p.x.clamp(0.0, length);
        p.distance(DVec3::new(x, 0.0, 0.0)) - r
    };
    let volume = PI * r * r * length + 4.0 / 3.0 * PI * r.powi(3);
    assert_closed(&swept.mesh);
    let surface: Vec<DVec3> = (0..400)
        .map(|k| {
            let (t, a) = (k as f64 / 400.0, k as f64 * 2.399);
            let x = -r + t * (length + 2.0 * r);
            let x_axis = x.clamp(0.0, length);
            let rho = (r * r - (x - x_axis).powi(2)).max(0.0).sqrt();
            DVec3::new(x, rho * a.cos(), rho * a.sin())
        })
        .collect();
    check_against("capsule", &swept, capsule, &surface, volume, h);
}

#[test]
fn a_box_turning_about_its_centre_sweeps_a_cylinder() {
    let (a, b, c, h) = (0.03, 0.015, 0.02, 0.003);
    let block = cuboid(DVec3::new(a, b, c));
    let path: Vec<PathFrame> = (0..=2000)
        .map(|i| {
            let turn = 2.0 * PI * i as f64 / 2000.0;
            frame(i, DVec3::new(0.1, -0.05, 0.2), DQuat::from_rotation_z(turn))
        })
        .collect();
    let swept = swept_volume(&block, &path, h, SweptLimits::default()).unwrap();
    let centre = DVec3::new(0.1, -0.05, 0.2);
    let rho = (a * a + b * b).sqrt();
    // The envelope: a cylinder of radius rho about z through the centre, |z| <= c.
    let cylinder = |p: DVec3| {
        let q = p - centre;
        let radial = q.truncate().length() - rho;
        let axial = q.z.abs() - c;
        radial.max(axial).min(0.0) + (radial.max(0.0).powi(2) + axial.max(0.0).powi(2)).sqrt()
    };
    let volume = PI * rho * rho * 2.0 * c;
    assert_closed(&swept.mesh);
    let surface: Vec<DVec3> = (0..400)
        .map(|k| {
            let ang = k as f64 * 2.399;
            let t = k as f64 / 400.0;
            if k % 3 == 0 {
                // On a cap.
                let s = t.sqrt() * rho;
                centre
                    + DVec3::new(
                        s * ang.cos(),
                        s * ang.sin(),
                        if k % 2 == 0 { c } else { -c },
                    )
            } else {
                centre + DVec3::new(rho * ang.cos(), rho * ang.sin(), -c + 2.0 * c * t)
            }
        })
        .collect();
    check_against("turning box", &swept, cylinder, &surface, volume, h);
}
