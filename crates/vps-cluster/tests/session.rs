//! Whole haptic sessions on the runtime's frame loop: the cluster's device writes are
//! bit-identical, frame by frame, to the one-process loop's, also when a worker leaves mid-run.

use crate::common;

use common::*;
use vps_haptic::Wrench;

/// Runs a cluster session with two thread workers; worker 1 is stopped at frame `leave_at`
/// (never when 0).
fn cluster_writes(leave_at: u64) -> (Vec<Wrench>, vps_cluster::ClusterReport) {
    let ids = identities();
    let (coordinator, mut workers) = coordinator_with_thread_workers(&ids, assets(), 2);
    let leaving = workers.pop().unwrap();
    let (device, writes) = hand(leave_at, leaving.stop.clone());
    let (_, cluster) = exact_cluster_session(&coordinator, split_always(), device, FRAMES);
    // The live snapshot, read after the session, is the final report.
    assert_eq!(coordinator.metrics().snapshot(), cluster);
    leaving.stop().unwrap();
    workers.pop().unwrap().stop().unwrap();
    let w = writes.lock().unwrap().clone();
    (w, cluster)
}

#[test]
fn a_two_worker_session_writes_the_same_wrenches_as_one_process() {
    let want = one_process_writes();
    let (got, cluster) = cluster_writes(0);
    assert_eq!(got.len(), want.len());
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(g, w, "frame {i}");
    }
    assert_eq!(cluster.frames, FRAMES);
    assert!(cluster.peers.iter().all(|p| p.merged > 0), "{cluster:?}");
    assert!(
        cluster
            .peers
            .iter()
            .all(|p| p.rtt_samples > 0 && p.scene_sent),
        "{cluster:?}"
    );
}

#[test]
fn a_worker_leaving_mid_session_misses_no_write_and_changes_no_bit() {
    let want = one_process_writes();
    let (got, cluster) = cluster_writes(FRAMES / 3);
    // One write per frame plus the final zero wrench, as in the one-process run.
    assert_eq!(got.len(), want.len());
    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
        assert_eq!(g, w, "frame {i}");
    }
    assert_eq!(cluster.peers.len(), 2);
}
