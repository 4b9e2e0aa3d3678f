//! A fixed pool of local threads that samples a [`ClassedShell`] against a voxmap.
//!
//! With `threads = T`, share `t` (for `t` in `0..T`) is the set of classes `c` with `c mod T == t`.
//! Share 0 is computed on the calling (frame) thread; shares `1..T` go to `T − 1` worker threads
//! spawned once by [`ClassPool::new`]. Each frame the caller hands out the pose, computes share 0,
//! then collects the workers' replies until a deadline; any share that has not arrived by then
//! (worker busy, slow or gone) is computed on the calling thread, and a reply that turns up later is
//! recognised by its sequence number and dropped. Partial sums are integers, so the merged result is
//! bit-identical for every thread count and whoever computed each share.

use crate::RuntimeError;
use crossbeam::channel::{bounded, Receiver, RecvTimeoutError, Sender, TrySendError};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Instant;
use vps_haptic::{sample_classes, ClassedShell, KernelPose, PartialSums};
use vps_voxmap::VoxelLookup;

struct Job {
    seq: u64,
    pose: KernelPose,
}

struct Reply {
    seq: u64,
    share: usize,
    sums: PartialSums,
}

struct Worker {
    jobs: Option<Sender<Job>>,
    thread: Option<JoinHandle<()>>,
}

/// The merged sums of one frame and how they were obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PoolResult {
    /// Sums over every class of the shell.
    pub sums: PartialSums,
    /// Shares the calling thread computed because their worker missed the deadline or was busy.
    pub fallback_shares: u32,
}

/// The pool. Owned by one frame thread (`compute` takes `&mut self`).
pub struct ClassPool<L: VoxelLookup + Send + Sync + 'static> {
    map: Arc<L>,
    shell: Arc<ClassedShell>,
    shares: Vec<Vec<u32>>,
    workers: Vec<Worker>,
    replies: Receiver<Reply>,
    arrived: Vec<bool>,
    seq: u64,
}

/// The classes of share `share` out of `threads`: `c mod threads == share`.
pub fn share_classes(class_count: u32, threads: usize, share: usize) -> Vec<u32> {
    (0..class_count)
        .filter(|&c| c as usize % threads == share)
        .collect()
}

impl<L: VoxelLookup + Send + Sync + 'static> ClassPool<L> {
    /// A pool of `threads` compute threads (the caller plus `threads − 1` workers named
    /// `vps-pool-N`). Errors when `threads` is 0 or a thread cannot be spawned. Allocates and
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
        let shares: Vec<Vec<u32>> = (0..threads)
            .map(|t| share_classes(shell.class_count(), threads, t))
            .collect();
        // Each worker has at most one queued and one running job, so two replies each can be in
        // flight; the frame thread drains stale ones.
        let (reply_tx, replies) = bounded(2 * threads);
        let mut workers = Vec::with_capacity(threads - 1);
        for (share, classes) in shares.iter().enumerate().skip(1) {
            let (job_tx, job_rx) = bounded::<Job>(1);
            let (map, shell, classes, reply_tx) = (
                map.clone(),
                shell.clone(),
                classes.clone(),
                reply_tx.clone(),
            );
            let thread = std::thread::Builder::new()
                .name(format!("vps-pool-{share}"))
                .spawn(move || {
                    for job in job_rx.iter() {
                        let sums = sample_classes(&*map, &shell, &job.pose, &classes);
                        // A full reply queue means the frame thread has moved on: drop the reply.
                        let _ = reply_tx.try_send(Reply {
                            seq: job.seq,
                            share,
                            sums,
                        });
                    }
                })
                .map_err(RuntimeError::Spawn)?;
            workers.push(Worker {
                jobs: Some(job_tx),
                thread: Some(thread),
            });
        }
        Ok(ClassPool {
            map,
            shell,
            shares,
            workers,
            replies,
            arrived: vec![false; threads],
            seq: 0,
        })
    }

    /// Number of compute threads, the caller included.
    pub fn threads(&self) -> usize {
        self.shares.len()
    }

    /// Samples every class at `pose`: hands shares `1..T` to the workers, computes share 0 here,
    /// waits for replies until `deadline` (blocking on the reply channel, never past `deadline`),
    /// then computes any missing share here. Does not allocate.
    pub fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult {
        self.seq += 1;
        let seq = self.seq;
        self.arrived.iter_mut().for_each(|a| *a = false);
        let mut pending = 0usize;
        for worker in &self.workers {
            let sent = match &worker.jobs {
                Some(tx) => !matches!(
                    tx.try_send(Job { seq, pose: *pose }),
                    Err(TrySendError::Full(_) | TrySendError::Disconnected(_))
                ),
                None => false,
            };
            // An unsent share stays not-arrived and is computed below as a fallback.
            pending += sent as usize;
        }
        let mut sums = sample_classes(&*self.map, &self.shell, pose, &self.shares[0]);
        self.arrived[0] = true;
        while pending > 0 {
            match self.replies.recv_deadline(deadline) {
                Ok(reply) if reply.seq == seq && !self.arrived[reply.share] => {
                    sums.merge(&reply.sums);
                    self.arrived[reply.share] = true;
                    pending -= 1;
                }
                Ok(_stale) => {}
                Err(RecvTimeoutError::Timeout | RecvTimeoutError::Disconnected) => break,
            }
        }
        let mut fallback_shares = 0;
        for share in 1..self.shares.len() {
            if !self.arrived[share] {
                sums.merge(&sample_classes(
                    &*self.map,
                    &self.shell,
                    pose,
                    &self.shares[share],
                ));
                fallback_shares += 1;
            }
        }
        PoolResult {
            sums,
            fallback_shares,
        }
    }
}

/// Where the frame thread gets a frame's merged sums: the local [`ClassPool`] by default, or a
/// cluster gatherer (remote workers with local fallback) passed to
/// [`spawn_loop_with`](crate::haptic_loop::spawn_loop_with).
///
/// Contract: `compute` returns the sums over every class of the shell at `pose` and returns by
/// `deadline` plus the time to compute locally what is missing at `deadline`; it must not wait on
/// an async timer. Called once per frame from the frame thread.
pub trait FrameSampler: Send {
    /// The merged sums of every class at `pose`; shares not in by `deadline` are computed locally.
    fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult;
}

impl<L: VoxelLookup + Send + Sync + 'static> FrameSampler for ClassPool<L> {
    fn compute(&mut self, pose: &KernelPose, deadline: Instant) -> PoolResult {
        ClassPool::compute(self, pose, deadline)
    }
}

impl<L: VoxelLookup + Send + Sync + 'static> Drop for ClassPool<L> {
    /// Closes the job channels and joins the workers (each finishes at most one job).
    fn drop(&mut self) {
        for w in &mut self.workers {
            w.jobs.take();
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
    use crate::test_scene::{sphere_shell, wall};
    use glam::{DQuat, DVec3};
    use std::time::Duration;
    use vps_haptic::{sample_all, PartState};

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
    fn a_past_deadline_falls_back_to_local_compute_with_the_same_result() {
        let map = Arc::new(wall());
        let shell = Arc::new(ClassedShell::new(&sphere_shell(300), 8));
        let pose = KernelPose::from_state(&PartState::at_rest(
            DVec3::new(0.05, 0.05, 0.06),
            DQuat::IDENTITY,
        ));
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
