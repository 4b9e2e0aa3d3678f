//! The feed reader: on its own thread, at [`crate::STATE_RATE_HZ`], takes the newest frame from the
//! loop's state feed (lock-free, never blocks the publisher), re-samples the contact points at the
//! published pose when the part touches something, and hands the JSON state to the server.

use crate::contacts::{sample_contacts, ContactSample};
use crate::content::ContactModel;
use crate::state::{FrameView, ViewState, ViewStatus, STALE_AFTER_S};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vps_runtime::StateFeedReceiver;

/// Most contact points sent per state message.
pub const MAX_CONTACT_POINTS: usize = 2_000;

/// Turns the feed into state messages, one per [`FeedSampler::tick`]. Sans-IO apart from the
/// feed's lock-free slot: the caller supplies the time.
#[derive(Debug)]
pub struct FeedSampler {
    feed: Option<StateFeedReceiver>,
    contact: Option<ContactModel>,
    max_contact_points: usize,
    /// The newest frame's view and when it arrived.
    newest: Option<(FrameView, Instant)>,
    scratch: Vec<ContactSample>,
}

impl FeedSampler {
    /// A sampler of `feed` (`None`: offline); `contact` enables the contact points, at most
    /// `max_contact_points` per message.
    pub fn new(
        feed: Option<StateFeedReceiver>,
        contact: Option<ContactModel>,
        max_contact_points: usize,
    ) -> Self {
        Self {
            feed,
            contact,
            max_contact_points,
            newest: None,
            scratch: Vec::new(),
        }
    }

    /// Reads the feed (never blocks) and returns the state at `now`. Re-samples the contact points
    /// only for a new frame in which the loop saw the part touching (one voxel lookup per shell
    /// point); otherwise allocates only the returned message.
    pub fn tick(&mut self, now: Instant) -> ViewState {
        let Some(feed) = self.feed.as_mut() else {
            return ViewState {
                status: ViewStatus::Offline,
                frame: None,
            };
        };
        if let Some(frame) = feed.try_next() {
            self.scratch.clear();
            if let (true, Some(model)) = (frame.touching, &self.contact) {
                sample_contacts(
                    &model.tree,
                    &model.shell,
                    frame.part.position,
                    frame.part.orientation,
                    self.max_contact_points,
                    &mut self.scratch,
                );
            }
            self.newest = Some((FrameView::new(&frame, &self.scratch), now));
        }
        match &self.newest {
            None => ViewState {
                status: ViewStatus::Waiting,
                frame: None,
            },
            Some((view, at)) => ViewState {
                status: if now.saturating_duration_since(*at).as_secs_f64() > STALE_AFTER_S {
                    ViewStatus::Stale
                } else {
                    ViewStatus::Live
                },
                frame: Some(view.clone()),
            },
        }
    }
}

/// The sampler thread's body: a tick every `period` until `stop`, each state's JSON given to
/// `publish` (which must not block).
pub(crate) fn run(
    mut sampler: FeedSampler,
    period: Duration,
    stop: Arc<AtomicBool>,
    mut publish: impl FnMut(String),
) {
    let mut next = Instant::now();
    while !stop.load(Ordering::Relaxed) {
        publish(sampler.tick(Instant::now()).to_json());
        next += period;
        let now = Instant::now();
        if next > now {
            std::thread::sleep(next - now);
        } else {
            next = now;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::content::tests::{slab, square_shell};
    use glam::DVec3;

    use vps_runtime::{state_feed, FeedFrame};

    fn frame(n: u64, z: f64, touching: bool) -> FeedFrame {
        FeedFrame {
            touching,
            compute_ns: 42_000,
            recent_max_compute_ns: 90_000,
            ..FeedFrame::at_rest(n, DVec3::new(0.2, 0.2, z))
        }
    }

    fn model() -> Option<ContactModel> {
        Some(ContactModel {
            tree: slab(),
            shell: square_shell(),
        })
    }

    #[test]
    fn no_feed_is_offline() {
        let s = FeedSampler::new(None, model(), 10).tick(Instant::now());
        assert_eq!((s.status, s.frame), (ViewStatus::Offline, None));
    }

    #[test]
    fn the_status_follows_the_feed_and_contacts_follow_the_pose() {
        let (tx, rx) = state_feed();
        let mut sampler = FeedSampler::new(Some(rx), model(), 10);
        let t0 = Instant::now();
        assert_eq!(sampler.tick(t0).status, ViewStatus::Waiting);

        tx.publish(frame(7, 0.102, true));
        let s = sampler.tick(t0);
        assert_eq!(s.status, ViewStatus::Live);
        let view = s.frame.unwrap();
        assert_eq!(view.frame, 7);
        assert_eq!(view.contact_points.len(), 10, "capped at 10 of 25");
        assert!((view.contact_points[0][3] - 0.003).abs() < 1e-6);
        assert!((view.compute_us - 42.0).abs() < 1e-9);

        // A frame the loop saw as not touching is not re-sampled.
        tx.publish(frame(8, 0.102, false));
        let view = sampler.tick(t0).frame.unwrap();
        assert_eq!((view.frame, view.contact_points.len()), (8, 0));

        let later = t0 + Duration::from_secs_f64(STALE_AFTER_S + 0.5);
        let s = sampler.tick(later);
        assert_eq!(s.status, ViewStatus::Stale);
        assert_eq!(s.frame.unwrap().frame, 8, "the last frame stays shown");
    }

    #[test]
    fn the_reader_never_holds_up_the_publisher() {
        let (tx, rx) = state_feed();
        let publisher = std::thread::spawn(move || {
            for n in 0..200_000 {
                tx.publish(frame(n, 0.102, n % 2 == 0));
            }
        });
        let mut sampler = FeedSampler::new(Some(rx), model(), 10);
        let mut seen = Vec::new();
        while !publisher.is_finished() {
            if let Some(view) = sampler.tick(Instant::now()).frame {
                seen.push(view.frame);
            }
        }
        publisher.join().unwrap();
        let last = sampler.tick(Instant::now()).frame.unwrap().frame;
        assert_eq!(last, 199_999, "the newest frame is always reached");
        assert!(seen.windows(2).all(|w| w[0] <= w[1]));
    }
}
