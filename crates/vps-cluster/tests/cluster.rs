//! Coordinator + workers over real QUIC on loopback, in one process.

use crate::common;

use common::*;
use std::time::{Duration, Instant};
use vps_cluster::fallback::StalePolicy;
use vps_cluster::protocol::{FrameReply, FrameRequest, REPLY_LEN};
use vps_cluster::GatherConfig;
use vps_haptic::{sample_all, JobTarget};
use vps_runtime::FrameSampler;

#[test]
fn two_workers_give_sums_bit_identical_to_one_process() {
    two_workers_match_one_process(assets());
}

/// The same with the `distance` force model: the band travels to the workers inside the voxmap
/// (`.vmap` v3) and their shares merge to the one-process sums bit for bit.
#[test]
fn two_workers_give_distance_model_sums_bit_identical_to_one_process() {
    let assets = vps_testkit::cluster::band_assets();
    assert!(assets.scene_map().distance_band().is_some());
    two_workers_match_one_process(assets);
}

/// Two thread workers over loopback QUIC, every frame split: the merged sums equal the
/// one-process sums of `assets` over 40 poses that touch and brake; both workers contribute, none
/// of their shares is judged implausible, and both received the scene.
fn two_workers_match_one_process(assets: std::sync::Arc<vps_cluster::ClusterAssets>) {
    let ids = identities();
    let (coordinator, workers) = coordinator_with_thread_workers(&ids, assets.clone(), 2);
    let mut shares = coordinator.shares(split_always()).unwrap();
    let poses = poses(40);
    let mut touched = false;
    for pose in &poses {
        let want = sample_all(&**assets.scene_map(), assets.first_shell(), pose);
        touched |= want.contacts > 0 && want.approaching > 0;
        let got = shares.compute(pose, Instant::now() + DEADLINE);
        assert_eq!(got.sums, want);
    }
    assert!(touched, "the poses must touch and brake");
    let report = shares.report();
    assert_eq!(report.frames, 40);
    assert_eq!(report.peers.len(), 2);
    for peer in &report.peers {
        assert!(
            peer.merged > 0,
            "worker {} contributed nothing: {peer:?}",
            peer.id
        );
        assert_eq!(peer.invalid, 0, "a genuine share was judged implausible");
    }
    drop(shares);
    for w in workers {
        let r = w.stop().unwrap();
        assert!(r.replies > 0);
        assert!(r.scene_transferred);
    }
}

#[test]
fn a_worker_leaving_mid_run_changes_nothing_in_the_sums() {
    let ids = identities();
    let assets = assets();
    let (coordinator, mut workers) = coordinator_with_thread_workers(&ids, assets.clone(), 2);
    let mut shares = coordinator.shares(split_always()).unwrap();
    let poses = poses(60);
    for (i, pose) in poses.iter().enumerate() {
        if i == 20 {
            workers.pop().unwrap().stop().unwrap();
        }
        let want = sample_all(&**assets.scene_map(), assets.first_shell(), pose);
        assert_eq!(
            shares.compute(pose, Instant::now() + DEADLINE).sums,
            want,
            "frame {i}"
        );
    }
    let report = shares.report();
    assert_eq!(report.peers.len(), 2);
    assert!(report.peers.iter().any(|p| !p.connected), "{report:?}");
    workers.pop().unwrap().stop().unwrap();
}

/// Ends a session with a hand-driven worker: the gatherer and the coordinator go first (the
/// connection closes, so the worker's thread ends), then that thread is joined.
fn end_with_fake<T>(
    shares: vps_cluster::RemoteShares,
    coordinator: vps_cluster::Coordinator,
    worker: std::thread::JoinHandle<T>,
) {
    drop(shares);
    drop(coordinator);
    worker.join().unwrap();
}

/// A coordinator on `assets` with one hand-driven worker joined over real QUIC: the coordinator,
/// the worker and its connection (the coordinator's address is `coordinator.local_addr()`).
fn coordinator_with_one_fake(
    assets: &std::sync::Arc<vps_cluster::ClusterAssets>,
) -> (vps_cluster::Coordinator, FakeWorker, quinn::Connection) {
    let ids = identities();
    let coordinator = start_coordinator(&ids, assets.clone());
    let addr = coordinator.local_addr().unwrap();
    let fake = FakeWorker::new(&ids.worker, &ids.coordinator);
    let conn = fake
        .join(addr, vps_cluster::protocol::PROTOCOL_VERSION)
        .unwrap();
    coordinator
        .wait_for_workers(1, Duration::from_secs(8))
        .unwrap();
    (coordinator, fake, conn)
}

#[test]
fn a_silent_worker_is_sidelined_and_a_recovered_one_gets_work_again() {
    let assets = assets();
    let (coordinator, fake, conn) = coordinator_with_one_fake(&assets);
    let config = GatherConfig {
        sideline_after: 3,
        probe_every: 2,
        reinstate_after: 2,
        ..split_always()
    };
    let mut shares = coordinator.shares(config).unwrap();
    let poses = poses(30);
    // Silent for 6 frames (short deadline: nobody answers anyway).
    assert_exact_frames(&mut shares, &assets, &poses[..6], Duration::from_millis(2));
    assert_eq!(shares.active_workers(), 0, "sidelined after 3 misses");
    // Now answer every request correctly from a thread.
    let answering = answer_slowly(&fake, conn.clone(), assets.clone(), Duration::ZERO);
    assert_exact_frames(&mut shares, &assets, &poses[6..], DEADLINE);
    let report = shares.report();
    let peer = &report.peers[0];
    assert!(peer.sidelined_times >= 1, "{peer:?}");
    assert!(!peer.sidelined, "recovered: {peer:?}");
    assert!(peer.merged > 0, "{peer:?}");
    assert!(peer.lost >= 3, "{peer:?}");
    end_with_fake(shares, coordinator, answering);
}

#[test]
fn garbage_truncated_and_implausible_replies_are_counted_and_recomputed() {
    let assets = assets();
    let (coordinator, fake, conn) = coordinator_with_one_fake(&assets);
    let addr = coordinator.local_addr().unwrap();
    // Raw UDP garbage at the coordinator's socket: counted (0xA5 lacks QUIC's fixed bit, and the
    // short ones are shorter than any QUIC packet), dropped by quinn, nothing panics. Garbage
    // shaped like QUIC (fixed bit set) names no connection of the coordinator: counted apart.
    let udp = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    let garbage = [0usize, 1, 7, 100, 1200, 1500];
    for n in garbage {
        let _ = udp.send_to(&vec![0xA5; n], addr);
    }
    let shaped = quic_shaped_garbage();
    for datagram in &shaped {
        let _ = udp.send_to(datagram, addr);
    }
    let mut shares = coordinator.shares(split_always()).unwrap();
    let frames = 8;
    let misbehave = {
        let (assets, conn) = (assets.clone(), conn.clone());
        let rt = fake.runtime.handle().clone();
        std::thread::spawn(move || {
            rt.block_on(async move {
                let mut buf = [0u8; REPLY_LEN];
                while let Ok(bytes) = conn.read_datagram().await {
                    let req = FrameRequest::decode(&bytes).unwrap();
                    let good = assets.sample_mask(req.job, &req.pose, req.classes);
                    let send = |b: &[u8]| {
                        let _ = conn.send_datagram(bytes::Bytes::copy_from_slice(b));
                    };
                    send(b"garbage");
                    encode_reply(&req, good, &mut buf);
                    send(&buf[..REPLY_LEN - 1]);
                    let mut implausible = good;
                    implausible.sampled += 1;
                    encode_reply(&req, implausible, &mut buf);
                    send(&buf);
                    // Correct sums after the share was rejected: too late, dropped.
                    encode_reply(&req, good, &mut buf);
                    send(&buf);
                }
            })
        })
    };
    assert_exact_frames(&mut shares, &assets, &poses(frames), DEADLINE);
    let report = shares.report();
    let peer = &report.peers[0];
    assert_eq!(peer.merged, 0, "{peer:?}");
    // Per request, "garbage" and the truncated reply fail to decode (counted when they arrive
    // before the session ends); the implausible one is rejected.
    assert!(
        peer.malformed >= 2 && peer.malformed <= 2 * peer.requests,
        "{peer:?}"
    );
    assert!(peer.invalid >= 3, "{peer:?}");
    assert!(peer.sidelined_times >= 1, "{peer:?}");
    assert_eq!(report.udp_not_quic, garbage.len() as u64, "{report:?}");
    assert_eq!(report.udp_foreign, shaped.len() as u64, "{report:?}");
    assert!(
        report.udp_datagrams > report.udp_not_quic + report.udp_foreign,
        "{report:?}"
    );
    end_with_fake(shares, coordinator, misbehave);
}

#[test]
fn a_worker_that_keeps_sending_implausible_sums_is_disconnected() {
    let assets = assets();
    let (coordinator, fake, conn) = coordinator_with_one_fake(&assets);
    const LIMIT: u32 = 6;
    let mut shares = coordinator
        .shares(GatherConfig {
            disconnect_after: LIMIT,
            probe_every: 1,
            ..split_always()
        })
        .unwrap();
    // Every reply, work or probe, claims one point more than it was asked for.
    let liar = {
        let assets = assets.clone();
        reply_with(&fake, conn.clone(), move |req| {
            let mut sums = assets.sample_mask(req.job, &req.pose, req.classes);
            sums.sampled += 1;
            Some(sums)
        })
    };
    // Every frame exact: bad shares are recomputed.
    assert_exact_frames(&mut shares, &assets, &poses(40), DEADLINE);
    let report = shares.report();
    let peer = &report.peers[0];
    assert!(peer.disconnected_for_bad_replies, "{peer:?}");
    assert!(!peer.connected, "{peer:?}");
    assert_eq!(peer.invalid, u64::from(LIMIT), "{peer:?}");
    // After the disconnect nothing more is asked of it.
    assert_eq!(peer.requests, u64::from(LIMIT), "{peer:?}");
    let (replies, closed) = liar.join().unwrap();
    assert_eq!(replies, LIMIT);
    match closed {
        quinn::ConnectionError::ApplicationClosed(close) => {
            assert_eq!(
                close.error_code,
                vps_cluster::shares::CLOSE_BAD_REPLIES.into()
            );
        }
        other => panic!("closed by {other:?}"),
    }
    drop(shares);
    drop(coordinator);
}

/// A worker that answers every request correctly after sleeping `per_class` for each class asked:
/// its round trip grows with its share, as a real worker's does.
fn answer_slowly(
    fake: &FakeWorker,
    conn: quinn::Connection,
    assets: std::sync::Arc<vps_cluster::ClusterAssets>,
    per_class: Duration,
) -> std::thread::JoinHandle<(u32, quinn::ConnectionError)> {
    answer(fake, conn, assets, per_class, usize::MAX)
}

/// Answers the first `count` requests as [`answer_slowly`] does, then reads the rest without
/// answering.
fn answer(
    fake: &FakeWorker,
    conn: quinn::Connection,
    assets: std::sync::Arc<vps_cluster::ClusterAssets>,
    per_class: Duration,
    count: usize,
) -> std::thread::JoinHandle<(u32, quinn::ConnectionError)> {
    let mut answered = 0;
    reply_with(fake, conn, move |req| {
        if answered == count {
            return None;
        }
        answered += 1;
        std::thread::sleep(per_class * req.classes.count_ones());
        Some(assets.sample_mask(req.job, &req.pose, req.classes))
    })
}

/// The reply to `req` carrying `sums`, encoded into `buf`.
fn encode_reply(req: &FrameRequest, sums: vps_haptic::PartialSums, buf: &mut [u8; REPLY_LEN]) {
    FrameReply {
        seq: req.seq,
        classes: req.classes,
        job: req.job,
        sums,
    }
    .encode(buf);
}

/// A fake worker that answers each request with the sums `reply` gives (none: no answer) until
/// its connection closes; returns how many replies it sent and why the connection closed.
fn reply_with(
    fake: &FakeWorker,
    conn: quinn::Connection,
    mut reply: impl FnMut(&FrameRequest) -> Option<vps_haptic::PartialSums> + Send + 'static,
) -> std::thread::JoinHandle<(u32, quinn::ConnectionError)> {
    let rt = fake.runtime.handle().clone();
    std::thread::spawn(move || {
        rt.block_on(async move {
            let mut buf = [0u8; REPLY_LEN];
            let mut replies = 0;
            loop {
                let bytes = match conn.read_datagram().await {
                    Ok(bytes) => bytes,
                    Err(closed) => return (replies, closed),
                };
                let req = FrameRequest::decode(&bytes).unwrap();
                let Some(sums) = reply(&req) else {
                    continue;
                };
                encode_reply(&req, sums, &mut buf);
                let _ = conn.send_datagram(bytes::Bytes::copy_from_slice(&buf));
                replies += 1;
            }
        })
    })
}

/// One fake worker needing 1 ms per class, `frames` frames with a 20 ms reply window, every
/// frame's sums checked against the one-process sums. Returns each frame's recomputed shares and
/// the worker's final report. Never sidelined, so only the share adaptation (when on) can help.
fn run_with_one_slow_worker(
    adaptive_shares: bool,
    frames: usize,
) -> (Vec<u32>, vps_cluster::PeerReport) {
    let assets = assets();
    let (coordinator, fake, conn) = coordinator_with_one_fake(&assets);
    let config = GatherConfig {
        sideline_after: u32::MAX,
        log_every: None,
        adaptive_shares,
        ..split_always()
    };
    let mut shares = coordinator.shares(config).unwrap();
    let slow = answer_slowly(&fake, conn, assets.clone(), Duration::from_millis(1));
    let mut recomputed = Vec::new();
    for (i, pose) in poses(frames).iter().enumerate() {
        let want = sample_all(&**assets.scene_map(), assets.first_shell(), pose);
        let got = shares.compute(pose, Instant::now() + Duration::from_millis(20));
        assert_eq!(got.sums, want, "frame {i}");
        recomputed.push(got.fallback_shares);
        // Let a late reply drain before the next frame, so frames do not queue behind it.
        std::thread::sleep(Duration::from_millis(15));
    }
    let peer = shares.report().peers[0].clone();
    end_with_fake(shares, coordinator, slow);
    (recomputed, peer)
}

#[test]
fn a_slow_worker_is_given_a_smaller_share_and_the_sums_stay_exact() {
    // An equal share (32 of 64 classes) takes 32 ms against a 20 ms window: always late.
    let (recomputed, peer) = run_with_one_slow_worker(true, 60);
    assert!(
        (1..=16).contains(&peer.classes),
        "a worker needing 1 ms per class in a 20 ms window should hold at most 16 classes: {peer:?}"
    );
    let merged_at_the_end = recomputed[40..].iter().filter(|&&r| r == 0).count();
    assert!(
        merged_at_the_end >= 10,
        "after adapting, most of its shares are merged: {merged_at_the_end} of 20; {peer:?}"
    );
}

#[test]
fn equal_shares_keep_a_slow_worker_at_half_the_classes() {
    let (recomputed, peer) = run_with_one_slow_worker(false, 10);
    assert_eq!(peer.classes, 32, "{peer:?}");
    assert!(
        recomputed.iter().all(|&r| r == 1),
        "always late: {recomputed:?}"
    );
}

/// One fake worker that answers only the first request, equal shares (the coordinator samples
/// the even classes, the worker the odd), the given stale policy: frame 0 with a generous deadline
/// (answered and merged), every later frame with a deadline already past (no time to recompute).
/// Returns each frame's result and the final report.
fn frames_after_the_worker_falls_silent(
    assets: &std::sync::Arc<vps_cluster::ClusterAssets>,
    stale: vps_cluster::fallback::StalePolicy,
    poses: &[vps_haptic::KernelPose],
) -> (Vec<vps_runtime::PoolResult>, vps_cluster::ClusterReport) {
    let (coordinator, fake, conn) = coordinator_with_one_fake(assets);
    let config = GatherConfig {
        adaptive_shares: false,
        log_every: None,
        stale,
        ..split_always()
    };
    let mut shares = coordinator.shares(config).unwrap();
    let worker = answer(&fake, conn, assets.clone(), Duration::ZERO, 1);
    let results = poses
        .iter()
        .enumerate()
        .map(|(i, pose)| {
            let deadline = if i == 0 {
                Instant::now() + DEADLINE
            } else {
                Instant::now()
            };
            shares.compute(pose, deadline)
        })
        .collect();
    let report = shares.report();
    end_with_fake(shares, coordinator, worker);
    (results, report)
}

#[test]
fn a_share_that_cannot_be_recomputed_in_time_is_stood_in_for_by_its_last_sums_for_three_frames() {
    let assets = assets();
    let poses = poses(5);
    let (got, report) =
        frames_after_the_worker_falls_silent(&assets, StalePolicy::default(), &poses);
    let (even, odd) = (0x5555_5555_5555_5555u64, 0xAAAA_AAAA_AAAA_AAAAu64);
    // Frame 0: answered in time and merged.
    assert_eq!(
        got[0].sums,
        sample_all(&**assets.scene_map(), assets.first_shell(), &poses[0])
    );
    // Frames 1–3: the odd classes' sums of frame 0 stand in (ages 1, 2, 3).
    for (result, pose) in got[1..4].iter().zip(&poses[1..4]) {
        let mut want = assets.sample_mask(JobTarget::FIRST, pose, even);
        want.merge(&assets.sample_mask(JobTarget::FIRST, &poses[0], odd));
        assert_eq!(result.sums, want);
        assert_eq!(result.fallback_shares, 0, "stood in for, not recomputed");
    }
    // Frame 4: those sums would be 4 frames old, too old: recomputed, exact again.
    assert_eq!(
        got[4].sums,
        sample_all(&**assets.scene_map(), assets.first_shell(), &poses[4])
    );
    assert_eq!(got[4].fallback_shares, 1);
    assert_eq!(
        (report.stale_shares, report.peers[0].stale),
        (3, 3),
        "{report:?}"
    );
    assert_ne!(
        sample_all(&**assets.scene_map(), assets.first_shell(), &poses[0]),
        sample_all(&**assets.scene_map(), assets.first_shell(), &poses[3]),
        "the poses must differ for this test to mean anything"
    );
}

#[test]
fn with_stale_reuse_off_a_late_share_is_always_recomputed() {
    let assets = assets();
    let poses = poses(4);
    let (got, report) = frames_after_the_worker_falls_silent(&assets, StalePolicy::NEVER, &poses);
    for (i, (result, pose)) in got.iter().zip(&poses).enumerate() {
        assert_eq!(
            result.sums,
            sample_all(&**assets.scene_map(), assets.first_shell(), pose),
            "frame {i}"
        );
    }
    assert_eq!(report.stale_shares, 0);
}

#[test]
fn a_zero_disconnect_limit_is_refused_by_name() {
    let assets = assets();
    let ids = identities();
    let coordinator = start_coordinator(&ids, assets);
    let err = coordinator
        .shares(GatherConfig {
            disconnect_after: 0,
            ..split_always()
        })
        .err()
        .expect("refused");
    assert!(err.to_string().contains("disconnect_after"), "{err}");
}
