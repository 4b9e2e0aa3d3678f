//! The analytic benchmark's own checks: the exact reference agrees with each scene's analytic
//! contact direction, and the voxel force meets the bounds documented in docs/fidelity.md on a
//! reduced grid (5 and 2.5 mm, 2- and 4-bit, both shell methods, every separation, 2 poses each).

use glam::DVec3;
use vps_fidelity::measure::{FidelityGrid, ForceModel, SettingRow};
use vps_fidelity::{run, SceneKind};
use vps_reference::{reference_contact, ExactScene};
use vps_voxelize::{point_shell, ShellMethod, VoxelWidth};

/// At a face-on pose half a voxel from the obstacle, the exact force points along the scene's
/// analytic direction (within 1°; the corner within 5°), and the tilted box's torque is about a horizontal axis.
#[test]
fn reference_matches_the_analytic_direction() {
    let s = 0.005;
    for scene in SceneKind::ALL {
        let part = scene.part();
        let shell = point_shell(&part, s, ShellMethod::ExactSurface).unwrap();
        let body: Vec<DVec3> = part
            .vertices
            .iter()
            .map(|v| *v - shell.mass.center_of_mass)
            .collect();
        // u = ½ puts the sphere's and the corner cube's rotation at identity; u[2] = 0 the others'.
        let u = match scene {
            SceneKind::SpherePlane | SceneKind::Corner => [0.5, 0.5, 0.5],
            _ => [0.5, 0.5, 0.0],
        };
        let (position, orientation) = scene.pose(&body, 0.5 * s, s, u);
        let exact = ExactScene::new(&scene.obstacles(s)).unwrap();
        let r = reference_contact(
            &exact,
            &shell.points,
            position,
            orientation,
            2.5 * s,
            3.5 * s,
        );
        let dir = r.force_direction().expect("contact at half a voxel");
        let err = dir
            .angle_between(scene.analytic_force_direction())
            .to_degrees();
        println!(
            "{}: exact direction {dir:.4} ({err:.3}° off), torque {:?}",
            scene.name(),
            r.depth_torque_sum_m2
        );
        // The corner cube's shell points on its edges lie within δ of both walls and are sampled
        // on the shell's own lattice, not mirror-symmetrically between the two faces: 3.4° off
        // the bisector measured at this pose.
        let tolerance = if scene == SceneKind::Corner { 5.0 } else { 1.0 };
        assert!(err < tolerance, "{}: {err}°", scene.name());
        assert_eq!(r.penetrating_points, 0, "{}", scene.name());
        if scene == SceneKind::TiltedBox {
            let t = r.depth_torque_sum_m2;
            assert!(t.length() > 0.0 && t.z.abs() < 1e-3 * t.length(), "{t}");
        }
    }
}

fn row<'a>(rows: &'a [SettingRow], mm: f64, bits: u32, method: &str) -> &'a SettingRow {
    rows.iter()
        .find(|r| {
            r.model == "tangent-plane"
                && r.voxel_size_mm == mm
                && r.bits == bits
                && r.method == method
        })
        .unwrap()
}

/// Bounds the current method meets on the reduced grid (the full grid's figures are in
/// docs/fidelity.md):
/// - 4-bit maps: pooled force direction error p50 ≤ 15° at 5 mm and ≤ 7° at 2.5 mm, no larger at
///   2.5 mm than at 5 mm (+1°), force ratio p50 in [0.6, 1.2], no pose with an Interior point, no
///   pose where the exact force pushes and the field does not; sliding, the p99 frame-to-frame force
///   jump is at most 7 % of the mean force.
/// - 2-bit maps (the paper's): force direction error p50 ≤ 90°, with Interior points at the
///   penetrating separations and a sliding p99 jump of 0.5–2× the mean force: the 2-bit depth
///   `N·(C − P)` restarts in every voxel of the force layer, so it neither grows with depth nor
///   stays smooth. The test holds these as the known weakness (it fails if they improve past the
///   4-bit figures without the doc being updated, or get worse).
#[test]
fn reduced_grid_meets_the_documented_bounds() {
    let grid = FidelityGrid {
        voxel_sizes_m: vec![0.005, 0.0025],
        widths: vec![VoxelWidth::Two, VoxelWidth::Four],
        poses: 2,
        slide_frames: 100,
        models: vec![ForceModel::TangentPlane],
        ..FidelityGrid::full()
    };
    let report = run(&grid).unwrap();
    for r in &report.rows {
        println!(
            "{} mm {}-bit {}: dir p50 {:.1}° p95 {:.1}°, ratio {:.2}, interior {}, ref-only {}, slide |F| {:.3} N p99 jump {:.3} N ({:.3})",
            r.voxel_size_mm, r.bits, r.method, r.all.force_dir_err_deg_p50, r.all.force_dir_err_deg_p95,
            r.all.force_ratio_p50, r.all.interior_poses, r.all.reference_only, r.slide_deep.mean_force_n,
            r.slide_deep.p99_jump_n, r.slide_deep.p99_jump_relative
        );
        assert!(r.all.compared > 0);
        for slide in [&r.slide_shallow, &r.slide_deep] {
            assert!(slide.reference_p99_jump_n < 1e-9 * slide.mean_force_n.max(1.0));
            assert!(slide.mean_force_n > 0.0);
        }
        println!(
            "   shallow slide |F| {:.3} N p99 jump {:.3} N ({:.3})",
            r.slide_shallow.mean_force_n,
            r.slide_shallow.p99_jump_n,
            r.slide_shallow.p99_jump_relative
        );
    }
    for method in ["centres", "exact"] {
        let (coarse, fine) = (
            row(&report.rows, 5.0, 4, method),
            row(&report.rows, 2.5, 4, method),
        );
        assert!(coarse.all.force_dir_err_deg_p50 <= 15.0, "{method}");
        assert!(fine.all.force_dir_err_deg_p50 <= 7.0, "{method}");
        assert!(fine.all.force_dir_err_deg_p50 <= coarse.all.force_dir_err_deg_p50 + 1.0);
        for r in [coarse, fine] {
            assert!((0.6..=1.2).contains(&r.all.force_ratio_p50), "{method}");
            assert_eq!(r.all.interior_poses, 0, "{method}");
            assert_eq!(r.all.reference_only, 0, "{method}");
            assert!(r.slide_deep.p99_jump_relative <= 0.07, "{method}");
        }
        for mm in [5.0, 2.5] {
            let two = row(&report.rows, mm, 2, method);
            assert!(two.all.force_dir_err_deg_p50 <= 90.0, "{method} {mm}");
            assert!(two.all.interior_poses > 0, "{method} {mm}");
            assert!(two.slide_deep.p99_jump_relative <= 2.0, "{method} {mm}");
        }
    }
}

/// The distance model (signed-distance band, default stand-off of half a voxel) on 4-bit maps with
/// exact-surface shells, at 5 mm and 2.5 mm: pooled force direction error p50 ≤ 1° and p95 ≤ 5°,
/// tilted box and corner p50 ≤ 2°, force ratio p50 in [0.9, 1.1], the error no larger at 2.5 mm
/// than at 5 mm, no pose where the exact force pushes and the band does not, and sliding at
/// 2.5 mm a p99 frame-to-frame jump of at most 1 % of the mean force.
#[test]
fn the_distance_model_follows_the_exact_geometry() {
    let grid = FidelityGrid {
        voxel_sizes_m: vec![0.005, 0.0025],
        widths: vec![VoxelWidth::Four],
        methods: vec![vps_voxelize::ShellMethod::ExactSurface],
        poses: 3,
        slide_frames: 100,
        models: vec![ForceModel::DISTANCE],
        ..FidelityGrid::full()
    };
    let report = run(&grid).unwrap();
    for r in &report.rows {
        println!(
            "{} mm {}: dir p50 {:.2}° p95 {:.2}°, ratio {:.3}, ref-only {}, slide p99 {:.4}",
            r.voxel_size_mm,
            r.model,
            r.all.force_dir_err_deg_p50,
            r.all.force_dir_err_deg_p95,
            r.all.force_ratio_p50,
            r.all.reference_only,
            r.slide_deep.p99_jump_relative
        );
        assert_eq!(r.model, "distance");
        assert!(r.all.compared > 50);
        assert!(r.all.force_dir_err_deg_p50 <= 1.0);
        assert!(r.all.force_dir_err_deg_p95 <= 5.0);
        assert!((0.9..=1.1).contains(&r.all.force_ratio_p50));
        assert_eq!(r.all.reference_only, 0);
        for scene in &r.scenes {
            if scene.scene == "tilted-box" || scene.scene == "corner" {
                assert!(scene.force_dir_err_deg_p50 <= 2.0, "{}", scene.scene);
            }
        }
    }
    let (coarse, fine) = (&report.rows[0], &report.rows[1]);
    assert!(fine.all.force_dir_err_deg_p50 <= coarse.all.force_dir_err_deg_p50 + 1e-9);
    for slide in [&fine.slide_shallow, &fine.slide_deep] {
        assert!(slide.mean_force_n > 0.0);
        assert!(slide.p99_jump_relative <= 0.01);
    }
}
