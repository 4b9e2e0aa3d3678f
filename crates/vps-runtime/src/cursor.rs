//! The class cursor of a [`crate::pool::ClassPool`] frame: one atomic word, `seq << 32 | next
//! class`, that the frame thread opens and every thread of the pool claims classes from.
//!
//! A claim succeeds only while the word's stamp is the claimer's frame and classes remain, so a
//! worker still busy with an old frame can never take a class of the new one with the old pose.
//! Lock-free: a failed compare-exchange retries with the value it saw. The word's type is a
//! parameter ([`Word`]) so that the same code runs on `std`'s atomic in the pool and on loom's in
//! the model test below, which checks every interleaving (and every weak-memory outcome loom
//! models) of two claimers and an opener.

use std::sync::atomic::{AtomicU64, Ordering};

/// The atomic 64-bit word a [`Cursor`] is built on: the three operations the cursor makes, each
/// with its memory ordering.
pub(crate) trait Word {
    /// A word holding `value`.
    fn with(value: u64) -> Self;
    /// Reads the word (`Acquire`).
    fn read(&self) -> u64;
    /// Replaces the word with `value` (a swap, `AcqRel`).
    fn replace(&self, value: u64);
    /// Adds one if the word still holds `current` (a weak compare-exchange, `AcqRel` on success,
    /// `Acquire` on failure); on failure, the value seen.
    fn step_from(&self, current: u64) -> Result<u64, u64>;
}

/// Implements [`Word`] for an atomic type with `AtomicU64`'s methods (std's, loom's).
macro_rules! impl_word {
    ($atomic:ty) => {
        impl Word for $atomic {
            fn with(value: u64) -> Self {
                <$atomic>::new(value)
            }
            fn read(&self) -> u64 {
                self.load(Ordering::Acquire)
            }
            fn replace(&self, value: u64) {
                self.swap(value, Ordering::AcqRel);
            }
            fn step_from(&self, current: u64) -> Result<u64, u64> {
                let (success, failure) = (Ordering::AcqRel, Ordering::Acquire);
                self.compare_exchange_weak(current, current + 1, success, failure)
            }
        }
    };
}

impl_word!(AtomicU64);

/// The frame's class cursor (see the module docs). Frame path: no allocation, no lock.
pub(crate) struct Cursor<W: Word = AtomicU64>(W);

impl<W: Word> Cursor<W> {
    /// A cursor with no frame open (stamp 0, class 0).
    pub(crate) fn new() -> Self {
        Cursor(W::with(0))
    }

    /// Opens frame `seq` at class 0. A swap rather than a plain store, with the same effect (once
    /// a frame): with every write a read-modify-write, loom's model of the word is exact (loom
    /// 0.7 lets a compare-exchange read a value a concurrent plain store has already replaced,
    /// tokio-rs/loom#254, and reported a double claim no real execution can make).
    pub(crate) fn open(&self, seq: u32) {
        self.0.replace(u64::from(seq) << 32);
    }

    /// The next unclaimed class of frame `seq` (of `classes`), if any.
    pub(crate) fn claim(&self, seq: u32, classes: u32) -> Option<u32> {
        let mut current = self.0.read();
        loop {
            let (stamp, next) = ((current >> 32) as u32, current as u32);
            if stamp != seq || next >= classes {
                return None;
            }
            match self.0.step_from(current) {
                Ok(_) => return Some(next),
                Err(seen) => current = seen,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    /// Every class of frame `seq` (of `classes`) this claimer gets, in order.
    fn claim_all<W: Word>(cursor: &Cursor<W>, seq: u32, classes: u32) -> Vec<u32> {
        std::iter::from_fn(|| cursor.claim(seq, classes)).collect()
    }

    #[test]
    fn each_class_is_claimed_once_per_frame_and_only_by_that_frame() {
        let cursor: Arc<Cursor> = Arc::new(Cursor::new());
        cursor.open(7);
        let claimed: Vec<Vec<u32>> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..4)
                .map(|_| {
                    let cursor = cursor.clone();
                    scope.spawn(move || claim_all(&cursor, 7, 1000))
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let mut all: Vec<u32> = claimed.concat();
        all.sort_unstable();
        assert_eq!(all, (0..1000).collect::<Vec<u32>>());
        // A claimer of an older or newer frame gets nothing, even with classes left.
        cursor.open(8);
        assert_eq!(cursor.claim(7, 1000), None);
        assert_eq!(cursor.claim(9, 1000), None);
        assert_eq!(cursor.claim(8, 1000), Some(0));
        assert_eq!(cursor.claim(8, 1), None);
    }

    impl_word!(loom::sync::atomic::AtomicU64);

    type ModelCursor = Cursor<loom::sync::atomic::AtomicU64>;

    /// Every interleaving of two claimers of frame 1 (three classes): each class is claimed by
    /// exactly one of them, and the frame thread, claiming too, gets the rest.
    #[test]
    fn loom_two_claimers_share_the_classes_without_a_double_claim() {
        loom::model(|| {
            let cursor = loom::sync::Arc::new(ModelCursor::new());
            cursor.open(1);
            let workers: Vec<_> = (0..2)
                .map(|_| {
                    let cursor = cursor.clone();
                    loom::thread::spawn(move || claim_all(&cursor, 1, 3))
                })
                .collect();
            let mut all: Vec<u32> = workers
                .into_iter()
                .flat_map(|w| w.join().unwrap())
                .collect();
            all.extend(claim_all(&cursor, 1, 3));
            all.sort_unstable();
            assert_eq!(all, vec![0, 1, 2]);
        });
    }

    /// Every interleaving of a worker still claiming for frame 1 while the frame thread opens
    /// frame 2 and claims from it: the worker's claims are classes of frame 1 only (taken before
    /// the open), and frame 2's classes are each claimed once, from 0, by the frame thread.
    #[test]
    fn loom_a_late_claimer_never_takes_a_class_of_the_next_frame() {
        loom::model(|| {
            let cursor = loom::sync::Arc::new(ModelCursor::new());
            cursor.open(1);
            let late = {
                let cursor = cursor.clone();
                loom::thread::spawn(move || claim_all(&cursor, 1, 2))
            };
            cursor.open(2);
            let next = claim_all(&cursor, 2, 2);
            let old = late.join().unwrap();
            assert_eq!(next, vec![0, 1], "frame 2's classes, each once");
            assert!(old.len() <= 2, "{old:?}");
            assert!(
                old.iter().enumerate().all(|(k, &c)| c == k as u32),
                "{old:?}"
            );
            // Frame 2 is fully claimed: the late claimer's frame is closed for good.
            assert_eq!(cursor.claim(1, 2), None);
        });
    }
}
