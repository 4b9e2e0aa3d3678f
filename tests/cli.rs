//! End-to-end tests of the `vps` binary: real files, real processes.

use std::path::Path;
use vps_testkit::process::{json, Vps};

/// The binary with a temporary directory and a private cache (`VPS_CACHE_DIR`).
fn sandbox() -> Vps {
    Vps::new(env!("CARGO_BIN_EXE_vps"))
}

/// `vps COMMAND MESH --voxel-size 5mm -o OUT --json` (`voxelize` or `shell`), then
/// `vps inspect OUT --json`: the two reports.
fn build_and_inspect(
    vps: &Vps,
    command: &str,
    mesh: &str,
    out: &str,
) -> (serde_json::Value, serde_json::Value) {
    let made = json(&vps.run(&[command, mesh, "--voxel-size", "5mm", "-o", out, "--json"]));
    let info = json(&vps.run(&["inspect", out, "--json"]));
    (made, info)
}

#[test]
fn voxelize_inspect_probe_round_trip_on_builtin_sphere() {
    let vps = sandbox();
    let vmap = vps.path("sphere.vmap");
    let (made, info) = build_and_inspect(&vps, "voxelize", "builtin:sphere", &vmap);
    assert_eq!(
        made["hash"], info["hash"],
        "hash survives the file round trip"
    );
    assert_eq!(info["voxel_size_m"].as_f64().unwrap(), 0.005);
    assert!(info["counts"]["interior"].as_u64().unwrap() > 0);
    assert!(info["counts"]["surface"].as_u64().unwrap() > 0);

    // The built-in sphere has radius 0.05 m and is centred at the origin.
    let csv = vps.path("points.csv");
    std::fs::write(&csv, "# x,y,z\n0,0,0\n1,1,1\n0.2,0,0\n").unwrap();
    let kinds = json(&vps.run(&["probe", &vmap, "--points", &csv, "--json"]));
    let kinds: Vec<&str> = kinds
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["kind"].as_str().unwrap())
        .collect();
    assert_eq!(kinds, ["interior", "free", "free"]);
}

#[test]
fn corrupted_voxmap_is_a_clear_error_not_a_panic() {
    let vps = sandbox();
    let vmap = vps.path("box.vmap");
    assert!(vps
        .run(&[
            "voxelize",
            "builtin:box",
            "--voxel-size",
            "10mm",
            "-o",
            &vmap
        ])
        .status
        .success());
    let mut bytes = std::fs::read(&vmap).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x5a;
    std::fs::write(&vmap, &bytes).unwrap();
    let out = vps.run(&["inspect", &vmap]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("box.vmap"), "error names the file: {err}");
    assert!(!err.contains("panicked"), "{err}");

    std::fs::write(&vmap, &bytes[..20]).unwrap();
    let out = vps.run(&["inspect", &vmap]);
    assert_eq!(out.status.code(), Some(1));
    assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
}

#[test]
fn bad_arguments_are_rejected_with_a_message() {
    let vps = sandbox();
    let out = vps.path("x.vmap");
    let err = vps.fails(&["voxelize", "builtin:box", "--voxel-size=-5mm", "-o", &out]);
    assert!(err.contains("positive"), "{err}");
    let err = vps.fails(&["voxelize", "builtin:nope", "-o", &out]);
    assert!(err.contains("unknown built-in scene"), "{err}");
    let err = vps.fails(&["voxelize", "/nonexistent/part.obj", "-o", &out]);
    assert!(err.contains("/nonexistent/part.obj"), "{err}");
}

#[test]
fn shell_file_round_trip() {
    let vps = sandbox();
    let shell = vps.path("teapot.vshell");
    let (made, info) = build_and_inspect(&vps, "shell", "builtin:teapot", &shell);
    assert_eq!(made["points"], info["points"]);
    assert!(info["points"].as_u64().unwrap() > 100);
}

#[test]
fn record_then_replay_reproduces_the_session_exactly() {
    let vps = sandbox();
    let trace = vps.path("session.jsonl");
    // The recorded session itself: a paced run may skip ticks on a loaded machine, so compare the
    // replay with this very run, not with another paced run.
    let recorded = json(&vps.run(&["run", "--seconds", "1", "--record", &trace, "--json"]));
    let replayed = json(&vps.run(&["replay", &trace, "--json"]));
    assert_eq!(replayed["stats"]["frames"], 1000);
    assert_eq!(
        replayed["final_position_m"], recorded["final_position_m"],
        "replay is bit-exact"
    );
    let out = vps.run(&["record", "-o", &trace, "--seconds", "1"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    std::fs::write(&trace, "{\"not\": \"a trace\"}\n").unwrap();
    let out = vps.run(&["replay", &trace]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("session.jsonl") && !err.contains("panicked"),
        "{err}"
    );
}

#[test]
fn devices_lists_or_says_there_are_none() {
    let vps = sandbox();
    let out = vps.run(&["devices"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        !text.trim().is_empty(),
        "prints a device per line or says none were found"
    );
}

/// Single-host multi-process mode: two real worker processes over QUIC (pinned mutual TLS on
/// loopback) give the same session as one process, to the last bit of the final state. Workers
/// that miss the frame deadline have their shares recomputed locally, so this holds however late
/// they are on a loaded machine.
#[test]
fn two_local_worker_processes_reproduce_the_one_process_session() {
    let vps = sandbox();
    let trace = vps.path("session.jsonl");
    assert!(vps
        .run(&["record", "-o", &trace, "--seconds", "1"])
        .status
        .success());
    let alone = json(&vps.run(&["replay", &trace, "--json"]));
    let device = format!("replay:{trace}");
    // No stale stand-ins: the wrench must not depend on how late a worker is on this machine.
    let clustered = json(&vps.run(&[
        "cluster",
        "--local-workers",
        "2",
        "--max-stale-frames",
        "0",
        "--device",
        &device,
        "--json",
    ]));
    assert_eq!(clustered["final_position_m"], alone["final_position_m"]);
    assert_eq!(clustered["stats"]["frames"], 1000);
    let peers = clustered["cluster"]["peers"]
        .as_array()
        .expect("per-worker report");
    assert_eq!(peers.len(), 2, "both workers joined");
}

#[test]
fn bench_host_counts_ticks_and_rejects_bad_arguments() {
    let vps = sandbox();
    let report = json(&vps.run(&[
        "bench",
        "host",
        "--seconds",
        "0.2",
        "--busy-us",
        "100",
        "--json",
    ]));
    // 200 ticks of 1 ms; a stalled machine may start the last one after the end and skip it.
    let ticks = report["ticks"].as_u64().unwrap();
    assert!((190..=200).contains(&ticks), "{ticks} ticks");
    assert!(report["disturbed_ticks"].as_u64().unwrap() <= ticks);
    let gaps = report["gaps"].as_array().unwrap();
    let counts: Vec<u64> = gaps.iter().map(|g| g["count"].as_u64().unwrap()).collect();
    assert!(
        counts.windows(2).all(|w| w[0] >= w[1]),
        "gap counts must fall with the threshold: {counts:?}"
    );
    for (bad, field) in [
        ("--seconds=-1", "--seconds"),
        ("--seconds=NaN", "--seconds"),
        ("--busy-us=1000", "--busy-us"),
    ] {
        let stderr = vps.fails(&["bench", "host", bad]);
        assert!(stderr.contains(field), "{bad}: {stderr}");
    }
}

/// `vps bench fidelity` on one voxel size: one row per force model, width and shell method, every
/// scene, both slides (the tangent-plane model at its 9 separations, the distance model at its 7
/// depths); `--models distance` gives the distance rows alone; bad arguments are errors naming the
/// flag.
#[test]
fn bench_fidelity_reports_every_setting_and_rejects_bad_arguments() {
    let vps = sandbox();
    let report = json(&vps.run(&[
        "bench",
        "fidelity",
        "--voxel-sizes",
        "5mm",
        "--poses",
        "1",
        "--json",
    ]));
    let rows = report["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 12, "2 models × 2/4/8 bits × centres/exact");
    for row in rows {
        assert_eq!(row["voxel_size_mm"], 5.0);
        assert_eq!(row["scenes"].as_array().unwrap().len(), 5);
        let separations = match row["model"].as_str() {
            Some("tangent-plane") => 9,
            Some("distance") => 7,
            other => panic!("model {other:?}"),
        };
        assert_eq!(row["all"]["poses"], 5 * separations);
        assert!(row["all"]["compared"].as_u64().unwrap() > 0);
        assert!(row["slide_deep"]["mean_force_n"].as_f64().unwrap() > 0.0);
    }
    let distance = json(&vps.run(&[
        "bench",
        "fidelity",
        "--voxel-sizes",
        "10mm",
        "--poses",
        "1",
        "--models",
        "distance",
        "--json",
    ]));
    let rows = distance["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 6);
    assert!(rows.iter().all(|r| r["model"] == "distance"));
    for (bad, field) in [
        (["--poses", "0"], "--poses"),
        (["--voxel-sizes", "50mm"], "--voxel-sizes"),
        (["--models", "layers"], "--models"),
    ] {
        let stderr = vps.fails(&["bench", "fidelity", bad[0], bad[1]]);
        assert!(stderr.contains(field), "{bad:?}: {stderr}");
    }
}

#[test]
fn the_service_config_files_are_read_checked_and_overridden_by_flags() {
    let vps = sandbox();
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    // The committed worker file loads; --cert given on the command line replaces the file's, so
    // the worker fails reading that certificate (before any network).
    let missing = vps.dir().join("flag.crt");
    let stderr = vps.fails(&[
        "worker",
        "--config",
        root.join("configs/worker.toml").to_str().unwrap(),
        "--cert",
        missing.to_str().unwrap(),
    ]);
    assert!(stderr.contains("flag.crt"), "{stderr}");
    // An unknown key is refused, naming the file and the key.
    for role in ["coordinator", "worker"] {
        let config = vps.dir().join(format!("bad-{role}.toml"));
        std::fs::write(&config, "threads = 1\nspin_usec = 100\n").unwrap();
        let stderr = vps.fails(&[role, "--config", config.to_str().unwrap()]);
        assert!(
            stderr.contains(&format!("bad-{role}.toml")) && stderr.contains("spin_usec"),
            "{role}: {stderr}"
        );
    }
}

/// A bridge mapping flag out of its documented range, or a `--device` of no known form, is a command
/// line the parser refuses (exit 2), naming the flag and what is allowed, before anything is
/// voxelized; they used to fail with exit 1 after the scene was built (the mapping naming the
/// bridge config's `mapping.scale` / `pose_timeout` in s).
#[test]
fn bridge_mapping_flags_out_of_range_are_refused_before_any_work() {
    let vps = sandbox();
    for (flag, value, range) in [
        ("--map-scale", "0", "0.001 to 1000"),
        ("--map-scale", "2000", "0.001 to 1000"),
        ("--force-scale", "0", "above 0, up to 1000"),
        ("--pose-timeout-ms", "1", "2 to 10000 (ms)"),
        ("--pose-timeout-ms", "NaN", "2 to 10000 (ms)"),
        // A misspelt device was refused with exit 1 after the scene was built.
        (
            "--device",
            "joystick",
            "expected sim, spacemouse, bridge[:ADDR] or replay:FILE",
        ),
        (
            "--device",
            "bridge:localhost",
            "not an address like 127.0.0.1:7700",
        ),
    ] {
        let mut args = vec!["run", "--scene", "builtin:rig-teapot", "--seconds", "1"];
        if flag != "--device" {
            args.extend(["--device", "bridge:127.0.0.1:0"]);
        }
        args.extend([flag, value]);
        let out = vps.run(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flag} {value}: {err}");
        assert!(
            err.contains(flag) && err.contains(range),
            "{flag} {value}: {err}"
        );
        assert!(
            !err.contains("voxmap"),
            "{flag} {value} built the scene: {err}"
        );
    }
}

/// A device that cannot be opened (a bridge port another program holds, a trace file that is not
/// there) or a `--haptic` file that cannot be read is reported before the voxmap is built, which can take minutes for a user's scene; the
/// error used to come after the build. A missing SpaceMouse goes the same way (not tested here: a
/// developer's machine may have one).
#[test]
fn a_device_that_cannot_open_or_a_bad_haptic_file_is_reported_before_the_voxmap_is_built() {
    let vps = sandbox();
    let held = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let bridge = format!("bridge:{}", held.local_addr().unwrap());
    let replay = format!("replay:{}", vps.path("no-such-trace.csv"));
    let haptic = vps.path("no-such-haptic.toml");
    for (flag, value, expected) in [
        ("--device", bridge.as_str(), "binding the device bridge on"),
        ("--device", replay.as_str(), "reading the trace to replay"),
        ("--haptic", haptic.as_str(), "cannot read haptic parameters"),
    ] {
        let out = vps.run(&[
            "run",
            "--scene",
            "builtin:rig-teapot",
            "--seconds",
            "1",
            "--no-cache",
            flag,
            value,
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{value}: {err}");
        assert!(err.contains(expected), "{value}: {err}");
        assert!(
            !err.contains("voxmap:"),
            "{value}: built before the check: {err}"
        );
    }
}

/// A CAD export in millimetres: `vps voxelize` / `vps shell` read it with `--units mm` (as a scene
/// file's `units`); without it the refusal says the file was read in metres and names the flag.
#[test]
fn voxelize_and_shell_read_a_mesh_in_millimetres_with_units() {
    let vps = sandbox();
    let obj = vps.path("block.obj");
    // A 100 × 40 × 100 mm block.
    let text = vps_testkit::obj::box_obj([-50.0, 0.0, -50.0], [50.0, 40.0, 50.0]);
    std::fs::write(&obj, text).unwrap();
    let vmap = vps.path("block.vmap");
    for command in ["voxelize", "shell"] {
        let err = vps.fails(&[command, &obj, "--voxel-size", "1mm", "-o", &vmap]);
        assert!(
            err.contains("read in metres: 100.0000 m across") && err.contains("--units mm"),
            "{command}: {err}"
        );
    }
    // `vps COMMAND block.obj --units mm --voxel-size 5mm -o OUT --json`, as JSON.
    let in_mm = |command: &str, out: &str| {
        json(&vps.run(&[
            command,
            &obj,
            "--units",
            "mm",
            "--voxel-size",
            "5mm",
            "-o",
            out,
            "--json",
        ]))
    };
    let made = in_mm("voxelize", &vmap);
    let info = json(&vps.run(&["inspect", &vmap, "--json"]));
    assert_eq!(made["hash"], info["hash"]);
    // 100 mm at 5 mm: 20 voxels across plus the padding, not 20,000.
    let dims = made["dims"][0].as_u64().unwrap();
    assert!((20..40).contains(&dims), "{made}");
    let shell = vps.path("block.vshell");
    let made = in_mm("shell", &shell);
    let radius = made["max_radius_m"].as_f64().unwrap();
    assert!((0.05..0.08).contains(&radius), "{made}");
    let err = vps.fails(&["voxelize", "builtin:box", "--units", "mm", "-o", &vmap]);
    assert!(err.contains("--units applies to mesh files"), "{err}");
}

/// A scene small enough for every command to run on it in a second or two in a test build: the
/// built-in sphere (0.1 m across) pressed by the hand onto the built-in 0.1 m cube, at 10 mm
/// voxels (it states no other voxel setting: the built-in defaults apply).
fn tiny_scene() -> &'static str {
    "name = \"tiny\"\npart = \"builtin:sphere\"\n\
     [[static]]\nsource = \"builtin:box\"\n\
     [voxels]\nvoxel_size = \"10mm\"\n\
     [hand]\nwaypoints = [[0.3, 0.0, 0.0], [0.0, 0.0, 0.0]]\nspeed = 0.5\n"
}

/// True when `stdout` is, or opens like, a JSON document (an object or a list).
fn looks_like_json(stdout: &[u8]) -> bool {
    let text = String::from_utf8_lossy(stdout);
    let t = text.trim_start();
    serde_json::from_str::<serde_json::Value>(&text).is_ok()
        || t.starts_with('{')
        || t.starts_with('[')
}

/// Every command's default output is text for a person, never JSON; `--json` gives JSON. Each
/// command runs once, cheaply (the tiny scene, few frames), without `--json`: it must succeed and
/// its stdout must not be (or open like) a JSON document; where `--json` is cheap it runs again
/// with it and its stdout must parse.
///
/// Not run here, and why:
/// - `vps bench viewer`, `vps bench clearance` and `vps bench scaling`: each runs a fixed
///   workload with no flag to shrink it (the viewer bench and the scaling bench's child runs
///   voxelize the 596k-triangle aircraft bay, the clearance bench its full grid of pegs, about
///   20 s in a release build); their text comes from the same `print_report` as the benches
///   run here, and `vps bench scaling` passes `--json` to the child benches it parses.
/// - `vps worker`, `vps coordinator` and `vps view` are services that run until stopped:
///   `worker` and `view` print to stderr only, and a coordinator's report is the one
///   `vps cluster` prints (the same `finish`), run here.
#[test]
fn no_command_prints_json_without_json() {
    let vps = sandbox();
    let scene = vps.path("tiny.toml");
    std::fs::write(&scene, tiny_scene()).unwrap();
    let (vmap, vshell, trace) = (
        vps.path("box.vmap"),
        vps.path("sphere.vshell"),
        vps.path("t.jsonl"),
    );
    let points = vps.path("points.csv");
    std::fs::write(&points, "0,0,0\n1,1,1\n").unwrap();
    let sweep = vps.path("sweep.toml");
    std::fs::write(
        &sweep,
        format!(
            "voxel_sizes_mm = [10.0]\nmethods = [\"exact\"]\nwidths = [4]\n[[run]]\nscene = {:?}\n",
            scene
        ),
    )
    .unwrap();
    let certs = vps.path("certs");
    std::fs::create_dir(&certs).unwrap();
    let deploy = vps.path("layout");
    let s = scene.as_str();
    // Two spheres over the box, for `bench parts`.
    let two = vps.path("two.toml");
    std::fs::write(
        &two,
        "[[static]]\nsource = \"builtin:box\"\n[voxels]\nvoxel_size = \"10mm\"\n\
         [[part]]\nsource = \"builtin:sphere\"\n\
         [part.hand]\nwaypoints = [[0.3, 0.0, 0.0], [0.0, 0.0, 0.0]]\nspeed = 0.5\n\
         [[part]]\nsource = \"builtin:sphere\"\n\
         [part.hand]\nwaypoints = [[0.0, 0.3, 0.0]]\n",
    )
    .unwrap();
    // (arguments, whether `--json` is cheap enough to run too)
    let commands: Vec<(Vec<&str>, bool)> = vec![
        (
            vec![
                "voxelize",
                "builtin:box",
                "--voxel-size",
                "20mm",
                "-o",
                &vmap,
            ],
            false,
        ),
        (
            vec![
                "shell",
                "builtin:sphere",
                "--voxel-size",
                "20mm",
                "-o",
                &vshell,
            ],
            false,
        ),
        (vec!["inspect", &vmap], true),
        (vec!["inspect", &vshell], true),
        (vec!["probe", &vmap, "--points", &points], true),
        (vec!["scene", "check", s], true),
        (vec!["devices"], true),
        (vec!["cert", "--out", &certs, "--name", "a"], false),
        // Run once: a second run into the same folder is refused (tests/deploy.rs runs --json).
        (
            vec!["deploy", "init", "--loopback", "1", "-o", &deploy],
            false,
        ),
        (vec!["demo", "--scene", s, "--seconds", "0.3"], false),
        (vec!["run", "--scene", s, "--seconds", "0.2"], true),
        (
            vec!["record", "--scene", s, "--seconds", "0.2", "-o", &trace],
            false,
        ),
        (vec!["replay", "--scene", s, &trace], true),
        (
            vec![
                "cluster",
                "--scene",
                s,
                "--local-workers",
                "1",
                "--seconds",
                "0.2",
            ],
            false,
        ),
        (
            vec![
                "netem-relay",
                "--listen",
                "127.0.0.1:0",
                "--forward",
                "127.0.0.1:9",
                "--seconds",
                "0.1",
            ],
            true,
        ),
        (vec!["sweep", "--quick", "--config", &sweep], false),
        (
            vec![
                "tune",
                "--scene",
                s,
                "--frames",
                "50",
                "--verify-frames",
                "50",
                "--budget-fraction",
                "1",
            ],
            false,
        ),
        (
            vec!["bench", "host", "--seconds", "0.1", "--busy-us", "100"],
            true,
        ),
        (
            vec!["bench", "kernel", "--points", "1000", "--seconds", "0.01"],
            true,
        ),
        (
            vec![
                "bench",
                "voxelize",
                "builtin:box",
                "--voxel-size",
                "20mm",
                "--repeat",
                "1",
            ],
            true,
        ),
        (
            vec![
                "bench",
                "tree-memory",
                "builtin:box",
                "--voxel-size",
                "20mm",
            ],
            true,
        ),
        (
            vec![
                "bench",
                "fidelity",
                "--voxel-sizes",
                "20mm",
                "--poses",
                "1",
                "--models",
                "distance",
            ],
            false,
        ),
        (
            vec![
                "bench",
                "loop",
                "--scene",
                s,
                "--points",
                "1000",
                "--frames",
                "100",
                "--threads",
                "1",
            ],
            true,
        ),
        (
            vec![
                "bench",
                "cluster",
                "--scene",
                s,
                "--points",
                "1000",
                "--frames",
                "100",
                "--workers",
                "1",
            ],
            false,
        ),
        (vec!["bench", "transport", "--frames", "100"], false),
        (
            vec![
                "bench", "parts", "--scene", &two, "--frames", "50", "--rounds", "1",
            ],
            true,
        ),
        (vec!["bench", "bridge", "--round-trips", "100"], false),
    ];
    for (args, json_too) in &commands {
        let out = vps.run(args);
        // Tune fails, having printed its table, when even its coarsest size misses the budget: a
        // timing on this machine, not a fault.
        let over_budget =
            args[0] == "tune" && String::from_utf8_lossy(&out.stderr).contains("voxels miss the");
        assert!(
            out.status.success() || over_budget,
            "vps {args:?} failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            !looks_like_json(&out.stdout),
            "vps {args:?} printed JSON without --json:\n{}",
            String::from_utf8_lossy(&out.stdout)
        );
        if *json_too {
            let mut with = args.clone();
            with.push("--json");
            json(&vps.run(&with));
        }
    }
}

/// `vps demo`'s text says what each of its figures means: every figure its summaries print
/// ("contact frames" and "touching", "local fallbacks", "period error", the paper's ratio) has a
/// line of meaning in the legend under them.
#[test]
fn the_demo_explains_each_figure() {
    let vps = sandbox();
    let scene = vps.path("tiny.toml");
    std::fs::write(&scene, tiny_scene()).unwrap();
    let out = vps.run(&["demo", "--scene", &scene, "--seconds", "0.5"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    let (figures, legend) = text
        .split_once("what the figures mean:\n")
        .unwrap_or_else(|| panic!("no legend in\n{text}"));
    for figure in [
        "frames",
        "missed deadlines",
        "watchdog trips",
        "local fallbacks",
        "compute",
        "period error",
        "contact frames",
        "touching",
        "penetrating",
        "penetration ratio",
        "braking",
    ] {
        assert!(
            figures.contains(figure),
            "{figure} not among the figures:\n{figures}"
        );
        let meaning = legend
            .lines()
            .find(|l| l.starts_with(&format!("  {figure}: ")))
            .unwrap_or_else(|| panic!("no meaning for {figure}:\n{legend}"));
        assert!(meaning.len() > figure.len() + 20, "{meaning}");
    }
    assert!(figures.contains("(the paper's: 6.0e-5)"), "{figures}");
    assert!(legend.contains("McNeely et al. 1999, Table 2"), "{legend}");
}
