//! The bridge device's workspace mapping, clutch and pose timeout, over real UDP on 127.0.0.1.
//!
//! Device time is passed in explicitly: each step polls `read` at one fixed time until the
//! datagram count is reached, so how long loopback delivery takes never changes what the device
//! sees as the pose's age.

use crate::common;

use common::{poll_until, DEADLINE};

use glam::{DQuat, DVec3};
use vps_device::HapticDevice;
use vps_haptic::{HandleSample, Wrench};
use vps_input::bridge::protocol::FLAG_CLUTCH;
use vps_input::{BridgeClient, BridgeConfig, BridgeCounters, BridgeDevice, WorkspaceMapping};

/// The voxel size of the default `vps run` scene (m): the bound on a release jump.
const VOXEL: f64 = 0.005;

fn at(p: DVec3) -> HandleSample {
    HandleSample {
        position: p,
        orientation: DQuat::from_rotation_x(0.2),
        linear_velocity: DVec3::new(0.3, 0.0, 0.0),
        angular_velocity: DVec3::new(0.0, 0.5, 0.0),
    }
}

/// Polls `read(t)` at the fixed time `t` until `done(counters)`; returns the last sample.
fn read_at(dev: &mut BridgeDevice, t: f64, done: impl Fn(&BridgeCounters) -> bool) -> HandleSample {
    poll_until(dev, &mut { t }, 0.0, done)
}

/// Writes [`PUSH`] to the device and returns the reply the client receives.
fn push(dev: &mut BridgeDevice, client: &mut BridgeClient) -> vps_input::bridge::WrenchReply {
    dev.write(&PUSH).unwrap();
    client.recv_wrench(DEADLINE).unwrap().expect("reply")
}

/// Reads at `t` until `accepted` poses have arrived, then checks that the part moved by `step` (m)
/// from `from` and that [`PUSH`] comes back as 2 N along +X: the device drives the part with the
/// mapping's scale and rotation, and forces return through it.
fn follows(
    dev: &mut BridgeDevice,
    client: &mut BridgeClient,
    t: f64,
    accepted: u64,
    from: &HandleSample,
    step: DVec3,
) {
    let moved = read_at(dev, t, |c| c.accepted == accepted);
    assert!(close(moved.position - from.position, step), "{moved:?}");
    let r = push(dev, client);
    assert!(close(r.wrench.force, DVec3::new(2.0, 0.0, 0.0)), "{r:?}");
}

fn mapping() -> WorkspaceMapping {
    WorkspaceMapping {
        scale: 5.0,
        rotate_deg: [0.0, 0.0, 90.0],
        offset: [1.0, 2.0, 3.0],
        force_scale: 0.5,
    }
}

fn device() -> (BridgeDevice, BridgeClient) {
    let dev = BridgeDevice::bind(BridgeConfig {
        mapping: mapping(),
        wrench_log_frames: 100,
        ..Default::default()
    })
    .unwrap();
    let client = BridgeClient::connect(dev.local_addr(), None).unwrap();
    (dev, client)
}

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-12
}

const PUSH: Wrench = Wrench {
    force: DVec3::new(0.0, 4.0, 0.0),
    torque: DVec3::ZERO,
};

#[test]
fn clutch_holds_the_target_and_release_does_not_jump() {
    let (mut dev, mut client) = device();
    let p0 = DVec3::new(0.01, 0.02, 0.0);
    client.send_pose_flags(&at(p0), 0).unwrap();
    let s0 = read_at(&mut dev, 0.000, |c| c.accepted == 1);
    // Scale 5, device X → scene Y, from the offset.
    assert!(
        close(s0.position, DVec3::new(1.0 - 0.1, 2.05, 3.0)),
        "{s0:?}"
    );
    assert!(close(s0.linear_velocity, DVec3::new(0.0, 1.5, 0.0)));

    // Forces go back rotated and scaled: scene +Y 4 N → device +X 2 N.
    let r = push(&mut dev, &mut client);
    assert!(close(r.wrench.force, DVec3::new(2.0, 0.0, 0.0)), "{r:?}");
    // And within the device's limits (15 N) whatever the scene asks.
    dev.write(&Wrench {
        force: DVec3::new(0.0, 1e6, 0.0),
        torque: DVec3::new(1e3, 0.0, 0.0),
    })
    .unwrap();
    let r = client.recv_wrench(DEADLINE).unwrap().expect("reply");
    assert!(r.wrench.force.length() <= 15.0 * (1.0 + 1e-12), "{r:?}");
    assert!(r.wrench.torque.length() <= 0.1 * (1.0 + 1e-12), "{r:?}");

    // Clutch pressed, then the handle moves a long way: the target stays put, velocities zero.
    let p1 = p0 + DVec3::new(0.03, -0.04, 0.02);
    client.send_pose_flags(&at(p0), FLAG_CLUTCH).unwrap();
    client.send_pose_flags(&at(p1), FLAG_CLUTCH).unwrap();
    let held = read_at(&mut dev, 0.001, |c| c.accepted == 3);
    assert!(dev.holding());
    assert_eq!(held.position, s0.position);
    assert_eq!(held.linear_velocity, DVec3::ZERO);
    assert_eq!(held.angular_velocity, DVec3::ZERO);
    let r = push(&mut dev, &mut client);
    assert_eq!(r.wrench, Wrench::ZERO, "no force while clutched");

    // Release at p1: the commanded target moves by less than one voxel across the release frame.
    client.send_pose_flags(&at(p1), 0).unwrap();
    let released = read_at(&mut dev, 0.002, |c| c.accepted == 4);
    assert!(!dev.holding());
    let jump = (released.position - held.position).length();
    assert!(jump < VOXEL, "release jump {jump} m");
    assert!(
        jump < 1e-12,
        "re-anchoring should be exact to rounding: {jump} m"
    );
    assert!(released.orientation.dot(held.orientation).abs() > 1.0 - 1e-12);

    // After release the handle drives the part again with the same scale and rotation.
    client
        .send_pose_flags(&at(p1 + DVec3::new(0.01, 0.0, 0.0)), 0)
        .unwrap();
    follows(
        &mut dev,
        &mut client,
        0.003,
        5,
        &released,
        DVec3::new(0.0, 0.05, 0.0),
    );

    // The session's closing zero reaches the device as exact +0.0 bits through the rotation.
    dev.write(&Wrench::ZERO).unwrap();
    let r = client.recv_wrench(DEADLINE).unwrap().expect("reply");
    let bits = [r.wrench.force.to_array(), r.wrench.torque.to_array()].concat();
    assert!(bits.iter().all(|v| v.to_bits() == 0), "{r:?}");

    let c = dev.counters();
    assert_eq!((c.clutch_presses, c.zeroed_frames, c.timeouts), (1, 1, 0));
    assert_eq!((c.zeroed_by_clutch, c.zeroed_by_timeout), (1, 0));
    assert_eq!(dev.monitor().counters(), c);
    let log = dev.monitor().sent_wrenches();
    assert_eq!(log.len(), 5);
    assert_eq!(log[2].wrench, Wrench::ZERO);
    assert_eq!(
        log.iter().map(|s| s.frame).collect::<Vec<_>>(),
        [1, 2, 3, 4, 5]
    );
}

/// A session whose client has not come yet: every frame is counted as one before the first
/// pose (the report then shows a session that never had a device), nothing is sent.
#[test]
fn frames_before_the_first_pose_are_counted() {
    let (mut dev, _client) = device();
    for i in 0..3 {
        dev.read(f64::from(i) * 1e-3).unwrap();
        dev.write(&PUSH).unwrap();
    }
    let c = dev.counters();
    assert_eq!(
        (c.frames_before_first_pose, c.sent, c.zeroed_frames),
        (3, 0, 0)
    );
}

#[test]
fn silent_device_is_zeroed_held_and_reanchored_on_resume() {
    let (mut dev, mut client) = device();
    let p0 = DVec3::new(0.0, 0.01, 0.0);
    client.send_pose(&at(p0)).unwrap();
    let s0 = read_at(&mut dev, 0.0, |c| c.accepted == 1);

    // Within the timeout (0.05 s) the pose is live and forces flow.
    let s = dev.read(0.049).unwrap();
    assert_eq!(s, s0);
    let r = push(&mut dev, &mut client);
    assert_ne!(r.wrench, Wrench::ZERO);

    // Past it: zero output, the target holds still, one timeout however long the silence.
    for t in [0.051, 0.1, 0.2] {
        let s = dev.read(t).unwrap();
        assert!(dev.holding());
        assert_eq!(s.position, s0.position);
        assert_eq!(s.orientation, s0.orientation);
        assert_eq!(
            (s.linear_velocity, s.angular_velocity),
            (DVec3::ZERO, DVec3::ZERO)
        );
        let r = push(&mut dev, &mut client);
        assert_eq!(r.wrench, Wrench::ZERO, "t = {t}");
    }
    assert_eq!(dev.counters().timeouts, 1);
    assert_eq!(dev.counters().zeroed_frames, 3);
    assert_eq!(
        (
            dev.counters().zeroed_by_timeout,
            dev.counters().zeroed_by_clutch
        ),
        (3, 0)
    );

    // The user moved the handle meanwhile; poses resume: no jump, then normal following.
    let p1 = p0 + DVec3::new(0.05, 0.0, -0.02);
    client.send_pose(&at(p1)).unwrap();
    let resumed = read_at(&mut dev, 0.3, |c| c.accepted == 2);
    assert!(!dev.holding());
    assert!((resumed.position - s0.position).length() < 1e-12);
    client
        .send_pose(&at(p1 + DVec3::new(0.0, 0.0, 0.01)))
        .unwrap();
    follows(
        &mut dev,
        &mut client,
        0.301,
        3,
        &resumed,
        DVec3::new(0.0, 0.0, 0.05),
    );
    assert_eq!(dev.counters().timeouts, 1);
}

#[test]
fn a_clutched_first_pose_anchors_the_device_at_the_initial_pose() {
    let start = DVec3::new(0.4, -0.1, 0.2);
    let mut dev = BridgeDevice::bind(BridgeConfig {
        initial_position: start,
        mapping: mapping(),
        ..Default::default()
    })
    .unwrap();
    let mut client = BridgeClient::connect(dev.local_addr(), None).unwrap();
    client
        .send_pose_flags(&at(DVec3::new(0.07, 0.0, 0.0)), FLAG_CLUTCH)
        .unwrap();
    let s = read_at(&mut dev, 0.0, |c| c.accepted == 1);
    assert_eq!(s.position, start);
    client
        .send_pose_flags(&at(DVec3::new(0.07, 0.0, 0.0)), 0)
        .unwrap();
    let s = read_at(&mut dev, 0.001, |c| c.accepted == 2);
    assert!((s.position - start).length() < 1e-12);
    assert_eq!(dev.counters().clutch_presses, 1);
}
