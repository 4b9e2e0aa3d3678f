//! The reference distance against closed-form distances on analytic shapes.

use glam::{DQuat, DVec3, Vec3};
use vps_mesh::builtin::{cuboid, cylinder, teapot, uv_sphere};
use vps_mesh::TriMesh;
use vps_reference::{reference_contact, ExactScene, ReferenceError};
use vps_testkit::shell::fibonacci_directions;

fn scene(mesh: TriMesh) -> ExactScene {
    ExactScene::new(&[mesh]).expect("valid mesh")
}

#[test]
fn cube_faces_edges_corners_inside() {
    let s = scene(cuboid(DVec3::splat(0.05)));
    let r3 = 3f64.sqrt();
    let r2 = 2f64.sqrt();
    // (point, distance, outward normal)
    let cases = [
        (DVec3::new(0.08, 0.01, -0.02), 0.03, DVec3::X),
        (DVec3::new(0.0, -0.09, 0.0), 0.04, DVec3::NEG_Y),
        (
            DVec3::new(0.08, 0.08, 0.0),
            0.03 * r2,
            DVec3::new(1.0, 1.0, 0.0) / r2,
        ),
        (
            DVec3::new(0.06, -0.06, 0.06),
            0.01 * r3,
            DVec3::new(1.0, -1.0, 1.0) / r3,
        ),
        (DVec3::new(0.02, 0.0, 0.0), -0.03, DVec3::X),
        (DVec3::new(0.0, 0.0, -0.045), -0.005, DVec3::NEG_Z),
        (DVec3::new(0.04, 0.0, 0.045), -0.005, DVec3::Z),
    ];
    for (p, d, n) in cases {
        let got = s.signed_distance(p);
        assert!(
            (got.distance_m - d).abs() < 1e-12,
            "{p}: {} != {d}",
            got.distance_m
        );
        assert!(got.normal.distance(n) < 1e-9, "{p}: normal {}", got.normal);
        assert!((got.closest.distance(p) - d.abs()).abs() < 1e-12);
    }
    // Centre: equidistant from all faces, depth 0.05.
    assert!((s.signed_distance(DVec3::ZERO).distance_m + 0.05).abs() < 1e-12);
    // On the face, an edge and a corner: zero, normal the pseudo-normal.
    for (p, n) in [
        (DVec3::new(0.05, 0.01, 0.02), DVec3::X),
        (DVec3::new(0.05, 0.05, 0.0), DVec3::new(1.0, 1.0, 0.0) / r2),
        (DVec3::splat(0.05), DVec3::ONE / r3),
    ] {
        let got = s.signed_distance(p);
        assert!(got.distance_m.abs() < 1e-15, "{p}");
        assert!(got.normal.distance(n) < 1e-9, "{p}: {}", got.normal);
    }
}

#[test]
fn sphere_matches_radius_within_tessellation() {
    let radius = 0.05;
    let s = scene(uv_sphere(radius, 48, 24));
    // Largest gap between the tessellation and the sphere: the sagitta of a 7.5° latitude band.
    let tolerance = radius * (1.0 - (7.5f64.to_radians() / 2.0).cos()) * 2.0;
    for (i, dir) in fibonacci_directions(200).into_iter().enumerate() {
        let r = [0.01, 0.03, 0.049, 0.051, 0.07, 0.2][i % 6];
        let got = s.signed_distance(dir * r);
        let exact = r - radius;
        assert!(
            (got.distance_m - exact).abs() < tolerance,
            "r {r} dir {dir}: {} vs {exact}",
            got.distance_m
        );
        if (r - radius).abs() > 0.01 {
            assert!(got.normal.dot(dir) > 0.99, "normal {} at {dir}", got.normal);
        }
    }
}

#[test]
fn cylinder_sides_caps_rims() {
    let (radius, half) = (0.025, 0.05);
    let s = scene(cylinder(radius, half, 48));
    let tolerance = radius * (1.0 - (std::f64::consts::PI / 48.0).cos()) + 1e-12;
    let exact = |p: DVec3| {
        let rho = p.truncate().length();
        let (dr, dz) = (rho - radius, p.z.abs() - half);
        if dr <= 0.0 && dz <= 0.0 {
            dr.max(dz)
        } else {
            (dr.max(0.0).powi(2) + dz.max(0.0).powi(2)).sqrt()
        }
    };
    for (i, dir) in fibonacci_directions(60).into_iter().enumerate() {
        let flat = DVec3::new(dir.x, dir.y, 0.0).normalize_or(DVec3::X);
        for rho in [0.0, 0.01, 0.02, 0.03, 0.06] {
            for z in [-0.08, -0.049, 0.0, 0.02, 0.05, 0.07] {
                let p = flat * rho + DVec3::Z * z + DVec3::Z * (i as f64 * 1e-4);
                let got = s.signed_distance(p).distance_m;
                assert!(
                    (got - exact(p)).abs() < tolerance,
                    "{p}: {got} vs {}",
                    exact(p)
                );
            }
        }
    }
}

#[test]
fn open_mesh_is_unsigned_and_matches_brute_force() {
    let pot = teapot();
    let s = scene(pot.clone());
    assert!(s.unsigned_components() > 0);
    for (i, dir) in fibonacci_directions(40).into_iter().enumerate() {
        let p = dir * (0.005 + 0.003 * i as f64);
        let brute = (0..pot.triangle_count())
            .map(|t| {
                vps_mesh::closest_point::closest_point(p, &pot.triangle(t))
                    .0
                    .distance(p)
            })
            .fold(f64::INFINITY, f64::min);
        let got = s.signed_distance(p);
        assert!(got.distance_m >= 0.0);
        assert!((got.distance_m - brute).abs() < 1e-12, "{p}");
    }
}

#[test]
fn overlapping_solids_form_a_union() {
    let mut two = cuboid(DVec3::splat(0.05));
    two.append(&cuboid(DVec3::splat(0.05)).transformed(1.0, DQuat::IDENTITY, DVec3::X * 0.08));
    let s = scene(two);
    assert_eq!(s.component_count(), 2);
    // Inside both boxes (depths 15 mm and 5 mm): the deeper single-box depth.
    let p = DVec3::new(0.035, 0.0, 0.0);
    assert!((s.signed_distance(p).distance_m + 0.015).abs() < 1e-12);
    // Inside the second box only (depth 30 mm), 10 mm outside the first.
    let q = DVec3::new(0.06, 0.0, 0.0);
    assert!((s.signed_distance(q).distance_m + 0.03).abs() < 1e-12);
    // Outside both: the plain distance.
    let r = DVec3::new(0.0, 0.08, 0.0);
    assert!((s.signed_distance(r).distance_m - 0.03).abs() < 1e-12);
    // Capped queries: beyond reach is None, inside is always resolved.
    assert!(s
        .signed_distance_within(DVec3::new(0.0, 0.2, 0.0), 0.1)
        .is_none());
    assert!(s.signed_distance_within(p, 1e-6).is_some());
}

#[test]
fn reference_contact_on_a_plane() {
    let s = scene(cuboid(DVec3::splat(0.05)));
    // A 3 × 3 patch of points 2 mm above the top face and one 4 mm inside it, body frame around the
    // part's origin at z = 0.06.
    let mut body: Vec<Vec3> = Vec::new();
    for i in -1..=1 {
        for j in -1..=1 {
            body.push(Vec3::new(i as f32 * 0.01, j as f32 * 0.01, -0.008));
        }
    }
    body.push(Vec3::new(0.0, 0.0, -0.014));
    let c = reference_contact(
        &s,
        &body,
        DVec3::new(0.0, 0.0, 0.06),
        DQuat::IDENTITY,
        0.005,
        0.02,
    );
    assert_eq!(c.points, 10);
    assert_eq!(c.resolved_points, 10);
    assert_eq!(c.penetrating_points, 1);
    assert_eq!(c.contact_points, 10);
    assert!((c.min_separation_m.unwrap() + 0.004).abs() < 1e-6);
    assert!((c.penetration_depth_m() - 0.004).abs() < 1e-6);
    // Depths: nine of 5 − 2 = 3 mm and one of 5 + 4 = 9 mm.
    assert!((c.depth_sum_m - (9.0 * 0.003 + 0.009)).abs() < 1e-6);
    assert!(c.force_direction().unwrap().distance(DVec3::Z) < 1e-9);
    // A symmetric patch gives no torque about the centre line.
    assert!(c.depth_torque_sum_m2.length() < 1e-9);
    // Rotated half a turn about x, the patch is above the part: far from the box, nothing resolved.
    let flipped = DQuat::from_rotation_x(std::f64::consts::PI);
    let far = reference_contact(&s, &body, DVec3::new(0.0, 0.0, 0.06), flipped, 0.005, 0.01);
    assert_eq!(far.resolved_points, 0);
    assert!(far.force_direction().is_none() && far.min_separation_m.is_none());
}

#[test]
fn bad_meshes_are_errors() {
    assert_eq!(ExactScene::new(&[]).unwrap_err(), ReferenceError::Empty);
    let bad_index = TriMesh::new(vec![DVec3::ZERO; 3], vec![[0, 1, 7]]);
    assert!(matches!(
        ExactScene::new(&[cuboid(DVec3::ONE), bad_index]),
        Err(ReferenceError::VertexIndex {
            mesh: 1,
            triangle: 0,
            index: 7,
            ..
        })
    ));
    let nan = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::NAN], vec![[0, 1, 2]]);
    let err = ExactScene::new(&[nan]).unwrap_err();
    assert!(err.to_string().contains("mesh 0, vertex 2"), "{err}");
}

/// The distance alone is `signed_to_triangle_at`'s distance bit for bit, on every triangle of a
/// closed teapot-and-box scene and an open one (a box missing a triangle: unsigned), from points
/// all around them (faces, edges and corners nearest; inside and out).
#[test]
fn the_distance_alone_is_the_signed_distance_s_bits() {
    let mut open = cuboid(DVec3::splat(0.05));
    open.triangles.pop();
    let closed = [
        teapot().transformed(1.0, DQuat::IDENTITY, DVec3::new(0.2, 0.0, 0.0)),
        cuboid(DVec3::splat(0.05)),
    ];
    let mut negative = 0;
    for meshes in [&closed[..], &[open][..]] {
        let s = ExactScene::new(meshes).expect("valid meshes");
        let count: usize = meshes.iter().map(TriMesh::triangle_count).sum();
        let directions = fibonacci_directions(64);
        for t in (0..count as u32).step_by(7) {
            let [a, b, c] = s.triangle(t);
            let centre = (a + b + c) / 3.0;
            for (i, d) in directions.iter().enumerate() {
                let p = centre + *d * (0.002 + 0.01 * (i % 5) as f64);
                let alone = s.signed_distance_to_triangle(p, t);
                let full = s.signed_to_triangle_at(p, t).distance_m;
                assert_eq!(alone.to_bits(), full.to_bits(), "triangle {t}, p {p}");
                negative += usize::from(alone < 0.0);
            }
        }
    }
    assert!(negative > 30, "{negative} points behind a triangle");
}
