//! Issue 15 through the binary: a closed stdout ends `vps` quietly (status 141), a full one is an
//! error naming stdout, output paths are checked before any work and never overwrite the input,
//! memory is budgeted from the plan, and odd files get messages naming them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use vps_testkit::full_stdout::assert_full_stdout_is_an_error;

fn vps() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vps"))
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
