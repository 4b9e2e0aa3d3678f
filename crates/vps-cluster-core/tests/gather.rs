//! The pure gather core, frame by frame: no socket, no sleep, no thread. Times are made-up
//! `Instant`s a few microseconds apart.

use std::time::{Duration, Instant};
use vps_cluster_core::fallback::StalePolicy;
use vps_cluster_core::gather::{
    Acceptance, GatherCore, Policy, Shape, SplitDecision, Transition, FAR_PROBE_FACTOR,
};
use vps_cluster_core::protocol::FrameReply;
use vps_haptic::job::{body_map, JobTarget, SCENE_MAP};
use vps_haptic::PartialSums;

const CLASSES: usize = 16;
const US: Duration = Duration::from_micros(1);

fn policy() -> Policy {
    Policy {
        sideline_after: 2,
        probe_every: 2,
        reinstate_after: 2,
        disconnect_after: 3,
        adaptive_shares: false,
        stale: StalePolicy::default(),
        predict: false,
    }
}

fn core_with(policy: Policy, workers: &[u32]) -> GatherCore {
    let shape = Shape {
        // Class c holds c + 1 points, so a share's point count depends on its classes.
        class_points: (1..=CLASSES as u64).collect(),
        max_depth: 0.01,
        max_radius: 0.05,
    };
    let mut core = GatherCore::new(policy, shape).unwrap();
    for &id in workers {
        core.join(id);
    }
    core
}

fn points(mask: u64) -> u64 {
    (0..CLASSES as u64)
        .filter(|c| mask >> c & 1 == 1)
        .map(|c| c + 1)
        .sum()
}

/// A plausible reply for `classes` in frame `seq`; `tag` makes the sums of different frames
/// differ (free-space points: sampled only).
fn reply(seq: u64, classes: u64, tag: u64) -> FrameReply {
    FrameReply {
        seq,
        classes,
        job: JobTarget::FIRST,
        sums: PartialSums {
            sampled: points(classes),
            non_free: tag.min(points(classes)),
            ..PartialSums::default()
        },
    }
}

fn asked(core: &GatherCore, id: u32) -> u64 {
    core.peer(id).unwrap().asked
}

/// Starts a frame at `t0`: assigns, and marks every request sent at `t0`. Returns the
/// coordinator's mask.
fn frame(core: &mut GatherCore, t0: Instant) -> u64 {
    core.begin_frame();
    let local = core.assign();
    let requests: Vec<u32> = core.requests().map(|r| r.0).collect();
    for id in requests {
        core.sent(id, t0, true);
    }
    local
}

#[test]
fn assignment_covers_every_class_exactly_once() {
    for workers in 0..=5u32 {
        for adaptive in [false, true] {
            let ids: Vec<u32> = (0..workers).collect();
            let mut core = core_with(
                Policy {
                    adaptive_shares: adaptive,
                    ..policy()
                },
                &ids,
            );
            let t0 = Instant::now();
            // Several frames, so adapted weights differ between workers: worker 0 always fast,
            // the others half-way to the deadline.
            for f in 0..6u64 {
                let local = frame(&mut core, t0);
                let mut union = local;
                for (id, mask, probing) in core.requests().collect::<Vec<_>>() {
                    assert!(!probing);
                    assert_eq!(
                        union & mask,
                        0,
                        "class given twice (frame {f}, {workers} workers)"
                    );
                    union |= mask;
                    let at = t0 + if id == 0 { 10 * US } else { 80 * US };
                    let got = core.accept(id, &reply(core.seq(), mask, 0), at);
                    assert!(matches!(got, Acceptance::Merged { .. }), "{got:?}");
                }
                assert_eq!(union, (1u64 << CLASSES) - 1, "every class once");
                assert!(core.settle(t0 + 100 * US).is_empty());
            }
            if adaptive && workers >= 2 {
                assert!(core.peer(0).unwrap().weight > core.peer(1).unwrap().weight);
            }
        }
    }
}

#[test]
fn a_late_workers_share_is_planned_for_local_fallback() {
    let mut core = core_with(policy(), &[7, 9]);
    let t0 = Instant::now();
    let local = frame(&mut core, t0);
    let (a, b) = (asked(&core, 7), asked(&core, 9));
    assert_eq!(local | a | b, (1u64 << CLASSES) - 1);
    assert!(matches!(
        core.accept(7, &reply(1, a, 0), t0 + 20 * US),
        Acceptance::Merged { .. }
    ));
    // Worker 9 never answers by the deadline.
    assert_eq!(core.settle(t0 + 100 * US), [(9, Transition::Lost)]);
    assert_eq!(core.missing().collect::<Vec<_>>(), [(9, b)]);
    let plan = core.plan_fallback(Duration::from_millis(1), US);
    assert_eq!(plan.recompute, b);
    assert_eq!(plan.recomputed, [9]);
    assert!(plan.stale.is_empty());
    // Its reply after the deadline, in the next frame: late, never merged.
    frame(&mut core, t0 + 1000 * US);
    assert_eq!(
        core.accept(9, &reply(1, b, 0), t0 + 1010 * US),
        Acceptance::Late
    );
}

#[test]
fn a_reply_for_an_old_frame_a_duplicate_or_a_wrong_one_is_refused() {
    let mut core = core_with(policy(), &[1]);
    let t0 = Instant::now();
    frame(&mut core, t0);
    let first = asked(&core, 1);
    core.settle(t0 + 100 * US);
    frame(&mut core, t0 + 1000 * US);
    let mask = asked(&core, 1);
    assert_eq!(
        core.accept(1, &reply(1, first, 0), t0 + 1001 * US),
        Acceptance::Late
    );
    assert!(
        !core.peer(1).unwrap().settled,
        "a late reply settles nothing"
    );
    // Wrong classes: settled as missing, counted as a bad reply.
    let mut wrong = reply(2, mask, 0);
    wrong.classes ^= 1;
    assert_eq!(core.accept(1, &wrong, t0 + 1002 * US), Acceptance::Rejected);
    assert_eq!(core.peer(1).unwrap().bad_replies, 1);
    // A good reply after the rejected one is a duplicate.
    assert_eq!(
        core.accept(1, &reply(2, mask, 0), t0 + 1003 * US),
        Acceptance::Unrequested
    );
    // Implausible sums (more points sampled than the share holds) are rejected too.
    frame(&mut core, t0 + 2000 * US);
    let mask = asked(&core, 1);
    let mut implausible = reply(3, mask, 0);
    implausible.sums.sampled += 1;
    assert_eq!(
        core.accept(1, &implausible, t0 + 2001 * US),
        Acceptance::Rejected
    );
    assert_eq!(core.accept(99, &reply(3, mask, 0), t0), Acceptance::Unknown);
}

#[test]
fn stale_stand_ins_follow_the_policy() {
    for (stale, frames_missed, want_stale) in [
        (StalePolicy::default(), 1, true),
        (StalePolicy::NEVER, 1, false),
        // Held sums older than max_age_frames (3) are never used.
        (StalePolicy::default(), 4, false),
    ] {
        let mut core = core_with(
            Policy {
                stale,
                // Never sidelined here: the share keeps its classes.
                sideline_after: 100,
                ..policy()
            },
            &[1],
        );
        let t0 = Instant::now();
        frame(&mut core, t0);
        let mask = asked(&core, 1);
        let held = reply(1, mask, 3);
        assert!(matches!(
            core.accept(1, &held, t0 + 10 * US),
            Acceptance::Merged { .. }
        ));
        core.settle(t0 + 100 * US);
        for f in 0..frames_missed {
            frame(&mut core, t0 + (f + 1) * 1000 * US);
            assert_eq!(asked(&core, 1), mask);
            core.settle(t0 + ((f + 1) * 1000 + 100) * US);
        }
        // No time left and a costly class: recomputing cannot finish before the write.
        let plan = core.plan_fallback(Duration::ZERO, 100 * US);
        if want_stale {
            assert_eq!(plan.stale, [1]);
            assert_eq!(plan.recompute, 0);
            assert_eq!(core.held_sums(1), [held.sums]);
        } else {
            assert!(plan.stale.is_empty(), "{stale:?} {frames_missed}");
            assert_eq!(plan.recompute, mask);
        }
        // With time to spare the share is always recomputed (exact).
        let plan = core.plan_fallback(Duration::from_secs(1), US);
        assert_eq!((plan.recompute, plan.stale.len()), (mask, 0));
    }
}

#[test]
fn a_silent_worker_is_sidelined_probed_and_reinstated() {
    let mut core = core_with(policy(), &[1]);
    let mut t = Instant::now();
    let mut next = |core: &mut GatherCore| {
        t += 1000 * US;
        (frame(core, t), t)
    };
    // Two missed shares (sideline_after = 2): sidelined.
    let (_, t0) = next(&mut core);
    assert_eq!(core.settle(t0 + 100 * US), [(1, Transition::Lost)]);
    let (_, t1) = next(&mut core);
    assert_eq!(
        core.settle(t1 + 100 * US),
        [(1, Transition::Lost), (1, Transition::Sidelined)]
    );
    // Sidelined: the coordinator keeps every class; on every probe_every-th frame the worker is
    // asked for one probe class, whose reply is checked but not merged.
    let mut probes = 0;
    let mut reinstated_at = None;
    for f in 0..8 {
        let (local, tf) = next(&mut core);
        assert_eq!(local, (1u64 << CLASSES) - 1, "frame {f}");
        let request: Vec<_> = core.requests().collect();
        if let [(1, mask, true)] = request[..] {
            assert_eq!(mask.count_ones(), 1);
            probes += 1;
            let got = core.accept(1, &reply(core.seq(), mask, 0), tf + 5 * US);
            assert!(matches!(got, Acceptance::Probe { .. }), "{got:?}");
        } else {
            assert!(request.is_empty(), "{request:?}");
        }
        let transitions = core.settle(tf + 100 * US).to_vec();
        if transitions == [(1, Transition::Reinstated)] {
            reinstated_at = Some(f);
            break;
        }
        assert!(transitions.is_empty(), "{transitions:?}");
    }
    assert_eq!(probes, 2, "reinstate_after = 2 probes");
    assert!(reinstated_at.is_some());
    let peer = core.peer(1).unwrap();
    assert!(!peer.sidelined);
    assert_eq!(peer.weight, 0.5, "back with a cautious share");
    // Given work again.
    let (local, _) = next(&mut core);
    assert_ne!(asked(&core, 1), 0);
    assert_eq!(local & asked(&core, 1), 0);
}

#[test]
fn a_probe_missed_restarts_the_streak() {
    let mut core = core_with(policy(), &[1]);
    let mut t = Instant::now();
    for _ in 0..2 {
        t += 1000 * US;
        frame(&mut core, t);
        core.settle(t + 100 * US);
    }
    assert!(core.peer(1).unwrap().sidelined);
    // Probe answered, probe missed, probe answered: still sidelined (2 in a row needed).
    let mut answered = [true, false, true].into_iter();
    for _ in 0..6 {
        t += 1000 * US;
        frame(&mut core, t);
        let request: Vec<_> = core.requests().collect();
        if let [(1, mask, true)] = request[..] {
            if answered.next().unwrap() {
                core.accept(1, &reply(core.seq(), mask, 0), t + 5 * US);
            }
        }
        assert!(core.settle(t + 100 * US).is_empty());
    }
    assert!(core.peer(1).unwrap().sidelined);
}

#[test]
fn bad_replies_in_a_row_mark_a_worker_for_disconnection_and_a_good_one_resets_them() {
    let mut core = core_with(policy(), &[1, 2]);
    let t0 = Instant::now();
    frame(&mut core, t0);
    assert!(core.malformed(1) && core.malformed(1));
    assert!(!core.malformed(42));
    let mask = asked(&core, 1);
    // A valid reply resets the count.
    core.accept(1, &reply(1, mask, 0), t0 + US);
    assert!(core.malformed(1) && core.malformed(1));
    for _ in 0..3 {
        core.malformed(2);
    }
    let mut gone = Vec::new();
    core.take_misbehaving(&mut gone);
    assert_eq!(gone, [(2, 3)]);
    assert!(core.peer(2).is_none() && core.peer(1).is_some());
}

#[test]
fn a_failed_send_is_missing_at_once_and_membership_keeps_join_order() {
    let mut core = core_with(policy(), &[5, 3]);
    assert_eq!(
        core.peers().iter().map(|p| p.id).collect::<Vec<_>>(),
        [3, 5]
    );
    let t0 = Instant::now();
    core.begin_frame();
    core.assign();
    core.sent(3, t0, false);
    core.sent(5, t0, true);
    let mask = asked(&core, 3);
    assert_eq!(
        core.accept(3, &reply(1, mask, 0), t0 + US),
        Acceptance::Unrequested
    );
    // Settled by the failed send: missing, but not "lost".
    assert_eq!(core.settle(t0 + 100 * US), [(5, Transition::Lost)]);
    assert_eq!(core.missing().count(), 2);
    assert!(core.leave(3) && !core.leave(3));
    core.begin_frame();
    assert_eq!(core.assign() | asked(&core, 5), (1u64 << CLASSES) - 1);
}

#[test]
fn a_zero_count_in_the_policy_is_refused() {
    let shape = Shape {
        class_points: vec![1; 4],
        max_depth: 0.01,
        max_radius: 0.05,
    };
    for bad in [
        Policy {
            sideline_after: 0,
            ..policy()
        },
        Policy {
            probe_every: 0,
            ..policy()
        },
        Policy {
            reinstate_after: 0,
            ..policy()
        },
        Policy {
            disconnect_after: 0,
            ..policy()
        },
    ] {
        assert!(GatherCore::new(bad, shape.clone()).is_err());
    }
    let none = Shape {
        class_points: vec![],
        ..shape
    };
    assert!(GatherCore::new(policy(), none).is_err());
}

fn predictor(probe_every: u64, workers: &[u32]) -> GatherCore {
    core_with(
        Policy {
            predict: true,
            probe_every,
            ..policy()
        },
        workers,
    )
}

/// The coordinator's sums of a probe class (the reply a correct worker sends).
fn own_sums(core: &GatherCore, mask: u64) -> PartialSums {
    reply(core.seq(), mask, 0).sums
}

/// A predicting core whose workers have each answered one unawaited probe with a round trip of
/// `base[i]` plus one class's compute at `per_class`, booked at the next frame's settle. Returns
/// the core and a time 10 ms later.
fn predicting(per_class: Duration, base: &[Duration]) -> (GatherCore, Instant) {
    let ids: Vec<u32> = (0..base.len() as u32).collect();
    let mut core = predictor(1000, &ids);
    core.set_local_cost(per_class);
    let t0 = Instant::now();
    let local = frame(&mut core, t0);
    assert_eq!(core.decision(), SplitDecision::KeptLocal, "no estimate yet");
    assert_eq!(local, (1u64 << CLASSES) - 1, "every class local");
    let probe = core.probe_classes();
    assert_eq!(probe.count_ones(), 1);
    assert_eq!(
        local & probe,
        probe,
        "the probe class is one the coordinator computes"
    );
    core.set_probe_result(&own_sums(&core, probe));
    let requests: Vec<_> = core.requests().collect();
    assert_eq!(requests.len(), ids.len());
    for &(_, mask, probing) in &requests {
        assert!(probing);
        assert_eq!(mask, probe);
    }
    // Nothing awaited, nothing missing: the frame ends at once.
    assert!(core.settle(t0 + 400 * US).is_empty());
    assert_eq!(core.missing().count(), 0);
    // The replies arrive after the frame; the next frame takes them and books them at its settle.
    let t1 = t0 + Duration::from_millis(1);
    core.begin_frame();
    for &(id, mask, _) in &requests {
        let rtt = base[id as usize] + per_class;
        let got = core.accept(id, &reply(1, mask, 0), t0 + rtt);
        assert_eq!(got, Acceptance::Probed { rtt: Some(rtt) });
        assert!(!got.settles(), "an unawaited probe is not waited for");
        assert_eq!(
            core.peer(id).unwrap().base_rtt,
            None,
            "booked at the settle"
        );
    }
    core.assign();
    core.settle(t1 + 400 * US);
    for &id in &ids {
        let peer = core.peer(id).unwrap();
        assert_eq!(peer.base_rtt, Some(base[id as usize]));
        assert_eq!(
            peer.predicted_base(),
            Some(3 * base[id as usize]),
            "srtt + 4 · srtt/2"
        );
        assert!(peer.probe.is_none());
    }
    assert_eq!(core.split_stats().probe_replies, ids.len() as u64);
    (core, t0 + Duration::from_millis(10))
}

#[test]
fn a_small_shell_stays_local_when_the_round_trip_costs_more_than_it_saves() {
    // 16 classes at 1 µs: 16 µs locally, against a 200 µs round trip.
    let (mut core, t) = predicting(US, &[200 * US]);
    let local = frame(&mut core, t);
    assert_eq!(core.decision(), SplitDecision::KeptLocal);
    assert_eq!(local, (1u64 << CLASSES) - 1, "every class local");
    assert!(
        core.requests().all(|r| r.2),
        "nothing but probes sent: {:?}",
        core.requests().collect::<Vec<_>>()
    );
    let stats = core.split_stats();
    assert_eq!((stats.kept_local_frames, stats.split_frames), (3, 0));
    assert_eq!(stats.predicted_local_ns, 16_000);
    assert_eq!(stats.worker_base_ns, 600_000);
    // Nothing asked is nothing missing: no fallback, no miss, no sidelining.
    assert!(core.settle(t + 100 * US).is_empty());
    assert_eq!(core.plan_fallback(Duration::ZERO, US).recompute, 0);
}

#[test]
fn a_costly_shell_is_split_when_the_round_trip_is_cheap() {
    // 16 classes at 100 µs: 1.6 ms locally; half of them at a worker whose round trip is
    // predicted at 150 µs (50 µs, pessimistically tripled after one sample).
    let (mut core, t) = predicting(100 * US, &[50 * US]);
    let local = frame(&mut core, t);
    assert_eq!(core.decision(), SplitDecision::Split);
    let asked = asked(&core, 0);
    assert!(!core.peer(0).unwrap().probing, "a work share, awaited");
    assert!(core.sent(0, t, true));
    assert_eq!(core.probe_classes(), 0, "no probe: the worker has a share");
    assert_eq!(local | asked, (1u64 << CLASSES) - 1);
    assert_eq!((local.count_ones(), asked.count_ones()), (8, 8));
    let stats = core.split_stats();
    assert_eq!(stats.predicted_split_ns, 950_000);
    assert_eq!(stats.predicted_local_ns, 1_600_000);
    assert!(stats.predicted_split_ns < stats.predicted_local_ns);
}

#[test]
fn a_slow_workers_share_is_kept_local_while_a_fast_one_still_gets_work() {
    // 16 classes at 100 µs, three parties: ~5 classes each. Worker 0's round trip costs 50 µs,
    // worker 1's 5 ms (more than computing everything locally).
    let (mut core, t) = predicting(100 * US, &[50 * US, 5000 * US]);
    let local = frame(&mut core, t);
    assert_eq!(core.decision(), SplitDecision::Split);
    assert_ne!(asked(&core, 0), 0, "the fast worker keeps its share");
    assert!(!core.peer(0).unwrap().probing);
    let slow = core.peer(1).unwrap();
    assert!(
        slow.asked == 0 || slow.probing,
        "the slow worker's share is computed locally (at most a probe goes out)"
    );
    assert_eq!(local | asked(&core, 0), (1u64 << CLASSES) - 1);
    let stats = core.split_stats();
    assert_eq!(
        stats.shares_kept_local, 5,
        "two kept-local frames of two shares, then one"
    );
    // Predicted no slower than the coordinator alone: adding the slow worker costs nothing.
    assert!(stats.predicted_split_ns <= stats.predicted_local_ns);
}

#[test]
fn the_predicted_split_is_never_slower_than_the_coordinator_alone() {
    for per_class in [US, 10 * US, 100 * US] {
        for fast in [0, 10, 100, 1000, 10_000u32] {
            for slow in [0, 50, 500, 5000u32] {
                let base = [fast * US, slow * US, (fast + slow) * US];
                let (mut core, t) = predicting(per_class, &base);
                let local = frame(&mut core, t);
                let stats = core.split_stats();
                assert!(
                    stats.predicted_split_ns <= stats.predicted_local_ns,
                    "{per_class:?} {base:?}: {stats:?}"
                );
                let work = core.requests().filter(|r| !r.2).fold(0, |u, r| u | r.1);
                assert_eq!(local & work, 0);
                assert_eq!(local | work, (1u64 << CLASSES) - 1, "every class once");
            }
        }
    }
}

/// One predicting frame at `t` with worker 0: its open probe, if any, is answered correctly at
/// `answered` (taken at the frame's start, as the driver drains its queue); then the assignment,
/// each probe's local sums, and every request sent (a probe never awaited, a share awaited).
/// Returns the requests; the caller settles.
fn probed_frame(core: &mut GatherCore, t: Instant, answered: Instant) -> Vec<(u32, u64, bool)> {
    core.begin_frame();
    if let Some(probe) = core.peer(0).unwrap().probe {
        let got = core.accept(0, &reply(probe.seq, probe.classes, 0), answered);
        assert!(
            matches!(got, Acceptance::Probed { rtt: Some(_) }),
            "{got:?}"
        );
    }
    core.assign();
    let requests: Vec<_> = core.requests().collect();
    for &(id, mask, probing) in &requests {
        if probing {
            core.set_probe_result(&own_sums(core, mask));
        }
        assert_eq!(
            core.sent(id, t, true),
            !probing,
            "only work shares are awaited"
        );
    }
    requests
}

#[test]
fn unawaited_probes_go_every_probe_every_frames_one_at_a_time_and_never_make_a_frame_wait() {
    // 16 classes at 10 µs (160 µs locally); the worker's round trip costs 40 µs more than its
    // one class: close enough to be worth measuring, not yet worth a share (8 classes).
    let mut core = predictor(4, &[0]);
    core.set_local_cost(10 * US);
    let t0 = Instant::now();
    let mut probed = Vec::new();
    for f in 1..=12u64 {
        let t = t0 + Duration::from_millis(f);
        // The previous frame's probe, answered 50 µs after it left.
        let requests = probed_frame(&mut core, t, t - 950 * US);
        assert_eq!(core.decision(), SplitDecision::KeptLocal);
        for &(_, _, probing) in &requests {
            assert!(probing);
            probed.push(f);
        }
        assert!(core.settle(t + 400 * US).is_empty());
        assert_eq!(core.missing().count(), 0);
    }
    // Frame 1: no estimate, at once; then every 4th frame.
    assert_eq!(probed, [1, 5, 9]);
    let stats = core.split_stats();
    assert_eq!(
        (stats.probes, stats.probe_replies, stats.probes_failed),
        (3, 3, 0)
    );
    assert_eq!(core.peer(0).unwrap().base_rtt, Some(40 * US));
    assert!(core.peer(0).unwrap().predicted_base().unwrap() < 160 * US);
    // At 1 µs a class (16 µs locally) the same worker can never shorten a frame: probed
    // FAR_PROBE_FACTOR times less often.
    let mut far = predictor(4, &[0]);
    far.set_local_cost(US);
    let mut probed = Vec::new();
    for f in 1..=60u64 {
        let t = t0 + Duration::from_millis(f);
        if !probed_frame(&mut far, t, t - 950 * US).is_empty() {
            probed.push(f);
        }
        far.settle(t + 400 * US);
    }
    assert_eq!(probed, [1, 1 + 4 * FAR_PROBE_FACTOR]);
    // With the prediction off the plain split is sent every frame.
    let mut plain = core_with(policy(), &[0]);
    frame(&mut plain, t0);
    assert_eq!(plain.decision(), SplitDecision::Plain);
    assert_ne!(asked(&plain, 0), 0);
    assert!(plain.sent(0, t0, true), "a work share is awaited");
}

#[test]
fn a_wrong_probe_reply_is_a_bad_reply_and_books_nothing() {
    let mut core = predictor(4, &[3]);
    core.set_local_cost(US);
    let t0 = Instant::now();
    frame(&mut core, t0);
    let probe = core.probe_classes();
    core.set_probe_result(&own_sums(&core, probe));
    core.settle(t0 + 400 * US);
    core.begin_frame();
    // Plausible, but not the coordinator's sums for the class.
    let got = core.accept(3, &reply(1, probe, 1), t0 + 100 * US);
    assert_eq!(got, Acceptance::Probed { rtt: None });
    assert_eq!(core.peer(3).unwrap().bad_replies, 1);
    // A second reply to the same probe is a duplicate.
    let again = core.accept(3, &reply(1, probe, 0), t0 + 110 * US);
    assert_eq!(again, Acceptance::Unrequested);
    core.assign();
    core.settle(t0 + 1400 * US);
    let peer = core.peer(3).unwrap();
    assert_eq!(peer.base_rtt, None);
    assert_eq!(core.split_stats().probes_failed, 1);
    // A reply for a frame it was not probed in is late.
    assert_eq!(
        core.accept(3, &reply(1, probe, 0), t0 + 1500 * US),
        Acceptance::Late
    );
}

#[test]
fn an_unanswered_probe_is_booked_as_its_frames_reply_window_after_probe_every_frames() {
    let mut core = predictor(3, &[5]);
    core.set_local_cost(US);
    let t0 = Instant::now();
    for f in 0..3u64 {
        let t = t0 + Duration::from_millis(f);
        frame(&mut core, t);
        assert_eq!(
            core.requests().count(),
            usize::from(f == 0),
            "one outstanding"
        );
        core.settle(t + 400 * US);
        assert_eq!(core.peer(5).unwrap().base_rtt, None);
    }
    // Frame 4's settle: 3 frames without an answer. The probe left at t0 and waited 3.4 ms,
    // but no frame waits longer than its 400 µs window: that is what it costs.
    let t = t0 + Duration::from_millis(3);
    core.begin_frame();
    core.assign();
    core.settle(t + 400 * US);
    assert_eq!(core.peer(5).unwrap().base_rtt, Some(400 * US));
    assert_eq!(core.split_stats().probes_failed, 1);
    assert!(core.peer(5).unwrap().probe.is_none());
}

#[test]
fn a_sidelined_worker_is_reinstated_by_timely_unawaited_probes() {
    // A costly shell (16 classes at 100 µs) and a worker whose probes come back in 100 µs, but
    // whose work shares never do: measured, split, sidelined after 2 misses, then back after 2
    // timely probes. No frame waits for a probe.
    let mut core = predictor(2, &[0]);
    core.set_local_cost(100 * US);
    let mut t = Instant::now();
    let mut transitions = Vec::new();
    for _ in 0..12 {
        probed_frame(&mut core, t, t - 900 * US);
        transitions.extend(core.settle(t + 400 * US).iter().map(|x| x.1));
        t += Duration::from_millis(1);
    }
    assert_eq!(
        transitions[..3],
        [Transition::Lost, Transition::Lost, Transition::Sidelined],
        "{transitions:?}"
    );
    assert_eq!(transitions[3], Transition::Reinstated, "{transitions:?}");
    assert!(core.split_stats().split_frames >= 2);
}

#[test]
fn a_worker_costs_at_most_the_reply_window_in_the_prediction() {
    // 16 classes at 100 µs (1.6 ms locally), one worker measured at 5 ms: uncapped, the split
    // would be predicted at 15.8 ms; but no frame waits more than its 400 µs window for it, and
    // its share is then recomputed, so the split is predicted at 400 + 800 µs.
    let (mut core, t) = predicting(100 * US, &[5000 * US]);
    core.set_reply_window(400 * US);
    frame(&mut core, t);
    assert_eq!(core.decision(), SplitDecision::Split);
    let stats = core.split_stats();
    assert_eq!(stats.worker_base_ns, 400_000);
    assert_eq!(stats.predicted_split_ns, 1_200_000);
    // On a small shell (1 µs a class) the same worker is never worth its window.
    let (mut small, t) = predicting(US, &[5000 * US]);
    small.set_reply_window(400 * US);
    frame(&mut small, t);
    assert_eq!(small.decision(), SplitDecision::KeptLocal);
}

/// A core with one worker whose frames hold three jobs: the first part in the scene, the second
/// part in the scene, and the first part's shell in the second part's body voxmap, whose shell
/// has twice the points per class.
fn three_jobs() -> (GatherCore, [JobTarget; 3]) {
    let mut core = core_with(
        Policy {
            sideline_after: 100,
            ..policy()
        },
        &[1],
    );
    let second = JobTarget {
        shell: 1,
        map: SCENE_MAP,
    };
    let pair = JobTarget {
        shell: 0,
        map: body_map(1),
    };
    let doubled = Shape {
        class_points: (1..=CLASSES as u64).map(|p| 2 * p).collect(),
        max_depth: 0.01,
        max_radius: 0.05,
    };
    core.add_target(second, doubled.clone()).unwrap();
    core.add_target(pair, doubled).unwrap();
    let jobs = [JobTarget::FIRST, second, pair];
    core.set_jobs(&jobs).unwrap();
    (core, jobs)
}

/// The reply to `job` of a share: `points` sampled (free space).
fn job_reply(seq: u64, classes: u64, job: JobTarget, points: u64) -> FrameReply {
    FrameReply {
        job,
        sums: PartialSums {
            sampled: points,
            ..PartialSums::default()
        },
        ..reply(seq, classes, 0)
    }
}

#[test]
fn a_share_of_several_jobs_is_merged_when_its_last_job_is_in_each_checked_by_its_own_shape() {
    let (mut core, [first, second, pair]) = three_jobs();
    let t0 = Instant::now();
    frame(&mut core, t0);
    let mask = asked(&core, 1);
    assert_eq!(core.jobs_asked(1), 3);
    let n = points(mask);
    // Job by job, in any order: partial until the last.
    assert_eq!(
        core.accept(1, &job_reply(1, mask, pair, 2 * n), t0 + 5 * US),
        Acceptance::Partial
    );
    assert_eq!(
        core.accept(1, &job_reply(1, mask, pair, 2 * n), t0 + 6 * US),
        Acceptance::Unrequested,
        "a duplicate job"
    );
    assert_eq!(
        core.accept(1, &job_reply(1, mask, first, n), t0 + 7 * US),
        Acceptance::Partial
    );
    assert_eq!(
        core.accept(1, &job_reply(1, mask, second, 2 * n), t0 + 9 * US),
        Acceptance::Merged { rtt: 9 * US }
    );
    let sampled: Vec<u64> = core.merged_sums(1).iter().map(|s| s.sampled).collect();
    assert_eq!(
        sampled,
        [n, 2 * n, 2 * n],
        "one sum per job, in the frame's order"
    );
    core.settle(t0 + 100 * US);

    // The second job's share counted with the first shell's points is implausible: rejected,
    // the share settled as missing; so is a reply for a job the frame does not hold.
    frame(&mut core, t0 + 1000 * US);
    let mask = asked(&core, 1);
    let n = points(mask);
    assert_eq!(
        core.accept(1, &job_reply(2, mask, second, 2 * n + 1), t0 + 1005 * US),
        Acceptance::Rejected
    );
    assert_eq!(
        core.accept(1, &job_reply(2, mask, first, n), t0 + 1006 * US),
        Acceptance::Unrequested
    );
    core.settle(t0 + 1100 * US);
    assert_eq!(core.missing().count(), 1);
    frame(&mut core, t0 + 2000 * US);
    let stranger = JobTarget { shell: 5, map: 0 };
    assert_eq!(
        core.accept(
            1,
            &job_reply(3, asked(&core, 1), stranger, 0),
            t0 + 2005 * US
        ),
        Acceptance::Rejected
    );
}

#[test]
fn held_sums_stand_in_only_for_a_frame_of_the_same_jobs() {
    let (mut core, jobs) = three_jobs();
    let t0 = Instant::now();
    frame(&mut core, t0);
    let mask = asked(&core, 1);
    let n = points(mask);
    for (job, points) in jobs.iter().zip([n, 2 * n, 2 * n]) {
        core.accept(1, &job_reply(1, mask, *job, points), t0 + 5 * US);
    }
    core.settle(t0 + 100 * US);
    // Frame 2, same jobs, no reply, no time: the held sums stand in, one per job.
    frame(&mut core, t0 + 1000 * US);
    core.settle(t0 + 1100 * US);
    let plan = core.plan_fallback(Duration::ZERO, 100 * US);
    assert_eq!(plan.stale, [1]);
    assert_eq!(core.held_sums(1).len(), 3);
    // Frame 3: the pair left the broad phase; the held sums are of other jobs: recomputed.
    core.begin_frame();
    core.set_jobs(&jobs[..2]).unwrap();
    core.assign();
    core.sent(1, t0 + 2000 * US, true);
    core.settle(t0 + 2100 * US);
    let plan = core.plan_fallback(Duration::ZERO, 100 * US);
    assert!(plan.stale.is_empty());
    assert_eq!(plan.recompute, mask);
}

#[test]
fn the_frames_jobs_must_be_known_distinct_and_start_with_the_first_part() {
    let (mut core, [first, second, pair]) = three_jobs();
    let unknown = JobTarget {
        shell: 2,
        map: SCENE_MAP,
    };
    for bad in [
        &[][..],
        &[second, first][..],
        &[first, second, second][..],
        &[first, unknown][..],
        &[first; 65][..],
    ] {
        let err = core.set_jobs(bad).unwrap_err();
        assert_eq!(err.field, "jobs", "{bad:?}");
    }
    assert_eq!(core.jobs(), [first, second, pair], "unchanged by a refusal");
    let wrong_classes = Shape {
        class_points: vec![1; CLASSES + 1],
        max_depth: 0.01,
        max_radius: 0.05,
    };
    assert_eq!(
        core.add_target(unknown, wrong_classes).unwrap_err().field,
        "class_count"
    );
}

/// A frame driven by the four events alone: the plan and the requests, the own share, one good
/// reply and one undecodable datagram, a late reply, and the outcome at the deadline.
#[test]
fn a_frame_runs_on_the_four_events() {
    use vps_cluster_core::frame::{FrameStart, Handled, Request};
    use vps_cluster_core::protocol::REPLY_LEN;
    let mut core = core_with(policy(), &[1, 2]);
    let t0 = Instant::now();
    let stranger = JobTarget { shell: 3, map: 0 };
    let bad = core.start_frame(FrameStart {
        jobs: &[JobTarget::FIRST, stranger],
        reply_window: 400 * US,
    });
    assert_eq!(bad.unwrap_err().field, "jobs");
    assert_eq!(core.seq(), 0, "a refused frame decides nothing");
    let plan = core
        .start_frame(FrameStart {
            jobs: &[JobTarget::FIRST],
            reply_window: 400 * US,
        })
        .unwrap();
    assert_eq!((plan.seq, plan.probe), (1, 0));
    let requests: Vec<Request> = core.frame_requests().collect();
    assert_eq!(requests.len(), 2);
    let all = requests.iter().fold(plan.local, |m, r| {
        assert_eq!(m & r.classes, 0, "each class once");
        m | r.classes
    });
    assert_eq!(all, (1 << CLASSES) - 1);
    for r in &requests {
        assert_eq!(r.jobs, 1);
        assert!(core.sent(r.peer, t0, true));
    }
    let cost = core.local_done(plan.local.count_ones(), 30 * US, None);
    assert_eq!(cost, 30 * US / plan.local.count_ones());
    let mut good = [0u8; REPLY_LEN];
    reply(1, requests[0].classes, 0).encode(&mut good);
    assert_eq!(
        core.handle_datagram(1, &good, t0 + 50 * US),
        Handled::Judged(Acceptance::Merged { rtt: 50 * US })
    );
    assert_eq!(core.merged_sums(1)[0].sampled, points(requests[0].classes));
    assert!(matches!(
        core.handle_datagram(2, b"garbage", t0 + 60 * US),
        Handled::Malformed { known: true, .. }
    ));
    assert!(matches!(
        core.handle_datagram(9, b"garbage", t0 + 60 * US),
        Handled::Malformed { known: false, .. }
    ));
    let outcome = core.finish(t0 + 400 * US, Duration::from_secs(1));
    assert_eq!(outcome.transitions, [(2, Transition::Lost)]);
    assert_eq!(outcome.fallback.recompute, requests[1].classes);
    assert_eq!(outcome.fallback.recomputed, [2]);
    // Worker 2's answer after the deadline: late, never merged, not a bad reply.
    let mut late = [0u8; REPLY_LEN];
    reply(1, requests[1].classes, 0).encode(&mut late);
    assert_eq!(
        core.handle_late_datagram(2, &late, t0 + 500 * US),
        Acceptance::Late
    );
    assert_eq!(
        core.handle_late_datagram(9, &late, t0 + 500 * US),
        Acceptance::Unknown
    );
}
