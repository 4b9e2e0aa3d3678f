//! Running the `vps` binary from the root package's tests.
//!
//! The binary's path is only known to the root package's tests (`env!("CARGO_BIN_EXE_vps")`), so
//! it is passed in: `let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));`. Every command made here has
//! `VPS_CACHE_DIR` set to a directory inside the test's own temporary directory, so a test never
//! writes into the user's cache (`~/.cache/vps`).
//!
//! The same test source can run against another build of `vps` (an older commit's, to show that a
//! test fails there): set `VPS_TEST_BINARY=/path/to/vps` and every binary path that goes through
//! [`vps_binary`] (so every [`Vps`]) is that file instead of `env!("CARGO_BIN_EXE_vps")`; the
//! substitution is printed on the test's stderr. `tests/hostile_old_vs_new.sh` uses it.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::sync::{mpsc, Arc, Mutex};
use std::time::{Duration, Instant};
use tempfile::TempDir;

/// The environment variable naming a `vps` binary to test instead of the one cargo built.
pub const TEST_BINARY_ENV: &str = "VPS_TEST_BINARY";

/// The `vps` binary a test runs: `bin` (`env!("CARGO_BIN_EXE_vps")`), or the path in
/// [`TEST_BINARY_ENV`] when that is set and not empty (printed on stderr, which the test harness
/// shows with a failing test's output or with `--nocapture`).
///
/// # Panics
/// When `VPS_TEST_BINARY` names no file, so that a mistyped path fails every test at once instead
/// of testing nothing.
pub fn vps_binary(bin: &str) -> PathBuf {
    match std::env::var_os(TEST_BINARY_ENV) {
        Some(other) if !other.is_empty() => {
            let other = PathBuf::from(other);
            assert!(
                other.is_file(),
                "{TEST_BINARY_ENV}={} is not a file",
                other.display()
            );
            eprintln!(
                "{TEST_BINARY_ENV}: testing {} instead of {bin}",
                other.display()
            );
            other
        }
        _ => PathBuf::from(bin),
    }
}

/// The `vps` binary with a temporary working directory and a private voxmap cache inside it
/// (both removed on drop).
pub struct Vps {
    bin: PathBuf,
    dir: TempDir,
    cache: PathBuf,
}

impl Vps {
    /// `bin` is `env!("CARGO_BIN_EXE_vps")` (replaced by `VPS_TEST_BINARY` when set:
    /// [`vps_binary`]).
    pub fn new(bin: &str) -> Vps {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let cache = dir.path().join("cache");
        Vps {
            bin: vps_binary(bin),
            dir,
            cache,
        }
    }

    /// The temporary directory (removed on drop).
    pub fn dir(&self) -> &Path {
        self.dir.path()
    }

    /// `name` inside [`Vps::dir`], as a string for a command line.
    pub fn path(&self, name: &str) -> String {
        self.dir.path().join(name).display().to_string()
    }

    /// The private cache directory every command gets as `VPS_CACHE_DIR`.
    pub fn cache(&self) -> &Path {
        &self.cache
    }

    /// `vps` with `VPS_CACHE_DIR` set and no arguments yet.
    pub fn cmd(&self) -> Command {
        let mut cmd = Command::new(&self.bin);
        cmd.env("VPS_CACHE_DIR", &self.cache);
        cmd
    }

    /// Runs `vps ARGS` to completion, capturing stdout and stderr.
    pub fn run(&self, args: &[&str]) -> Output {
        self.cmd().args(args).output().expect("vps runs")
    }

    /// Runs `vps COMMAND --scene SCENE --seconds SECONDS MORE...` to completion: a session of a
    /// set length (`run`, `record`, `cluster`, ...) on the scene file `SCENE`.
    pub fn session(&self, command: &str, scene: &str, seconds: &str, more: &[&str]) -> Output {
        let mut args = vec![command, "--scene", scene, "--seconds", seconds];
        args.extend_from_slice(more);
        self.run(&args)
    }

    /// Runs `vps ARGS`, asserts that it failed, and returns its stderr.
    pub fn fails(&self, args: &[&str]) -> String {
        let out = self.run(args);
        assert!(!out.status.success(), "vps {args:?} succeeded");
        stderr(&out)
    }
}

/// The stderr of a command that must have failed; panics (with its stdout) where it succeeded.
pub fn failed(out: &Output) -> String {
    assert!(
        !out.status.success(),
        "the command succeeded: {}",
        String::from_utf8_lossy(&out.stdout)
    );
    stderr(out)
}

/// The JSON document on a successful command's stdout; panics with its stderr if it failed.
pub fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "vps failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("valid JSON on stdout")
}

/// A UDP port free on loopback just now (bound and released: another process may take it
/// before the caller binds it).
pub fn free_udp_port() -> u16 {
    std::net::UdpSocket::bind("127.0.0.1:0")
        .expect("a loopback UDP socket")
        .local_addr()
        .expect("its address")
        .port()
}

/// A command's stderr as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Child processes that are killed (SIGKILL) and reaped on drop, so a failing test leaves none
/// behind.
#[derive(Default)]
pub struct Children(pub Vec<Child>);

impl Children {
    /// Adds `child`; returns its index.
    pub fn push(&mut self, child: Child) -> usize {
        self.0.push(child);
        self.0.len() - 1
    }

    /// SIGKILLs child `index` and reaps it.
    pub fn kill(&mut self, index: usize) {
        let child = &mut self.0[index];
        child.kill().expect("SIGKILL the child");
        child.wait().expect("reap the child");
    }
}

impl Drop for Children {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// Spawns `cmd` with stderr piped and waits up to `patience` for a stderr line holding `marker`;
/// returns the child and the rest of that line after the marker, trimmed. A thread echoes every
/// stderr line to the test's stderr as `[label] LINE` until the child closes it. Panics (after
/// killing the child) when no such line comes in time.
pub fn spawn_until_line(
    cmd: Command,
    label: &str,
    marker: &str,
    patience: Duration,
) -> (Child, String) {
    let (child, mut rests) = spawn_until_lines(cmd, label, marker, 1, patience);
    (child, rests.remove(0))
}

/// [`spawn_until_line`] waiting for `count` lines holding `marker` (all within `patience`);
/// returns the rests of those lines in order.
pub fn spawn_until_lines(
    mut cmd: Command,
    label: &str,
    marker: &str,
    count: usize,
    patience: Duration,
) -> (Child, Vec<String>) {
    let mut child = cmd
        .stderr(Stdio::piped())
        .spawn()
        .expect("the child starts");
    let stderr = child.stderr.take().expect("piped stderr");
    let (tx, rx) = mpsc::channel();
    let (label, wanted) = (label.to_string(), marker.to_string());
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if let Some(rest) = line.split(&wanted).nth(1) {
                let _ = tx.send(rest.trim().to_string());
            }
            eprintln!("[{label}] {line}");
        }
    });
    let deadline = std::time::Instant::now() + patience;
    let mut rests = Vec::with_capacity(count);
    while rests.len() < count {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match rx.recv_timeout(left) {
            Ok(rest) => rests.push(rest),
            Err(_) => {
                let _ = child.kill();
                let _ = child.wait();
                panic!(
                    "{cmd:?} printed {} of {count} {marker:?} lines within {patience:?}",
                    rests.len()
                );
            }
        }
    }
    (child, rests)
}

/// A child process whose stderr lines are collected (and echoed to the test's stderr as
/// `[label] LINE`), so a test can wait for a line, count lines, signal it and wait for its exit,
/// each wait bounded by `patience`. Killed (SIGKILL) and reaped on drop.
pub struct WatchedProcess {
    child: Child,
    lines: Arc<Mutex<Vec<String>>>,
    patience: Duration,
}

impl WatchedProcess {
    /// Spawns `cmd` with stdin and stdout null and stderr collected.
    pub fn spawn(mut cmd: Command, label: &str, patience: Duration) -> WatchedProcess {
        let mut child = cmd
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("the child starts");
        let stderr = child.stderr.take().expect("piped stderr");
        let lines = Arc::new(Mutex::new(Vec::new()));
        let sink = lines.clone();
        let label = label.to_string();
        std::thread::spawn(move || {
            for line in BufReader::new(stderr).lines().map_while(Result::ok) {
                eprintln!("[{label}] {line}");
                sink.lock().unwrap().push(line);
            }
        });
        WatchedProcess {
            child,
            lines,
            patience,
        }
    }

    /// Stderr lines so far that contain `text`.
    pub fn count(&self, text: &str) -> usize {
        self.lines
            .lock()
            .unwrap()
            .iter()
            .filter(|l| l.contains(text))
            .count()
    }

    /// The stderr lines so far that contain `text`.
    pub fn lines_containing(&self, text: &str) -> Vec<String> {
        let lines = self.lines.lock().unwrap();
        lines.iter().filter(|l| l.contains(text)).cloned().collect()
    }

    /// Waits until `count` stderr lines contain `text`; panics after the patience.
    pub fn wait_for(&self, text: &str, count: usize) {
        let until = Instant::now() + self.patience;
        while self.count(text) < count {
            assert!(Instant::now() < until, "no {count}× {text:?} on stderr");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Sends signal `name` (`TERM`, `INT`, ...) with `kill`.
    pub fn signal(&self, name: &str) {
        let ok = Command::new("kill")
            .args([format!("-{name}"), self.child.id().to_string()])
            .status()
            .expect("kill runs")
            .success();
        assert!(ok, "kill -{name} failed");
    }

    /// Whether the process has not exited yet.
    pub fn is_running(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }

    /// Waits for the process to exit; panics after the patience.
    pub fn wait_exit(&mut self) -> ExitStatus {
        let until = Instant::now() + self.patience;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(Instant::now() < until, "the process did not exit");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for WatchedProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}
