//! Entry points for the application layer (`vps-app`): a coordinator session on the runtime's frame loop, and local worker
//! processes for `vps cluster --local-workers N`.

use crate::coordinator::Coordinator;
use crate::report::ClusterReport;
use crate::shares::GatherConfig;
use crate::tls::{make_cert, CertFiles};
use crate::ClusterError;
use std::ffi::OsString;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use vps_runtime::{spawn_loop_with, KeepOffFrameCore, LoopReport, SessionSetup};

/// Runs a haptic session whose frames are gathered from `coordinator`'s workers (local fallback
/// for every missing share), on the runtime's frame loop: same clock, watchdog, statistics and
/// device handling as `vps_runtime::run_loop`. Replies are awaited until `config.watchdog / 2`
/// into each frame; `config.threads` is unused (the local share uses `gather.local_threads`).
/// Blocks until the session ends.
pub fn run_coordinator_session(
    coordinator: &Coordinator,
    gather: GatherConfig,
    setup: SessionSetup,
) -> Result<(LoopReport, ClusterReport), ClusterError> {
    let shares = coordinator.shares(gather)?;
    let slot = shares.report_slot();
    let report = spawn_loop_with(Box::new(shares), setup)?.join()?;
    let cluster = slot
        .lock()
        .ok()
        .and_then(|mut s| s.take())
        .unwrap_or_default();
    Ok((report, cluster))
}

/// The certificates of a local cluster: one for the coordinator, one per worker (the coordinator
/// admits one live connection per certificate, see [`crate::coordinator`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LocalCerts {
    /// `DIR/coordinator.crt`, `DIR/coordinator.key`.
    pub coordinator: CertFiles,
    /// `DIR/worker-K.crt`, `DIR/worker-K.key` for K in `0..n`.
    pub workers: Vec<CertFiles>,
}

impl LocalCerts {
    /// The workers' certificate files, for the coordinator's `--pin`.
    pub fn worker_pins(&self) -> Vec<PathBuf> {
        self.workers.iter().map(|w| w.cert.clone()).collect()
    }

    /// The command line of local worker `k` dialling `coordinator`: its own certificate, the
    /// coordinator's pinned, no cache, `threads` compute threads. `None` when `k` has no
    /// certificate here.
    pub fn worker_args(
        &self,
        k: usize,
        coordinator: SocketAddr,
        threads: Option<usize>,
    ) -> Option<LocalWorkerArgs> {
        let files = self.workers.get(k)?;
        Some(LocalWorkerArgs {
            coordinator,
            cert: files.cert.clone(),
            key: files.key.clone(),
            pins: vec![self.coordinator.cert.clone()],
            cache_dir: None,
            threads,
        })
    }
}

/// Writes fresh certificates for a coordinator and `workers` workers into `dir` (which should be
/// a new private temporary directory) for `vps cluster --local-workers N`.
pub fn local_cluster_certs(dir: &Path, workers: usize) -> Result<LocalCerts, ClusterError> {
    Ok(LocalCerts {
        coordinator: make_cert(dir, "coordinator")?,
        workers: (0..workers)
            .map(|k| make_cert(dir, &format!("worker-{k}")))
            .collect::<Result<_, _>>()?,
    })
}

/// The command line of a `vps worker` process.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LocalWorkerArgs {
    /// `--coordinator ADDR`.
    pub coordinator: SocketAddr,
    /// `--cert FILE`: the worker's certificate.
    pub cert: PathBuf,
    /// `--key FILE`: the worker's key.
    pub key: PathBuf,
    /// `--pin FILE`, repeated: the coordinator certificates accepted.
    pub pins: Vec<PathBuf>,
    /// `--cache DIR`, optional.
    pub cache_dir: Option<PathBuf>,
    /// `--threads N`, optional.
    pub threads: Option<usize>,
}

/// Local workers end with their coordinator instead of waiting for the next one
/// (`vps worker --exit-with-coordinator`), so that none outlives its `vps cluster`.
const EXIT_WITH_COORDINATOR: &str = "--exit-with-coordinator";

impl LocalWorkerArgs {
    /// The arguments after the program name: `worker --coordinator ADDR --cert FILE --key FILE
    /// --pin FILE... [--cache DIR] [--threads N] --exit-with-coordinator` (local workers do not
    /// outlive their coordinator).
    pub fn to_args(&self) -> Vec<OsString> {
        let mut args: Vec<OsString> = vec![
            "worker".into(),
            "--coordinator".into(),
            self.coordinator.to_string().into(),
            "--cert".into(),
            self.cert.clone().into(),
            "--key".into(),
            self.key.clone().into(),
        ];
        for pin in &self.pins {
            args.push("--pin".into());
            args.push(pin.clone().into());
        }
        if let Some(dir) = &self.cache_dir {
            args.push("--cache".into());
            args.push(dir.clone().into());
        }
        if let Some(n) = self.threads {
            args.push("--threads".into());
            args.push(n.to_string().into());
        }
        args.push(EXIT_WITH_COORDINATOR.into());
        args
    }
}

/// Worker child processes; dropping this kills (SIGKILL) and reaps any still running.
pub struct LocalWorkers {
    children: Vec<Child>,
}

impl LocalWorkers {
    /// Process ids, in spawn order.
    pub fn pids(&self) -> Vec<u32> {
        self.children.iter().map(Child::id).collect()
    }

    /// Kills worker `index` with SIGKILL and reaps it (no-op if already gone or out of range).
    pub fn kill(&mut self, index: usize) {
        if let Some(child) = self.children.get_mut(index) {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

impl Drop for LocalWorkers {
    fn drop(&mut self) {
        for index in 0..self.children.len() {
            self.kill(index);
        }
    }
}

/// Starts one worker process per entry of `args`: `exe` (normally `std::env::current_exe()`)
/// with [`LocalWorkerArgs::to_args`] (each worker its own certificate: the coordinator refuses a
/// second live connection with the same one). stdin is closed, stdout/stderr are inherited. If
/// one fails to start, those already started are killed. With `keep_off`, each child is
/// restricted at spawn (between `fork` and `exec`, so every thread it ever starts inherits it) to
/// the cores other than the frame thread's, and the outcome is recorded in `keep_off`'s
/// [`vps_runtime::Placement`].
pub fn spawn_local_workers(
    exe: &Path,
    args: &[LocalWorkerArgs],
    keep_off: Option<&KeepOffFrameCore>,
) -> Result<LocalWorkers, ClusterError> {
    let mut workers = LocalWorkers {
        children: Vec::with_capacity(args.len()),
    };
    for args in args {
        let mut command = Command::new(exe);
        command.args(args.to_args()).stdin(Stdio::null());
        if let Some(keep) = keep_off {
            restrict_child(&mut command, keep.other_cores());
        }
        let child = command.spawn().map_err(|e| ClusterError::File {
            path: exe.to_path_buf(),
            message: format!("cannot start a worker process: {e}"),
        })?;
        if let Some(keep) = keep_off {
            // `spawn` returns once the child has run `exec`, so its mask is set by now.
            keep.note(match vps_runtime::rt::affinity_of(child.id()) {
                Ok(cores) => format!("local worker process: cores {cores:?}"),
                Err(e) => format!("local worker process: mask unknown ({e})"),
            });
        }
        workers.children.push(child);
    }
    Ok(workers)
}

/// Makes `command`'s child restrict itself to `cores` before it runs `exec`. A refusal is not
/// fatal: the child then keeps its parent's mask (the report reads the mask back).
#[cfg(target_os = "linux")]
fn restrict_child(command: &mut Command, cores: &[usize]) {
    use std::os::unix::process::CommandExt;
    // Built here, before the fork: the child only makes the syscall.
    let set = vps_runtime::rt::cpu_set(cores);
    // SAFETY: the closure runs in the forked child before exec and makes one async-signal-safe
    // syscall on memory it owns (a copy of `set`); it does not allocate or lock.
    unsafe {
        command.pre_exec(move || {
            // A refusal leaves the parent's mask (see above), so its error is dropped.
            let _ = vps_runtime::rt::apply_cpu_set(0, &set);
            Ok(())
        });
    }
}

#[cfg(not(target_os = "linux"))]
fn restrict_child(_command: &mut Command, _cores: &[usize]) {}
