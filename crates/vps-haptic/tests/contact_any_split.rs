//! The contact sums are rounded per point (fixed point), so they are the same bits whatever the
//! class count, not only for any grouping of a fixed class count.

mod common;

use common::*;
use glam::{DQuat, DVec3};
use vps_haptic::{kernel, sample_all, ClassedShell, KernelPose, PartState};

#[test]
fn contact_sums_are_identical_for_every_class_count() {
    let shell = cube_shell(0.012, 24);
    for (map, z) in [(wall(), 0.0), (thin_plate(), 0.0115)] {
        let state = PartState::at_rest(
            DVec3::new(0.0013, -0.0021, z),
            DQuat::from_euler(glam::EulerRot::XYZ, 0.2, -0.1, 0.3),
        );
        let pose = KernelPose::from_state(&state);
        let one = sample_all(&map, &ClassedShell::new(&shell, 1), &pose);
        assert!(one.contacts > 100, "{one:?}");
        for classes in [2u32, 3, 7, 64, 1000] {
            let split = sample_all(&map, &ClassedShell::new(&shell, classes), &pose);
            assert_eq!(
                (split.depth_normal, split.depth_torque, split.contacts),
                (one.depth_normal, one.depth_torque, one.contacts),
                "{classes} classes"
            );
        }
        // The previous kernel (f64 per class) agrees to within its rounding: a few LSB of 2^-40 m
        // per class plus half a quantum (2^-29 m = 2^11 LSB) per contact of the new one.
        let previous = kernel::previous::sample_all(&map, &ClassedShell::new(&shell, 1), &pose);
        assert_eq!(previous.contacts, one.contacts);
        for k in 0..3 {
            let diff = (previous.depth_normal[k] - one.depth_normal[k]).abs();
            assert!(diff <= 2 + ((one.contacts as i128) << 10), "{diff}");
        }
    }
}
