//! How a frame's classes are split between the coordinator and its workers, and how each worker's
//! share adapts to how fast it answers. Pure functions over numbers: no clocks, no sockets.
//!
//! Each party has a *weight*; the coordinator's is 1 (its own threads), a worker's starts at 1 and
//! follows its replies, additive increase and multiplicative decrease as TCP does for its window:
//! a reply merged with room to spare before the deadline raises the weight by
//! [`Adapt::increase`]; one merged close to the deadline lowers it gently; a share that missed the
//! deadline (late, lost or rejected) halves it. A worker that is slower than the coordinator (a
//! busy host, a long network path) thus settles on a share it can return in time instead of
//! missing every other frame and being recomputed late on the frame thread; a faster one is given
//! more than an equal share. Sums combine exactly in any grouping, so the split never changes the
//! wrench, only who computes what.

use std::time::Duration;

/// The adaptation constants. All weights are relative to the coordinator's 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Adapt {
    /// A merged reply whose round trip took less than this fraction of the time the worker had
    /// (request sent to deadline) raises the weight.
    pub fast_fraction: f64,
    /// A merged reply above this fraction lowers the weight by `gentle_decrease`.
    pub slow_fraction: f64,
    /// Added to the weight after a fast reply.
    pub increase: f64,
    /// Factor applied after a slow (but merged) reply.
    pub gentle_decrease: f64,
    /// Factor applied after a missed share.
    pub miss_decrease: f64,
    /// Smallest weight: however often a worker misses, its weight is never halved below this.
    pub min_weight: f64,
    /// Largest weight a worker can reach (the coordinator's is 1).
    pub max_weight: f64,
}

impl Default for Adapt {
    fn default() -> Self {
        Adapt {
            fast_fraction: 0.7,
            slow_fraction: 0.85,
            increase: 0.05,
            gentle_decrease: 0.95,
            miss_decrease: 0.5,
            min_weight: 0.05,
            max_weight: 8.0,
        }
    }
}

/// What became of a worker's share this frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShareOutcome {
    /// Merged in time.
    Merged {
        /// The share's round trip: request sent to reply received (s).
        rtt: Duration,
        /// The time the worker had: request sent to the reply deadline (s).
        window: Duration,
    },
    /// Not merged: late, lost or rejected.
    Missed,
}

impl Adapt {
    /// The weight after `outcome`, within `[min_weight, max_weight]`. A non-finite weight (never
    /// produced here) is reset to 1.
    pub fn next_weight(&self, weight: f64, outcome: ShareOutcome) -> f64 {
        let weight = if weight.is_finite() { weight } else { 1.0 };
        let next = match outcome {
            ShareOutcome::Missed => weight * self.miss_decrease,
            ShareOutcome::Merged { rtt, window } => {
                let used = rtt.as_secs_f64() / window.as_secs_f64().max(1e-9);
                if used < self.fast_fraction {
                    weight + self.increase
                } else if used > self.slow_fraction {
                    weight * self.gentle_decrease
                } else {
                    weight
                }
            }
        };
        next.clamp(self.min_weight, self.max_weight)
    }
}

/// Splits classes `0..class_count` (at most 64) between parties with these weights (party 0 is
/// the coordinator; weights must be finite and positive, others count as the minimum). Returns one
/// class mask per party: disjoint, together every class. Each party's count is its weight's share
/// of `class_count` rounded by largest remainder, except that every worker (party ≥ 1) gets at
/// least one class while classes last, so its speed keeps being measured. Classes are dealt round
/// robin among the parties with quota left, so equal weights give class `c` to party
/// `c mod parties`, and each party's classes are spread over the shell (a class is itself a
/// cyclic subset of the points). Deterministic; allocates the result only.
pub fn split_classes(class_count: u32, weights: &[f64]) -> Vec<u64> {
    let class_count = class_count.min(64) as usize;
    let parties = weights.len();
    let mut masks = vec![0u64; parties];
    if parties == 0 || class_count == 0 {
        return masks;
    }
    let clean: Vec<f64> = weights
        .iter()
        .map(|&w| if w.is_finite() && w > 0.0 { w } else { 1e-6 })
        .collect();
    let total: f64 = clean.iter().sum();
    let exact: Vec<f64> = clean
        .iter()
        .map(|w| w / total * class_count as f64)
        .collect();
    let mut quota: Vec<usize> = exact.iter().map(|e| e.floor() as usize).collect();
    // Largest remainders first (ties to the lower party index) until every class has a party.
    let mut order: Vec<usize> = (0..parties).collect();
    order.sort_by(|&a, &b| {
        let (ra, rb) = (exact[a] - exact[a].floor(), exact[b] - exact[b].floor());
        rb.total_cmp(&ra).then(a.cmp(&b))
    });
    // The floors add up to at most `class_count` and leave fewer than `parties` classes over
    // (cycling only guards against rounding): afterwards the quotas add up to `class_count`
    // exactly, which the dealing below relies on.
    let left = class_count.saturating_sub(quota.iter().sum::<usize>());
    for &p in order.iter().cycle().take(left) {
        quota[p] += 1;
    }
    // Every worker at least one class, taken from the party with the largest quota.
    for p in 1..parties {
        if quota[p] == 0 {
            let (richest, &most) = quota
                .iter()
                .enumerate()
                .max_by(|a, b| a.1.cmp(b.1).then(b.0.cmp(&a.0)))
                .expect("parties is not empty");
            if most <= 1 {
                break;
            }
            quota[richest] -= 1;
            quota[p] = 1;
        }
    }
    let mut party = 0;
    for class in 0..class_count {
        while quota[party] == 0 {
            party = (party + 1) % parties;
        }
        masks[party] |= 1 << class;
        quota[party] -= 1;
        party = (party + 1) % parties;
    }
    masks
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn equal_weights_deal_classes_cyclically() {
        for parties in 1..=5usize {
            let masks = split_classes(64, &vec![1.0; parties]);
            for class in 0..64 {
                assert_ne!(
                    masks[class % parties] & (1 << class),
                    0,
                    "{parties} {class}"
                );
            }
        }
    }

    #[test]
    fn a_slow_worker_gets_fewer_classes_and_a_fast_one_more() {
        let masks = split_classes(64, &[1.0, 0.25, 3.0]);
        let counts: Vec<u32> = masks.iter().map(|m| m.count_ones()).collect();
        assert_eq!(counts, [15, 4, 45]);
    }

    #[test]
    fn every_worker_keeps_one_class_while_there_are_classes() {
        let masks = split_classes(64, &[1.0, 0.0001, 0.0001]);
        let counts: Vec<u32> = masks.iter().map(|m| m.count_ones()).collect();
        assert_eq!(counts, [62, 1, 1]);
        // Fewer classes than parties: the coordinator keeps what it has when it has one.
        let masks = split_classes(2, &[1.0, 1.0, 1.0]);
        assert_eq!(masks.iter().map(|m| m.count_ones()).sum::<u32>(), 2);
    }

    #[test]
    fn weights_adapt_up_when_fast_and_halve_on_a_miss() {
        let a = Adapt::default();
        let window = Duration::from_micros(400);
        let fast = ShareOutcome::Merged {
            rtt: Duration::from_micros(100),
            window,
        };
        let slow = ShareOutcome::Merged {
            rtt: Duration::from_micros(390),
            window,
        };
        let ok = ShareOutcome::Merged {
            rtt: Duration::from_micros(300),
            window,
        };
        assert_eq!(a.next_weight(1.0, fast), 1.05);
        assert_eq!(a.next_weight(1.0, ok), 1.0);
        assert_eq!(a.next_weight(1.0, slow), 0.95);
        assert_eq!(a.next_weight(1.0, ShareOutcome::Missed), 0.5);
        assert_eq!(
            a.next_weight(a.min_weight, ShareOutcome::Missed),
            a.min_weight
        );
        assert_eq!(a.next_weight(a.max_weight, fast), a.max_weight);
        assert_eq!(a.next_weight(f64::NAN, ok), 1.0);
        // A zero window (deadline already past when sent) counts as slow, never as a division
        // by zero.
        let none = ShareOutcome::Merged {
            rtt: Duration::from_micros(1),
            window: Duration::ZERO,
        };
        assert_eq!(a.next_weight(1.0, none), 0.95);
    }

    proptest! {
        #[test]
        fn the_split_is_a_partition_close_to_the_weights(
            class_count in 0u32..=64,
            weights in prop::collection::vec(prop_oneof![0.0..10.0f64, Just(f64::NAN), Just(-1.0)], 1..6),
        ) {
            let masks = split_classes(class_count, &weights);
            prop_assert_eq!(masks.len(), weights.len());
            let mut union = 0u64;
            for m in &masks {
                prop_assert_eq!(union & m, 0, "disjoint");
                union |= m;
            }
            let all = if class_count == 64 { u64::MAX } else { (1u64 << class_count) - 1 };
            prop_assert_eq!(union, all, "every class once");
            // Each count within one class of its exact share, plus the workers' minimum of one.
            let clean: Vec<f64> = weights.iter().map(|&w| if w.is_finite() && w > 0.0 { w } else { 1e-6 }).collect();
            let total: f64 = clean.iter().sum();
            let minimums = (weights.len() as f64 - 1.0).max(0.0);
            for (m, w) in masks.iter().zip(&clean) {
                let exact = w / total * f64::from(class_count);
                let got = f64::from(m.count_ones());
                prop_assert!(got <= exact.ceil() + 1.0 && got >= exact.floor() - minimums - 1.0,
                    "got {} for exact {}", got, exact);
            }
        }
    }
}
