//! The sampling kernel against hand-made voxmaps: the tangent-plane formula, grid boundaries, and
//! exact merging of partial sums in any split, grouping and order.

use crate::common;

use common::*;
use glam::{DQuat, DVec3, IVec3, Vec3};
use proptest::prelude::*;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vps_haptic::{
    sample_all, sample_class, sample_classes, step, ClassedShell, HapticParams, KernelPose,
    PartState, PartialSums,
};
use vps_voxmap::{DenseGrid, Voxel};

/// A grid of [`spec`] with one Surface voxel, the voxel's centre (m) and an oblique unit normal.
fn one_surface_voxel() -> (DenseGrid, DVec3, Vec3) {
    let mut grid = DenseGrid::new(spec());
    let ijk = IVec3::new(21, 22, 23);
    grid.set(ijk, Voxel::Surface);
    let centre = grid.spec.center_of(ijk);
    (grid, centre, Vec3::new(0.3, -0.5, 0.8).normalize())
}

/// One point in one Surface voxel: the sums are d N and (P − x) × d N with
/// d = max(0, N·(C − P)), computed here independently in f64.
#[test]
fn single_point_matches_the_tangent_plane_formula() {
    let (grid, centre, body_normal) = one_surface_voxel();
    let body_point = Vec3::new(0.004, -0.002, 0.003);
    let shell = ClassedShell::new(&shell_from(&[body_point], &[body_normal]), 1);
    let orientation = DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.2, 0.7);
    let lever = orientation * body_point.as_dvec3();
    let normal = orientation * body_normal.as_dvec3();
    // Place the point 1.1 mm from the centre against the normal, plus a tangential offset.
    let tangent = normal.any_orthonormal_vector();
    let world = centre - 0.0011 * normal + 0.0007 * tangent;
    let state = PartState::at_rest(world - lever, orientation);
    let sums = sample_all(&grid, &shell, &KernelPose::from_state(&state));

    let depth = normal.dot(centre - world).max(0.0);
    assert!((depth - 0.0011).abs() < 1e-9);
    assert_eq!(
        (sums.surface, sums.contacts, sums.non_free, sums.sampled),
        (1, 1, 1, 1)
    );
    let tol = 1e-6 * S;
    assert!(
        (sums.depth_normal_si() - depth * normal).length() < tol,
        "{sums:?}"
    );
    assert!((sums.depth_torque_si() - lever.cross(depth * normal)).length() < tol * 0.05);

    // The frame's contact force is K_ff d N (one contact: no averaging).
    let params = HapticParams::default();
    let handle = handle_at(state.position, DVec3::ZERO);
    let out = step(&params, &state, &handle, &sums);
    let expected = params.gains().k_ff * depth * normal;
    assert!((out.contact_wrench.force - expected).length() < 1e-5 * expected.length());
    assert!(out.touching && !out.penetrating && out.contacts == 1);
}

/// A point above the voxel centre (along its normal) has zero depth: it is in Surface but not a
/// contact.
#[test]
fn point_on_the_outer_half_of_a_surface_voxel_is_not_a_contact() {
    let mut grid = DenseGrid::new(spec());
    let ijk = IVec3::new(20, 20, 20);
    grid.set(ijk, Voxel::Surface);
    let shell = ClassedShell::new(&shell_from(&[Vec3::ZERO], &[Vec3::Z]), 1);
    let state = PartState::at_rest(grid.spec.center_of(ijk) + DVec3::Z * 0.001, DQuat::IDENTITY);
    let sums = sample_all(&grid, &shell, &KernelPose::from_state(&state));
    assert_eq!((sums.surface, sums.contacts), (1, 0));
    assert_eq!(sums.depth_normal, [0; 3]);
}

/// Points outside the grid, on every side, read Free; a point just inside the minimum corner reads
/// its voxel.
#[test]
fn outside_the_grid_is_free() {
    let mut grid = DenseGrid::new(spec());
    grid.data.fill(Voxel::Interior as u8);
    let lo = grid.spec.origin;
    let hi = grid.spec.max_corner();
    let outside = [
        lo - DVec3::splat(1e-4),
        DVec3::new(lo.x - 1e-4, 0.0, 0.0),
        DVec3::new(0.0, hi.y + 1e-4, 0.0),
        DVec3::new(0.0, 0.0, hi.z + 1e-4),
        DVec3::splat(1e5),
    ];
    let shell = ClassedShell::new(&shell_from(&[Vec3::ZERO], &[Vec3::Z]), 1);
    for p in outside {
        let sums = sample_all(
            &grid,
            &shell,
            &KernelPose::from_state(&PartState::at_rest(p, DQuat::IDENTITY)),
        );
        assert_eq!(sums.non_free, 0, "{p}");
    }
    let inside = PartState::at_rest(lo + DVec3::splat(1e-4), DQuat::IDENTITY);
    let sums = sample_all(&grid, &shell, &KernelPose::from_state(&inside));
    assert_eq!(sums.interior, 1);
}

/// Approaching Proximity points feed the braking sums; receding ones do not.
#[test]
fn braking_sums_only_for_approaching_points() {
    let grid = half_space();
    let shell = ClassedShell::new(&shell_from(&[Vec3::ZERO], &[Vec3::Z]), 1);
    let mut state = PartState::at_rest(DVec3::new(0.0011, 0.0012, 0.002), DQuat::IDENTITY);
    state.linear_velocity = DVec3::new(0.1, 0.0, -0.3);
    let sums = sample_all(&grid, &shell, &KernelPose::from_state(&state));
    assert_eq!((sums.non_free, sums.approaching), (1, 1));
    assert!((sums.brake_sq_si() - 0.09).abs() < 1e-7);
    assert!((sums.brake_force_si() - DVec3::new(0.0, 0.0, -0.3)).length() < 1e-7);
    state.linear_velocity.z = 0.3;
    let sums = sample_all(&grid, &shell, &KernelPose::from_state(&state));
    assert_eq!((sums.non_free, sums.approaching, sums.brake_sq), (1, 0, 0));
}

/// A random voxmap around the origin and a random shell of `n` points.
fn random_scene(seed: u64, n: usize) -> (DenseGrid, vps_voxmap::PointShell) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut grid = DenseGrid::new(spec());
    for b in grid.data.iter_mut() {
        *b = rng.gen_range(0..4u8);
    }
    let points: Vec<Vec3> = (0..n)
        .map(|_| {
            Vec3::new(
                rng.gen_range(-0.03..0.03),
                rng.gen_range(-0.03..0.03),
                rng.gen_range(-0.03..0.03),
            )
        })
        .collect();
    let normals: Vec<Vec3> = (0..n)
        .map(|_| {
            Vec3::new(
                rng.gen_range(-1.0..1.0),
                rng.gen_range(-1.0..1.0),
                rng.gen_range(0.1..1.0),
            )
        })
        .collect();
    (grid, shell_from(&points, &normals))
}

fn random_state(rng: &mut ChaCha8Rng) -> PartState {
    let mut s = PartState::at_rest(
        DVec3::new(
            rng.gen_range(-0.05..0.05),
            rng.gen_range(-0.05..0.05),
            rng.gen_range(-0.05..0.05),
        ),
        DQuat::from_scaled_axis(DVec3::new(
            rng.gen_range(-2.0..2.0),
            rng.gen_range(-2.0..2.0),
            rng.gen_range(-2.0..2.0),
        )),
    );
    s.linear_velocity = DVec3::new(
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    );
    s.angular_velocity = DVec3::new(
        rng.gen_range(-9.0..9.0),
        rng.gen_range(-9.0..9.0),
        rng.gen_range(-9.0..9.0),
    );
    s
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// For a fixed class count C, the merged sums and the step's output are bit-identical for any
    /// grouping of the classes into shares, merged in any order (docs/architecture.md#exact-sums-and-the-cluster: classes are the unit of
    /// work). Across different class counts the rounding of the class totals differs, so sums
    /// agree to within a few LSB per class, not bit for bit.
    #[test]
    fn partial_sums_merge_exactly_in_any_split(seed in any::<u64>(), n in 1usize..600) {
        let (grid, shell) = random_scene(seed, n);
        let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
        let state = random_state(&mut rng);
        let pose = KernelPose::from_state(&state);
        let single = sample_all(&grid, &ClassedShell::new(&shell, 1), &pose);
        prop_assert_eq!(single.sampled, n as u64);
        prop_assert!(single.non_free > 0 || n < 5);
        prop_assert!(single.is_plausible(n as u64, PartialSums::max_contact_depth(S, 1)));
        prop_assert!(single.torque_within(
            shell.max_radius() + 1e-6,
            PartialSums::max_contact_depth(S, 1)
        ));
        let params = HapticParams::default();
        let handle = handle_at(DVec3::new(0.01, 0.0, 0.0), DVec3::ZERO);
        for classes in [1u32, 2, 3, 8, 64] {
            let classed = ClassedShell::new(&shell, classes);
            prop_assert_eq!(classed.len(), n);
            let total: usize = (0..classes).map(|c| classed.class_len(c)).sum();
            prop_assert_eq!(total, n);
            let reference = sample_all(&grid, &classed, &pose);
            let reference_out = step(&params, &state, &handle, &reference);
            // Counters are exact across class counts; rounded sums within 2 LSB per class.
            prop_assert_eq!(reference.contacts, single.contacts);
            prop_assert_eq!(reference.non_free, single.non_free);
            for k in 0..3 {
                prop_assert!((reference.depth_normal[k] - single.depth_normal[k]).abs() <= 2 * classes as i128);
            }
            // Random order, random groups, groups merged in random order.
            let mut order: Vec<u32> = (0..classes).collect();
            order.shuffle(&mut rng);
            let mut groups: Vec<PartialSums> = Vec::new();
            let mut rest = order.as_slice();
            while !rest.is_empty() {
                let take = rng.gen_range(1..=rest.len());
                groups.push(sample_classes(&grid, &classed, &pose, &rest[..take]));
                rest = &rest[take..];
            }
            groups.shuffle(&mut rng);
            let mut merged = PartialSums::default();
            for g in &groups {
                merged.merge(g);
            }
            prop_assert_eq!(merged, reference);
            let mut one_by_one = PartialSums::default();
            for &c in order.iter().rev() {
                one_by_one.merge(&sample_class(&grid, &classed, &pose, c));
            }
            prop_assert_eq!(one_by_one, reference);
            prop_assert_eq!(step(&params, &state, &handle, &merged), reference_out);
        }
    }
}

/// Tampered replies fail the plausibility checks.
#[test]
fn implausible_sums_are_detected() {
    let (grid, shell) = random_scene(7, 400);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let sums = sample_all(
        &grid,
        &ClassedShell::new(&shell, 1),
        &KernelPose::from_state(&random_state(&mut rng)),
    );
    let depth = PartialSums::max_contact_depth(S, 1);
    assert!(sums.is_plausible(400, depth));
    assert!(!sums.is_plausible(399, depth));
    let mut bad = sums;
    bad.contacts = bad.surface + bad.interior + 1;
    assert!(!bad.is_plausible(400, depth));
    let mut bad = sums;
    bad.depth_normal[0] = i128::from(i64::MAX);
    assert!(!bad.is_plausible(400, depth));
    let mut bad = sums;
    bad.brake_sq = -1;
    assert!(!bad.is_plausible(400, depth));
    let mut bad = sums;
    bad.non_free = bad.sampled + 1;
    assert!(!bad.is_plausible(400, depth));
    let mut bad = sums;
    bad.depth_torque[2] = i128::MAX / 2;
    assert!(!bad.torque_within(0.06, depth));
}

/// A class index past the end, or an insane pose, samples nothing.
#[test]
fn unknown_class_and_insane_pose_sample_nothing() {
    let (grid, shell) = random_scene(3, 50);
    let classed = ClassedShell::new(&shell, 4);
    let pose = KernelPose::from_state(&PartState::at_rest(DVec3::ZERO, DQuat::IDENTITY));
    assert_eq!(
        sample_class(&grid, &classed, &pose, 4),
        PartialSums::default()
    );
    let mut insane = pose;
    insane.translation.x = f32::NAN;
    let sums = sample_class(&grid, &classed, &insane, 0);
    assert_eq!(
        (sums.sampled, sums.non_free),
        (classed.class_len(0) as u64, 0)
    );
    assert_eq!(ClassedShell::new(&shell, 0).class_count(), 1);
    assert_eq!(ClassedShell::new(&shell, 80).class_len(79), 0);
}

/// A dense grid whose Surface voxels report one distance layer: a hand-made stand-in for a 4- or
/// 8-bit voxmap.
struct LayeredGrid {
    grid: DenseGrid,
    surface_layer: u8,
}

impl vps_voxmap::VoxelLookup for LayeredGrid {
    fn spec(&self) -> &vps_voxmap::GridSpec {
        &self.grid.spec
    }
    fn get(&self, ijk: IVec3) -> Voxel {
        self.grid.get(ijk)
    }
    fn get_layered(&self, ijk: IVec3) -> vps_voxmap::LayeredVoxel {
        let kind = self.grid.get(ijk);
        let layer = if kind == Voxel::Surface {
            self.surface_layer
        } else {
            0
        };
        vps_voxmap::LayeredVoxel { kind, layer }
    }
}

/// A point in a Surface voxel of layer ℓ gets depth `d = max(0, N·(C − P) + ℓ s)`: the force grows
/// by `K_ff ℓ s` per layer, also for a point on the outer half of its voxel (negative plane depth).
#[test]
fn deeper_surface_layers_add_one_voxel_of_depth_each() {
    let (grid, centre, body_normal) = one_surface_voxel();
    let shell = ClassedShell::new(&shell_from(&[Vec3::ZERO], &[body_normal]), 1);
    let normal = body_normal.as_dvec3();
    // 1.3 mm on the outer side of the centre: plane depth −1.3 mm.
    let world = centre + 0.0013 * normal;
    let pose = KernelPose::from_state(&PartState::at_rest(world, DQuat::IDENTITY));
    for layer in [0u8, 1, 2, 5] {
        let map = LayeredGrid {
            grid: grid.clone(),
            surface_layer: layer,
        };
        let sums = sample_all(&map, &shell, &pose);
        let depth = (normal.dot(centre - world) + f64::from(layer) * S).max(0.0);
        assert_eq!((sums.surface, sums.contacts), (1, u64::from(layer > 0)));
        assert!(
            (sums.depth_normal_si() - depth * normal).length() < 1e-6 * S,
            "layer {layer}: {sums:?}"
        );
        let params = HapticParams::default();
        let state = PartState::at_rest(world, DQuat::IDENTITY);
        let out = step(&params, &state, &handle_at(world, DVec3::ZERO), &sums);
        let expected = params.gains().k_ff * depth * normal;
        assert!((out.contact_wrench.force - expected).length() <= 1e-5 * expected.length());
    }
}

/// A map reporting layer 0 everywhere (every 2-bit map) gives bit-identical sums to the kind-only
/// lookup, on random scenes with every voxel kind; so does the 512-tree of the same grid, looked
/// up through its leaf directory (block lookups) or walked (no directory).
#[test]
fn layer_zero_maps_give_bit_identical_sums() {
    for seed in 0..4 {
        let (grid, shell) = random_scene(seed, 517);
        let tree = vps_voxmap::VoxelTree::from_dense(&grid, vps_voxmap::TreeConfig::default())
            .expect("valid grid");
        assert!(tree.directory_bytes() > 0);
        let walked = tree.clone().without_directory();
        assert_eq!(walked.directory_bytes(), 0);
        let layered = LayeredGrid {
            grid: grid.clone(),
            surface_layer: 0,
        };
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        for classes in [1u32, 3] {
            let classed = ClassedShell::new(&shell, classes);
            let pose = KernelPose::from_state(&random_state(&mut rng));
            let want = sample_all(&grid, &classed, &pose);
            assert!(want.surface > 0 && want.approaching > 0);
            assert_eq!(sample_all(&layered, &classed, &pose), want);
            assert_eq!(sample_all(&tree, &classed, &pose), want);
            assert_eq!(sample_all(&walked, &classed, &pose), want);
        }
    }
}

/// A shell much finer than the voxmap (many consecutive points per voxel, where the kernel looks up
/// a voxel once for a run of points in it) gives the same counts as sampling every point in a class
/// of its own (no runs), and sums within the rounding of the class totals.
#[test]
fn runs_of_points_in_one_voxel_match_points_sampled_alone() {
    let shell = cube_shell(0.012, 24);
    let n = shell.points.len();
    for (map, z) in [(half_space(), 0.0), (thin_plate(), 0.0115)] {
        let mut state = PartState::at_rest(
            DVec3::new(0.0013, -0.0021, z),
            DQuat::from_euler(glam::EulerRot::XYZ, 0.2, -0.1, 0.3),
        );
        state.linear_velocity = DVec3::new(0.05, 0.02, -0.2);
        state.angular_velocity = DVec3::new(0.5, -1.0, 2.0);
        let pose = KernelPose::from_state(&state);
        let runs = sample_all(&map, &ClassedShell::new(&shell, 1), &pose);
        let alone = sample_all(&map, &ClassedShell::new(&shell, n as u32), &pose);
        // The 512-tree, with its leaf directory and walked, gives the same bits.
        let tree = vps_voxmap::VoxelTree::from_dense(&map, vps_voxmap::TreeConfig::default())
            .expect("valid grid");
        for tree in [tree.clone(), tree.without_directory()] {
            assert_eq!(
                sample_all(&tree, &ClassedShell::new(&shell, 1), &pose),
                runs
            );
        }
        assert!(
            runs.surface > 100 && runs.interior > 10 && runs.approaching > 100,
            "{runs:?}"
        );
        let counts = |s: &PartialSums| {
            (
                s.surface,
                s.contacts,
                s.interior,
                s.approaching,
                s.non_free,
                s.sampled,
            )
        };
        assert_eq!(counts(&runs), counts(&alone));
        for k in 0..3 {
            assert!((runs.depth_normal[k] - alone.depth_normal[k]).abs() <= n as i128);
            assert!((runs.brake_force[k] - alone.brake_force[k]).abs() <= n as i128);
        }
    }
}

/// The voxels of a [`DenseGrid`] with distance layers made up from the position, as the codes of
/// `width`: a 4- or 8-bit voxmap source.
struct LayeredSource<'a> {
    grid: &'a DenseGrid,
    width: vps_voxmap::VoxelWidth,
}

impl vps_voxmap::CubeSource for LayeredSource<'_> {
    fn cube(&self, origin: glam::UVec3, extent: u32, out: &mut [u8]) -> Option<u8> {
        let e = extent as usize;
        for (i, o) in out.iter_mut().enumerate() {
            let p =
                origin + glam::UVec3::new((i % e) as u32, (i / e % e) as u32, (i / (e * e)) as u32);
            let kind = self.grid.get(p.as_ivec3());
            let layer = match kind {
                Voxel::Surface => (p.x + 2 * p.y + p.z) % u32::from(self.width.surface_layers()),
                Voxel::Proximity => {
                    (p.x + p.y + 3 * p.z) % u32::from(self.width.proximity_layers())
                }
                _ => 0,
            };
            let inside = (0..3).all(|a| p[a] < self.grid.spec.dims[a]);
            *o = if inside {
                let v = vps_voxmap::LayeredVoxel {
                    kind,
                    layer: layer as u8,
                };
                self.width.encode(v).expect("layer within the width")
            } else {
                0
            };
        }
        None
    }
}

/// A tree's lookups as plain calls: no per-format copy of the kernel
/// (`VoxelLookup::specialised` left at its default).
struct Unspecialised<'a>(&'a vps_voxmap::VoxelTree);

impl vps_voxmap::VoxelLookup for Unspecialised<'_> {
    fn spec(&self) -> &vps_voxmap::GridSpec {
        self.0.spec()
    }
    fn get(&self, ijk: IVec3) -> Voxel {
        self.0.get(ijk)
    }
    fn get_layered(&self, ijk: IVec3) -> vps_voxmap::LayeredVoxel {
        self.0.get_layered(ijk)
    }
}

/// The kernel's copy for a tree's format (2-, 4- and 8-bit 512-trees and another shape, with and
/// without the leaf directory) gives the sums of plain per-voxel lookups, bit for bit, for a
/// random shell (whole-block lookups) and a shell finer than the voxmap (lane-by-lane lookups and
/// blocks wholly in one voxel); and so does the previous kernel (at most the AVX2 copy, 8-lane
/// blocks), so the AVX-512 copy's 16-lane blocks are checked against other code.
#[test]
fn tree_formats_give_the_sums_of_plain_lookups() {
    use vps_voxmap::{TreeConfig, VoxelTree, VoxelWidth};
    let (grid, random_shell) = random_scene(11, 700);
    let fine_shell = cube_shell(0.012, 24);
    // ≈ 40 consecutive points per voxel: whole blocks of 16 in the voxel looked up last.
    let finer_shell = cube_shell(0.012, 200);
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for width in VoxelWidth::ALL {
        for config in [TreeConfig::default(), TreeConfig::uniform(2)] {
            let source = LayeredSource { grid: &grid, width };
            let tree = VoxelTree::from_source(grid.spec, width, config, &source).unwrap();
            assert!(tree.directory_bytes() > 0);
            for tree in [tree.clone(), tree.without_directory()] {
                for (shell, classes) in [(&random_shell, 3), (&fine_shell, 5), (&finer_shell, 1)] {
                    let classed = ClassedShell::new(shell, classes);
                    let pose = KernelPose::from_state(&random_state(&mut rng));
                    let want = sample_all(&Unspecialised(&tree), &classed, &pose);
                    assert!(want.surface > 0, "{width:?} {config:?}: {want:?}");
                    assert_eq!(
                        sample_all(&tree, &classed, &pose),
                        want,
                        "{width:?} {config:?}"
                    );
                    assert_eq!(
                        vps_haptic::avx2_only::sample_all(&tree, &classed, &pose),
                        want,
                        "{width:?} {config:?}, previous kernel"
                    );
                }
            }
        }
    }
}

/// A pose prepared once per frame ([`vps_haptic::KernelFrame`]) samples every class to the same
/// bits as preparing it per class, and [`vps_haptic::sample_mask`] gives the merged classes of its
/// mask: on the layered wall and on its distance band, at poses in contact, moving, and insane.
#[test]
fn a_frame_prepared_once_samples_every_class_to_the_same_bits() {
    let shell = ClassedShell::new(&cube_shell(0.02, 12), 64);
    let layered = half_space();
    let band = half_space_band(0.001);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut poses: Vec<KernelPose> = (0..20)
        .map(|_| {
            let state = PartState {
                position: DVec3::new(
                    rng.gen_range(-0.03..0.03),
                    rng.gen_range(-0.03..0.03),
                    rng.gen_range(0.0..0.03),
                ),
                orientation: DQuat::from_euler(
                    glam::EulerRot::XYZ,
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                    rng.gen_range(-1.0..1.0),
                ),
                linear_velocity: DVec3::new(0.0, 0.0, -rng.gen_range(0.0..2.0)),
                angular_velocity: DVec3::new(rng.gen_range(-3.0..3.0), 0.0, 0.0),
            };
            KernelPose::from_state(&state)
        })
        .collect();
    let mut insane = poses[0];
    insane.translation.x = f32::NAN;
    poses.push(insane);
    let mut touched = 0;
    for pose in &poses {
        touched += prepared_once_matches(&layered, &shell, pose);
        touched += prepared_once_matches(&band, &shell, pose);
    }
    assert!(touched > 0, "some poses touch the wall");
}

/// Asserts, for `map` at `pose`, that every class sampled with the pose prepared once equals the
/// class sampled on its own, and that a mask's sums are its classes' merged; returns the mask's
/// non-Free point count.
fn prepared_once_matches<L: vps_voxmap::VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
) -> u64 {
    use vps_haptic::{sample_class_in, sample_mask, KernelFrame};
    let mask = 0xA5A5_F00F_0123_4567u64;
    let frame = KernelFrame::new(map, shell, pose);
    let mut merged = PartialSums::default();
    for class in 0..64 {
        let per_class = sample_class(map, shell, pose, class);
        assert_eq!(
            per_class,
            sample_class_in(map, shell, &frame, class),
            "class {class} at {pose:?}"
        );
        if mask >> class & 1 == 1 {
            merged.merge(&per_class);
        }
    }
    assert_eq!(merged, sample_mask(map, shell, pose, mask), "{pose:?}");
    merged.non_free
}
