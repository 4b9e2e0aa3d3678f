//! The pure gather core, frame by frame: no socket, no sleep, no thread. Times are made-up
//! `Instant`s a few microseconds apart.

use std::time::{Duration, Instant};
use vps_cluster::fallback::StalePolicy;
use vps_cluster::gather::{Acceptance, GatherCore, Policy, Shape, SplitDecision, Transition};
use vps_cluster::protocol::FrameReply;
use vps_haptic::PartialSums;

const CLASSES: usize = 16;
const US: Duration = Duration::from_micros(1);

fn policy() -> Policy {
    Policy {
        bench_after: 2,
        probe_every: 2,
        unbench_after: 2,
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
                // Never benched here: the share keeps its classes.
                bench_after: 100,
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
            assert_eq!(plan.stale, [(1, held.sums)]);
            assert_eq!(plan.recompute, 0);
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
fn a_silent_worker_is_benched_probed_and_unbenched() {
    let mut core = core_with(policy(), &[1]);
    let mut t = Instant::now();
    let mut next = |core: &mut GatherCore| {
        t += 1000 * US;
        (frame(core, t), t)
    };
    // Two missed shares (bench_after = 2): benched.
    let (_, t0) = next(&mut core);
    assert_eq!(core.settle(t0 + 100 * US), [(1, Transition::Lost)]);
    let (_, t1) = next(&mut core);
    assert_eq!(
        core.settle(t1 + 100 * US),
        [(1, Transition::Lost), (1, Transition::Benched)]
    );
    // Benched: the coordinator keeps every class; on every probe_every-th frame the worker is
    // asked for one probe class, whose reply is checked but not merged.
    let mut probes = 0;
    let mut unbenched_at = None;
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
        if transitions == [(1, Transition::Unbenched)] {
            unbenched_at = Some(f);
            break;
        }
        assert!(transitions.is_empty(), "{transitions:?}");
    }
    assert_eq!(probes, 2, "unbench_after = 2 probes");
    assert!(unbenched_at.is_some());
    let peer = core.peer(1).unwrap();
    assert!(!peer.benched);
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
    assert!(core.peer(1).unwrap().benched);
    // Probe answered, probe missed, probe answered: still benched (2 in a row needed).
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
    assert!(core.peer(1).unwrap().benched);
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
            bench_after: 0,
            ..policy()
        },
        Policy {
            probe_every: 0,
            ..policy()
        },
        Policy {
            unbench_after: 0,
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

/// A predicting core whose workers have answered one measuring frame with round trips of
/// `base[i]` plus their classes' compute at `per_class`.
fn predicting(per_class: Duration, base: &[Duration]) -> (GatherCore, Instant) {
    let ids: Vec<u32> = (0..base.len() as u32).collect();
    let mut core = core_with(
        Policy {
            predict: true,
            probe_every: 1000,
            ..policy()
        },
        &ids,
    );
    core.set_local_cost(per_class);
    let t0 = Instant::now();
    frame(&mut core, t0);
    assert_eq!(core.decision(), SplitDecision::Measure, "no estimate yet");
    for (id, mask, _) in core.requests().collect::<Vec<_>>() {
        let rtt = base[id as usize] + per_class * mask.count_ones();
        let got = core.accept(id, &reply(1, mask, 0), t0 + rtt);
        assert!(matches!(got, Acceptance::Merged { .. }));
    }
    core.settle(t0 + Duration::from_secs(1));
    for &id in &ids {
        assert_eq!(core.peer(id).unwrap().base_rtt, Some(base[id as usize]));
    }
    (core, t0 + Duration::from_millis(10))
}

#[test]
fn a_small_shell_stays_local_when_the_round_trip_costs_more_than_it_saves() {
    // 16 classes at 1 µs: 16 µs locally, against a 200 µs round trip.
    let (mut core, t) = predicting(US, &[200 * US]);
    let local = frame(&mut core, t);
    assert_eq!(core.decision(), SplitDecision::KeptLocal);
    assert_eq!(local, (1u64 << CLASSES) - 1, "every class local");
    assert_eq!(core.requests().count(), 0, "nothing sent");
    let stats = core.split_stats();
    assert_eq!((stats.kept_local, stats.split, stats.measured), (1, 0, 1));
    assert_eq!(stats.predicted_local_ns, 16_000);
    // Nothing asked is nothing missing: no fallback, no miss, no bench.
    assert!(core.settle(t + 100 * US).is_empty());
    assert_eq!(core.plan_fallback(Duration::ZERO, US).recompute, 0);
}

#[test]
fn a_costly_shell_is_split_when_the_round_trip_is_cheap() {
    // 16 classes at 100 µs: 1.6 ms locally; half of them at a worker with a 50 µs round trip.
    let (mut core, t) = predicting(100 * US, &[50 * US]);
    let local = frame(&mut core, t);
    assert_eq!(core.decision(), SplitDecision::Split);
    let asked = asked(&core, 0);
    assert_eq!(local | asked, (1u64 << CLASSES) - 1);
    assert_eq!((local.count_ones(), asked.count_ones()), (8, 8));
    let stats = core.split_stats();
    assert_eq!(stats.predicted_split_ns, 850_000);
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
    assert_eq!(
        asked(&core, 1),
        0,
        "the slow worker's share is computed locally"
    );
    assert_eq!(local | asked(&core, 0), (1u64 << CLASSES) - 1);
    let stats = core.split_stats();
    assert_eq!(stats.shares_kept_local, 1);
    // Predicted no slower than the coordinator alone: adding the slow worker costs nothing.
    assert!(stats.predicted_split_ns <= stats.predicted_local_ns);
}

#[test]
fn every_probe_every_frames_the_split_is_measured_again() {
    let mut core = core_with(
        Policy {
            predict: true,
            probe_every: 4,
            ..policy()
        },
        &[0],
    );
    core.set_local_cost(US);
    let t0 = Instant::now();
    let mut decisions = Vec::new();
    for f in 0..8u64 {
        let t = t0 + Duration::from_millis(f);
        frame(&mut core, t);
        decisions.push(core.decision());
        for (id, mask, probing) in core.requests().collect::<Vec<_>>() {
            assert!(!probing);
            core.accept(id, &reply(core.seq(), mask, 0), t + 200 * US);
        }
        core.settle(t + 500 * US);
    }
    use SplitDecision::*;
    assert_eq!(
        decisions,
        [Measure, KeptLocal, KeptLocal, Measure, KeptLocal, KeptLocal, KeptLocal, Measure]
    );
    // With the prediction off the plain split is sent every frame.
    let mut plain = core_with(policy(), &[0]);
    frame(&mut plain, t0);
    assert_eq!(plain.decision(), Plain);
    assert_ne!(asked(&plain, 0), 0);
}
