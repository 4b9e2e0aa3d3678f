//! The mistakes a lab admin makes when deploying the cluster services, with real `vps` processes,
//! real certificate files and real sockets: a key that is not the certificate's, a port already
//! held, relative paths in a config file run from another directory. Each is reported at once,
//! naming the file or the address, before any voxmap is built, and the process exits 1 instead
//! of retrying. Without `RUST_LOG`, a worker and its coordinator still log the join.
//!
//! Nothing here depends on timing: every wait is bounded by a generous deadline only.

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::Duration;
use vps_cluster::{make_cert, CertFiles};
use vps_testkit::process::WatchedProcess;

const DEADLINE: Duration = Duration::from_secs(240);

/// Runs `vps ARGS` in `cwd` to its end (its voxmap cache in `cache`), with no `RUST_LOG`.
fn run(cwd: &Path, cache: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vps"))
        .args(args)
        .current_dir(cwd)
        .env("VPS_CACHE_DIR", cache)
        .env_remove("RUST_LOG")
        .stdin(Stdio::null())
        .output()
        .expect("run vps")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A temporary directory with a coordinator's and a worker's certificates (`vps cert`'s files).
struct Certs {
    dir: tempfile::TempDir,
    coordinator: CertFiles,
    worker: CertFiles,
}

impl Certs {
    fn new() -> Certs {
        let dir = tempfile::tempdir().unwrap();
        let coordinator = make_cert(dir.path(), "coordinator").unwrap();
        let worker = make_cert(dir.path(), "worker").unwrap();
        Certs {
            dir,
            coordinator,
            worker,
        }
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    /// A 1 s coordinator session's command line on `listen` with the coordinator's certificate,
    /// the key `key` and the worker's certificate pinned.
    fn coordinator_args(&self, key: &Path, listen: &str) -> Vec<String> {
        let cert = &self.coordinator.cert;
        let pin = &self.worker.cert;
        let args = ["coordinator", "--listen", listen, "--cert", &text(cert)];
        let rest = ["--key", &text(key), "--pin", &text(pin), "--seconds", "1"];
        args.iter().chain(&rest).map(|a| a.to_string()).collect()
    }

    /// Runs [`Certs::coordinator_args`] to its end in the directory (cache `DIR/cache`).
    fn run_coordinator(&self, key: &Path, listen: &str) -> Output {
        self.run_coordinator_with(key, listen, &[])
    }

    /// [`Certs::run_coordinator`] with `more` arguments after the others.
    fn run_coordinator_with(&self, key: &Path, listen: &str, more: &[&str]) -> Output {
        let args = self.coordinator_args(key, listen);
        let args: Vec<&str> = args
            .iter()
            .map(String::as_str)
            .chain(more.iter().copied())
            .collect();
        run(self.path(), &self.path().join("cache"), &args)
    }
}

fn text(path: &Path) -> String {
    path.to_string_lossy().into_owned()
}

#[test]
fn a_key_of_another_certificate_is_refused_at_once_by_both_services() {
    let certs = Certs::new();
    let (d, c, w) = (certs.path(), &certs.coordinator, &certs.worker);
    let s = text;

    let out = certs.run_coordinator(&w.key, "127.0.0.1:0");
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let expected = format!(
        "{}: not the private key of the certificate {}",
        w.key.display(),
        c.cert.display()
    );
    assert!(err.contains(&expected), "{err}");
    assert!(!err.contains("voxmap"), "checked before the voxmap: {err}");

    // A worker used to retry this for ever ("keys may not be consistent: KeyMismatch; retrying").
    let out = run(
        d,
        &d.join("cache"),
        &[
            "worker",
            "--coordinator",
            "127.0.0.1:9",
            "--cert",
            &s(&w.cert),
            "--key",
            &s(&c.key),
            "--pin",
            &s(&c.cert),
        ],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("not the private key of the certificate"),
        "{err}"
    );
    assert!(!err.contains("cannot join"), "{err}");
}

#[test]
fn a_port_already_held_is_reported_before_the_voxmap_is_built() {
    let certs = Certs::new();
    let d = certs.path();
    let held = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let listen = held.local_addr().unwrap().to_string();
    let out = certs.run_coordinator(&certs.coordinator.key, &listen);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(&format!("cannot listen on UDP {listen}"))
            && err.contains("another process holds that port"),
        "{err}"
    );
    assert!(!err.contains("voxmap"), "checked before the voxmap: {err}");
    assert!(!d.join("cache").exists(), "nothing was built: {err}");
}

#[test]
fn relative_paths_in_a_config_file_are_its_directorys_whatever_the_working_directory() {
    let dir = tempfile::tempdir().unwrap();
    let etc = dir.path().join("etc");
    make_cert(&etc, "worker").unwrap();
    make_cert(&etc, "other").unwrap();
    make_cert(&etc.join("pins"), "coordinator").unwrap();
    let config = etc.join("worker.toml");
    // The key is another certificate's, so the worker stops at once, naming the path it used.
    std::fs::write(
        &config,
        "coordinator = \"127.0.0.1:9\"\ncert = \"worker.crt\"\nkey = \"other.key\"\npins = [\"pins/coordinator.crt\"]\n",
    )
    .unwrap();
    // Run from `/`, as systemd does.
    let out = run(
        Path::new("/"),
        &dir.path().join("cache"),
        &["worker", "--config", &config.to_string_lossy()],
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let expected = format!(
        "{}: not the private key of the certificate {}",
        etc.join("other.key").display(),
        etc.join("worker.crt").display()
    );
    assert!(err.contains(&expected), "{err}");
}

/// Starts `vps ARGS` with its voxmap cache in `cache` and no `RUST_LOG` (as under systemd).
fn start(label: &str, cache: &Path, args: &[String]) -> WatchedProcess {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vps"));
    cmd.args(args)
        .env("VPS_CACHE_DIR", cache)
        .env_remove("RUST_LOG");
    WatchedProcess::spawn(cmd, label, DEADLINE)
}

#[test]
fn without_rust_log_the_join_is_logged_on_both_sides() {
    let certs = Certs::new();
    let (d, c, w) = (certs.path(), &certs.coordinator, &certs.worker);
    let s = text;
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let listen = format!("127.0.0.1:{port}");
    let mut coordinator = start(
        "coordinator",
        &d.join("cache"),
        &certs.coordinator_args(&c.key, &listen),
    );
    // A worker that exits with its coordinator gives up if it is not there yet.
    coordinator.wait_for("waiting for 1 worker", 1);
    let worker_args: Vec<String> = [
        "worker",
        "--coordinator",
        &listen,
        "--cert",
        &s(&w.cert),
        "--key",
        &s(&w.key),
        "--pin",
        &s(&c.cert),
        "--threads",
        "1",
        "--exit-with-coordinator",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    let mut worker = start("worker", &d.join("worker-cache"), &worker_args);
    assert_eq!(coordinator.wait_exit().code(), Some(0));
    assert_eq!(worker.wait_exit().code(), Some(0));
    assert_eq!(worker.count(&format!("joined {listen}")), 1);
    // The coordinator's session ending is routine: said at info, not as a warning.
    let went_away: Vec<String> = worker.lines_containing("went away (");
    assert_eq!(went_away.len(), 1, "{went_away:?}");
    assert!(
        went_away[0].contains(" INFO ") && went_away[0].contains("coordinator done"),
        "{went_away:?}"
    );
    let joined = coordinator
        .lines_containing("joined (scene sent: true)")
        .iter()
        .filter(|l| l.contains("worker 0 at 127.0.0.1:"))
        .count();
    assert_eq!(joined, 1);
}

#[test]
fn a_coordinator_whose_workers_do_not_come_says_what_to_check() {
    let certs = Certs::new();
    // `--join-wait` shortens the default 20 s wait (the message names the wait it had).
    let key = &certs.coordinator.key;
    let out = certs.run_coordinator_with(key, "127.0.0.1:0", &["--join-wait", "1.5"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "only 0 of 1 worker(s) joined within 1.5 s (0 refused for an unpinned certificate"
        ),
        "{err}"
    );
    assert!(
        err.contains("start the workers (each dials 127.0.0.1:"),
        "{err}"
    );
    assert!(err.contains("(or wait longer: `join_wait`)"), "{err}");
    assert!(!err.contains("network:"), "{err}");

    // Out of range: refused naming the flag and the range, before anything is built.
    let out = certs.run_coordinator_with(key, "127.0.0.1:0", &["--join-wait", "0"]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("--join-wait"), "{err}");
    assert!(err.contains("allowed 0.1..=3600 s"), "{err}");
    // The same key in a config file: refused naming the file, the key and the range.
    let config = certs.path().join("waits-too-long.toml");
    std::fs::write(&config, "join_wait = 5000\n").unwrap();
    let out = certs.run_coordinator_with(key, "127.0.0.1:0", &["--config", &text(&config)]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    let expected = format!("{}: `join_wait`: allowed 0.1..=3600 s", config.display());
    assert!(err.contains(&expected), "{err}");
}

/// A worker whose coordinator is not there (nothing listens on the port it dials).
fn start_lonely_worker(certs: &Certs) -> (WatchedProcess, String) {
    let (c, w) = (&certs.coordinator, &certs.worker);
    // Bound, then released: nothing listens there while the worker runs.
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let dial = format!("127.0.0.1:{port}");
    let args: Vec<String> = [
        "worker",
        "--coordinator",
        &dial,
        "--cert",
        &text(&w.cert),
        "--key",
        &text(&w.key),
        "--pin",
        &text(&c.cert),
        "--threads",
        "1",
    ]
    .iter()
    .map(|a| a.to_string())
    .collect();
    let worker = start("worker", &certs.path().join("cache"), &args);
    (worker, dial)
}

#[test]
fn a_worker_whose_coordinator_is_not_up_says_what_to_check() {
    let certs = Certs::new();
    let (mut worker, dial) = start_lonely_worker(&certs);
    worker.wait_for(&format!("cannot join {dial}"), 1);
    let line = worker
        .lines_containing(&format!("cannot join {dial}"))
        .remove(0);
    assert!(
        line.contains(&format!("connect to {dial}: timed out")),
        "{line}"
    );
    let port = dial.rsplit(':').next().unwrap();
    for hint in [
        format!("no coordinator answered at {dial}"),
        "is `vps coordinator` running".to_string(),
        format!("is UDP port {port} open"),
        "is `coordinator` in this worker's config (worker.toml, or --coordinator)".to_string(),
    ] {
        assert!(line.contains(&hint), "{hint:?} not in {line}");
    }
    assert!(worker.is_running(), "a service worker keeps waiting");
}

/// The worker used to finish its QUIC handshake attempt (up to the 3 s idle timeout) before
/// looking at SIGTERM (about 2.7 s); it now watches its stop flag every 20 ms while connecting.
/// The bound asserted is a generous 2 s, for a loaded test machine; typically it exits within
/// tens of milliseconds.
#[test]
fn sigterm_ends_a_worker_at_once_while_it_connects() {
    let certs = Certs::new();
    let (mut worker, dial) = start_lonely_worker(&certs);
    // After the first failed attempt (3 s), it waits at most 100 ms and dials again: a SIGTERM
    // 0.5 s later arrives in the middle of that second 3 s attempt.
    worker.wait_for(&format!("cannot join {dial}"), 1);
    std::thread::sleep(Duration::from_millis(500));
    let asked = std::time::Instant::now();
    worker.signal("TERM");
    let status = worker.wait_exit();
    let took = asked.elapsed();
    assert_eq!(status.code(), Some(0));
    assert_eq!(
        worker.count("worker stopped (SIGTERM) after 0 session(s)"),
        1
    );
    assert!(
        took < Duration::from_secs(2),
        "exited {took:?} after SIGTERM"
    );
    eprintln!("exited {took:?} after SIGTERM");
}
