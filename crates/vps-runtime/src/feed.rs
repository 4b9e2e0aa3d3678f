//! The state feed for viewers: the frame thread publishes every frame into a lock-free latest-value
//! slot (a crossbeam `ArrayQueue` of capacity 1, overwritten with `force_push`); a viewer reads the
//! newest value at its own rate (≥ 20 Hz is plenty). Publishing never blocks and never allocates,
//! whether or not anyone reads.
//!
//! A reader at 30 Hz sees one frame in about 33; so that a strip chart still shows the slow frames
//! in between, each frame also carries [`RecentMax`] figures of compute time and period error over
//! the last 32 to 64 frames.

use crossbeam::queue::ArrayQueue;
use std::sync::Arc;
use vps_haptic::{HandleSample, PartState, Wrench};

/// One frame as a viewer sees it. Plain `Copy` data.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FeedFrame {
    /// Frame index (frames run so far − 1).
    pub frame: u64,
    /// Scheduled time of the frame since the session started (s).
    pub time: f64,
    /// The part's state after the frame.
    pub part: PartState,
    /// The handle as read this frame.
    pub handle: HandleSample,
    /// The wrench written to the device (N, N·m).
    pub device_wrench: Wrench,
    /// Contact count N this frame.
    pub contacts: u32,
    /// ≥ 1 point in Surface or Interior.
    pub touching: bool,
    /// ≥ 1 point in Interior.
    pub penetrating: bool,
    /// Missed deadlines so far.
    pub missed_deadlines: u64,
    /// Watchdog trips so far.
    pub watchdog_trips: u64,
    /// Frames with ≥ 1 point in Interior so far.
    pub penetrating_frames: u64,
    /// Frames with ≥ 1 point in Surface or Interior so far.
    pub touching_frames: u64,
    /// This frame's compute time, device read to the end of the device write (ns).
    pub compute_ns: u64,
    /// The largest `compute_ns` over the last 32 to 64 frames, this one included (ns).
    pub recent_max_compute_ns: u64,
    /// How late this frame's tick started (ns); 0 in free-running mode.
    pub period_error_ns: u64,
    /// The largest `period_error_ns` over the last 32 to 64 frames, this one included (ns).
    pub recent_max_period_error_ns: u64,
    /// How many of `other_parts` hold a part (0 in a one-part session).
    pub other_count: u32,
    /// The other moving parts after the frame, in the scene file's order (the first
    /// `other_count`; the rest unused).
    pub other_parts: [OtherPartFrame; MAX_OTHER_PARTS],
}

/// Most moving parts a session holds besides its first.
pub const MAX_OTHER_PARTS: usize = 7;

/// A moving part's pose (its grip frame) as a viewer draws it.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PartPose {
    /// Position of the grip (m).
    pub position: glam::DVec3,
    /// Orientation, body → world.
    pub orientation: glam::DQuat,
}

/// Another moving part's frame as a viewer draws it: where it is, where its hand is, and what its
/// device was sent.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OtherPartFrame {
    /// The part's pose after the frame.
    pub part: PartPose,
    /// Its handle as read this frame (the ghost the part is coupled to); the part's own pose
    /// until its device has answered once.
    pub handle: PartPose,
    /// The wrench written to its device this frame (N, N·m; saturated to its limits, zero when
    /// the watchdog tripped and before its first write).
    pub device_wrench: Wrench,
}

impl FeedFrame {
    /// The other parts (the first [`FeedFrame::other_count`]).
    pub fn others(&self) -> &[OtherPartFrame] {
        &self.other_parts[..(self.other_count as usize).min(MAX_OTHER_PARTS)]
    }
}

/// The running maximum of a per-frame figure over the last [`RecentMax::WINDOW`] to
/// 2 × `WINDOW` values: two half windows, the finished one and the one being filled. Plain
/// integers: recording never allocates or blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RecentMax {
    current: u64,
    previous: u64,
    filled: u32,
}

impl RecentMax {
    /// Values per half window.
    pub const WINDOW: u32 = 32;

    /// Records `value` and returns the largest value of the last `WINDOW` to `2 × WINDOW` records
    /// (fewer at the start), `value` included. Does not allocate or block.
    pub fn record(&mut self, value: u64) -> u64 {
        if self.filled == Self::WINDOW {
            self.previous = self.current;
            self.current = 0;
            self.filled = 0;
        }
        self.current = self.current.max(value);
        self.filled += 1;
        self.current.max(self.previous)
    }
}

/// The loop's end of the feed. `Send`; cloning gives another publisher to the same slot.
#[derive(Clone, Debug)]
pub struct StateFeedSender {
    slot: Arc<ArrayQueue<FeedFrame>>,
}

/// A viewer's end of the feed.
#[derive(Debug)]
pub struct StateFeedReceiver {
    slot: Arc<ArrayQueue<FeedFrame>>,
    last: Option<FeedFrame>,
}

/// A connected sender/receiver pair around one empty slot.
pub fn state_feed() -> (StateFeedSender, StateFeedReceiver) {
    let slot = Arc::new(ArrayQueue::new(1));
    (
        StateFeedSender { slot: slot.clone() },
        StateFeedReceiver { slot, last: None },
    )
}

impl StateFeedSender {
    /// Replaces whatever is in the slot with `frame`. Lock-free: never blocks, never allocates.
    pub fn publish(&self, frame: FeedFrame) {
        let _ = self.slot.force_push(frame);
    }
}

impl StateFeedReceiver {
    /// The frame published since the last call, if any. Never blocks.
    pub fn try_next(&mut self) -> Option<FeedFrame> {
        let fresh = self.slot.pop();
        if fresh.is_some() {
            self.last = fresh;
        }
        fresh
    }

    /// The newest frame ever published (a fresh one if there is one). Never blocks.
    pub fn latest(&mut self) -> Option<FeedFrame> {
        self.try_next();
        self.last
    }
}

impl FeedFrame {
    /// Frame `n` (at `n` ms) of a part and handle at rest at `position` (m), everything else zero:
    /// a starting point for tests, which set the fields they need with struct-update syntax.
    #[cfg(any(test, feature = "test-support"))]
    pub fn at_rest(n: u64, position: glam::DVec3) -> FeedFrame {
        FeedFrame {
            frame: n,
            time: n as f64 * 1e-3,
            part: PartState::at_rest(position, glam::DQuat::IDENTITY),
            handle: HandleSample {
                position,
                orientation: glam::DQuat::IDENTITY,
                linear_velocity: glam::DVec3::ZERO,
                angular_velocity: glam::DVec3::ZERO,
            },
            device_wrench: Wrench::ZERO,
            contacts: 0,
            touching: false,
            penetrating: false,
            missed_deadlines: 0,
            watchdog_trips: 0,
            penetrating_frames: 0,
            touching_frames: 0,
            compute_ns: 0,
            recent_max_compute_ns: 0,
            period_error_ns: 0,
            recent_max_period_error_ns: 0,
            other_count: 0,
            other_parts: [OtherPartFrame::default(); MAX_OTHER_PARTS],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn frame(n: u64) -> FeedFrame {
        FeedFrame::at_rest(n, DVec3::ZERO)
    }

    #[test]
    fn recent_max_keeps_a_spike_for_one_to_two_windows() {
        let w = RecentMax::WINDOW as usize;
        let mut m = RecentMax::default();
        assert_eq!(m.record(5), 5);
        assert_eq!(m.record(900), 900);
        // The spike was the 2nd value of the first half window: visible until that window is
        // dropped, i.e. through the end of the second half window.
        for i in 2..2 * w {
            assert_eq!(m.record(1), 900, "record {i}");
        }
        assert_eq!(m.record(1), 1, "gone once its half window is two back");
        assert_eq!(m.record(7), 7);
    }

    #[test]
    fn publishing_with_nobody_reading_never_blocks_and_keeps_the_newest() {
        let (tx, mut rx) = state_feed();
        for n in 0..100_000 {
            tx.publish(frame(n));
        }
        assert_eq!(rx.try_next().map(|f| f.frame), Some(99_999));
        assert_eq!(rx.try_next(), None);
        assert_eq!(rx.latest().map(|f| f.frame), Some(99_999));
        drop(rx);
        for n in 0..1000 {
            tx.publish(frame(n));
        }
    }

    #[test]
    fn a_reader_on_another_thread_sees_increasing_frames() {
        let (tx, mut rx) = state_feed();
        let reader = std::thread::spawn(move || {
            let mut seen = Vec::new();
            while seen.last() != Some(&9_999) {
                if let Some(f) = rx.try_next() {
                    seen.push(f.frame);
                }
                std::hint::spin_loop();
            }
            seen
        });
        for n in 0..10_000 {
            tx.publish(frame(n));
        }
        let seen = reader.join().unwrap();
        assert!(seen.windows(2).all(|w| w[0] < w[1]));
    }
}
