//! The state feed for viewers: the frame thread publishes every frame into a lock-free latest-value
//! slot (a crossbeam `ArrayQueue` of capacity 1, overwritten with `force_push`); a viewer reads the
//! newest value at its own rate (≥ 20 Hz is plenty). Publishing never blocks and never allocates,
//! whether or not anyone reads.

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

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3};

    fn frame(n: u64) -> FeedFrame {
        FeedFrame {
            frame: n,
            time: n as f64 * 1e-3,
            part: PartState::at_rest(DVec3::ZERO, DQuat::IDENTITY),
            handle: HandleSample {
                position: DVec3::ZERO,
                orientation: DQuat::IDENTITY,
                linear_velocity: DVec3::ZERO,
                angular_velocity: DVec3::ZERO,
            },
            device_wrench: Wrench::ZERO,
            contacts: 0,
            touching: false,
            penetrating: false,
            missed_deadlines: 0,
            watchdog_trips: 0,
            penetrating_frames: 0,
            touching_frames: 0,
        }
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
