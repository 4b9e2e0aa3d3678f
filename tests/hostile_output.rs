//! Issue 15 through the binary: a closed stdout ends `vps` quietly (status 141), a full one is an
//! error naming stdout, output paths are checked before any work and never overwrite the input,
//! memory is budgeted from the plan, and odd files get messages naming them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use vps_testkit::full_stdout::assert_full_stdout_is_an_error;

fn vps() -> Command {
    Command::new(vps_testkit::process::vps_binary(env!("CARGO_BIN_EXE_vps")))
}

fn run(cmd: &mut Command) -> Output {
    cmd.stdin(Stdio::null()).output().expect("spawning vps")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A small voxmap made by the binary.
fn small_map(dir: &Path) -> PathBuf {
    let path = dir.join("box.vmap");
    let out = run(vps()
        .args(["voxelize", "builtin:box", "--voxel-size", "1cm", "-o"])
        .arg(&path));
    assert!(out.status.success(), "{}", stderr(&out));
    path
}

#[test]
fn a_closed_stdout_ends_quietly_with_status_141() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map(dir.path());
    let points = dir.path().join("points.csv");
    std::fs::write(&points, "0,0,0\n".repeat(10_000)).unwrap();
    let cases: [Vec<&std::ffi::OsStr>; 3] = [
        vec!["inspect".as_ref(), map.as_os_str(), "--json".as_ref()],
        vec!["inspect".as_ref(), map.as_os_str()],
        vec![
            "probe".as_ref(),
            map.as_os_str(),
            "--points".as_ref(),
            points.as_os_str(),
        ],
    ];
    for args in cases {
        // The reader is closed before vps starts: its first write meets EPIPE.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = vps()
            .args(&args)
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(141), "{args:?}: {}", stderr(&out));
        assert!(out.stderr.is_empty(), "{args:?}: {}", stderr(&out));
    }
}

#[test]
fn a_full_stdout_is_an_error_naming_stdout() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map(dir.path());
    assert_full_stdout_is_an_error(vps().arg("inspect").arg(&map).arg("--json"));
}

#[test]
fn output_equal_to_the_input_mesh_is_refused_and_the_mesh_kept() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("tetra.obj");
    let text = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    std::fs::write(&mesh, text).unwrap();
    for cmd in ["voxelize", "shell"] {
        let out = run(vps()
            .arg(cmd)
            .arg(&mesh)
            .args(["--voxel-size", "1cm", "-o"])
            .arg(&mesh));
        let err = stderr(&out);
        assert!(
            !out.status.success() && err.contains("is the input"),
            "{cmd}: {err}"
        );
        assert_eq!(std::fs::read_to_string(&mesh).unwrap(), text, "{cmd}");
    }
}

#[test]
fn a_bad_output_directory_is_refused_before_voxelizing() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("missing/dir/cube.vmap");
    let cube = dir.path().join("cube10m.obj");
    write_cube(&cube, 10.0);
    // At 1 mm this cube would be refused for memory; the path check must come first.
    let out = run(vps()
        .arg("voxelize")
        .arg(&cube)
        .args(["--voxel-size", "1mm", "-o"])
        .arg(&out_path));
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    assert!(
        err.contains("does not exist") && err.contains("missing/dir"),
        "{err}"
    );
    assert!(!err.contains("memory"), "{err}");
}

/// A cube of edge `size` (m) centred at the origin, as OBJ.
fn write_cube(path: &Path, size: f64) {
    let h = size / 2.0;
    std::fs::write(path, vps_testkit::obj::box_obj([-h; 3], [h; 3])).unwrap();
}

#[test]
fn a_ten_metre_cube_at_one_millimetre_is_refused_naming_the_budget() {
    let dir = tempfile::tempdir().unwrap();
    let cube = dir.path().join("cube10m.obj");
    write_cube(&cube, 10.0);
    let out_path = dir.path().join("cube.vmap");
    let out = run(vps()
        .arg("voxelize")
        .arg(&cube)
        .args(["--voxel-size", "1mm", "--max-memory", "4GiB", "-o"])
        .arg(&out_path));
    let err = stderr(&out);
    assert!(!out.status.success(), "{err}");
    for needle in ["voxel size 0.001 m", "4.00 GiB", "--max-memory"] {
        assert!(err.contains(needle), "{needle:?} missing: {err}");
    }
    assert!(!out_path.exists());
}

#[test]
fn inspect_of_an_empty_or_short_file_says_so() {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes, word) in [
        ("empty.vmap", &b""[..], "empty"),
        ("short.vmap", b"VPS", "truncated"),
    ] {
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let out = run(vps().arg("inspect").arg(&path));
        let err = stderr(&out);
        assert!(!out.status.success(), "{err}");
        assert!(err.contains(name) && err.contains(word), "{err}");
        assert!(!err.contains("failed to fill whole buffer"), "{err}");
    }
}

#[test]
fn a_missing_file_names_its_cause_once() {
    let out = run(vps().args(["inspect", "/nonexistent/nope.vmap"]));
    let err = stderr(&out);
    assert!(err.contains("nope.vmap"), "{err}");
    assert_eq!(err.matches("No such file or directory").count(), 1, "{err}");
}

#[test]
fn a_crafted_map_of_2_pow_39_voxels_is_inspected_and_probed_from_its_tree() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("huge.vmap");
    std::fs::write(&map, vps_fuzz::seeds::uniform_vmap([8192; 3], 0.001, 1)).unwrap();
    let out = run(vps().arg("inspect").arg(&map).arg("--json"));
    assert!(out.status.success(), "{}", stderr(&out));
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(info["voxel_count"], 1u64 << 39);
    assert_eq!(info["counts"]["interior"], 1u64 << 39);
    assert!(info["note"].as_str().unwrap().contains("dense"), "{info}");
    let points = dir.path().join("p.csv");
    std::fs::write(&points, "1,1,1\n-1,0,0\n").unwrap();
    let out = run(vps().arg("probe").arg(&map).arg("--points").arg(&points));
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("interior") && text.contains("free"), "{text}");
}

/// Runs `vps ARGS`, killing it (and failing) if it has not ended within 60 s: the failure being
/// tested for is a command that waits forever on a pipe.
fn run_with_deadline(args: &[&std::ffi::OsStr]) -> Output {
    let mut child = vps()
        .args(args)
        .env(
            "VPS_CACHE_DIR",
            std::env::temp_dir().join("vps-hostile-input-cache"),
        )
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawning vps");
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    while child.try_wait().unwrap().is_none() {
        if std::time::Instant::now() > deadline {
            child.kill().unwrap();
            panic!("vps {args:?} still running after 60 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

#[test]
fn a_pipe_a_device_or_a_directory_named_as_an_input_file_is_refused_at_once() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map(dir.path());
    let fifo = |name: &str| {
        let path = dir.path().join(name);
        let status = Command::new("mkfifo")
            .arg(&path)
            .status()
            .expect("mkfifo runs");
        assert!(status.success());
        path
    };
    // A link with a mesh extension to an endless device: the extension check passes, the open
    // must not.
    let zero_stl = dir.path().join("zero.stl");
    std::os::unix::fs::symlink("/dev/zero", &zero_stl).unwrap();
    let (part_stl, map_fifo, points_fifo, scene_fifo, config_fifo) = (
        fifo("part.stl"),
        fifo("map.vmap"),
        fifo("points.csv"),
        fifo("scene.toml"),
        fifo("worker.toml"),
    );
    let out_map = dir.path().join("out.vmap");
    let zero = PathBuf::from("/dev/zero");
    let replay_zero = std::ffi::OsString::from("replay:/dev/zero");
    let a_dir = dir.path().to_path_buf();
    let cases: Vec<(Vec<&std::ffi::OsStr>, &Path, &str)> = vec![
        (
            vec![
                "voxelize".as_ref(),
                part_stl.as_ref(),
                "-o".as_ref(),
                out_map.as_ref(),
            ],
            &part_stl,
            "a named pipe (FIFO)",
        ),
        (
            vec![
                "voxelize".as_ref(),
                zero_stl.as_ref(),
                "-o".as_ref(),
                out_map.as_ref(),
            ],
            &zero_stl,
            "a character device",
        ),
        (
            vec!["inspect".as_ref(), map_fifo.as_ref()],
            &map_fifo,
            "a named pipe",
        ),
        (
            vec!["inspect".as_ref(), zero.as_ref()],
            &zero,
            "a character device",
        ),
        (
            vec!["inspect".as_ref(), a_dir.as_ref()],
            &a_dir,
            "a directory",
        ),
        (
            vec![
                "probe".as_ref(),
                map.as_ref(),
                "--points".as_ref(),
                points_fifo.as_ref(),
            ],
            &points_fifo,
            "a named pipe",
        ),
        (
            vec![
                "probe".as_ref(),
                zero.as_ref(),
                "--points".as_ref(),
                points_fifo.as_ref(),
            ],
            &zero,
            "a character device",
        ),
        (
            vec![
                "run".as_ref(),
                "--scene".as_ref(),
                scene_fifo.as_ref(),
                "--seconds".as_ref(),
                "0.1".as_ref(),
            ],
            &scene_fifo,
            "a named pipe",
        ),
        (
            vec![
                "run".as_ref(),
                "--haptic".as_ref(),
                zero.as_ref(),
                "--seconds".as_ref(),
                "0.1".as_ref(),
            ],
            &zero,
            "a character device",
        ),
        (
            vec![
                "run".as_ref(),
                "--device".as_ref(),
                replay_zero.as_ref(),
                "--seconds".as_ref(),
                "0.1".as_ref(),
            ],
            &zero,
            "a character device",
        ),
        (
            vec!["sweep".as_ref(), "--config".as_ref(), zero.as_ref()],
            &zero,
            "a character device",
        ),
        (
            vec!["worker".as_ref(), "--config".as_ref(), config_fifo.as_ref()],
            &config_fifo,
            "a named pipe",
        ),
        (
            vec![
                "worker".as_ref(),
                "--coordinator".as_ref(),
                "127.0.0.1:9".as_ref(),
                "--cert".as_ref(),
                zero.as_ref(),
                "--key".as_ref(),
                zero.as_ref(),
                "--pin".as_ref(),
                zero.as_ref(),
            ],
            &zero,
            "a character device",
        ),
    ];
    for (args, path, what) in cases {
        let out = run_with_deadline(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "vps {args:?}: {err}");
        let name = path.display().to_string();
        assert!(
            err.contains(&name),
            "vps {args:?}: the error does not name {name}: {err}"
        );
        assert!(
            err.contains("not a regular file") && err.contains(what),
            "vps {args:?}: the error does not say it is {what}: {err}"
        );
    }
    assert!(!out_map.exists());
}

/// The hand of the small scenes: down onto the slab and back.
const HAND: &str = "[hand]\nwaypoints = [[0.0, 0.0, 0.1], [0.0, 0.0, 0.03]]\nspeed = 0.1\n";

/// A scene in `dir` of one static mesh file (`floor.obj`, a 20 cm slab) and the built-in box as
/// the part, at 1 cm voxels (quick to build): `scene.toml`.
fn small_scene(dir: &Path) -> PathBuf {
    std::fs::write(
        dir.join("floor.obj"),
        vps_testkit::obj::box_obj([-0.1, -0.1, -0.02], [0.1, 0.1, 0.0]),
    )
    .unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "name = \"small\"\npart = \"builtin:box\"\n\n[[static]]\nsource = \"floor.obj\"\n\n\
             {HAND}\n[voxels]\nvoxel_size = \"1cm\"\n"
        ),
    )
    .unwrap();
    scene
}

/// Whether `path` is still what it was: a FIFO, a character device or a symbolic link.
fn kind(path: &Path) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = std::fs::symlink_metadata(path).unwrap().file_type();
    if t.is_symlink() {
        "link"
    } else if t.is_fifo() {
        "fifo"
    } else if t.is_char_device() {
        "char device"
    } else if t.is_file() {
        "file"
    } else {
        "other"
    }
}

/// Issue 36 item 2: as root, `--record /dev/null`, `--report` to a FIFO, a device or a link to
/// `/proc/self/fd/1`, and `vps voxelize -o` replaced the node with a regular file; `--report
/// /dev/full` exited 0. Each output flag given a FIFO, a character device (made with mknod when
/// this runs as root), a link to `/dev/null` or `/dev/full`, or a dangling link, is refused
/// before any work with status 1, naming the flag, the path and what is there; the node is left
/// as it was.
#[test]
fn an_output_that_is_a_fifo_a_device_or_a_link_to_one_is_refused_and_left_alone() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = small_scene(d);
    let fifo = d.join("out.fifo");
    assert!(Command::new("mkfifo")
        .arg(&fifo)
        .status()
        .unwrap()
        .success());
    let to_null = d.join("null.json");
    std::os::unix::fs::symlink("/dev/null", &to_null).unwrap();
    let to_full = d.join("full.trace");
    std::os::unix::fs::symlink("/dev/full", &to_full).unwrap();
    let to_stdout = d.join("stdout.json");
    std::os::unix::fs::symlink("/proc/self/fd/1", &to_stdout).unwrap();
    let dangling = d.join("dangling.vmap");
    std::os::unix::fs::symlink(d.join("nowhere/x.vmap"), &dangling).unwrap();
    // A character device of our own (1, 7: what /dev/full is), so the real one is never at risk.
    let full = d.join("full");
    let made_device = Command::new("mknod")
        .arg(&full)
        .args(["c", "1", "7"])
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success());
    if !made_device {
        println!("SKIPPED: the character-device case (mknod needs root)");
    }
    let session = |flag: &str, path: &Path| -> Vec<std::ffi::OsString> {
        let mut args: Vec<std::ffi::OsString> = vec!["run".into(), "--scene".into()];
        args.push(scene.clone().into());
        args.extend(["--seconds".into(), "0.1".into(), flag.into()]);
        args.push(path.into());
        args
    };
    let mut cases: Vec<(Vec<std::ffi::OsString>, &str, &Path, &str)> = vec![
        (
            session("--report", &fifo),
            "--report",
            &fifo,
            "a named pipe (FIFO)",
        ),
        (
            session("--record", &to_null),
            "--record",
            &to_null,
            "a symbolic link to /dev/null",
        ),
        (
            session("--report", &to_full),
            "--report",
            &to_full,
            "a symbolic link to /dev/full",
        ),
        (
            session("--report", &to_stdout),
            "--report",
            &to_stdout,
            "not a regular file",
        ),
        (
            vec![
                "voxelize".into(),
                "builtin:box".into(),
                "--voxel-size".into(),
                "1cm".into(),
                "-o".into(),
                fifo.clone().into(),
            ],
            "-o",
            &fifo,
            "a named pipe (FIFO)",
        ),
        (
            vec![
                "shell".into(),
                "builtin:box".into(),
                "--voxel-size".into(),
                "1cm".into(),
                "-o".into(),
                dangling.clone().into(),
            ],
            "-o",
            &dangling,
            "does not exist",
        ),
        (
            vec![
                "run".into(),
                "--scene".into(),
                scene.clone().into(),
                "--device".into(),
                "bridge:127.0.0.1:0".into(),
                "--seconds".into(),
                "0.1".into(),
                "--log-wrenches".into(),
                fifo.clone().into(),
            ],
            "--log-wrenches",
            &fifo,
            "a named pipe (FIFO)",
        ),
    ];
    if made_device {
        cases.push((
            session("--report", &full),
            "--report",
            &full,
            "a character device",
        ));
    }
    for (args, flag, path, what) in &cases {
        let before = kind(path);
        let args: Vec<&std::ffi::OsStr> = args.iter().map(|a| a.as_os_str()).collect();
        let out = run_with_deadline(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "vps {args:?}: {err}");
        let named = format!("{flag} {}", path.display());
        assert!(
            err.contains(&named),
            "vps {args:?}: does not name {named}: {err}"
        );
        assert!(
            err.contains(what),
            "vps {args:?}: does not say {what}: {err}"
        );
        assert!(
            !err.contains("voxmap:"),
            "vps {args:?}: work was done first: {err}"
        );
        assert_eq!(
            kind(path),
            before,
            "vps {args:?} changed {}",
            path.display()
        );
    }
}

/// Issue 36 item 3: `--report s.toml` turned the scene into the report, `--record bracket.obj`
/// overwrote a mesh the scene names, and `--report X --record X` lost one file, each with status
/// 0. An output that is an input of the session (the scene file, one of its meshes, the haptic
/// file, the replayed trace; through a link or another spelling too) or another output is refused
/// before the voxmap is built, and the input is left as it was.
#[test]
fn an_output_equal_to_an_input_or_another_output_is_refused_before_any_work() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = small_scene(d);
    let floor = d.join("floor.obj");
    let haptic = d.join("haptic.toml");
    std::fs::write(&haptic, "k_ff = 1000.0\n").unwrap();
    let trace = d.join("hand.trace");
    let recorded = run(vps()
        .env("VPS_CACHE_DIR", d.join("cache"))
        .args(["record", "--seconds", "0.2", "--scene"])
        .arg(&scene)
        .arg("-o")
        .arg(&trace));
    assert!(recorded.status.success(), "{}", stderr(&recorded));
    let scene_link = d.join("link-to-scene.json");
    std::os::unix::fs::symlink(&scene, &scene_link).unwrap();
    let dotted_floor = d.join(".").join("floor.obj");
    let same = d.join("same.out");
    let replay = std::ffi::OsString::from(format!("replay:{}", trace.display()));
    let cases: Vec<(Vec<&std::ffi::OsStr>, &str)> = vec![
        (vec!["--report".as_ref(), scene.as_ref()], "is the input"),
        (
            vec!["--report".as_ref(), scene_link.as_ref()],
            "is the input",
        ),
        (vec!["--record".as_ref(), floor.as_ref()], "is the input"),
        (
            vec!["--record".as_ref(), dotted_floor.as_ref()],
            "is the input",
        ),
        (
            vec![
                "--haptic".as_ref(),
                haptic.as_ref(),
                "--report".as_ref(),
                haptic.as_ref(),
            ],
            "is the input",
        ),
        (
            vec![
                "--device".as_ref(),
                replay.as_os_str(),
                "--record".as_ref(),
                trace.as_ref(),
            ],
            "is the input",
        ),
        (
            vec![
                "--report".as_ref(),
                same.as_ref(),
                "--record".as_ref(),
                same.as_ref(),
            ],
            "name the same file",
        ),
        (
            vec![
                "--device".as_ref(),
                "bridge:127.0.0.1:0".as_ref(),
                "--report".as_ref(),
                same.as_ref(),
                "--log-wrenches".as_ref(),
                same.as_ref(),
            ],
            "name the same file",
        ),
    ];
    let inputs = [&scene, &floor, &haptic, &trace];
    let before: Vec<Vec<u8>> = inputs.iter().map(|p| std::fs::read(p).unwrap()).collect();
    for (extra, why) in cases {
        let mut args: Vec<&std::ffi::OsStr> =
            vec!["run".as_ref(), "--scene".as_ref(), scene.as_ref()];
        args.extend([
            std::ffi::OsStr::new("--seconds"),
            std::ffi::OsStr::new("0.2"),
        ]);
        args.extend(extra.iter().copied());
        let out = run_with_deadline(&args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "vps {args:?}: {err}");
        assert!(err.contains(why), "vps {args:?}: {err}");
        assert!(
            !err.contains("voxmap:"),
            "vps {args:?}: work was done first: {err}"
        );
        assert!(!same.exists(), "vps {args:?} wrote {}", same.display());
        for (path, bytes) in inputs.iter().zip(&before) {
            assert_eq!(
                &std::fs::read(path).unwrap(),
                bytes,
                "vps {args:?} changed {path:?}"
            );
        }
    }
}

/// Issue 36 item 8: a scene's `name` and `voxels.reason` were printed raw, so
/// `\u001b]0;…\u0007\u001b[2J\r\nFAKE: ok` retitled the terminal, cleared it and forged a line.
/// `vps scene check` prints them, and an error quotes a mesh source with the same bytes, with
/// every control character escaped: no ESC, BEL or CR reaches the terminal and no line begins
/// with the forged text.
#[test]
fn control_characters_from_a_scene_file_are_printed_escaped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = small_scene(d);
    let hostile = r"\u001b]0;owned\u0007\u001b[2J\r\nFAKE: ok";
    let text = std::fs::read_to_string(&scene)
        .unwrap()
        .replace("name = \"small\"", &format!("name = \"{hostile}\""))
        + &format!("reason = \"{hostile}\"\n");
    std::fs::write(&scene, text).unwrap();
    let missing = d.join("missing.toml");
    std::fs::write(
        &missing,
        format!("part = \"builtin:box\"\n\n[[static]]\nsource = \"{hostile}.obj\"\n\n{HAND}"),
    )
    .unwrap();
    let check = run(vps()
        .env("VPS_CACHE_DIR", d.join("cache"))
        .args(["scene", "check"])
        .arg(&scene));
    assert!(check.status.success(), "{}", stderr(&check));
    let error = run(vps()
        .env("VPS_CACHE_DIR", d.join("cache"))
        .args(["run", "--seconds", "0.1", "--scene"])
        .arg(&missing));
    assert_eq!(error.status.code(), Some(1), "{}", stderr(&error));
    for (what, bytes) in [
        ("scene check stdout", &check.stdout),
        ("scene check stderr", &check.stderr),
        ("the error", &error.stderr),
    ] {
        for raw in [0x1b, 0x07, b'\r'] {
            assert!(
                !bytes.contains(&raw),
                "{what} holds the raw byte {raw:#04x}: {:?}",
                String::from_utf8_lossy(bytes)
            );
        }
        let text = String::from_utf8_lossy(bytes);
        assert!(
            !text.lines().any(|l| l.starts_with("FAKE")),
            "{what} has a forged line: {text}"
        );
    }
    let shown = r"\u{1b}]0;owned\u{7}\u{1b}[2J\r\nFAKE: ok";
    let out = String::from_utf8_lossy(&check.stdout);
    assert!(
        out.contains(&format!("scene {shown} (")),
        "the name, escaped: {out}"
    );
    assert!(
        out.contains(&format!("why (scene file): {shown}")),
        "the reason, escaped: {out}"
    );
    assert!(stderr(&error).contains(shown), "{}", stderr(&error));
}

/// Issue 36 item 10: a scene file of arrays nested 100,000 deep echoed a 600 KB line in its
/// error, and a cache "directory" that is a file gave only "File exists (os error 17)". The error
/// is cut to a bounded length; the cache says what is wrong and the session still runs.
#[test]
fn a_deeply_nested_scene_and_a_cache_that_is_a_file_get_short_clear_messages() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let nested = d.join("nested.toml");
    let depth = 100_000;
    std::fs::write(
        &nested,
        format!("name = {}{}\n", "[ ".repeat(depth), "] ".repeat(depth)),
    )
    .unwrap();
    let out = run_with_deadline(&["scene".as_ref(), "check".as_ref(), nested.as_os_str()]);
    let err = stderr(&out);
    assert_eq!(
        out.status.code(),
        Some(1),
        "{}",
        &err[..err.len().min(2000)]
    );
    assert!(
        err.contains("nested.toml"),
        "{}",
        &err[..err.len().min(2000)]
    );
    assert!(err.len() < 16 * 1024, "{} bytes of error", err.len());

    let scene = small_scene(d);
    let not_a_dir = d.join("cache-file");
    std::fs::write(&not_a_dir, "").unwrap();
    let out = run(vps()
        .env("VPS_CACHE_DIR", &not_a_dir)
        .args(["run", "--seconds", "0.1", "--scene"])
        .arg(&scene));
    let err = stderr(&out);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("is not a directory") && err.contains("VPS_CACHE_DIR"),
        "{err}"
    );
    assert!(!err.contains("os error 17"), "{err}");
}

/// Issue 36 item 6: a scene file of millions of empty arrays (under the 64 MiB size bound) was
/// parsed whole (a 63 MiB one peaked at 8.7 GB) before being refused, and 10,000 statics naming
/// `builtin:aircraft-bay` set out to build about 140 GB of placed copies. The first is refused
/// before parsing, naming the count and the limit; the second before any copy is made, naming
/// the memory and the budget.
#[test]
fn scenes_that_would_take_unbounded_memory_are_refused_before_it_is_taken() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let arrays = d.join("arrays.toml");
    std::fs::write(
        &arrays,
        format!("name = [{}]\n", "[],".repeat(7 * 1024 * 1024)),
    )
    .unwrap();
    let out = run_with_deadline(&["scene".as_ref(), "check".as_ref(), arrays.as_os_str()]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("arrays.toml") && err.contains("arrays and tables") && err.contains("400000"),
        "{err}"
    );

    let many = d.join("many-bays.toml");
    let mut text = String::from("part = \"builtin:box\"\n");
    for i in 0..10_000 {
        text += &format!(
            "[[static]]\nsource = \"builtin:aircraft-bay\"\ntranslate = [{}, 0, 0]\n",
            i * 4
        );
    }
    text += "[hand]\nwaypoints = [[0.0, 0.0, 0.1]]\n";
    std::fs::write(&many, text).unwrap();
    let out = run_with_deadline(&["scene".as_ref(), "check".as_ref(), many.as_os_str()]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    for want in [
        "many-bays.toml",
        "`static`",
        "10000 placed copies of 1 mesh",
        "GiB",
    ] {
        assert!(err.contains(want), "{want:?} not in: {err}");
    }
}

/// Issue 36 item 10: `corridor.spacing = 1e-300` printed a 180-digit waypoint count; the count is
/// now in scientific notation and the message short, naming the file and the key.
#[test]
fn an_absurd_corridor_spacing_is_refused_with_a_short_count() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/scenes/rig-teapot.toml");
    let text = std::fs::read_to_string(rig).unwrap();
    // `force_model = "tangent-plane"` (the default) left out, so that a binary from before the
    // force models reads the same scene (tests/hostile_old_vs_new.py runs this test against one).
    let tiny = text
        .replace("spacing = 0.025", "spacing = 1e-300")
        .replace("force_model = \"tangent-plane\"\n", "");
    assert_ne!(tiny, text);
    let scene = dir.path().join("tiny.toml");
    std::fs::write(&scene, tiny).unwrap();
    let out = run(vps().args(["scene", "check"]).arg(&scene));
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("tiny.toml") && err.contains("corridor.spacing") && err.contains("3.00e299"),
        "{err}"
    );
    let longest_digits = err
        .split(|c: char| !c.is_ascii_digit())
        .map(str::len)
        .max()
        .unwrap_or(0);
    assert!(
        longest_digits < 20,
        "a {longest_digits}-digit number in: {err}"
    );
    assert!(err.len() < 600, "{} bytes: {err}", err.len());
}
