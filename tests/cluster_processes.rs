//! Real separate `vps worker` processes, certificates from files, SIGKILL mid-session: every
//! device write stays bit-identical, frame by frame, to the one-process run. The coordinator runs
//! in this test process (the same library code as `vps coordinator`) so that every write can be
//! logged.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use vps_cluster::GatherConfig;
use vps_testkit::cluster::*;
use vps_testkit::process::Children;

#[test]
fn two_worker_processes_one_killed_mid_session_keep_every_write_bit_identical() {
    let want = one_process_writes();
    let dir = tempfile::tempdir().unwrap();
    let (coordinator, certs) = loopback_coordinator(dir.path());
    let addr = coordinator.local_addr().unwrap();
    let children = Arc::new(Mutex::new(Children::default()));
    for k in 0..2 {
        let worker = spawn_worker(
            env!("CARGO_BIN_EXE_vps"),
            &worker_args(addr, &certs, k, None),
        );
        children.lock().unwrap().push(worker);
    }
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
            children.lock().unwrap().kill(0);
        })
    };
    let (device, writes) = hand(FRAMES / 3, trip);
    let (_, cluster) = exact_cluster_session(
        &coordinator,
        GatherConfig {
            sideline_after: 2,
            // These tests exercise the split itself (`--split always`).
            predict: false,
            ..GatherConfig::default()
        },
        device,
        FRAMES,
    );
    killer.join().unwrap();
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
}
