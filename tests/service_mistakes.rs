//! The mistakes a lab admin makes when deploying the cluster services, with real `vps` processes,
//! real certificate files and real sockets: a key that is not the certificate's, a port already
//! held, relative paths in a config file run from another directory. Each is reported at once,
//! naming the file or the address, before any voxmap is built, and the process exits 1 instead
//! of retrying. Without `RUST_LOG`, a worker and its coordinator still log the join.
//!
//! Nothing here depends on timing: every wait is bounded by a generous deadline only.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vps_cluster::make_cert;

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

/// A coordinator's command line with its certificate `cert`, key `key`, on `listen`.
fn coordinator_args<'a>(
    cert: &'a str,
    key: &'a str,
    pin: &'a str,
    listen: &'a str,
) -> Vec<&'a str> {
    vec![
        "coordinator",
        "--listen",
        listen,
        "--cert",
        cert,
        "--key",
        key,
        "--pin",
        pin,
        "--seconds",
        "1",
    ]
}

#[test]
fn a_key_of_another_certificate_is_refused_at_once_by_both_services() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = make_cert(d, "coordinator").unwrap();
    let w = make_cert(d, "worker").unwrap();
    let s = |p: &Path| p.to_string_lossy().into_owned();

    let out = run(
        d,
        &d.join("cache"),
        &coordinator_args(&s(&c.cert), &s(&w.key), &s(&w.cert), "127.0.0.1:0"),
    );
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
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = make_cert(d, "coordinator").unwrap();
    let w = make_cert(d, "worker").unwrap();
    let held = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let listen = held.local_addr().unwrap().to_string();
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let out = run(
        d,
        &d.join("cache"),
        &coordinator_args(&s(&c.cert), &s(&c.key), &s(&w.cert), &listen),
    );
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

/// A child `vps` process (no `RUST_LOG`) whose stderr lines are collected; killed on drop.
struct Proc {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
}

impl Proc {
    fn start(label: &'static str, cache: &Path, args: &[String]) -> Proc {
        let mut child = Command::new(env!("CARGO_BIN_EXE_vps"))
            .args(args)
            .env("VPS_CACHE_DIR", cache)
            .env_remove("RUST_LOG")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start vps");
        let stderr = child.stderr.take().unwrap();
        let lines = Arc::new(Mutex::new(Vec::new()));
        let sink = lines.clone();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                eprintln!("[{label}] {line}");
                sink.lock().unwrap().push(line);
            }
        });
        Proc { child, lines }
    }

    fn count(&self, text: &str) -> usize {
        self.lines
            .lock()
            .unwrap()
            .iter()
            .filter(|l| l.contains(text))
            .count()
    }

    /// Waits until a stderr line contains `text`.
    fn wait_for(&self, text: &str) {
        let until = Instant::now() + DEADLINE;
        while self.count(text) == 0 {
            assert!(Instant::now() < until, "no {text:?} on stderr");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn wait_exit(&mut self) -> Option<i32> {
        let until = Instant::now() + DEADLINE;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status.code();
            }
            assert!(Instant::now() < until, "the process did not exit");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn without_rust_log_the_join_is_logged_on_both_sides() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = make_cert(d, "coordinator").unwrap();
    let w = make_cert(d, "worker").unwrap();
    let port = std::net::UdpSocket::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let listen = format!("127.0.0.1:{port}");
    let mut coordinator = Proc::start(
        "coordinator",
        &d.join("cache"),
        &coordinator_args(&s(&c.cert), &s(&c.key), &s(&w.cert), &listen)
            .iter()
            .map(|a| a.to_string())
            .collect::<Vec<_>>(),
    );
    // A worker that exits with its coordinator gives up if it is not there yet.
    coordinator.wait_for("waiting for 1 worker");
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
    let mut worker = Proc::start("worker", &d.join("worker-cache"), &worker_args);
    assert_eq!(coordinator.wait_exit(), Some(0));
    assert_eq!(worker.wait_exit(), Some(0));
    assert_eq!(worker.count(&format!("joined {listen}")), 1);
    // The coordinator's session ending is routine: said at info, not as a warning.
    let went_away: Vec<String> = worker
        .lines
        .lock()
        .unwrap()
        .iter()
        .filter(|l| l.contains("went away ("))
        .cloned()
        .collect();
    assert_eq!(went_away.len(), 1, "{went_away:?}");
    assert!(
        went_away[0].contains(" INFO ") && went_away[0].contains("coordinator done"),
        "{went_away:?}"
    );
    let joined = coordinator
        .lines
        .lock()
        .unwrap()
        .iter()
        .filter(|l| l.contains("worker 0 at 127.0.0.1:") && l.contains("joined (scene sent: true)"))
        .count();
    assert_eq!(joined, 1);
}

#[test]
fn a_coordinator_whose_workers_do_not_come_says_what_to_check() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let c = make_cert(d, "coordinator").unwrap();
    let w = make_cert(d, "worker").unwrap();
    let s = |p: &Path| p.to_string_lossy().into_owned();
    let out = run(
        d,
        &d.join("cache"),
        &coordinator_args(&s(&c.cert), &s(&c.key), &s(&w.cert), "127.0.0.1:0"),
    );
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "only 0 of 1 worker(s) joined within 20 s (0 refused for an unpinned certificate"
        ),
        "{err}"
    );
    assert!(
        err.contains("start the workers (each dials 127.0.0.1:"),
        "{err}"
    );
    assert!(!err.contains("network:"), "{err}");
}
