//! One live connection per pinned certificate, over real QUIC on loopback: a second worker with
//! the certificate of a connected one is refused (close code `CLOSE_DUPLICATE_IDENTITY`) and told
//! why; once the first has gone the certificate joins again; an unpinned worker is told that its
//! certificate is not pinned.

mod common;

use common::*;
use std::time::{Duration, Instant};
use vps_cluster::close::{is_refusal, CLOSE_BAD_REPLIES, CLOSE_DUPLICATE_IDENTITY};
use vps_cluster::{run_worker, ClusterError, PeerTls, TlsIdentity, WorkerConfig};

const JOIN_WAIT: Duration = Duration::from_secs(20);

fn wait_until(what: &str, mut done: impl FnMut() -> bool) {
    let until = Instant::now() + JOIN_WAIT;
    while !done() {
        assert!(Instant::now() < until, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A coordinator with worker 0 joined: (coordinator, its address, the worker).
fn coordinator_with_first_worker(
    ids: &Identities,
) -> (vps_cluster::Coordinator, std::net::SocketAddr, ThreadWorker) {
    let coordinator = start_coordinator(ids, assets());
    let addr = coordinator.local_addr().unwrap();
    let first = ThreadWorker::spawn(worker_config(ids, addr));
    coordinator.wait_for_workers(1, JOIN_WAIT).unwrap();
    (coordinator, addr, first)
}

#[test]
fn a_second_worker_with_a_connected_certificate_is_refused_and_told_why() {
    let ids = identities();
    let (coordinator, addr, first) = coordinator_with_first_worker(&ids);

    let err = run_worker(worker_config(&ids, addr)).expect_err("the duplicate is refused");
    match &err {
        ClusterError::Refused(m) => assert!(
            m.contains(
                "refused by the coordinator: another worker with this certificate is connected"
            ),
            "{m}"
        ),
        other => panic!("not a refusal: {other:?}"),
    }
    assert_eq!(coordinator.refused_duplicates(), 1);
    assert_eq!(coordinator.joined_workers(), 1, "the first is still joined");
    assert_eq!(coordinator.admitted_workers(), 1);
    // A different pinned certificate is not a duplicate.
    let other = ThreadWorker::spawn(worker_config_k(&ids, addr, 1));
    coordinator.wait_for_workers(2, JOIN_WAIT).unwrap();
    other.stop().unwrap();
    let report = first.stop().expect("the first worker was left alone");
    assert_eq!(report.ended, "stopped");
}

#[test]
fn the_certificate_joins_again_after_the_first_worker_has_gone() {
    let ids = identities();
    let (coordinator, addr, first) = coordinator_with_first_worker(&ids);
    first.stop().unwrap();
    wait_until("the first worker's departure", || {
        coordinator.joined_workers() == 0
    });

    let replacement = ThreadWorker::spawn(worker_config(&ids, addr));
    wait_until("the replacement's join", || {
        coordinator.admitted_workers() == 2
    });
    assert_eq!(coordinator.joined_workers(), 1);
    assert_eq!(coordinator.refused_duplicates(), 0);
    assert_eq!(replacement.stop().unwrap().ended, "stopped");
}

#[test]
fn an_unpinned_worker_is_told_its_certificate_is_not_pinned() {
    let ids = identities();
    let coordinator = start_coordinator(&ids, assets());
    let addr = coordinator.local_addr().unwrap();
    let config = worker_config(&ids, addr);
    let err = run_worker(WorkerConfig {
        tls: PeerTls {
            identity: TlsIdentity::generate("stranger").unwrap(),
            ..config.tls
        },
        ..config
    })
    .expect_err("refused");
    match &err {
        ClusterError::Refused(m) => {
            assert!(m.contains("certificate not pinned"), "{m}");
            assert!(!m.contains("connection lost"), "{m}");
        }
        other => panic!("not a refusal: {other:?}"),
    }
    wait_until("the refusal count", || coordinator.refused_unpinned() == 1);
    assert_eq!(coordinator.refused_duplicates(), 0);
}

#[test]
fn a_duplicate_is_a_refusal_for_good_and_a_disconnection_for_bad_replies_is_not() {
    assert_ne!(CLOSE_BAD_REPLIES, CLOSE_DUPLICATE_IDENTITY);
    assert!(is_refusal(u64::from(CLOSE_DUPLICATE_IDENTITY)));
    assert!(!is_refusal(u64::from(CLOSE_BAD_REPLIES)));
}
