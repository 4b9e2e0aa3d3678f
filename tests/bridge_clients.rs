//! The C and Python bridge clients (clients/c, clients/python) against a live
//! `vps run --device bridge`: each example runs for 3 s, must end with `wrenches N`, N ≥ 2,500,
//! and every wrench it decoded must equal, bit for bit, the one vps logged as sent
//! (`--log-wrenches`, matched by frame number).
//!
//! Two C examples at once drive the two parts of a scene of two `[[part]]`s, one bridge each: each
//! gets ≥ 2,500 wrenches, all finite and within the device limits.
//!
//! Also: a scene file's `[device]` mapping places the device in the scene through a live session,
//! and a command-line flag overrides one of its keys; and the device SDK skeletons
//! (clients/c/*_skeleton.c) compile cleanly as stubs without their SDKs.
//!
//! gcc and python3 are required; when one is missing its half prints a SKIPPED line. Nothing here
//! asserts on timing: N counts wrenches, and the examples pace to absolute deadlines.

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;
use vps_testkit::process::spawn_until_line;
use vps_testkit::table::csv_column;

/// The session is long enough for both examples (3 s each) plus their start-up on a loaded
/// machine; the examples run back to back after the bridge is listening, and the test ends the
/// session once they are done (`end_session`).
const SESSION_SECONDS: &str = "20";
/// Start-up of a debug `vps run` on a shared 2-core machine (voxelizing the scene) can be slow.
const STARTUP_DEADLINE: Duration = Duration::from_secs(600);
const MIN_WRENCHES: u64 = 2500;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The voxmap cache of the sessions started here: inside the build's target directory, never the
/// user's cache.
fn cache_dir() -> PathBuf {
    Path::new(env!("CARGO_TARGET_TMPDIR")).join("vps-cache")
}

fn available(tool: &str) -> bool {
    Command::new(tool)
        .arg("--version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

/// The C example (clients/c/example.c) compiled into `dir`; returns the executable.
fn compile_example(dir: &Path) -> PathBuf {
    let example = dir.join("example");
    let status = Command::new("gcc")
        .args(["-std=c99", "-O2", "-o"])
        .arg(&example)
        .arg(repo().join("clients/c/example.c"))
        .arg("-lm")
        .status()
        .expect("gcc runs");
    assert!(status.success(), "the C example compiles");
    example
}

/// Ends a session once its clients are done, with SIGTERM (the safe stop: zero force first, then
/// the report of the frames run), and returns its JSON report. `SESSION_SECONDS` is only a ceiling
/// for a slow start-up; a session that already ran its length is taken as it ended.
fn end_session(child: Child) -> serde_json::Value {
    let sent = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success(), "kill -TERM failed");
    let out = child.wait_with_output().expect("vps finishes");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    match out.status.code() {
        Some(143) => assert_eq!(report["end"], "stopped by SIGTERM", "{report}"),
        Some(0) => assert_eq!(report["complete"], true, "{report}"),
        other => panic!("vps run exited {other:?}: {report}"),
    }
    report
}

/// Starts the session; returns the child and the bridge's address (read from its stderr).
fn start_vps(log: &Path) -> (Child, SocketAddr) {
    start_vps_with(&[
        "run",
        "--device",
        "bridge:127.0.0.1:0",
        "--voxel-size",
        "10mm",
        "--seconds",
        SESSION_SECONDS,
        // The examples move 0.15 m; scaled ×6 the part reaches the bay's floor, so contact
        // wrenches (not only zeros) are compared.
        "--map-scale",
        "6",
        "--log-wrenches",
        log.to_str().unwrap(),
        "--json",
    ])
}

/// Starts `vps ARGS` (a session on the bridge); returns the child and the bridge's address.
fn start_vps_with(args: &[&str]) -> (Child, SocketAddr) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vps"));
    cmd.args(args)
        .env("VPS_CACHE_DIR", cache_dir())
        .stdout(Stdio::piped());
    let (child, addr) =
        spawn_until_line(cmd, "vps", "device bridge listening on ", STARTUP_DEADLINE);
    (child, addr.parse().expect("a socket address"))
}

/// Runs an example for 3 s with VPS_DUMP set; returns (N from `wrenches N`, dumped lines).
fn run_example(mut cmd: Command, addr: SocketAddr, dump: &Path) -> (u64, Vec<String>) {
    let out = cmd
        .arg(addr.to_string())
        .arg("3")
        .env("VPS_DUMP", dump)
        .output()
        .expect("example runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "example failed: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let last = stdout.lines().last().unwrap_or("");
    let n: u64 = last
        .strip_prefix("wrenches ")
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("last line `{last}` is not `wrenches N`"));
    let lines: Vec<String> = std::fs::read_to_string(dump)
        .expect("dump written")
        .lines()
        .map(str::to_string)
        .collect();
    (n, lines)
}

/// Every dumped line equals vps's line for the same frame; at least one is a non-zero wrench.
fn check_bit_exact(who: &str, n: u64, dumped: &[String], sent: &HashMap<String, String>) {
    eprintln!("{who}: wrenches {n}");
    assert!(n >= MIN_WRENCHES, "{who}: only {n} wrenches");
    assert_eq!(dumped.len() as u64, n, "{who}: one dump line per wrench");
    let zero = format!(" {:016x}", 0u64).repeat(6);
    let mut non_zero = 0;
    for line in dumped {
        let frame = line.split(' ').next().unwrap_or("");
        let logged = sent
            .get(frame)
            .unwrap_or_else(|| panic!("{who}: frame {frame} was not logged by vps"));
        assert_eq!(
            line, logged,
            "{who}: decoded wrench differs from the sent one"
        );
        if !line.ends_with(&zero) {
            non_zero += 1;
        }
    }
    assert!(non_zero > 0, "{who}: only zero wrenches were compared");
}

#[test]
fn c_and_python_clients_decode_exactly_what_vps_sends() {
    let has_gcc = available("gcc");
    let has_python = available("python3");
    if !has_gcc {
        println!("SKIPPED: the C bridge client (gcc not found)");
    }
    if !has_python {
        println!("SKIPPED: the Python bridge client (python3 not found)");
    }
    if !has_gcc && !has_python {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let example = dir.path().join("example");
    if has_gcc {
        let status = Command::new("gcc")
            .args([
                "-std=c99",
                "-O2",
                "-Wall",
                "-Wextra",
                "-pedantic",
                "-Werror",
                "-o",
            ])
            .arg(&example)
            .arg(repo().join("clients/c/example.c"))
            .arg("-lm")
            .status()
            .expect("gcc runs");
        assert!(status.success(), "the C example compiles cleanly");
        // The SDK skeletons build (without their SDKs) as stubs that say what they need.
        for (skeleton, sdk) in [
            ("openhaptics_skeleton.c", "VPS_WITH_OPENHAPTICS"),
            ("dhd_skeleton.c", "VPS_WITH_DHD"),
        ] {
            let stub = dir.path().join(skeleton.trim_end_matches(".c"));
            let status = Command::new("gcc")
                .args(["-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", "-o"])
                .arg(&stub)
                .arg(repo().join("clients/c").join(skeleton))
                .status()
                .expect("gcc runs");
            assert!(status.success(), "{skeleton} compiles cleanly");
            let out = Command::new(&stub).output().expect("the stub runs");
            let err = String::from_utf8_lossy(&out.stderr);
            assert_eq!(out.status.code(), Some(1), "{skeleton}: {err}");
            assert!(err.contains(sdk), "{skeleton}: {err}");
        }
    }
    let log = dir.path().join("sent.log");
    let (child, addr) = start_vps(&log);

    let mut results = Vec::new();
    if has_gcc {
        let dump = dir.path().join("c.dump");
        results.push(("C", run_example(Command::new(&example), addr, &dump)));
    }
    if has_python {
        let dump = dir.path().join("py.dump");
        let mut cmd = Command::new("python3");
        cmd.arg(repo().join("clients/python/example.py"));
        results.push(("Python", run_example(cmd, addr, &dump)));
    }

    let report = end_session(child);
    let bridge = &report["bridge"];
    assert_eq!(bridge["garbage"], 0, "{bridge}");
    assert_eq!(bridge["unlogged"], 0, "{bridge}");
    // Each example holds the clutch for its first 0.1 s.
    assert_eq!(bridge["clutch_presses"], results.len(), "{bridge}");

    let sent: HashMap<String, String> = std::fs::read_to_string(&log)
        .expect("wrench log written")
        .lines()
        .map(|l| (l.split(' ').next().unwrap_or("").to_string(), l.to_string()))
        .collect();
    assert_eq!(sent.len() as u64, bridge["sent"].as_u64().unwrap());
    for (who, (n, dumped)) in &results {
        check_bit_exact(who, *n, dumped, &sent);
    }
}

#[test]
fn bridge_flags_are_checked_with_clear_messages() {
    let run = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_vps"))
            .env("VPS_CACHE_DIR", cache_dir())
            .args(["run", "--voxel-size", "10mm", "--seconds", "0.01"])
            .args(args)
            .output()
            .expect("vps runs");
        assert!(!out.status.success(), "{args:?} should fail");
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let e = run(&["--device", "bridge:127.0.0.1:0", "--map-offset", "1,2"]);
    assert!(e.contains("expected three numbers"), "{e}");
    let e = run(&[
        "--device",
        "bridge:127.0.0.1:0",
        "--map-rotate-deg",
        "0,nan,0",
    ]);
    assert!(e.contains("not a finite number"), "{e}");
    // Out of range: refused by the parser, naming the flag and the documented range.
    let e = run(&["--device", "bridge:127.0.0.1:0", "--map-scale", "0"]);
    assert!(
        e.contains("--map-scale") && e.contains("0.001 to 1000"),
        "{e}"
    );
    let e = run(&["--device", "bridge:127.0.0.1:0", "--pose-timeout-ms", "0"]);
    assert!(
        e.contains("--pose-timeout-ms") && e.contains("2 to 10000 (ms)"),
        "{e}"
    );
    let e = run(&["--device", "sim", "--force-scale", "2"]);
    assert!(e.contains("need --device bridge"), "{e}");
}

/// A scene whose device is the bridge, mapped: device +X is scene +Y (rotated 90° about Z),
/// scaled ×2, the device origin at the part's start (0, 0, 0.5), far above the floor.
fn mapped_scene() -> String {
    let device = vps_fuzz::seeds::bridge_device_section(
        "127.0.0.1:0",
        200,
        2.0,
        [0, 0, 90],
        [0.0, 0.0, 0.5],
    );
    format!(
        r#"
part = "builtin:sphere"
[[static]]
source = "builtin:box"
scale = [10.0, 10.0, 1.0]
[voxels]
voxel_size = "10mm"
[hand]
waypoints = [[0.0, 0.0, 0.5], [0.0, 0.0, 0.6]]
{device}"#
    )
}

/// Runs a 2.5 s session on `scene` with `extra` flags while a client moves the device 0.02 m
/// along +X and holds it there; returns where the part ended (m).
fn drive_mapped_scene(scene: &Path, extra: &[&str]) -> [f64; 3] {
    use vps_haptic::HandleSample;
    let scene = scene.to_str().unwrap();
    let mut args = vec![
        "run",
        "--scene",
        scene,
        "--no-cache",
        "--seconds",
        "2.5",
        "--json",
    ];
    args.extend_from_slice(extra);
    let (child, addr) = start_vps_with(&args);
    let mut client = vps_input::BridgeClient::connect(addr, None).expect("client binds");
    // 0.5 s ramp from the device origin to 0.02 m along +X, then held for 1 s; then silent, so
    // the pose timeout holds the part where it is until the session ends.
    let start = std::time::Instant::now();
    let mut next = start;
    loop {
        let t = start.elapsed().as_secs_f64();
        if t > 1.5 {
            break;
        }
        let x = 0.02 * (t / 0.5).min(1.0);
        let sample = HandleSample {
            position: glam::DVec3::new(x, 0.0, 0.0),
            orientation: glam::DQuat::IDENTITY,
            linear_velocity: glam::DVec3::ZERO,
            angular_velocity: glam::DVec3::ZERO,
        };
        client.send_pose(&sample).expect("pose sent");
        while client
            .recv_wrench(Duration::ZERO)
            .expect("receive")
            .is_some()
        {}
        next += Duration::from_millis(1);
        if let Some(wait) = next.checked_duration_since(std::time::Instant::now()) {
            std::thread::sleep(wait);
        }
    }
    let out = child.wait_with_output().expect("vps ends");
    assert!(out.status.success(), "vps failed");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert!(
        report["bridge"]["accepted"].as_u64().unwrap() > 500,
        "{}",
        report["bridge"]
    );
    let p = &report["final_position_m"];
    [0, 1, 2].map(|i| p[i].as_f64().unwrap())
}

#[test]
fn a_scene_files_mapping_places_the_device_and_flags_override_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("mapped.toml");
    std::fs::write(&scene, mapped_scene()).unwrap();
    let close = |p: [f64; 3], want: [f64; 3]| {
        let d = (0..3).map(|i| (p[i] - want[i]).powi(2)).sum::<f64>().sqrt();
        assert!(d < 0.005, "part at {p:?}, expected {want:?} (off by {d} m)");
    };
    // The scene's mapping: 0.02 m along device +X is 0.04 m along scene +Y.
    close(drive_mapped_scene(&scene, &[]), [0.0, 0.04, 0.5]);
    // --map-scale replaces the scene's scale; its rotation and offset stay.
    close(
        drive_mapped_scene(&scene, &["--map-scale", "5"]),
        [0.0, 0.1, 0.5],
    );
}

/// A part with no inside (one triangle, 50 mm legs) driven by the C client into a 0.2 m thick
/// block: the session renders it two-sided (the distance model, zero normals), so the scene's
/// force on the part never points into the block (its z component is never negative, over every
/// frame of the session's study) and the part never ends inside it (its plane never goes below the
/// block's top; no frame penetrates). Without gcc the test says so and passes.
#[test]
fn a_single_triangle_part_is_pushed_out_of_a_block_never_in() {
    if !available("gcc") {
        println!("SKIPPED: the single-triangle part over the bridge (gcc not found)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let example = compile_example(dir.path());
    std::fs::write(
        dir.path().join("triangle.obj"),
        "v -0.02 -0.02 0\nv 0.03 -0.02 0\nv -0.02 0.03 0\nf 1 2 3\n",
    )
    .unwrap();
    // The block: the built-in 0.1 m cube scaled to 0.4 × 0.4 × 0.2 m, its top at z = 0. The
    // part starts 30 mm above it; the example moves the device 0.15 m down (to 0.12 m inside the
    // block) and back every 2 s.
    let scene = dir.path().join("sheet.toml");
    std::fs::write(
        &scene,
        "[part]\nsource = \"triangle.obj\"\n\
         [[static]]\nsource = \"builtin:box\"\nscale = [4.0, 4.0, 2.0]\ntranslate = [0.0, 0.0, -0.1]\n\
         [voxels]\nvoxel_size = \"5mm\"\n\
         [hand]\nwaypoints = [[0.0, 0.0, 0.03], [0.0, 0.0, 0.031]]\n",
    )
    .unwrap();
    let study = dir.path().join("study");
    let (child, addr) = start_vps_with(&[
        "run",
        "--scene",
        scene.to_str().unwrap(),
        "--device",
        "bridge:127.0.0.1:0",
        "--seconds",
        "6",
        "--study",
        study.to_str().unwrap(),
        "--json",
    ]);
    let (n, _) = run_example(Command::new(&example), addr, &dir.path().join("c.dump"));
    assert!(n >= MIN_WRENCHES, "only {n} wrenches");
    let out = child.wait_with_output().expect("vps finishes");
    assert!(out.status.success(), "vps run failed");
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON report");
    assert_eq!(report["stats"]["penetrating_frames"], 0, "{report}");

    let csv = std::fs::read_to_string(study.join("path.csv")).expect("the study's path.csv");
    let (z, fz) = (
        csv_column(&csv, "part_z_m"),
        csv_column(&csv, "contact_force_z_n"),
    );
    let (mut frames, mut pushed, mut lowest, mut most_down) = (0, 0, f64::INFINITY, 0.0f64);
    for (&part_z, &force_z) in z.iter().zip(&fz) {
        frames += 1;
        pushed += usize::from(force_z > 0.01);
        lowest = lowest.min(part_z);
        most_down = most_down.min(force_z);
    }
    eprintln!(
        "single-triangle part: {frames} frames, {pushed} pushed up by the block, lowest grip z \
         {:.2} mm, most downward scene force {most_down:e} N",
        lowest * 1e3
    );
    assert!(
        pushed > 100,
        "the part never pressed on the block ({pushed} frames)"
    );
    assert!(
        most_down >= 0.0,
        "the block pulled the part in: Fz {most_down} N"
    );
    assert!(
        lowest >= 0.0,
        "the part's plane went {:.3} mm into the block",
        -lowest * 1e3
    );
}

/// Two cubes of 40 mm, each a `[[part]]` on its own bridge: the C example's device stroke
/// (0.15 m along −Z, scaled by 0.2) turned towards the other cube, so the two hands press the
/// cubes together and apart every 2 s.
fn two_bridged_cubes() -> String {
    let bridged = |side: f64| {
        format!(
            "[part.hand]\nwaypoints = [[{:?}, 0.0, 0.0]]\n[part.device]\nkind = \"bridge:127.0.0.1:0\"\n\
             mapping = {{ scale = 0.2, rotate_deg = [0.0, {:?}, 0.0] }}\n",
            0.035 * side,
            90.0 * side
        )
    };
    let scene = vps_testkit::parts::two_parts(
        vps_testkit::parts::CUBE_40MM,
        bridged,
        "\n[voxels]\nvoxel_size = \"5mm\"\n",
    );
    format!("name = \"two bridged cubes\"\n{scene}")
}

/// The dumped wrench lines (`FRAME` and six IEEE-754 hex words: force N, torque N·m) as numbers.
fn dumped_wrenches(lines: &[String]) -> Vec<[f64; 6]> {
    lines
        .iter()
        .map(|line| {
            let words: Vec<f64> = line
                .split(' ')
                .skip(1)
                .map(|w| f64::from_bits(u64::from_str_radix(w, 16).expect("a hex word")))
                .collect();
            words.try_into().expect("six words")
        })
        .collect()
}

#[test]
fn two_c_clients_drive_two_parts_in_one_session() {
    if !available("gcc") {
        println!("SKIPPED: two C bridge clients (gcc not found)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let example = compile_example(dir.path());
    let scene = dir.path().join("two.toml");
    std::fs::write(&scene, two_bridged_cubes()).unwrap();
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vps"));
    cmd.args(["run", "--scene", scene.to_str().unwrap()])
        .args(["--seconds", SESSION_SECONDS, "--json"])
        .env("VPS_CACHE_DIR", cache_dir())
        .stdout(Stdio::piped());
    let (child, addrs) = vps_testkit::process::spawn_until_lines(
        cmd,
        "vps",
        "device bridge listening on ",
        2,
        STARTUP_DEADLINE,
    );
    let addrs: Vec<SocketAddr> = addrs.iter().map(|a| a.parse().unwrap()).collect();
    assert_ne!(addrs[0], addrs[1], "one port each");
    // Both clients at once, one per part.
    let clients: Vec<_> = addrs
        .iter()
        .enumerate()
        .map(|(k, &addr)| {
            let (example, dump) = (example.clone(), dir.path().join(format!("{k}.dump")));
            std::thread::spawn(move || run_example(Command::new(example), addr, &dump))
        })
        .collect();
    let results: Vec<(u64, Vec<String>)> = clients.into_iter().map(|c| c.join().unwrap()).collect();
    let report = end_session(child);
    let parts = report["parts"].as_array().expect("both parts reported");
    assert_eq!(parts.len(), 2, "{report}");
    for (part, (n, lines)) in parts.iter().zip(&results) {
        let name = &part["name"];
        assert!(*n >= MIN_WRENCHES, "{name}: only {n} wrenches");
        let wrenches = dumped_wrenches(lines);
        assert_eq!(
            wrenches.len() as u64,
            *n,
            "{name}: one dump line per wrench"
        );
        let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        assert!(
            wrenches.iter().all(|w| w.iter().all(|x| x.is_finite())),
            "{name}: a non-finite wrench reached the device"
        );
        // The default device limits: 15 N, 0.1 N·m.
        let max_force = wrenches.iter().map(|w| norm(&w[..3])).fold(0.0, f64::max);
        let max_torque = wrenches.iter().map(|w| norm(&w[3..])).fold(0.0, f64::max);
        assert!(
            max_force <= 15.0 && max_torque <= 0.1,
            "{name}: {max_force} N, {max_torque} N·m"
        );
        assert!(max_force > 0.0, "{name}: only zero wrenches");
        eprintln!(
            "{name}: {n} wrenches, largest {max_force:.3} N and {max_torque:.4} N·m, {} frames \
             touching the other part",
            part["pair_contact_frames"]
        );
        assert!(
            part["pair_contact_frames"].as_u64().unwrap() > 100,
            "{part}"
        );
        assert_eq!(part["non_finite_frames"], 0, "{part}");
        assert!(
            part["max_device_force_n"].as_f64().unwrap() <= 15.0,
            "{part}"
        );
        // Each part's own bridge counted what its client sent and got.
        let counters = &part["device_counters"];
        assert_eq!(counters["garbage"], 0, "{counters}");
        assert!(
            counters["accepted"].as_u64().unwrap() >= MIN_WRENCHES,
            "{counters}"
        );
        assert!(counters["sent"].as_u64().unwrap() >= *n, "{counters}");
    }
}
