//! What the frame thread does, at the reply deadline, with worker shares that did not come back:
//! recompute them on local threads (exact), or, when that cannot finish before the device write is
//! due, reuse the share's sums from an earlier frame (degraded accuracy: a force up to a few
//! milliseconds old for those points, counted). Pure: the caller measures the time and passes it
//! in.
//!
//! The device write is due at the end of the frame's budget: the runtime hands the gatherer a
//! reply deadline half-way through its watchdog budget, so the write is due one reply window
//! (frame start → reply deadline) after the deadline. The local recompute is estimated from the
//! coordinator's own share of the same frame (same pose, so the same mix of contact and free
//! space): its time per class times the missing classes.

use std::time::Duration;

/// How stale sums may be reused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StalePolicy {
    /// A share's sums may stand in for it for at most this many frames after they were computed
    /// (0: never reuse, always recompute).
    pub max_age_frames: u64,
    /// Kept free before the device write is due, for the frame step and the write itself.
    pub write_margin: Duration,
}

impl StalePolicy {
    /// Never reuse: every missing share is recomputed, so the sums are exact whatever the timing.
    pub const NEVER: StalePolicy = StalePolicy {
        max_age_frames: 0,
        ..StalePolicy::DEFAULT
    };

    /// The default: sums up to 3 frames old, 40 µs kept for the step and the write.
    const DEFAULT: StalePolicy = StalePolicy {
        max_age_frames: 3,
        write_margin: Duration::from_micros(40),
    };
}

impl Default for StalePolicy {
    fn default() -> Self {
        StalePolicy::DEFAULT
    }
}

/// A missing share, as the planner sees it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MissingShare {
    /// Classes in it.
    pub classes: u32,
    /// Frames since the reusable sums of this same class set were computed (`None`: none held).
    pub stale_age: Option<u64>,
}

/// What to do with one missing share.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FallbackAction {
    /// Sample its classes on local threads (exact).
    Recompute,
    /// Use the held sums from `age` frames ago.
    ReuseStale,
}

/// Plans the fallback for `missing` shares (same order in the result). `left` is the time from
/// now until the device write is due; `per_class` the local cost of one class this frame.
///
/// Recomputes everything when it fits in `left − write_margin`. Otherwise it reuses held sums
/// (no older than `max_age_frames`), largest shares first, until what remains to recompute fits;
/// a share with nothing reusable is always recomputed (the watchdog then decides whether the frame
/// is written). So with a generous budget (tests, slow debug builds with a long watchdog) it always
/// recomputes and the sums stay exact.
pub fn plan_fallback(
    missing: &[MissingShare],
    left: Duration,
    per_class: Duration,
    policy: StalePolicy,
) -> Vec<FallbackAction> {
    let mut actions = vec![FallbackAction::Recompute; missing.len()];
    let budget = left.saturating_sub(policy.write_margin);
    let cost = |classes: u32| per_class.saturating_mul(classes);
    let mut to_recompute: Duration = missing
        .iter()
        .map(|m| cost(m.classes))
        .fold(Duration::ZERO, Duration::saturating_add);
    if to_recompute <= budget {
        return actions;
    }
    let mut order: Vec<usize> = (0..missing.len()).collect();
    // Largest first; the sort is stable, so ties stay in the callers' order.
    order.sort_by_key(|&i| std::cmp::Reverse(missing[i].classes));
    for i in order {
        if to_recompute <= budget {
            break;
        }
        let reusable = missing[i]
            .stale_age
            .is_some_and(|age| age >= 1 && age <= policy.max_age_frames);
        if reusable {
            actions[i] = FallbackAction::ReuseStale;
            to_recompute = to_recompute.saturating_sub(cost(missing[i].classes));
        }
    }
    actions
}

#[cfg(test)]
mod tests {
    use super::*;
    use FallbackAction::*;

    const US: Duration = Duration::from_micros(1);

    fn share(classes: u32, stale_age: Option<u64>) -> MissingShare {
        MissingShare { classes, stale_age }
    }

    #[test]
    fn recomputes_everything_that_fits() {
        let missing = [share(20, Some(1)), share(12, Some(1))];
        // 32 classes × 5 µs = 160 µs against 400 − 40.
        let plan = plan_fallback(&missing, 400 * US, 5 * US, StalePolicy::default());
        assert_eq!(plan, [Recompute, Recompute]);
    }

    #[test]
    fn reuses_the_largest_stale_shares_until_the_rest_fits() {
        let missing = [share(12, Some(1)), share(20, Some(2)), share(4, Some(1))];
        // 36 classes × 10 µs = 360 µs against 240 − 40 = 200: dropping the 20-class share
        // leaves 160 µs, which fits.
        let plan = plan_fallback(&missing, 240 * US, 10 * US, StalePolicy::default());
        assert_eq!(plan, [Recompute, ReuseStale, Recompute]);
    }

    #[test]
    fn never_reuses_sums_that_are_too_old_missing_or_from_this_frame() {
        let missing = [share(20, Some(4)), share(20, None), share(20, Some(0))];
        let plan = plan_fallback(&missing, 10 * US, 10 * US, StalePolicy::default());
        assert_eq!(plan, [Recompute, Recompute, Recompute]);
        let never = StalePolicy {
            max_age_frames: 0,
            ..StalePolicy::default()
        };
        let plan = plan_fallback(&[share(20, Some(1))], US, 10 * US, never);
        assert_eq!(plan, [Recompute]);
    }

    #[test]
    fn past_the_write_or_with_absurd_costs_nothing_overflows() {
        let missing = [share(64, Some(1))];
        for left in [Duration::ZERO, Duration::MAX] {
            let plan = plan_fallback(&missing, left, Duration::MAX, StalePolicy::default());
            assert_eq!(plan, [ReuseStale], "{left:?} left");
        }
        assert!(plan_fallback(&[], Duration::ZERO, US, StalePolicy::default()).is_empty());
    }
}
