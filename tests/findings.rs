//! The audit's findings that had no test through the binary yet, each re-run as its command (the
//! table in docs/robustness.md maps every finding to its tests), and `vps bench viewer` stopped by
//! a signal. `tests/findings_old_vs_new.py` runs the same commands against an old and a new binary.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};
use vps_testkit::full_stdout::assert_full_stdout_is_an_error;
use vps_testkit::process::spawn_until_line;

/// Generous: the machine running the tests may be loaded.
const DEADLINE: Duration = Duration::from_secs(240);

fn vps() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_vps"));
    c.env(
        "VPS_CACHE_DIR",
        Path::new(env!("CARGO_TARGET_TMPDIR")).join("vps-cache"),
    );
    c
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A non-zero exit with an error naming every one of `wants`, and no panic.
fn refused(out: &Output, wants: &[&str]) {
    let err = stderr(out);
    assert!(
        matches!(out.status.code(), Some(c) if c != 0),
        "accepted: {err}"
    );
    for want in wants {
        assert!(err.contains(want), "{want:?} not in: {err}");
    }
    assert!(
        !err.contains("panicked") && !err.contains("memory allocation"),
        "{err}"
    );
}

/// A child killed when dropped.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

impl Running {
    fn signal(&self, name: &str) {
        let ok = Command::new("kill")
            .args([format!("-{name}"), self.0.id().to_string()])
            .status()
            .unwrap()
            .success();
        assert!(ok, "kill -{name}");
    }

    fn wait_exit(&mut self) -> std::process::ExitStatus {
        let until = Instant::now() + DEADLINE;
        loop {
            if let Some(status) = self.0.try_wait().unwrap() {
                return status;
            }
            assert!(Instant::now() < until, "the process did not exit");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

/// Starts `vps view ARGS` and returns it with the URL it printed (`http://ADDR/`).
fn start_view(args: &[&std::ffi::OsStr]) -> (Running, String) {
    let mut cmd = vps();
    cmd.arg("view")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null());
    let (child, rest) = spawn_until_line(cmd, "vps view", "viewer: ", DEADLINE);
    let url = rest.split_whitespace().next().unwrap_or("").to_string();
    (Running(child), url)
}

fn addr_of(url: &str) -> SocketAddr {
    url.trim_start_matches("http://")
        .trim_end_matches('/')
        .parse()
        .expect("a socket address in the URL")
}

/// The status code of one request with the given extra header lines.
fn status_of(addr: SocketAddr, path: &str, host: &str, extra: &str) -> u16 {
    let mut c = TcpStream::connect(addr).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let close = if extra.contains("Connection:") {
        ""
    } else {
        "Connection: close\r\n"
    };
    write!(
        c,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\n{close}{extra}\r\n"
    )
    .unwrap();
    let mut head = [0u8; 12];
    c.read_exact(&mut head).unwrap();
    std::str::from_utf8(&head[9..12]).unwrap().parse().unwrap()
}

/// A small voxmap made by the binary.
fn small_map(dir: &Path) -> PathBuf {
    let path = dir.join("sphere.vmap");
    let out = vps()
        .args(["voxelize", "builtin:sphere", "--voxel-size", "1cm", "-o"])
        .arg(&path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    path
}

/// Finding 2: `vps view` of a valid 16 KiB map of 2^39 voxels asked for 549 GB and aborted; it now
/// builds its boxes from the tree and serves the scene.
#[test]
fn view_serves_a_crafted_map_of_2_pow_39_voxels() {
    let dir = tempfile::tempdir().unwrap();
    let map = dir.path().join("huge.vmap");
    std::fs::write(&map, vps_fuzz::seeds::uniform_vmap([8192; 3], 0.001, 1)).unwrap();
    let (mut view, url) = start_view(&[map.as_os_str(), "--addr".as_ref(), "127.0.0.1:0".as_ref()]);
    let addr = addr_of(&url);
    assert_eq!(status_of(addr, "/scene", &addr.to_string(), ""), 200);
    assert_eq!(status_of(addr, "/scene/boxes", &addr.to_string(), ""), 200);
    assert!(view.0.try_wait().unwrap().is_none(), "the viewer exited");
    view.signal("TERM");
    view.wait_exit();
}

/// Finding 4: a scene's corridor sized an allocation: `spacing = 1e-300` panicked with "capacity
/// overflow" in `tune`, `1e-12` aborted allocating 7.2 TB, `to = [1e6, 0, 0]` grew to 7.1 GB. Each
/// is now refused before anything is built, naming the file and `corridor.spacing`.
#[test]
fn a_corridor_sizing_an_absurd_allocation_is_refused_by_tune_and_sweep() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/scenes/rig-teapot.toml");
    let text = std::fs::read_to_string(rig).unwrap();
    let without_workspace = text.split("[workspace]").next().unwrap().to_string();
    let cases = [
        (
            "tiny.toml",
            text.replace("spacing = 0.025", "spacing = 1e-300"),
        ),
        (
            "small.toml",
            text.replace("spacing = 0.025", "spacing = 1e-12"),
        ),
        (
            "far.toml",
            without_workspace.replace("to = [0.35, 0.0, 0.0]", "to = [1e6, 0.0, 0.0]"),
        ),
    ];
    for (name, body) in cases {
        assert_ne!(body, text, "{name}: the replacement matched nothing");
        let scene = dir.path().join(name);
        std::fs::write(&scene, body).unwrap();
        let started = Instant::now();
        let out = vps()
            .args([
                "tune",
                "--frames",
                "100",
                "--verify-frames",
                "100",
                "--scene",
            ])
            .arg(&scene)
            .output()
            .unwrap();
        refused(&out, &[name, "corridor.spacing", "at most 100000"]);
        let out = vps()
            .args(["sweep", "--quick", "--scene"])
            .arg(&scene)
            .output()
            .unwrap();
        refused(&out, &[name, "corridor.spacing"]);
        // Refused from the file alone: far under the time a build of anything would take.
        assert!(started.elapsed() < Duration::from_secs(60), "{name}");
    }
}

/// Finding 5: `vps devices | head -0` panicked on the broken pipe; it now ends quietly with 141.
#[test]
fn devices_into_a_closed_pipe_ends_quietly_with_141() {
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let out = vps()
        .args(["devices"])
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    let err = stderr(&out);
    // With no device attached `devices` prints a line to stdout too, so EPIPE is met either way.
    assert_eq!(out.status.code(), Some(141), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// Finding 5: `vps run --seconds 1 --json > /dev/full` panicked after the session and lost the
/// report; it is now an error naming stdout, status 1.
#[test]
fn a_session_report_to_a_full_stdout_is_an_error_naming_stdout() {
    assert_full_stdout_is_an_error(vps().args(["run", "--seconds", "0.2", "--json"]));
}

/// Finding 5: `--record` into a missing directory was found out only after the session; it is now
/// refused before the session starts.
#[test]
fn a_bad_record_path_is_refused_before_the_session() {
    let out = vps()
        .args([
            "run",
            "--seconds",
            "600",
            "--record",
            "/nonexistent/dir/t.trace",
        ])
        .output()
        .unwrap();
    // A 600 s session would outlast the test's patience: refusing it at all shows the order.
    refused(&out, &["/nonexistent/dir"]);
    assert!(!stderr(&out).contains("frames"), "{}", stderr(&out));
}

/// Finding 6: a sweep with `voxel_sizes_mm = []` exited 0 having measured nothing, and a run with
/// `seconds = -1` ran one frame and exited 0. Both must be refused naming the sweep file and field.
#[test]
fn a_sweep_with_no_sizes_or_negative_seconds_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/scenes/rig-teapot.toml");
    for (name, body, field) in [
        (
            "nosizes.toml",
            format!("voxel_sizes_mm = []\nmethods = [\"centres\"]\n[[run]]\nscene = {rig:?}\n"),
            "voxel_sizes_mm",
        ),
        (
            "negative.toml",
            format!(
                "voxel_sizes_mm = [10.0]\nmethods = [\"centres\"]\n[[run]]\nscene = {rig:?}\n\
                 seconds = -1\n"
            ),
            "run[0].seconds",
        ),
    ] {
        let config = dir.path().join(name);
        std::fs::write(&config, body).unwrap();
        let out = vps()
            .args(["sweep", "--quick", "--config"])
            .arg(&config)
            .arg("--json")
            .arg(dir.path().join("out.json"))
            .output()
            .unwrap();
        refused(&out, &[name, field]);
    }
}

/// Finding 7: `vps view --addr 0.0.0.0:P` printed `http://127.0.0.1:P/`; it prints the address
/// really bound.
#[test]
fn view_prints_the_address_it_really_bound() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map(dir.path());
    let (mut view, url) = start_view(&[map.as_os_str(), "--addr".as_ref(), "0.0.0.0:0".as_ref()]);
    assert!(url.starts_with("http://0.0.0.0:"), "{url}");
    assert_ne!(addr_of(&url).port(), 0, "{url}");
    view.signal("TERM");
    view.wait_exit();
}

/// Finding 7: a page on any site could open the viewer's WebSocket and read the live state; a
/// foreign Origin or Host is now refused (403) while the viewer's own page is let in.
#[test]
fn view_refuses_a_foreign_origin_and_host() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map(dir.path());
    let (mut view, url) = start_view(&[map.as_os_str(), "--addr".as_ref(), "127.0.0.1:0".as_ref()]);
    let addr = addr_of(&url);
    let here = addr.to_string();
    let upgrade = "Upgrade: websocket\r\nConnection: Upgrade\r\nSec-WebSocket-Version: 13\r\n\
                   Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n";
    let foreign = format!("Origin: http://evil.example\r\n{upgrade}");
    assert_eq!(status_of(addr, "/ws", &here, &foreign), 403);
    let foreign_host = format!("evil.example:{}", addr.port());
    assert_eq!(status_of(addr, "/state", &foreign_host, ""), 403);
    let own = format!("Origin: http://{here}\r\n{upgrade}");
    assert_eq!(status_of(addr, "/ws", &here, &own), 101);
    view.signal("TERM");
    view.wait_exit();
}

/// `vps bench viewer` stopped by SIGINT or SIGTERM mid-session: it exits with 128 + N (no hang),
/// prints no figures, and says the session ended early.
fn bench_viewer_stops_on(signal: &str, code: i32) {
    let mut child = vps()
        .args(["bench", "viewer", "--seconds", "600", "--rounds", "1"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start vps bench viewer");
    let mut out = child.stdout.take().unwrap();
    let err = child.stderr.take().unwrap();
    let (tx, rx) = mpsc::channel();
    let lines = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(err).lines().map_while(Result::ok) {
            if line.starts_with("voxmap:") {
                let _ = tx.send(());
            }
            all += &line;
            all.push('\n');
        }
        all
    });
    let mut bench = Running(child);
    // The scene is built (or read from the cache) before the first session starts.
    rx.recv_timeout(DEADLINE)
        .expect("the voxmap line on stderr");
    std::thread::sleep(Duration::from_millis(500));
    bench.signal(signal);
    let status = bench.wait_exit();
    let mut printed = String::new();
    out.read_to_string(&mut printed).unwrap();
    let err = lines.join().unwrap();
    assert_eq!(status.code(), Some(code), "{err}");
    assert!(printed.is_empty(), "figures printed: {printed}");
    assert!(err.contains(&format!("stopped by SIG{signal}")), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
fn bench_viewer_stops_on_sigint_with_130() {
    bench_viewer_stops_on("INT", 130);
}

#[test]
fn bench_viewer_stops_on_sigterm_with_143() {
    bench_viewer_stops_on("TERM", 143);
}
