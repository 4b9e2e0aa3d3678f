//! One frame: averaging, the free-space rule, the coupling clamp, input rejection, unit
//! quaternions and the device-output invariant.

use crate::common;

use common::*;
use glam::{DQuat, DVec3};
use proptest::prelude::*;
use vps_haptic::contact::contact_wrench;
use vps_haptic::coupling::rotation_vector;
use vps_haptic::sums::LENGTH_SCALE;
use vps_haptic::{step, ClassedShell, HandleSample, HapticParams, PartState, PartialSums};

fn sums_with_contacts(contacts: u64) -> PartialSums {
    PartialSums {
        depth_normal: [0, 0, (0.001 * LENGTH_SCALE) as i128],
        contacts,
        surface: contacts,
        non_free: contacts,
        sampled: contacts,
        ..PartialSums::default()
    }
}

/// Below 10 contacts the force is K_ff Σ d N; from exactly 10 it is (10/N) K_ff Σ d N.
#[test]
fn averaging_starts_at_ten_contacts() {
    let params = HapticParams::default();
    let g = params.gains();
    let raw = g.k_ff * sums_with_contacts(1).depth_normal_si().z;
    assert!((raw - g.k_ff * 0.001).abs() < 1e-9);
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-14 * b.abs();
    let force_z = |n| contact_wrench(&params, &g, &sums_with_contacts(n)).force.z;
    assert_eq!(force_z(1), raw);
    assert_eq!(force_z(9), raw);
    assert!(close(force_z(10), raw));
    assert!(close(force_z(11), raw * 10.0 / 11.0));
    assert!(close(force_z(40), raw * 0.25));
    // With threshold 5 averaging starts at 5.
    let p5 = HapticParams {
        contact_average_threshold: 5,
        ..params
    };
    assert_eq!(contact_wrench(&p5, &g, &sums_with_contacts(4)).force.z, raw);
    assert!(close(
        contact_wrench(&p5, &g, &sums_with_contacts(6)).force.z,
        raw * 5.0 / 6.0
    ));
}

/// All points Free: the device gets exactly zero, however stretched the spring; the part still
/// follows the handle.
#[test]
fn free_space_gives_exactly_zero() {
    let params = HapticParams::default();
    let shell = ClassedShell::new(&cube_shell(0.01, 4), 3);
    let map = half_space();
    let state = PartState::at_rest(DVec3::new(0.0, 0.0, 0.05), DQuat::IDENTITY);
    let handle = HandleSample {
        position: DVec3::new(0.02, -0.01, 0.06),
        orientation: DQuat::from_rotation_z(0.5),
        linear_velocity: DVec3::new(0.1, 0.0, 0.0),
        angular_velocity: DVec3::new(0.0, 0.0, 1.0),
    };
    let out = frame(&params, &map, &shell, &state, &handle);
    assert_eq!(out.device_wrench.force, DVec3::ZERO);
    assert_eq!(out.device_wrench.torque, DVec3::ZERO);
    assert!(out.coupling_wrench.force.length() > 0.1);
    assert!(!out.touching && out.contacts == 0);
    assert!(
        (out.next_state
            .linear_velocity
            .dot(handle.position - state.position))
            > 0.0
    );
    // One point in Proximity is enough to give the device the coupling force.
    let near = PartState::at_rest(DVec3::new(0.0, 0.0, 0.0115), DQuat::IDENTITY);
    let out = frame(&params, &map, &shell, &near, &handle);
    assert!(out.device_wrench.force.length() > 0.1);
    assert_eq!(out.device_wrench.force, -out.coupling_wrench.force);
}

/// The coupling force never exceeds k_T s/2, nor the torque k_R s/(2 r_max).
#[test]
fn coupling_clamp_holds() {
    let params = HapticParams::default();
    let g = params.gains();
    let state = PartState::at_rest(DVec3::ZERO, DQuat::IDENTITY);
    let sums = PartialSums {
        non_free: 1,
        sampled: 1,
        ..PartialSums::default()
    };
    for (offset, speed, angle) in [
        (0.001, 0.0, 0.0),
        (1.0, 0.0, 0.0),
        (0.0, 50.0, 0.0),
        (0.0, 0.0, 3.0),
    ] {
        let handle = HandleSample {
            position: DVec3::new(offset, 0.0, 0.0),
            orientation: DQuat::from_rotation_y(angle),
            linear_velocity: DVec3::new(speed, 0.0, 0.0),
            angular_velocity: DVec3::ZERO,
        };
        let out = step(&params, &state, &handle, &sums);
        let f = out.coupling_wrench.force.length();
        let t = out.coupling_wrench.torque.length();
        assert!(
            f <= g.k_t * params.voxel_size / 2.0,
            "{offset} {speed}: {f}"
        );
        assert!(
            t <= g.k_r * params.voxel_size / (2.0 * params.max_radius),
            "{angle}: {t}"
        );
        assert_eq!(
            out.coupling_clamped,
            offset > 0.01 || speed > 1.0 || angle > 0.1
        );
    }
}

/// The rotation vector takes the shortest arc and matches the axis·angle.
#[test]
fn rotation_vector_is_shortest_arc() {
    let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, -1.0).normalize(), 0.7);
    let v = rotation_vector(q);
    assert!((v - DVec3::new(1.0, 2.0, -1.0).normalize() * 0.7).length() < 1e-12);
    assert!((rotation_vector(-q) - v).length() < 1e-12);
    let big = DQuat::from_rotation_z(1.5 * std::f64::consts::PI);
    assert!(
        (rotation_vector(big) - DVec3::new(0.0, 0.0, -0.5 * std::f64::consts::PI)).length() < 1e-12
    );
    assert_eq!(rotation_vector(DQuat::IDENTITY), DVec3::ZERO);
}

/// NaN, infinite or absurd handle samples are rejected: zero device wrench, state kept.
#[test]
fn bad_handle_samples_are_rejected() {
    let params = HapticParams::default();
    let state = PartState::at_rest(DVec3::new(0.0, 0.0, 0.001), DQuat::IDENTITY);
    let sums = PartialSums {
        non_free: 5,
        surface: 5,
        sampled: 5,
        ..PartialSums::default()
    };
    let good = handle_at(DVec3::new(0.0, 0.0, -0.01), DVec3::ZERO);
    assert!(!step(&params, &state, &good, &sums).rejected_input);
    let mut bad = vec![];
    for f in [f64::NAN, f64::INFINITY, 2e3] {
        bad.push(HandleSample {
            position: DVec3::new(f, 0.0, 0.0),
            ..good
        });
        bad.push(HandleSample {
            linear_velocity: DVec3::new(0.0, f, 0.0),
            ..good
        });
        bad.push(HandleSample {
            angular_velocity: DVec3::new(0.0, 0.0, f * 10.0),
            ..good
        });
    }
    bad.push(HandleSample {
        orientation: DQuat::from_xyzw(0.0, 0.0, 0.0, 2.0),
        ..good
    });
    bad.push(HandleSample {
        orientation: DQuat::from_xyzw(f64::NAN, 0.0, 0.0, 1.0),
        ..good
    });
    for h in bad {
        let out = step(&params, &state, &h, &sums);
        assert!(out.rejected_input, "{h:?}");
        assert_eq!(out.device_wrench, vps_haptic::Wrench::ZERO);
        assert_eq!(out.next_state, state);
    }
    let mut nan_state = state;
    nan_state.angular_velocity.y = f64::NAN;
    let out = step(&params, &nan_state, &good, &sums);
    assert!(out.non_finite && out.device_wrench == vps_haptic::Wrench::ZERO);
}

/// The orientation stays a unit quaternion over 100k steps of fast tumbling.
#[test]
fn quaternion_stays_unit() {
    let params = HapticParams::default();
    let sums = PartialSums {
        non_free: 1,
        sampled: 1,
        ..PartialSums::default()
    };
    let mut state = PartState::at_rest(DVec3::ZERO, DQuat::IDENTITY);
    let mut worst: f64 = 0.0;
    for i in 0..100_000 {
        let t = i as f64 * params.dt;
        let handle = HandleSample {
            position: DVec3::ZERO,
            orientation: DQuat::from_euler(
                glam::EulerRot::XYZ,
                3.0 * t,
                2.0 * (1.3 * t).sin(),
                5.0 * t,
            ),
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
        };
        state = step(&params, &state, &handle, &sums).next_state;
        worst = worst.max((state.orientation.length() - 1.0).abs());
    }
    assert!(worst < 1e-12, "{worst}");
    assert!(state.angular_velocity.length() > 0.1, "the part did rotate");
}

fn wild_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1.0f64..1.0,
        1 => -1e6f64..1e6,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(-f64::INFINITY),
        1 => Just(1e300),
        1 => any::<f64>(),
    ]
}

fn wild_vec() -> impl Strategy<Value = DVec3> {
    (wild_f64(), wild_f64(), wild_f64()).prop_map(|(x, y, z)| DVec3::new(x, y, z))
}

fn wild_quat() -> impl Strategy<Value = DQuat> {
    prop_oneof![
        3 => (-3.0f64..3.0, -3.0f64..3.0, -3.0f64..3.0).prop_map(|(x, y, z)| DQuat::from_scaled_axis(DVec3::new(x, y, z))),
        1 => (wild_f64(), wild_f64(), wild_f64(), wild_f64()).prop_map(|(x, y, z, w)| DQuat::from_xyzw(x, y, z, w)),
    ]
}

fn wild_i128() -> impl Strategy<Value = i128> {
    prop_oneof![3 => -(1i128 << 50)..(1i128 << 50), 1 => any::<i128>()]
}

fn wild_sums() -> impl Strategy<Value = PartialSums> {
    (
        [wild_i128(), wild_i128(), wild_i128()],
        [wild_i128(), wild_i128(), wild_i128()],
        wild_i128(),
        [wild_i128(), wild_i128(), wild_i128()],
        0u64..1_000_000,
        0u64..2,
    )
        .prop_map(|(dn, dt, sq, bf, n, free)| PartialSums {
            depth_normal: dn,
            depth_torque: dt,
            brake_sq: sq,
            brake_force: bf,
            brake_torque: dt,
            contacts: n,
            approaching: n,
            surface: n,
            interior: n / 2,
            non_free: n * free * 3,
            sampled: n * 3,
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    /// Whatever goes in, the device wrench is finite and within the device limits, and the next
    /// state is finite whenever the input state was.
    #[test]
    fn device_output_is_always_finite_and_limited(
        x in wild_vec(), q in wild_quat(), v in wild_vec(), w in wild_vec(),
        hx in wild_vec(), hq in wild_quat(), hv in wild_vec(), hw in wild_vec(),
        sums in wild_sums(),
    ) {
        let params = HapticParams::default();
        let state = PartState { position: x, orientation: q, linear_velocity: v, angular_velocity: w };
        let handle = HandleSample { position: hx, orientation: hq, linear_velocity: hv, angular_velocity: hw };
        let out = step(&params, &state, &handle, &sums);
        let d = out.device_wrench;
        prop_assert!(d.force.is_finite() && d.torque.is_finite());
        // Not limited here (the device layer limits it), but never more than the coupling's.
        prop_assert!(d.force.length() <= out.coupling_wrench.force.length());
        prop_assert!(d.torque.length() <= out.coupling_wrench.torque.length());
        if state.is_finite() {
            prop_assert!(out.next_state.is_finite());
        }
        if !out.rejected_input && !out.non_finite {
            prop_assert!((out.next_state.orientation.length() - 1.0).abs() < 1e-9);
            let speed = out.next_state.linear_velocity.length()
                + out.next_state.angular_velocity.length() * params.max_radius;
            prop_assert!(speed <= params.velocity_guard_fraction * params.voxel_size / params.dt * (1.0 + 1e-9));
        }
    }
}
