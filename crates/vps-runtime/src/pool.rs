//! A fixed pool of local threads that samples the classes of a [`ClassedShell`] against a voxmap
//! by a deadline: the one local sampler of vps. The 1 kHz loop samples its part's whole shell
//! with it ([`ClassPool::compute`]); a cluster coordinator samples its own share and its fallback
//! of each job with it, and a worker the share a request names ([`ClassPool::compute_mask`]:
//! any voxmap and shell, the classes of a mask).
//!
//! The classes of a frame are claimed one at a time from a shared cursor (an atomic counter
//! stamped with the frame's sequence number) by the calling (frame) thread and by `T − 1` worker
//! threads spawned once by [`ClassPool::new`]: whoever is free takes the next class, so a worker
//! that wakes late or is preempted simply takes fewer classes instead of holding back a fixed
//! share. Once every class is claimed, the frame thread waits for the classes the workers are
//! still computing (at most one each), but only for about as long as they should take: twice its
//! own mean time per class this frame plus [`HEDGE_SLACK`], and never past the caller's deadline
//! (the *hedge*). Any class not in by then — its worker was preempted or woke late — is computed
//! on the calling thread, and a reply that turns up later is recognised by its sequence number
//! and dropped. Partial sums are integers, so the merged result is bit-identical for every thread
//! count and whoever computed each class.

use crate::cursor::Cursor;
use crate::RuntimeError;
use crossbeam::channel::{bounded, Receiver, Sender};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::{Arc, OnceLock};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use vps_haptic::{sample_class_in, ClassedShell, KernelFrame, KernelPose, PartialSums, SampleJob};
use vps_voxmap::VoxelLookup;

/// What the frame thread waits, beyond twice its own mean time per class, for a class a worker
/// still holds once none is left to claim, before computing that class itself: room for a
/// reply's hand-off and for classes that cost more than the mean (20 µs).
pub const HEDGE_SLACK: Duration = Duration::from_micros(20);

/// How many of its own mean class times the frame thread waits for a class in flight (see
/// [`HEDGE_SLACK`]). A class in flight was claimed before the frame thread's last claim, so it
/// should be in within one class time.
const HEDGE_CLASS_TIMES: u32 = 2;

/// A frame handed to the pool's threads: its sequence number, pose, what to sample and which
/// classes (the first `count` of `classes`, claimed in that order). Cloning its two `Arc`s is the
/// only cost of a hand-off; nothing is allocated.
struct WorkOrder<L> {
    seq: u32,
    pose: KernelPose,
    map: Arc<L>,
    shell: Arc<ClassedShell>,
    classes: ClassList,
}

/// Up to 64 class indices, in claim order.
#[derive(Clone, Copy)]
struct ClassList {
    classes: [u8; 64],
    count: u32,
}

impl ClassList {
    /// The classes of `mask` below `class_count` (at most 64), lowest first.
    fn of_mask(mask: u64, class_count: u32) -> ClassList {
        let mut list = ClassList {
            classes: [0; 64],
            count: 0,
        };
        for class in 0..class_count.min(64) {
            if mask >> class & 1 == 1 {
                list.classes[list.count as usize] = class as u8;
                list.count += 1;
            }
        }
        list
    }

    /// The class claimed as the `index`-th.
    fn class(&self, index: u32) -> u32 {
        u32::from(self.classes[index as usize])
    }
}

struct Reply {
    seq: u32,
    class: u32,
    sums: PartialSums,
}

struct Worker<L> {
    orders: Option<Sender<WorkOrder<L>>>,
    thread: Option<JoinHandle<()>>,
}

/// The merged sums of one frame and how they were obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PoolResult {
    /// Sums over every class of the shell.
    pub sums: PartialSums,
    /// Shares the calling thread computed because whoever had them missed the deadline (for the
    /// local pool: classes a worker had claimed; for a cluster: a worker's class set).
    pub fallback_shares: u32,
}

/// The pool. Owned by one frame thread (`compute` takes `&mut self`).
pub struct ClassPool<L: VoxelLookup + Send + Sync + 'static> {
    map: Arc<L>,
    shell: Arc<ClassedShell>,
    cursor: Arc<Cursor>,
    workers: Vec<Worker<L>>,
    replies: Receiver<Reply>,
    /// Per class: its sums are merged into this frame's total.
    done: [bool; 64],
    seq: u32,
    /// The first worker panic (which thread, the message); set once by that worker.
    failure: Arc<OnceLock<String>>,
}

/// The text of a caught panic's payload.
pub(crate) fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".into())
}

/// The classes of share `share` out of `threads`: `c mod threads == share` (the cyclic split of
/// docs/architecture.md#exact-sums-and-the-cluster, used where class sets are fixed per worker).
pub fn share_classes(class_count: u32, threads: usize, share: usize) -> Vec<u32> {
    (0..class_count)
        .filter(|&c| c as usize % threads == share)
        .collect()
}

impl<L: VoxelLookup + Send + Sync + 'static> ClassPool<L> {
    /// A pool of `threads` compute threads (the caller plus `threads − 1` workers named
    /// `vps-pool-N`) whose [`ClassPool::compute`] samples `shell` in `map`. Errors when `threads`
    /// is 0, `shell` has more than 64 classes, or a thread cannot be spawned. Allocates and
    /// spawns; not for the frame path.
    pub fn new(
        map: Arc<L>,
        shell: Arc<ClassedShell>,
        threads: usize,
    ) -> Result<Self, RuntimeError> {
        if threads == 0 {
            return Err(RuntimeError::Config {
                field: "threads",
                message: "must be at least 1".into(),
            });
        }
        let classes = shell.class_count();
        if classes > 64 {
            return Err(RuntimeError::Config {
                field: "class_count",
                message: format!("{classes}: a pool samples at most 64 classes"),
            });
        }
        let cursor: Arc<Cursor> = Arc::new(Cursor::new());
        // Room for every class of a frame plus stale replies of the previous one (a worker
        // finishes at most one old class after the frame moves on): a reply never waits for room.
        let (reply_tx, replies) = bounded(64 + 2 * threads);
        let mut workers = Vec::with_capacity(threads - 1);
        let failure = Arc::new(OnceLock::new());
        for index in 1..threads {
            let (order_tx, order_rx) = bounded::<WorkOrder<L>>(1);
            let (cursor, reply_tx, failure) = (cursor.clone(), reply_tx.clone(), failure.clone());
            let thread = std::thread::Builder::new()
                .name(format!("vps-pool-{index}"))
                .spawn(move || {
                    for order in order_rx.iter() {
                        let work = catch_unwind(AssertUnwindSafe(|| {
                            let (map, shell) = (&*order.map, &*order.shell);
                            // Prepared once for the frame, used for every class this thread takes.
                            let frame = KernelFrame::new(map, shell, &order.pose);
                            let list = order.classes;
                            while let Some(index) = cursor.claim(order.seq, list.count) {
                                let class = list.class(index);
                                let sums = sample_class_in(map, shell, &frame, class);
                                // Full only if the frame thread stopped reading: drop the reply.
                                let _ = reply_tx.try_send(Reply {
                                    seq: order.seq,
                                    class,
                                    sums,
                                });
                            }
                        }));
                        if let Err(payload) = work {
                            let _ = failure.set(format!(
                                "pool thread vps-pool-{index} panicked: {}",
                                panic_message(&*payload)
                            ));
                            // Its claimed class is recomputed by the frame thread, which ends
                            // the session at this frame (see `FrameSampler::failure`).
                            return;
                        }
                    }
                })
                .map_err(RuntimeError::Spawn)?;
            workers.push(Worker {
                orders: Some(order_tx),
                thread: Some(thread),
            });
        }
        Ok(ClassPool {
            map,
            shell,
            cursor,
            workers,
            replies,
            done: [false; 64],
            seq: 0,
            failure,
        })
    }

    /// Number of compute threads, the caller included.
    pub fn threads(&self) -> usize {
        self.workers.len() + 1
    }

    /// Samples every class of the pool's own shell in its own voxmap at `pose`
    /// ([`ClassPool::compute_mask`] with every class). Does not allocate or block.
    pub fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult {
        let (map, shell) = (self.map.clone(), self.shell.clone());
        self.compute_mask(&map, &shell, pose, u64::MAX, deadline)
    }

    /// [`ClassPool::compute_mask`] with no deadline of its own: the pool's threads are waited for
    /// only as the hedge allows, then what is missing is computed here (a coordinator's own
    /// share, a fallback, a worker's reply: the caller's clock decides what is late). Does not
    /// allocate or block.
    pub fn sample_mask(
        &mut self,
        map: &Arc<L>,
        shell: &Arc<ClassedShell>,
        pose: &KernelPose,
        mask: u64,
    ) -> PartialSums {
        // Far past any frame: the hedge, not this, ends the wait.
        let no_deadline = Instant::now() + Duration::from_secs(3600);
        self.compute_mask(map, shell, pose, mask, no_deadline).sums
    }

    /// Samples the classes of `shell` whose bits are set in `mask` (those below its class count)
    /// in `map` at `pose`: opens the frame's cursor, hands the frame to the workers, claims and
    /// computes classes here until none is left, waits (spinning) for the classes the workers
    /// still hold until the hedge time (twice this thread's mean class time this frame plus
    /// [`HEDGE_SLACK`] after its last class) or `deadline`, whichever is first, then computes
    /// here any class still missing, one at a time, taking replies that arrive in between. The
    /// sums are exact: the same bits whoever computed each class. Does not allocate or block
    /// (clones the two `Arc`s once per worker).
    pub fn compute_mask(
        &mut self,
        map: &Arc<L>,
        shell: &Arc<ClassedShell>,
        pose: &KernelPose,
        mask: u64,
        deadline: Instant,
    ) -> PoolResult {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        let list = ClassList::of_mask(mask, shell.class_count());
        self.done = [false; 64];
        // Replies of earlier frames.
        while self.replies.try_recv().is_ok() {}
        self.cursor.open(seq);
        for worker in &self.workers {
            if let Some(tx) = &worker.orders {
                // Fails when the worker still holds an older order (it will find that frame closed
                // and skip it; this frame's classes go to the others) or has gone.
                let _ = tx.try_send(WorkOrder {
                    seq,
                    pose: *pose,
                    map: map.clone(),
                    shell: shell.clone(),
                    classes: list,
                });
            }
        }
        let (map, shell) = (&**map, &**shell);
        let mut sums = PartialSums::default();
        let mut missing = list.count as usize;
        let own_started = Instant::now();
        let mut own = 0u32;
        let frame = KernelFrame::new(map, shell, pose);
        while let Some(index) = self.cursor.claim(seq, list.count) {
            let class = list.class(index);
            sums.merge(&sample_class_in(map, shell, &frame, class));
            self.done[class as usize] = true;
            missing -= 1;
            own += 1;
        }
        if missing > 0 {
            let now = Instant::now();
            let wait_until = match own {
                // Every class went to a worker: no own class time to judge by.
                0 => deadline,
                _ => {
                    deadline.min(now + (now - own_started) / own * HEDGE_CLASS_TIMES + HEDGE_SLACK)
                }
            };
            loop {
                missing -= self.take_replies(seq, &mut sums);
                if missing == 0 || Instant::now() >= wait_until {
                    break;
                }
                std::hint::spin_loop();
            }
        }
        let mut fallback_shares = 0;
        for index in 0..list.count {
            if missing == 0 {
                break;
            }
            missing -= self.take_replies(seq, &mut sums);
            let class = list.class(index);
            if !self.done[class as usize] {
                sums.merge(&sample_class_in(map, shell, &frame, class));
                self.done[class as usize] = true;
                missing -= 1;
                fallback_shares += 1;
            }
        }
        PoolResult {
            sums,
            fallback_shares,
        }
    }

    /// Merges the queued replies of frame `seq` for classes not yet done; returns how many.
    /// Replies of other frames and repeats are dropped. Does not block or allocate.
    fn take_replies(&mut self, seq: u32, sums: &mut PartialSums) -> usize {
        let mut taken = 0;
        while let Ok(reply) = self.replies.try_recv() {
            if reply.seq == seq && !self.done[reply.class as usize] {
                sums.merge(&reply.sums);
                self.done[reply.class as usize] = true;
                taken += 1;
            }
        }
        taken
    }
}

/// Where the frame thread gets a frame's merged sums: the local [`ClassPool`] by default, or a
/// cluster gatherer (remote workers with local fallback) passed to
/// [`spawn_loop_with`](crate::haptic_loop::spawn_loop_with).
///
/// Contract: `compute` returns the sums over every class of the shell at `pose` and returns by
/// `deadline` plus the time to compute locally what is missing at `deadline`; it must not wait on
/// an async timer. Called once per frame from the frame thread. The one allowed departure from
/// "at `pose`": a cluster gatherer whose stale policy allows it may stand in for a late share with
/// that share's sums from an earlier frame, and counts it (`vps_cluster::fallback`). The local
/// pool neither allocates nor blocks beyond that bound; the cluster gatherer allocates its share
/// split each frame (see its `compute`).
pub trait FrameSampler: Send {
    /// The merged sums of every class at `pose`; shares not in by `deadline` are computed locally
    /// (or, for a cluster gatherer, stood in for by earlier sums where its policy allows).
    fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult;

    /// The sums of every job of a frame of several parts ([`vps_haptic::job`]): `sums[k]` for
    /// `jobs[k]`, `jobs[0]` being the first part in the static scene at the pose `compute` would
    /// get; returns the shares computed locally because whoever had them missed the deadline.
    /// `None` (the default): this sampler samples only the first part's shell in the static
    /// scene (the local class pool), so the loop calls [`FrameSampler::compute`] and samples the
    /// other jobs itself. A cluster gatherer splits every job's classes over its workers.
    /// `sums` holds at least `jobs.len()` entries. Same timing contract as `compute`.
    fn compute_jobs(
        &mut self,
        _jobs: &[SampleJob],
        _deadline: Instant,
        _sums: &mut [PartialSums],
    ) -> Option<u32> {
        None
    }

    /// A failure of one of the sampler's own threads (a caught panic: which thread, the message)
    /// that must end the session; the frame loop checks it after every `compute`, before the
    /// frame's device write. `None` (the default) while all is well. Does not block or allocate.
    fn failure(&self) -> Option<String> {
        None
    }
}

impl<L: VoxelLookup + Send + Sync + 'static> FrameSampler for ClassPool<L> {
    fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult {
        ClassPool::compute(self, pose, deadline)
    }

    /// Allocates the message (only when a worker has panicked).
    fn failure(&self) -> Option<String> {
        self.failure.get().cloned()
    }
}

impl<L: VoxelLookup + Send + Sync + 'static> Drop for ClassPool<L> {
    /// Closes the order channels and joins the workers (each finishes at most one order).
    fn drop(&mut self) {
        for w in &mut self.workers {
            w.orders.take();
        }
        for w in &mut self.workers {
            if let Some(t) = w.thread.take() {
                let _ = t.join();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DQuat, DVec3};
    use std::sync::atomic::{AtomicBool, Ordering};
    use vps_haptic::{sample_all, PartState};
    use vps_testkit::scene::{wall, ArmedWall};
    use vps_testkit::shell::sphere_shell;

    #[test]
    fn shares_partition_the_classes_cyclically() {
        assert_eq!(share_classes(7, 3, 0), vec![0, 3, 6]);
        assert_eq!(share_classes(7, 3, 2), vec![2, 5]);
        assert_eq!(share_classes(2, 4, 3), Vec::<u32>::new());
    }

    #[test]
    fn any_thread_count_gives_identical_sums() {
        let map = Arc::new(wall());
        let shell = Arc::new(ClassedShell::new(&sphere_shell(300), 16));
        let poses: Vec<KernelPose> = [0.064, 0.062, 0.058, 0.05, 0.2]
            .iter()
            .map(|&z| {
                let mut s =
                    PartState::at_rest(DVec3::new(0.05, 0.05, z), DQuat::from_rotation_x(0.3));
                s.linear_velocity = DVec3::new(0.01, 0.0, -0.2);
                KernelPose::from_state(&s)
            })
            .collect();
        let reference: Vec<PartialSums> =
            poses.iter().map(|p| sample_all(&*map, &shell, p)).collect();
        assert!(
            reference.iter().any(|s| s.contacts > 0),
            "the poses must touch the wall"
        );
        assert!(
            reference.iter().any(|s| s.approaching > 0),
            "and brake before it"
        );
        for threads in 1..=4 {
            let mut pool = ClassPool::new(map.clone(), shell.clone(), threads).unwrap();
            for (pose, want) in poses.iter().zip(&reference) {
                let got = pool.compute(pose, Instant::now() + Duration::from_secs(5));
                assert_eq!(&got.sums, want, "threads = {threads}");
            }
        }
    }

    #[test]
    fn any_mask_of_any_shell_gives_the_serial_sums_on_any_thread_count() {
        // The pool's own target is one shell; each call names another shell and a mask, as a
        // cluster coordinator's share and a worker's request do.
        let map = Arc::new(wall());
        let own = Arc::new(ClassedShell::new(&sphere_shell(100), 8));
        let other = Arc::new(ClassedShell::new(&sphere_shell(300), 64));
        let mut s = PartState::at_rest(DVec3::new(0.05, 0.05, 0.058), DQuat::from_rotation_x(0.3));
        s.linear_velocity = DVec3::new(0.01, 0.0, -0.2);
        let pose = KernelPose::from_state(&s);
        let masks = [
            u64::MAX,
            0,
            1,
            1 << 63,
            0x5555_5555_5555_5555,
            0xF0F0_0000_0000_F00F,
        ];
        for threads in 1..=3 {
            let mut pool = ClassPool::new(map.clone(), own.clone(), threads).unwrap();
            for mask in masks {
                let want = vps_haptic::sample_mask(&*map, &other, &pose, mask);
                let got = pool.compute_mask(
                    &map,
                    &other,
                    &pose,
                    mask,
                    Instant::now() + Duration::from_secs(5),
                );
                assert_eq!(got.sums, want, "threads = {threads}, mask = {mask:#x}");
            }
            // And its own shell between the others' (the loop's call).
            let own_sums = pool
                .compute(&pose, Instant::now() + Duration::from_secs(5))
                .sums;
            assert_eq!(
                own_sums,
                sample_all(&*map, &own, &pose),
                "threads = {threads}"
            );
        }
        assert!(
            vps_haptic::sample_mask(&*map, &other, &pose, u64::MAX).contacts > 0,
            "the pose must touch the wall"
        );
    }

    /// A 300-point sphere shell in 8 classes, and a pose at rest with its centre 1 cm above the
    /// wall's face (the 1.5 cm sphere dips into the wall: in contact).
    fn shell_above_wall() -> (Arc<ClassedShell>, KernelPose) {
        let shell = Arc::new(ClassedShell::new(&sphere_shell(300), 8));
        let pose = KernelPose::from_state(&PartState::at_rest(
            DVec3::new(0.05, 0.05, 0.06),
            DQuat::IDENTITY,
        ));
        (shell, pose)
    }

    /// What the stalling lookup and its test share.
    #[derive(Default)]
    struct Stall {
        /// Set by the pool thread `vps-pool-1` when its lookup stalls.
        stalled: AtomicBool,
        /// Set by the test to let the stalled lookup go on.
        released: AtomicBool,
    }

    /// The wall, except that once armed a lookup on the pool thread `vps-pool-1` stalls until
    /// `released`, and lookups on any other thread wait until that pool thread has stalled (so
    /// that it holds a class of the frame).
    fn stalls_on_pool_thread() -> ArmedWall<Stall, impl Fn(&Stall) + Sync> {
        ArmedWall::new(Stall::default(), |stall: &Stall| {
            // A backstop so that a failing test does not hang.
            let backstop = Instant::now() + Duration::from_secs(30);
            let on_pool = std::thread::current().name() == Some("vps-pool-1");
            if on_pool {
                stall.stalled.store(true, Ordering::Release);
            }
            let flag = if on_pool {
                &stall.released
            } else {
                &stall.stalled
            };
            while !flag.load(Ordering::Acquire) && Instant::now() < backstop {
                std::thread::sleep(Duration::from_micros(100));
            }
        })
    }

    #[test]
    fn a_class_held_by_a_stalled_thread_is_computed_here_long_before_the_deadline() {
        let map = Arc::new(stalls_on_pool_thread());
        let (shell, pose) = shell_above_wall();
        let want = sample_all(&map.wall, &shell, &pose);
        let mut pool = ClassPool::new(map.clone(), shell, 2).unwrap();
        map.armed.store(true, Ordering::Release);
        let deadline = Instant::now() + Duration::from_secs(20);
        let got = pool.compute(&pose, deadline);
        let returned = Instant::now();
        map.armed.store(false, Ordering::Release);
        map.state.released.store(true, Ordering::Release);
        assert!(
            map.state.stalled.load(Ordering::Acquire),
            "the pool thread held a class"
        );
        assert_eq!(got.sums, want);
        assert_eq!(got.fallback_shares, 1, "the stalled thread's one class");
        assert!(
            returned < deadline,
            "the frame thread waited for the stalled class until the deadline"
        );
        // The stalled thread's late reply is dropped; the next frame is whole again.
        let again = pool.compute(&pose, Instant::now() + Duration::from_secs(20));
        assert_eq!(again.sums, want);
    }

    #[test]
    fn a_past_deadline_falls_back_to_local_compute_with_the_same_result() {
        let map = Arc::new(wall());
        let (shell, pose) = shell_above_wall();
        let want = sample_all(&*map, &shell, &pose);
        let mut pool = ClassPool::new(map, shell, 3).unwrap();
        for _ in 0..20 {
            let got = pool.compute(&pose, Instant::now() - Duration::from_millis(1));
            assert_eq!(got.sums, want);
            assert!(got.fallback_shares <= 2);
        }
        assert!(matches!(
            ClassPool::new(
                Arc::new(wall()),
                Arc::new(ClassedShell::new(&sphere_shell(10), 1)),
                0
            ),
            Err(RuntimeError::Config { .. })
        ));
    }
}
