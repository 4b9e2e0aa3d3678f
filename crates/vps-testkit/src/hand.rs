//! The scripted simulated hand of the standard test session.

use glam::{DQuat, DVec3};
use vps_device::script::{approach_and_rest, Pace};
use vps_device::{HandParams, HapticDevice, SimulatedHand, SurfaceContact};

use crate::scene::WALL_TOP;
use crate::shell::SPHERE_RADIUS;

/// Where the hand (and the part, at rest) starts (m): 4 cm above the wall of
/// [`crate::scene::wall`], over its middle.
pub const START: DVec3 = DVec3::new(0.05, 0.05, 0.09);

/// A simulated hand that moves from [`START`] straight down at 0.1 m/s until the sphere shell
/// ([`crate::shell::sphere_shell`]) would touch the wall, presses 5 mm further (past the half
/// voxel by which the field starts inside the Surface layer) and rests there for 0.1 s.
pub fn approach_and_rest_on_wall() -> Box<dyn HapticDevice> {
    approach_and_rest_on_wall_shifted(DVec3::ZERO)
}

/// [`approach_and_rest_on_wall`] with its start and contact point moved by `shift` (m, along the
/// wall).
pub fn approach_and_rest_on_wall_shifted(shift: DVec3) -> Box<dyn HapticDevice> {
    let contact = SurfaceContact {
        point: DVec3::new(0.05, 0.05, WALL_TOP + SPHERE_RADIUS) + shift,
        normal: DVec3::Z,
        orientation: DQuat::IDENTITY,
    };
    let pace = Pace {
        speed: 0.1,
        press_depth: 0.005,
        dwell: 0.1,
    };
    let script = approach_and_rest(START + shift, &contact, &pace).expect("a valid script");
    Box::new(SimulatedHand::new(script, HandParams::default()).expect("a valid hand"))
}
