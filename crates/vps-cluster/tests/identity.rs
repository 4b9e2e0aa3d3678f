//! One live connection per pinned certificate, the newest, over real QUIC on loopback: a second
//! worker with the certificate of a connected one replaces it, and the first is closed (close
//! code `CLOSE_REPLACED`) and told why; once the first has gone the certificate joins again; an
//! unpinned worker is told that its certificate is not pinned.

use crate::common;

use common::*;
use std::time::{Duration, Instant};
use vps_cluster::close::{is_refusal, CLOSE_BAD_REPLIES, CLOSE_DUPLICATE_IDENTITY, CLOSE_REPLACED};
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

/// Issue 36 item 5: a worker restarted within about 3 s of a crash was refused for good ("another
/// worker with this certificate is connected") while the coordinator still held the dead
/// connection. The newer connection now replaces the older: here the first worker is alive, is
/// closed and told why (a refusal, so the two do not take turns), and the second stays joined.
#[test]
fn a_second_worker_with_a_connected_certificate_replaces_it_and_the_first_is_told_why() {
    let ids = identities();
    let (coordinator, addr, first) = coordinator_with_first_worker(&ids);

    let second = ThreadWorker::spawn(worker_config(&ids, addr));
    wait_until("the second worker's join", || {
        coordinator.admitted_workers() == 2
    });
    let err = first
        .thread
        .join()
        .expect("no panic")
        .expect_err("the first is replaced");
    match &err {
        ClusterError::Refused(m) => assert!(
            m.contains("refused by the coordinator: a newer connection with this worker's certificate joined in its place"),
            "{m}"
        ),
        other => panic!("not a refusal: {other:?}"),
    }
    assert_eq!(coordinator.replaced_connections(), 1);
    wait_until("one joined worker", || coordinator.joined_workers() == 1);
    // A different pinned certificate replaces nothing.
    let other = ThreadWorker::spawn(worker_config_k(&ids, addr, 1));
    coordinator.wait_for_workers(2, JOIN_WAIT).unwrap();
    other.stop().unwrap();
    assert_eq!(coordinator.replaced_connections(), 1);
    let report = second.stop().expect("the second worker was left alone");
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
    assert_eq!(coordinator.replaced_connections(), 0);
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
    assert_eq!(coordinator.replaced_connections(), 0);
}

#[test]
fn a_duplicate_is_a_refusal_for_good_and_a_disconnection_for_bad_replies_is_not() {
    assert_ne!(CLOSE_BAD_REPLIES, CLOSE_DUPLICATE_IDENTITY);
    assert!(is_refusal(u64::from(CLOSE_DUPLICATE_IDENTITY)));
    assert!(!is_refusal(u64::from(CLOSE_BAD_REPLIES)));
    assert!(is_refusal(u64::from(CLOSE_REPLACED)));
}
