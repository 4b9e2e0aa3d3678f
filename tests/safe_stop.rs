//! The stop path through the binary: `vps run` driven over the UDP device bridge by a client that
//! holds the handle pressed into the built-in bay, then stopped by a signal. The client's last
//! WrenchOut must be the exact zero wrench, the report file must exist and say why the session
//! stopped, and the exit status must be 128 + the signal number.
//!
//! Nothing here depends on timing: every wait is bounded by a generous deadline only.

use glam::{DQuat, DVec3};
use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use vps_haptic::{HandleSample, Wrench};
use vps_input::BridgeClient;
use vps_testkit::process::{spawn_until_line, WatchedProcess};

/// Bounds every wait (scene build, contact, exit); never reached when all is well.
const DEADLINE: Duration = Duration::from_secs(240);

/// A `vps` child process, killed and reaped on drop.
struct Vps(Child);

impl Drop for Vps {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// `vps` with its voxmap cache inside the build's target directory, never the user's cache.
fn vps() -> Command {
    let mut cmd = Command::new(vps_testkit::process::vps_binary(env!("CARGO_BIN_EXE_vps")));
    cmd.env(
        "VPS_CACHE_DIR",
        std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("vps-cache"),
    );
    cmd
}

/// `vps run` on the bridge (port 0) for `seconds`, stdin and stdout null: the command of every
/// bridge session here, its other flags still to come.
fn bridge_run(seconds: &str) -> Command {
    let mut cmd = vps();
    cmd.args([
        "run",
        "--device",
        "bridge:127.0.0.1:0",
        "--seconds",
        seconds,
    ])
    .stdin(Stdio::null())
    .stdout(Stdio::null());
    cmd
}

/// Starts `vps run` on the bridge (port 0) for `seconds` and returns it with the bridge's
/// address, read from its stderr.
fn start_bridge_session(report: &std::path::Path, seconds: &str) -> (Vps, SocketAddr) {
    let mut cmd = bridge_run(seconds);
    cmd.arg("--report").arg(report);
    let (child, addr) = spawn_until_line(cmd, "vps", "device bridge listening on ", DEADLINE);
    (Vps(child), addr.parse().expect("a socket address"))
}

fn handle_at(position: DVec3) -> HandleSample {
    HandleSample {
        position,
        orientation: DQuat::IDENTITY,
        linear_velocity: DVec3::ZERO,
        angular_velocity: DVec3::ZERO,
    }
}

fn is_exact_zero(w: &Wrench) -> bool {
    w.force
        .to_array()
        .into_iter()
        .chain(w.torque.to_array())
        .all(|c| c.to_bits() == 0)
}

/// Presses the handle 1 m below the session's start point (the part comes to rest on the bay's
/// surface below it, held there by the coupling) until 3000 WrenchOuts in a row carry force (the
/// saturated coupling pulls from the first frame; with the bay's 4-bit exact-surface shell the
/// braked part had not reached the surface after 1385 frames), signals the process,
/// keeps holding the handle until it exits, and returns the last WrenchOut, the exit status and
/// the report.
fn press_then_signal(signal: &str) -> (Wrench, Option<i32>, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let report_path = dir.path().join("report.json");
    let (mut vps, addr) = start_bridge_session(&report_path, "600");
    let start = vps_mesh::builtin::bay_corridor()[0];
    let pressed = handle_at(start - DVec3::new(0.0, 0.0, 1.0));
    let mut client = BridgeClient::connect(addr, None).unwrap();
    let until = Instant::now() + DEADLINE;
    let mut in_contact = 0;
    while in_contact < 3000 {
        assert!(
            Instant::now() < until,
            "no contact force within {DEADLINE:?}"
        );
        client.send_pose(&pressed).unwrap();
        if let Some(reply) = client.recv_wrench(Duration::from_millis(5)).unwrap() {
            in_contact = if reply.wrench.force.length() > 0.1 {
                in_contact + 1
            } else {
                0
            };
        }
    }
    let status = Command::new("kill")
        .args([format!("-{signal}"), vps.0.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    let mut last = None;
    let exit = loop {
        assert!(Instant::now() < until, "vps did not exit after SIG{signal}");
        let _ = client.send_pose(&pressed);
        // Once the process has gone, a send draws an ICMP "connection refused", reported by
        // the next receive: not a WrenchOut, skipped.
        if let Ok(Some(reply)) = client.recv_wrench(Duration::from_millis(5)) {
            last = Some(reply.wrench);
        }
        if let Some(status) = vps.0.try_wait().unwrap() {
            break status;
        }
    };
    // Whatever the process sent before it exited is in the socket's queue by now.
    loop {
        match client.recv_wrench(Duration::from_millis(200)) {
            Ok(Some(reply)) => last = Some(reply.wrench),
            Ok(None) => break,
            Err(_refused) => {}
        }
    }
    let text = std::fs::read_to_string(&report_path).expect("the report file was written");
    let report: serde_json::Value = serde_json::from_str(&text).unwrap();
    (last.expect("WrenchOuts received"), exit.code(), report)
}

fn assert_stopped_safely(signal: &str, code: i32) {
    let (last, exit, report) = press_then_signal(signal);
    assert!(
        is_exact_zero(&last),
        "the last WrenchOut after SIG{signal} was {last:?}"
    );
    assert_eq!(exit, Some(code), "exit status after SIG{signal}");
    assert_eq!(report["end"], format!("stopped by SIG{signal}"), "{report}");
    assert_eq!(report["complete"], false, "{report}");
    assert_eq!(report["exit_code"], code, "{report}");
    assert!(
        report["stats"]["contact_frames"].as_u64().unwrap() > 0,
        "{report}"
    );
}

#[test]
fn sigterm_leaves_zero_force_on_the_device_and_a_partial_report() {
    assert_stopped_safely("TERM", 143);
}

#[test]
fn sigint_leaves_zero_force_on_the_device_and_a_partial_report() {
    assert_stopped_safely("INT", 130);
}

/// `vps demo` (the simulated hand on the default scene file) stopped by SIGINT once it has
/// announced its scene: the first session stops, its partial figures are printed and the status
/// is 130 (the demo's handlers are installed before the announcement).
#[test]
fn a_demo_stopped_by_sigint_prints_its_partial_session_and_exits_130() {
    let mut child = vps()
        .args(["demo", "--seconds", "600"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start vps demo");
    let mut stdout = BufReader::new(child.stdout.take().unwrap());
    let mut vps = Vps(child);
    let mut printed = String::new();
    let mut line = String::new();
    while !line.starts_with("part: ") {
        line.clear();
        assert!(
            stdout.read_line(&mut line).unwrap() > 0,
            "vps demo ended before announcing its part: {printed}"
        );
        printed.push_str(&line);
    }
    let status = Command::new("kill")
        .args(["-INT", &vps.0.id().to_string()])
        .status()
        .unwrap();
    assert!(status.success());
    // Reading to the end returns once the process has exited (the deadline bounds a hang).
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut rest = String::new();
        let _ = std::io::Read::read_to_string(&mut stdout, &mut rest);
        let _ = tx.send(rest);
    });
    let rest = rx
        .recv_timeout(DEADLINE)
        .expect("vps demo exited after SIGINT");
    let exit = vps.0.wait().unwrap();
    let mut stderr = String::new();
    std::io::Read::read_to_string(vps.0.stderr.as_mut().unwrap(), &mut stderr).unwrap();
    assert_eq!(exit.code(), Some(130), "{printed}{rest}{stderr}");
    assert!(
        rest.contains("partial session (stopped by SIGINT)"),
        "{printed}{rest}"
    );
    assert!(stderr.contains("stopped by SIGINT"), "{stderr}");
}

/// A client whose every handle sample is absurd (10 km from the origin): the core rejects each, the
/// device gets zero, and the report of the complete session counts those frames (finding 9: such
/// a session ended as a clean `FramesDone` with no counts).
#[test]
fn rejected_handle_samples_are_counted_in_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let report_path = dir.path().join("report.json");
    let (mut vps, addr) = start_bridge_session(&report_path, "2");
    let absurd = handle_at(DVec3::new(1.0e4, 0.0, 0.0));
    let mut client = BridgeClient::connect(addr, None).unwrap();
    let until = Instant::now() + DEADLINE;
    let mut wrenches = 0u64;
    let exit = loop {
        assert!(Instant::now() < until, "the 2 s session did not end");
        let _ = client.send_pose(&absurd);
        if let Ok(Some(reply)) = client.recv_wrench(Duration::from_millis(5)) {
            assert!(is_exact_zero(&reply.wrench), "{:?}", reply.wrench);
            wrenches += 1;
        }
        if let Some(status) = vps.0.try_wait().unwrap() {
            break status;
        }
    };
    assert!(wrenches > 0, "no WrenchOut received");
    assert_eq!(exit.code(), Some(0));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
    assert_eq!(report["end"], "frames done", "{report}");
    assert_eq!(report["complete"], true, "{report}");
    let stats = &report["stats"];
    let rejected = stats["rejected_input_frames"].as_u64().unwrap();
    assert!(rejected > 0, "{report}");
    assert!(
        stats["zeroed_frames"].as_u64().unwrap() >= rejected,
        "{report}"
    );
    assert_eq!(stats["frames"], 2000, "{report}");
}

/// Issue 36 item 4: with `[device] max_force = 0.3` the largest |F| sent was
/// 0.30000000000000004 (1,105 of 2,759 wrenches over the limit in exact arithmetic); torque the
/// same. A client pressing the part onto the bay's floor and turning it, so that the coupling's
/// pull and twist are clamped in most frames, checks each WrenchOut it receives until 2000 of
/// each were at their limit, without rounding
/// (`vps_device::norm::exceeds_exactly`), against both limits: none may exceed them.
#[test]
fn no_wrench_sent_exceeds_the_device_limits_by_an_ulp() {
    let dir = tempfile::tempdir().unwrap();
    // The standard scene (its geometry, so its cached voxmap) with a 0.3 N, 2 mN·m device.
    let scene = dir.path().join("limits.toml");
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/scenes/bay-teapot.toml"),
    )
    .unwrap();
    // As shipped (the tangent-plane model). tests/hostile_old_vs_new.py ran this test against a
    // binary from before the force models with that key left out, when tangent-plane was the
    // default; such a binary refuses the key.
    let (max_force, max_torque) = (0.3, 0.002);
    std::fs::write(
        &scene,
        format!("{text}\n[device]\nmax_force = {max_force}\nmax_torque = {max_torque}\n"),
    )
    .unwrap();
    let mut cmd = bridge_run("600");
    cmd.arg("--scene").arg(&scene);
    let (child, addr) = spawn_until_line(cmd, "vps", "device bridge listening on ", DEADLINE);
    let _vps = Vps(child);
    let addr: SocketAddr = addr.parse().expect("a socket address");
    let start = vps_mesh::builtin::bay_corridor()[0];
    // Turned as well as pressed, so that the coupling's torque is clamped too.
    let pressed = HandleSample {
        orientation: DQuat::from_axis_angle(DVec3::new(1.0, 1.0, 0.3).normalize(), 0.6),
        ..handle_at(start - DVec3::new(0.0, 0.0, 1.0))
    };
    let mut client = BridgeClient::connect(addr, None).unwrap();
    let until = Instant::now() + DEADLINE;
    let (mut received, mut at_force_limit, mut at_torque_limit) = (0u64, 0u64, 0u64);
    while at_force_limit < 2000 || at_torque_limit < 2000 {
        assert!(
            Instant::now() < until,
            "only {at_force_limit} clamped wrenches within {DEADLINE:?}"
        );
        client.send_pose(&pressed).unwrap();
        if let Some(reply) = client.recv_wrench(Duration::from_millis(5)).unwrap() {
            let w = reply.wrench;
            received += 1;
            assert!(
                !vps_device::norm::exceeds_exactly(w.force, max_force),
                "|F| = {:?} > {max_force} N (frame {}, {:?})",
                w.force.length(),
                reply.frame,
                w.force
            );
            assert!(
                !vps_device::norm::exceeds_exactly(w.torque, max_torque),
                "|T| = {:?} > {max_torque} N·m (frame {}, {:?})",
                w.torque.length(),
                reply.frame,
                w.torque
            );
            if w.force.length() >= max_force * (1.0 - 1e-12) {
                at_force_limit += 1;
            }
            if w.torque.length() >= max_torque * (1.0 - 1e-12) {
                at_torque_limit += 1;
            }
        }
    }
    eprintln!(
        "{received} wrenches checked: {at_force_limit} at the force limit, {at_torque_limit} at \
         the torque limit"
    );
}

/// Issue 36 item 9: one datagram with sequence u64::MAX locked its source out for the session
/// (every later pose stale, zero output, nothing said); a client restarted on the same port was
/// dropped until it passed its old sequence. Here the u64::MAX datagram holds the clutch (the
/// device sends zero), then the same socket counts from 1 again, moving the hand down onto the
/// floor: once the u64::MAX pose has timed out (50 ms) the stream is taken back and force comes. The
/// report counts the restart and the stale poses, and stderr says why poses were dropped.
#[test]
fn a_sender_restarting_its_sequence_is_taken_back_after_the_pose_timeout() {
    use vps_input::bridge::protocol::{Datagram, Message, FLAG_CLUTCH};
    let dir = tempfile::tempdir().unwrap();
    let report_path = dir.path().join("report.json");
    let mut cmd = bridge_run("600");
    cmd.args(["--pose-timeout-ms", "50", "--report"])
        .arg(&report_path);
    let mut vps = WatchedProcess::spawn(cmd, "vps", DEADLINE);
    let marker = "device bridge listening on ";
    vps.wait_for(marker, 1);
    let addr: SocketAddr = vps.lines_containing(marker)[0]
        .split(marker)
        .nth(1)
        .unwrap()
        .trim()
        .parse()
        .expect("a socket address");
    let start = vps_mesh::builtin::bay_corridor()[0];
    let mut client = BridgeClient::connect(addr, None).unwrap();
    let far_ahead = Datagram {
        token: [0; 16],
        sequence: u64::MAX,
        message: Message::PoseInFlags {
            sample: handle_at(start),
            flags: FLAG_CLUTCH,
        },
    };
    let mut bytes = [0u8; vps_input::bridge::protocol::MAX_DATAGRAM];
    let n = far_ahead.encode(&mut bytes);
    client.send_raw(&bytes[..n]).unwrap();
    let until = Instant::now() + DEADLINE;
    let mut with_force = 0;
    let mut sent = 0u32;
    while with_force < 500 {
        assert!(
            Instant::now() < until,
            "the restarted sender got no force within {DEADLINE:?}"
        );
        // Taken back, the stream is re-anchored where the part was held: the hand then moves
        // down 1 m, 2 mm a pose, pressing the part onto the bay's floor.
        sent += 1;
        let down = (f64::from(sent) * 0.002).min(1.0);
        client
            .send_pose(&handle_at(start - DVec3::new(0.0, 0.0, down)))
            .unwrap();
        if let Ok(Some(reply)) = client.recv_wrench(Duration::from_millis(5)) {
            if reply.wrench.force.length() > 0.1 {
                with_force += 1;
            }
        }
    }
    vps.signal("TERM");
    assert_eq!(vps.wait_exit().code(), Some(143));
    vps.wait_for("dropped as stale", 1);
    let said = vps.lines_containing("dropped as stale").join("\n");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
    let bridge = &report["bridge"];
    assert_eq!(bridge["restarts"], 1, "{bridge}");
    assert!(bridge["stale"].as_u64().unwrap() > 0, "{bridge}");
    assert!(said.contains("restarted client"), "{said}");
}
