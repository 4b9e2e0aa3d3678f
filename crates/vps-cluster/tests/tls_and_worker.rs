//! Pinning, certificates, the worker's side of the protocol (join, cache, malformed datagrams).

use crate::common;

use common::*;
use std::sync::atomic::AtomicU64;
use std::sync::Arc;
use std::time::Duration;
use vps_cluster::protocol::{
    read_join, write_frame, write_join, FrameReply, FrameRequest, JoinMessage, PROTOCOL_VERSION,
    REQUEST_LEN,
};
use vps_cluster::tls::server_config;
use vps_cluster::{make_cert, run_worker, ClusterError, PeerTls, TlsIdentity, WorkerConfig};
use vps_haptic::sample_all;

/// A coordinator on [`assets`] and the error of one worker joining it with the standard worker
/// configuration changed by `change`.
fn refused_worker(
    change: impl FnOnce(WorkerConfig) -> WorkerConfig,
) -> (vps_cluster::Coordinator, ClusterError) {
    let ids = identities();
    let coordinator = start_coordinator(&ids, assets());
    let addr = coordinator.local_addr().unwrap();
    let err = run_worker(change(worker_config(&ids, addr))).unwrap_err();
    (coordinator, err)
}

#[test]
fn a_worker_with_an_unpinned_certificate_is_refused_and_counted() {
    let stranger = TlsIdentity::generate("stranger").unwrap();
    let (coordinator, err) = refused_worker(|config| WorkerConfig {
        tls: PeerTls {
            identity: stranger,
            ..config.tls
        },
        ..config
    });
    // A refusal for good, saying why (not "join: read: connection lost").
    assert!(
        matches!(err, ClusterError::Refused(ref m) if m.contains("refused this worker's certificate")),
        "{err}"
    );
    // The server verifier ran and counted the refusal before the client saw the failure.
    for _ in 0..200 {
        if coordinator.refused_unpinned() > 0 {
            break;
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(coordinator.refused_unpinned(), 1);
    assert_eq!(coordinator.joined_workers(), 0);
}

#[test]
fn a_worker_refuses_a_coordinator_it_did_not_pin() {
    let other = TlsIdentity::generate("other").unwrap();
    let (coordinator, err) = refused_worker(|config| WorkerConfig {
        tls: PeerTls {
            pins: vec![other.cert.clone()],
            ..config.tls
        },
        ..config
    });
    assert!(
        matches!(err, ClusterError::Refused(ref m) if m.contains("does not accept")),
        "{err}"
    );
    assert_eq!(coordinator.joined_workers(), 0);
}

#[test]
fn a_wrong_protocol_version_is_rejected_at_join() {
    let ids = identities();
    let coordinator = start_coordinator(&ids, assets());
    let fake = FakeWorker::new(&ids.worker, &ids.coordinator);
    let err = fake
        .join(coordinator.local_addr().unwrap(), PROTOCOL_VERSION + 1)
        .unwrap_err();
    assert!(err.contains("Reject"), "{err}");
    assert_eq!(coordinator.joined_workers(), 0);
}

#[test]
fn make_cert_writes_loadable_pem_files_and_refuses_to_overwrite() {
    let dir = tempfile::tempdir().unwrap();
    let files = make_cert(dir.path(), "node-1").unwrap();
    assert_eq!(files.cert, dir.path().join("node-1.crt"));
    let id = TlsIdentity::load(&files.cert, &files.key).unwrap();
    assert_eq!(id.cert, vps_cluster::tls::load_cert(&files.cert).unwrap());
    assert!(make_cert(dir.path(), "node-1").is_err());
    assert!(make_cert(dir.path(), "../x").is_err());
    assert!(matches!(
        TlsIdentity::load(&files.key, &files.key),
        Err(ClusterError::File { .. })
    ));
    assert!(vps_cluster::tls::load_pins(&[]).is_err());
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&files.key).unwrap().permissions().mode();
        assert_eq!(mode & 0o077, 0, "key is private");
    }
}

/// A hand-driven coordinator: accepts one pinned worker, ships the assets on request, then sends
/// garbage, truncated and valid requests and checks the one valid reply.
#[test]
fn a_worker_survives_garbage_counts_it_and_uses_its_scene_cache() {
    let ids = identities();
    let assets = assets();
    let cache = tempfile::tempdir().unwrap();
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap();
    let endpoint = {
        let _g = rt.enter();
        let config = server_config(
            &PeerTls {
                identity: ids.coordinator.clone(),
                pins: vec![ids.worker.cert.clone()],
            },
            Arc::new(AtomicU64::new(0)),
        )
        .unwrap();
        quinn::Endpoint::server(config, "127.0.0.1:0".parse().unwrap()).unwrap()
    };
    let addr = endpoint.local_addr().unwrap();
    let pose = poses(10)[7];
    let want = sample_all(&**assets.scene_map(), assets.first_shell(), &pose);
    assert!(want.contacts > 0);
    // Round 0: an empty cache, both files sent; round 1: both cached; round 2: the shell's
    // cached file removed, only the shell sent (the voxmap read from the cache).
    for round in 0..3 {
        if round == 2 {
            let shell = cache.path().join(format!(
                "{}.shell",
                vps_cluster::assets::hex(&assets.identity.files[1].hash)
            ));
            std::fs::remove_file(&shell).expect("the shell was cached");
        }
        let worker = ThreadWorker::spawn(WorkerConfig {
            cache_dir: Some(cache.path().to_path_buf()),
            ..worker_config(&ids, addr)
        });
        let (assets, endpoint) = (assets.clone(), endpoint.clone());
        let reply = rt.block_on(async move {
            let conn = endpoint.accept().await.unwrap().await.unwrap();
            let (mut send, mut recv) = conn.accept_bi().await.unwrap();
            assert_eq!(
                read_join(&mut recv).await.unwrap(),
                JoinMessage::Hello {
                    version: PROTOCOL_VERSION
                }
            );
            write_join(
                &mut send,
                &JoinMessage::Welcome {
                    worker_id: 9,
                    assets: assets.identity.clone(),
                },
            )
            .await
            .unwrap();
            let need = read_join(&mut recv).await.unwrap();
            let files = [0b11, 0, 0b10][round];
            assert_eq!(need, JoinMessage::Need { files });
            for k in (0..2).filter(|k| files >> k & 1 == 1) {
                write_frame(&mut send, assets.file(k)).await.unwrap();
            }
            assert_eq!(read_join(&mut recv).await.unwrap(), JoinMessage::Ready);
            // Raw UDP garbage at the worker's socket (counted by its shape, dropped by quinn),
            // garbage shaped like QUIC (a short header naming an ID the worker never issued, a
            // long header of an unknown version and a Handshake packet naming a stranger: counted
            // as foreign); then QUIC-level garbage: every truncation of a valid request, then
            // noise, then one valid request.
            let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
            let worker_addr = conn.remote_address();
            for n in [0usize, 3, 100] {
                udp.send_to(&vec![0xA5; n], worker_addr).unwrap();
            }
            for shaped in quic_shaped_garbage() {
                udp.send_to(&shaped, worker_addr).unwrap();
            }
            let mut buf = [0u8; REQUEST_LEN];
            FrameRequest {
                seq: 77,
                classes: u64::MAX,
                job: vps_haptic::JobTarget::FIRST,
                pose,
            }
            .encode(&mut buf);
            for n in [0, 1, 8, 50, REQUEST_LEN - 1] {
                conn.send_datagram(bytes::Bytes::copy_from_slice(&buf[..n]))
                    .unwrap();
            }
            conn.send_datagram(bytes::Bytes::from_static(&[0xff; 200]))
                .unwrap();
            let mut nan = buf;
            nan[28..32].copy_from_slice(&f32::NAN.to_le_bytes());
            conn.send_datagram(bytes::Bytes::copy_from_slice(&nan))
                .unwrap();
            // A job the assets lack (a second part's shell, a body voxmap).
            for (shell, map) in [(1, 0), (0, 1)] {
                let mut stranger = buf;
                stranger[6] = shell;
                stranger[7] = map;
                conn.send_datagram(bytes::Bytes::copy_from_slice(&stranger))
                    .unwrap();
            }
            conn.send_datagram(bytes::Bytes::copy_from_slice(&buf))
                .unwrap();
            let reply = tokio::time::timeout(Duration::from_secs(5), conn.read_datagram())
                .await
                .unwrap()
                .unwrap();
            conn.close(0u32.into(), b"done");
            reply
        });
        let reply = FrameReply::decode(&reply).unwrap();
        assert_eq!(reply.seq, 77);
        assert_eq!(reply.sums, want, "a worker's sums are the one-process sums");
        let report = worker.thread.join().unwrap().unwrap();
        assert_eq!(report.invalid_datagrams, 9, "{report:?}");
        assert_eq!(report.udp_not_quic, 3, "{report:?}");
        assert_eq!(report.udp_foreign, 3, "{report:?}");
        assert_eq!(report.requests, 1);
        assert_eq!(report.scene_transferred, round != 1);
        assert_eq!(report.worker_id, 9);
    }
}
