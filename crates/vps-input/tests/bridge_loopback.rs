//! End-to-end bridge tests over real UDP sockets on 127.0.0.1.
//!
//! Loopback delivery is not instantaneous from the receiver's point of view, so the tests poll
//! `read` until a datagram count is reached (bounded by a generous deadline); nothing asserts on
//! timing.

use crate::common;

use common::{poll_until, DEADLINE};
use std::time::Duration;

use glam::{DQuat, DVec3};
use vps_device::{DeviceError, HapticDevice};
use vps_haptic::{HandleSample, Wrench};
use vps_input::bridge::protocol::{Datagram, Message, MAX_DATAGRAM};
use vps_input::{BridgeClient, BridgeConfig, BridgeCounters, BridgeDevice};

/// The default configuration with the longest pose timeout, so a slow loopback delivery on a
/// loaded machine (the tests advance device time 1 ms per poll) never makes the device hold.
fn patient() -> BridgeConfig {
    BridgeConfig {
        pose_timeout: 10.0,
        ..Default::default()
    }
}

fn sample(x: f64) -> HandleSample {
    HandleSample {
        position: DVec3::new(x, 0.5, -0.25),
        orientation: DQuat::from_rotation_z(x),
        linear_velocity: DVec3::new(0.1, 0.0, 0.0),
        angular_velocity: DVec3::new(0.0, 0.0, 0.2),
    }
}

/// Reads at times `t, t + 1 ms, ...` until `done(counters)` holds; returns the last sample.
fn read_until(
    dev: &mut BridgeDevice,
    t: &mut f64,
    done: impl Fn(&BridgeCounters) -> bool,
) -> HandleSample {
    poll_until(dev, t, 1e-3, done)
}

fn seen(c: &BridgeCounters) -> u64 {
    c.accepted + c.stale + c.garbage + c.unauthorized
}

#[test]
fn initial_pose_before_any_datagram() {
    let cfg = BridgeConfig {
        initial_position: DVec3::new(1.0, 2.0, 3.0),
        ..Default::default()
    };
    let mut dev = BridgeDevice::bind(cfg).unwrap();
    let s = dev.read(0.0).unwrap();
    assert_eq!(s.position, DVec3::new(1.0, 2.0, 3.0));
    assert_eq!(s.linear_velocity, DVec3::ZERO);
    assert_eq!(s.angular_velocity, DVec3::ZERO);
    // No peer yet: writing sends nothing and succeeds.
    dev.write(&Wrench::ZERO).unwrap();
    assert_eq!(dev.counters().sent, 0);
    assert!(dev.local_addr().ip().is_loopback());
    assert_ne!(dev.local_addr().port(), 0);
}

#[test]
fn poses_in_wrenches_out() {
    let mut dev = BridgeDevice::bind(patient()).unwrap();
    let mut client = BridgeClient::connect(dev.local_addr(), None).unwrap();
    let mut t = 0.0;
    for k in 1..=5u64 {
        let seq = client.send_pose(&sample(0.01 * k as f64)).unwrap();
        assert_eq!(seq, k);
        let s = read_until(&mut dev, &mut t, |c| c.accepted == k);
        assert!((s.position.x - 0.01 * k as f64).abs() < 1e-15);
        assert_eq!(s.linear_velocity, DVec3::new(0.1, 0.0, 0.0));
        assert!((s.orientation - DQuat::from_rotation_z(0.01 * k as f64)).length() < 1e-12);

        let w = Wrench {
            force: DVec3::new(0.0, k as f64, 0.0),
            torque: DVec3::new(0.0, 0.0, 1.0), // saturated to 0.1 N·m
        };
        dev.write(&w).unwrap();
        let reply = client.recv_wrench(DEADLINE).unwrap().expect("wrench reply");
        assert_eq!(reply.frame, k);
        assert_eq!(reply.wrench.force, w.force);
        assert!((reply.wrench.torque.z - 0.1).abs() < 1e-12);
    }
    assert_eq!(dev.peer(), Some(client.local_addr().unwrap()));
    let c = dev.counters();
    assert_eq!((c.accepted, c.sent, c.garbage, c.stale), (5, 5, 0, 0));
    // Nothing more pending: a zero-timeout poll returns None.
    assert_eq!(client.recv_wrench(Duration::ZERO).unwrap(), None);
}

#[test]
fn older_sequences_are_dropped_and_velocity_times_out() {
    let mut dev = BridgeDevice::bind(patient()).unwrap();
    let client = BridgeClient::connect(dev.local_addr(), None).unwrap();
    let mut t = 0.0;
    client.send_pose_with_sequence(&sample(0.3), 10).unwrap();
    read_until(&mut dev, &mut t, |c| c.accepted == 1);
    client.send_pose_with_sequence(&sample(0.1), 9).unwrap();
    client.send_pose_with_sequence(&sample(0.2), 10).unwrap();
    let s = read_until(&mut dev, &mut t, |c| c.stale == 2);
    assert_eq!(s.position.x, 0.3, "stale poses must not replace the newest");
    assert_eq!(dev.counters().accepted, 1);

    // No new pose for longer than velocity_timeout (0.1 s): pose held, velocities zero.
    let s = dev.read(t + 0.2).unwrap();
    assert_eq!(s.position.x, 0.3);
    assert_eq!(s.linear_velocity, DVec3::ZERO);
    assert_eq!(s.angular_velocity, DVec3::ZERO);
}

/// Issue 36 item 9: a pose with sequence u64::MAX made every later pose of that sender stale for
/// the session. Within the pose timeout a lower sequence is still stale; once the newest pose has
/// timed out, a lower sequence is taken back as a restart, and the stream goes on from it.
#[test]
fn a_sender_that_restarts_its_sequence_is_taken_back_after_the_pose_timeout() {
    let cfg = BridgeConfig {
        pose_timeout: 0.05,
        ..Default::default()
    };
    let mut dev = BridgeDevice::bind(cfg).unwrap();
    let client = BridgeClient::connect(dev.local_addr(), None).unwrap();
    // Device time advances only by what the test passes to `read`, so delivery delays cannot
    // time the pose out: 0.1 µs per poll.
    let mut t = 0.0;
    client
        .send_pose_with_sequence(&sample(0.3), u64::MAX)
        .unwrap();
    poll_until(&mut dev, &mut t, 1e-7, |c| c.accepted == 1);
    client.send_pose_with_sequence(&sample(0.1), 1).unwrap();
    let s = poll_until(&mut dev, &mut t, 1e-7, |c| c.stale == 1);
    assert_eq!(
        s.position.x, 0.3,
        "within the timeout a lower sequence is stale"
    );
    // Past the timeout (the device holds the last pose): the restarted sender's next pose is
    // taken back (re-anchored onto the held pose), then its stream goes on and moves the handle.
    t += 0.1;
    let held = dev.read(t).unwrap();
    assert_eq!(dev.counters().timeouts, 1);
    client.send_pose_with_sequence(&sample(0.2), 2).unwrap();
    let s = poll_until(&mut dev, &mut t, 1e-7, |c| c.accepted == 2);
    assert!((s.position - held.position).length() < 1e-12, "re-anchored");
    client.send_pose_with_sequence(&sample(0.25), 3).unwrap();
    let s = poll_until(&mut dev, &mut t, 1e-7, |c| c.accepted == 3);
    assert!(
        (s.position - held.position).length() > 0.01,
        "the stream moves again"
    );
    let c = dev.counters();
    assert_eq!((c.restarts, c.stale), (1, 1), "{c:?}");
}

#[test]
fn garbage_is_counted_and_ignored() {
    let mut dev = BridgeDevice::bind(patient()).unwrap();
    let mut client = BridgeClient::connect(dev.local_addr(), None).unwrap();
    let mut t = 0.0;
    client.send_pose(&sample(0.05)).unwrap();
    read_until(&mut dev, &mut t, |c| c.accepted == 1);

    let mut good = [0u8; MAX_DATAGRAM];
    let n = Datagram {
        token: [0; 16],
        sequence: 100,
        message: Message::PoseIn(sample(0.9)),
    }
    .encode(&mut good);
    let good = &good[..n];

    let mut bad: Vec<Vec<u8>> = vec![
        vec![],
        b"hello".to_vec(),
        good[..n - 1].to_vec(),      // truncated
        [good, &[0u8][..]].concat(), // one byte too long
        vec![0xAB; 2000],            // oversized
    ];
    let mut wrong_magic = good.to_vec();
    wrong_magic[..4].copy_from_slice(b"VPSX");
    bad.push(wrong_magic);
    let mut nan = good.to_vec();
    nan[30..38].copy_from_slice(&f64::NAN.to_le_bytes());
    bad.push(nan);
    let mut inf = good.to_vec();
    inf[110..118].copy_from_slice(&f64::INFINITY.to_le_bytes());
    bad.push(inf);
    // A WrenchOut sent to the device is the wrong direction.
    let mut w = [0u8; MAX_DATAGRAM];
    let wn = Datagram {
        token: [0; 16],
        sequence: 101,
        message: Message::WrenchOut {
            wrench: Wrench::ZERO,
            frame: 1,
        },
    }
    .encode(&mut w);
    bad.push(w[..wn].to_vec());

    for b in &bad {
        client.send_raw(b).unwrap();
    }
    let expected = 1 + bad.len() as u64;
    let s = read_until(&mut dev, &mut t, |c| seen(c) == expected);
    let c = dev.counters();
    assert_eq!(c.garbage, bad.len() as u64, "{c:?}");
    assert_eq!(c.accepted, 1);
    assert_eq!(s.position.x, 0.05, "the newest valid pose is kept");

    // The stream continues normally afterwards.
    client.send_pose(&sample(0.06)).unwrap();
    let s = read_until(&mut dev, &mut t, |c| c.accepted == 2);
    assert_eq!(s.position.x, 0.06);
}

#[test]
fn token_is_enforced_when_configured() {
    let token = [0x5a; 16];
    let cfg = BridgeConfig {
        token: Some(token),
        ..patient()
    };
    let mut dev = BridgeDevice::bind(cfg).unwrap();
    let mut wrong = BridgeClient::connect(dev.local_addr(), Some([0x5b; 16])).unwrap();
    let mut none = BridgeClient::connect(dev.local_addr(), None).unwrap();
    let mut right = BridgeClient::connect(dev.local_addr(), Some(token)).unwrap();
    let mut t = 0.0;
    wrong.send_pose(&sample(0.7)).unwrap();
    none.send_pose(&sample(0.8)).unwrap();
    let s = read_until(&mut dev, &mut t, |c| c.unauthorized == 2);
    assert_eq!(s.position, DVec3::ZERO, "still the initial pose");
    assert_eq!(dev.peer(), None);

    right.send_pose(&sample(0.1)).unwrap();
    let s = read_until(&mut dev, &mut t, |c| c.accepted == 1);
    assert_eq!(s.position.x, 0.1);
    dev.write(&Wrench::ZERO).unwrap();
    let reply = right.recv_wrench(DEADLINE).unwrap().expect("reply");
    assert_eq!(reply.frame, 1);
}

#[test]
fn non_finite_write_is_an_error_and_keeps_the_previous_wrench() {
    let mut dev = BridgeDevice::bind(patient()).unwrap();
    let w = Wrench {
        force: DVec3::X,
        torque: DVec3::ZERO,
    };
    dev.write(&w).unwrap();
    let e = dev
        .write(&Wrench {
            force: DVec3::new(f64::NAN, 0.0, 0.0),
            torque: DVec3::ZERO,
        })
        .unwrap_err();
    assert!(matches!(e, DeviceError::NonFinite { .. }));
    assert_eq!(dev.last_wrench(), w);
    assert!(matches!(
        dev.read(-1.0).and_then(|_| dev.read(-2.0)),
        Err(DeviceError::TimeWentBackwards { .. })
    ));
}

#[test]
fn remote_bind_without_token_is_refused() {
    let cfg = BridgeConfig {
        bind: "0.0.0.0:0".parse().unwrap(),
        allow_remote: true,
        ..Default::default()
    };
    let e = BridgeDevice::bind(cfg).err().expect("refused");
    assert!(e.to_string().contains("token"), "{e}");
}

#[test]
fn devices_are_usable_as_boxed_haptic_devices() {
    let dev = BridgeDevice::bind(patient()).unwrap();
    let boxed: Box<dyn HapticDevice> = Box::new(dev);
    assert_eq!(boxed.name(), "udp bridge");
    fn assert_send<T: Send>() {}
    assert_send::<vps_input::SpaceMouse>();
}
