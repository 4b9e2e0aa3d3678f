//! Workers are long-lived services, with real processes on loopback: a `vps worker` outlives its
//! coordinator's SIGTERM (the coordinator tells it so with its close code) and joins a second
//! coordinator started afterwards on the same port; SIGTERM then ends the worker with status 0.
//! A worker whose certificate the coordinator does not pin is told why and exits with status 2
//! instead of retrying.
//!
//! Nothing here depends on timing: every wait is bounded by a generous deadline only.

use std::path::Path;
use std::process::Command;
use std::time::Duration;
use vps_cluster::make_cert;
use vps_testkit::process::{free_udp_port, WatchedProcess};

const DEADLINE: Duration = Duration::from_secs(240);

/// Starts `vps ARGS` with its voxmap cache in `dir` and `RUST_LOG=vps_cluster=info`.
fn start(label: &str, dir: &Path, args: &[&str]) -> WatchedProcess {
    let mut cmd = Command::new(vps_testkit::process::vps_binary(env!("CARGO_BIN_EXE_vps")));
    cmd.args(args)
        .env("VPS_CACHE_DIR", dir.join("cache"))
        .env("RUST_LOG", "vps_cluster=info");
    WatchedProcess::spawn(cmd, label, DEADLINE)
}

fn coordinator(dir: &Path, port: u16, seconds: &str, report: &str) -> WatchedProcess {
    let p = |name: &str| dir.join(name).to_string_lossy().into_owned();
    start(
        "coordinator",
        dir,
        &[
            "coordinator",
            "--listen",
            &format!("127.0.0.1:{port}"),
            "--cert",
            &p("coordinator.crt"),
            "--key",
            &p("coordinator.key"),
            "--pin",
            &p("worker.crt"),
            "--workers",
            "1",
            "--seconds",
            seconds,
            "--report",
            &p(report),
        ],
    )
}

fn worker(dir: &Path, port: u16, name: &str) -> WatchedProcess {
    let p = |file: String| dir.join(file).to_string_lossy().into_owned();
    start(
        "worker",
        dir,
        &[
            "worker",
            "--coordinator",
            &format!("127.0.0.1:{port}"),
            "--cert",
            &p(format!("{name}.crt")),
            "--key",
            &p(format!("{name}.key")),
            "--pin",
            &p("coordinator.crt".into()),
            "--threads",
            "1",
        ],
    )
}

fn report(dir: &Path, name: &str) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join(name)).unwrap()).unwrap()
}

#[test]
fn a_worker_outlives_its_coordinators_sigterm_and_joins_the_next_one() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["coordinator", "worker", "stranger"] {
        make_cert(dir.path(), name).unwrap();
    }
    let port = free_udp_port();
    let mut first = coordinator(dir.path(), port, "600", "first.json");
    first.wait_for("waiting for 1 worker", 1);

    // Not pinned by the coordinator: told why, and no retrying.
    let mut stranger = worker(dir.path(), port, "stranger");
    let status = stranger.wait_exit();
    assert_eq!(status.code(), Some(2), "a refused worker exits 2");
    assert_eq!(stranger.count("refused this worker's certificate"), 1);
    // The coordinator names the refused certificate as `vps cert` made it, with the fingerprint
    // `vps cert` printed (openssl's SHA-256 of the certificate).
    let stranger_cert = vps_cluster::tls::load_cert(&dir.path().join("stranger.crt")).unwrap();
    first.wait_for(
        &format!(
            "refused a worker with an unpinned certificate: `stranger` (sha256 {})",
            vps_cluster::tls::fingerprint(&stranger_cert)
        ),
        1,
    );

    let mut w = worker(dir.path(), port, "worker");
    w.wait_for("joined", 1);
    first.signal("TERM");
    assert_eq!(first.wait_exit().code(), Some(143));
    let r = report(dir.path(), "first.json");
    assert_eq!(r["end"], "stopped by SIGTERM", "{r}");
    assert_eq!(r["complete"], false, "{r}");

    // The worker heard why and waits for the next coordinator.
    w.wait_for("coordinator stopping (SIGTERM)", 1);
    assert!(w.is_running(), "the worker exited");

    let mut second = coordinator(dir.path(), port, "1", "second.json");
    w.wait_for("joined", 2);
    assert_eq!(second.wait_exit().code(), Some(0));
    let r = report(dir.path(), "second.json");
    assert_eq!(r["end"], "frames done", "{r}");
    assert_eq!(r["complete"], true, "{r}");

    // Told to stop: closes cleanly and exits 0.
    w.signal("TERM");
    assert_eq!(w.wait_exit().code(), Some(0));
    assert_eq!(w.count("worker stopped (SIGTERM)"), 1);
    // Its log went to a pipe (as to a file or the systemd journal): no terminal colour codes.
    assert!(w.count("joined") >= 2);
    assert_eq!(w.count("\u{1b}["), 0, "colour codes in a piped log");
    assert_eq!(first.count("\u{1b}["), 0, "colour codes in a piped log");
}

/// Issue 36 item 5: a worker restarted within about 3 s of a crash was refused for good ("another
/// worker with this certificate is connected") while the coordinator still held the dead
/// connection; with the shipped unit (`RestartPreventExitStatus=1 2`) it never came back. Here a
/// worker is killed (SIGKILL) mid-session and a new one with the same certificate is started at
/// once: it joins, replacing the dead connection, and stays.
#[test]
fn a_worker_restarted_at_once_after_a_crash_replaces_its_dead_connection() {
    let dir = tempfile::tempdir().unwrap();
    for name in ["coordinator", "worker"] {
        make_cert(dir.path(), name).unwrap();
    }
    let port = free_udp_port();
    let mut coord = coordinator(dir.path(), port, "600", "report.json");
    coord.wait_for("waiting for 1 worker", 1);
    let mut crashed = worker(dir.path(), port, "worker");
    crashed.wait_for("joined", 1);
    crashed.signal("KILL");
    crashed.wait_exit();
    let mut restarted = worker(dir.path(), port, "worker");
    restarted.wait_for("joined", 1);
    coord.wait_for("closed that one (a worker restarted after a crash", 1);
    assert!(restarted.is_running(), "the restarted worker exited");
    assert_eq!(restarted.count("refused"), 0);
    coord.signal("TERM");
    assert_eq!(coord.wait_exit().code(), Some(143));
    restarted.wait_for("coordinator stopping (SIGTERM)", 1);
    restarted.signal("TERM");
    assert_eq!(restarted.wait_exit().code(), Some(0));
}
