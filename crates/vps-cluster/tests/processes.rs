//! Real separate worker processes, certificates from files, SIGKILL mid-session. The test binary
//! re-executes itself as a worker (the `child_worker_entry` test, inert unless its environment
//! variables are set), so this needs no CLI; `vps cluster --local-workers N` runs the same code
//! with `vps worker` processes.

mod common;

use common::*;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use vps_cluster::{run_worker, GatherConfig, LocalWorkerArgs, WorkerConfig};

const ENV_ADDR: &str = "VPS_CLUSTER_TEST_WORKER_ADDR";
const ENV_CERT: &str = "VPS_CLUSTER_TEST_WORKER_CERT";
const ENV_KEY: &str = "VPS_CLUSTER_TEST_WORKER_KEY";
const ENV_PIN: &str = "VPS_CLUSTER_TEST_WORKER_PIN";

/// The worker process body: does nothing in a normal test run.
#[test]
fn child_worker_entry() {
    let Ok(addr) = std::env::var(ENV_ADDR) else {
        return;
    };
    let var = |k: &str| std::path::PathBuf::from(std::env::var(k).unwrap());
    let mut config = WorkerConfig::from_files(
        addr.parse().unwrap(),
        &var(ENV_CERT),
        &var(ENV_KEY),
        &[var(ENV_PIN)],
    )
    .unwrap();
    config.threads = 1;
    let _ = run_worker(config);
}

fn spawn_child(args: &LocalWorkerArgs) -> Child {
    Command::new(std::env::current_exe().unwrap())
        .args([
            "--exact",
            "child_worker_entry",
            "--test-threads=1",
            "--nocapture",
        ])
        .env(ENV_ADDR, args.coordinator.to_string())
        .env(ENV_CERT, &args.cert)
        .env(ENV_KEY, &args.key)
        .env(ENV_PIN, &args.pins[0])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .unwrap()
}

#[test]
fn two_worker_processes_one_killed_mid_session_keep_every_write_bit_identical() {
    let want = one_process_writes();
    let dir = tempfile::tempdir().unwrap();
    let (coordinator, certs) = loopback_coordinator(dir.path());
    let addr = coordinator.local_addr().unwrap();
    let children: Arc<Mutex<Vec<Child>>> = Arc::new(Mutex::new(
        (0..2)
            .map(|k| spawn_child(&certs.worker_args(k, addr, None).unwrap()))
            .collect(),
    ));
    coordinator
        .wait_for_workers(2, Duration::from_secs(8))
        .unwrap();
    // SIGKILL worker 0 when the device is read for frame FRAMES / 3.
    let trip = Arc::new(AtomicBool::new(false));
    let killer = {
        let (trip, children) = (trip.clone(), children.clone());
        std::thread::spawn(move || {
            while !trip.load(Ordering::Relaxed) {
                std::thread::sleep(Duration::from_micros(200));
            }
            let mut c = children.lock().unwrap();
            c[0].kill().unwrap();
            c[0].wait().unwrap();
        })
    };
    let (device, writes) = hand(FRAMES / 3, trip);
    let (report, cluster) = exact_cluster_session(
        &coordinator,
        GatherConfig {
            bench_after: 2,
            ..GatherConfig::default()
        },
        device,
        FRAMES,
    );
    killer.join().unwrap();
    assert_eq!(report.stats.frames, FRAMES);
    assert_eq!(report.stats.watchdog_trips, 0);
    let got = writes.lock().unwrap().clone();
    assert_eq!(got.len(), want.len(), "no missed device write");
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(g, w, "frame {i}");
    }
    eprintln!("{cluster:#?}");
    assert_eq!(cluster.peers.len(), 2);
    assert!(cluster.peers.iter().any(|p| p.merged > 0), "{cluster:?}");
    // Genuine traffic, a killed worker included, is never counted as garbage.
    assert!(cluster.udp_datagrams > FRAMES, "{cluster:?}");
    assert_eq!(
        (cluster.udp_not_quic, cluster.udp_foreign),
        (0, 0),
        "{cluster:?}"
    );
    drop(coordinator);
    for c in children.lock().unwrap().iter_mut() {
        let _ = c.kill();
        let _ = c.wait();
    }
}

#[test]
fn local_worker_args_are_the_documented_command_line() {
    let args = LocalWorkerArgs {
        coordinator: "127.0.0.1:4433".parse().unwrap(),
        cert: "w.crt".into(),
        key: "w.key".into(),
        pins: vec!["c.crt".into(), "d.crt".into()],
        cache_dir: Some("cache".into()),
        threads: Some(2),
    };
    let got: Vec<String> = args
        .to_args()
        .iter()
        .map(|a| a.to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        got.join(" "),
        "worker --coordinator 127.0.0.1:4433 --cert w.crt --key w.key --pin c.crt --pin d.crt \
         --cache cache --threads 2 --exit-with-coordinator"
    );
}
