//! Cluster membership changes with real `vps worker` processes: a worker SIGKILLed mid-session and
//! restarted rejoins (from its scene cache) and is given work again, and a worker that joins
//! mid-session gets work too — while every device write stays bit-identical, frame by frame, to
//! the one-process run. The coordinator runs in this test process (the same library code as
//! `vps coordinator`) so that every write can be logged.

use std::sync::{Arc, Mutex};
use std::time::Duration;
use vps_cluster::GatherConfig;
use vps_testkit::cluster::*;
use vps_testkit::process::Children;

const SESSION_FRAMES: u64 = 600;
const KILL_AT: u64 = 100;
const RESTART_AT: u64 = 200;
const NEW_WORKER_AT: u64 = 300;
const JOIN_WAIT: Duration = Duration::from_secs(20);

const VPS: &str = env!("CARGO_BIN_EXE_vps");

#[test]
fn a_killed_worker_rejoins_and_a_new_worker_joins_mid_session_without_changing_a_bit() {
    let want = one_process_writes_for(SESSION_FRAMES);
    let dir = tempfile::tempdir().unwrap();
    let (coordinator, certs) = loopback_coordinator(dir.path());
    let coordinator = Arc::new(coordinator);
    let addr = coordinator.local_addr().unwrap();
    let args = |k: usize, cache: &str| worker_args(addr, &certs, k, Some(dir.path().join(cache)));
    let (args_a, args_b, args_c) = (args(0, "cache-a"), args(1, "cache-b"), args(2, "cache-c"));
    let workers = Arc::new(Mutex::new(Children::default()));
    // Worker ids follow join order: A is 0, B is 1.
    let a = workers.lock().unwrap().push(spawn_worker(VPS, &args_a));
    coordinator.wait_for_admitted(1, JOIN_WAIT).unwrap();
    workers.lock().unwrap().push(spawn_worker(VPS, &args_b));
    coordinator.wait_for_admitted(2, JOIN_WAIT).unwrap();

    // Membership changes run after a device write, before the next frame starts: blocking here
    // never shortens a frame's reply deadline.
    let hook = {
        let (workers, coordinator) = (workers.clone(), coordinator.clone());
        Box::new(move |write: u64| match write {
            KILL_AT => workers.lock().unwrap().kill(a),
            RESTART_AT => {
                // A's certificate may join again once the coordinator saw A's connection end
                // (its idle timeout): one live connection per certificate.
                let until = std::time::Instant::now() + JOIN_WAIT;
                while coordinator.joined_workers() > 1 && std::time::Instant::now() < until {
                    std::thread::sleep(Duration::from_millis(10));
                }
                workers.lock().unwrap().push(spawn_worker(VPS, &args_a));
                coordinator.wait_for_admitted(3, JOIN_WAIT).unwrap();
            }
            NEW_WORKER_AT => {
                workers.lock().unwrap().push(spawn_worker(VPS, &args_c));
                coordinator.wait_for_admitted(4, JOIN_WAIT).unwrap();
            }
            _ => {}
        })
    };
    let (device, writes) = hand_with_hook(hook);
    let (_, cluster) = exact_cluster_session(
        &coordinator,
        GatherConfig {
            sideline_after: 2,
            log_every: None,
            // These tests exercise the split itself (`--split always`).
            predict: false,
            ..GatherConfig::default()
        },
        device,
        SESSION_FRAMES,
    );
    assert_same_writes(&writes.lock().unwrap(), &want);

    eprintln!("{cluster:#?}");
    let ids: Vec<u32> = cluster.peers.iter().map(|p| p.id).collect();
    assert_eq!(ids, [0, 1, 2, 3], "A, B, A restarted, C");
    let [killed, survivor, rejoined, newcomer] = &cluster.peers[..] else {
        unreachable!()
    };
    assert!(killed.scene_sent && survivor.scene_sent && newcomer.scene_sent);
    assert!(
        killed.recomputed > 0,
        "the killed worker's shares were recomputed locally: {killed:?}"
    );
    assert!(survivor.merged > 0, "{survivor:?}");
    assert!(
        !rejoined.scene_sent,
        "the restarted worker loaded the scene from its cache: {rejoined:?}"
    );
    assert!(
        rejoined.requests > 0 && rejoined.merged > 0,
        "the restarted worker was given classes and its replies were used: {rejoined:?}"
    );
    assert!(
        newcomer.requests > 0 && newcomer.merged > 0,
        "the worker that joined mid-session was given work: {newcomer:?}"
    );
}
