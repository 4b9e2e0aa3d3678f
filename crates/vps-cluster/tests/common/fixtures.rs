//! Fixtures that need no network crate (shared with the root package's `tests/cluster_*.rs`
//! through `#[path]`): a wall voxmap, a sphere shell, poses, a logging simulated hand, the
//! one-process reference run.
#![allow(dead_code)]

use glam::{DQuat, DVec3};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use vps_cluster::fallback::StalePolicy;
use vps_cluster::{
    local_cluster_certs, run_coordinator_session, ClusterAssets, ClusterReport, Coordinator,
    CoordinatorConfig, GatherConfig, LocalCerts,
};
use vps_device::script::{approach_and_rest, Pace};
use vps_device::{
    DeviceError, DeviceLimits, HandParams, HapticDevice, SimulatedHand, SurfaceContact,
};
use vps_haptic::{HandleSample, HapticParams, KernelPose, PartState, Wrench};
use vps_runtime::{run_loop, LoopConfig, LoopReport, SessionSetup};
use vps_voxmap::{TreeConfig, VoxelTree};

pub use vps_runtime::test_scene::{sphere_shell, VOXEL};

/// Radius of the test sphere shell (m).
pub const RADIUS: f64 = vps_runtime::test_scene::SPHERE_RADIUS;
pub const CLASSES: u32 = 64;

/// The runtime's test wall (5 mm voxels: Interior below z index 8, Surface at 8–9, Proximity at 10,
/// face at z = 0.05 m) as a tree.
pub fn wall() -> VoxelTree {
    VoxelTree::from_dense(&vps_runtime::test_scene::wall(), TreeConfig::uniform(2))
        .expect("valid tree config")
}

/// Workers [`loopback_coordinator`] makes certificates for.
pub const LOOPBACK_WORKERS: usize = 4;

/// A coordinator on loopback serving [`scene`], with fresh certificates written to `dir` and
/// pinned both ways (the [`LOOPBACK_WORKERS`] workers' are the only ones admitted, one live
/// connection each).
pub fn loopback_coordinator(dir: &std::path::Path) -> (Coordinator, LocalCerts) {
    let certs = local_cluster_certs(dir, LOOPBACK_WORKERS).expect("certificates");
    let coordinator = Coordinator::start(
        CoordinatorConfig::from_files(
            "127.0.0.1:0".parse().expect("addr"),
            &certs.coordinator.cert,
            &certs.coordinator.key,
            &certs.worker_pins(),
        )
        .expect("coordinator config"),
        scene(),
    )
    .expect("coordinator starts");
    (coordinator, certs)
}

pub fn scene() -> Arc<ClusterAssets> {
    Arc::new(ClusterAssets::new(Arc::new(wall()), &sphere_shell(600), CLASSES).expect("scene"))
}

/// Poses descending onto the wall, turning, with velocities (contacts and braking both occur).
pub fn poses(n: usize) -> Vec<KernelPose> {
    (0..n)
        .map(|i| {
            let t = i as f64 / n.max(1) as f64;
            let mut s = PartState::at_rest(
                DVec3::new(0.05 + 0.01 * t, 0.05, 0.07 - 0.016 * t),
                DQuat::from_rotation_x(0.3 + t),
            );
            s.linear_velocity = DVec3::new(0.01, 0.0, -0.2);
            s.angular_velocity = DVec3::new(0.0, 1.0, 0.5);
            KernelPose::from_state(&s)
        })
        .collect()
}

pub const START: DVec3 = DVec3::new(0.05, 0.05, 0.09);
pub const FRAMES: u64 = 400;

pub type Writes = Arc<Mutex<Vec<Wrench>>>;
/// Called after write number `n` (1-based) was logged, on the frame thread, before the next
/// frame starts (so blocking in it delays the session but never a frame's deadline).
pub type WriteHook = Box<dyn FnMut(u64) + Send>;

/// A simulated hand that logs every write, raises `trip` at read number `trip_at` and runs
/// `hook` after every write.
struct Logged {
    inner: SimulatedHand,
    writes: Writes,
    reads: u64,
    trip_at: u64,
    trip: Arc<AtomicBool>,
    hook: Option<WriteHook>,
}

impl HapticDevice for Logged {
    fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError> {
        self.reads += 1;
        if self.reads == self.trip_at {
            self.trip.store(true, Ordering::Relaxed);
        }
        self.inner.read(t)
    }
    fn write(&mut self, w: &Wrench) -> Result<(), DeviceError> {
        let n = {
            let mut writes = self.writes.lock().unwrap();
            writes.push(*w);
            writes.len() as u64
        };
        if let Some(hook) = &mut self.hook {
            hook(n);
        }
        self.inner.write(w)
    }
    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }
    fn name(&self) -> &str {
        self.inner.name()
    }
}

fn logged(
    trip_at: u64,
    trip: Arc<AtomicBool>,
    hook: Option<WriteHook>,
) -> (Box<dyn HapticDevice>, Writes) {
    let contact = SurfaceContact {
        point: DVec3::new(0.05, 0.05, 0.05 + RADIUS),
        normal: DVec3::Z,
        orientation: DQuat::IDENTITY,
    };
    let pace = Pace {
        speed: 0.1,
        press_depth: 0.005,
        dwell: 0.1,
    };
    let script = approach_and_rest(START, &contact, &pace).unwrap();
    let writes = Writes::default();
    let device = Logged {
        inner: SimulatedHand::new(script, HandParams::default()).unwrap(),
        writes: writes.clone(),
        reads: 0,
        trip_at,
        trip,
        hook,
    };
    (Box::new(device), writes)
}

/// The logging hand, raising `trip` at read number `trip_at` (never when 0).
pub fn hand(trip_at: u64, trip: Arc<AtomicBool>) -> (Box<dyn HapticDevice>, Writes) {
    logged(trip_at, trip, None)
}

/// The logging hand, running `hook` after every write.
pub fn hand_with_hook(hook: WriteHook) -> (Box<dyn HapticDevice>, Writes) {
    logged(0, Arc::new(AtomicBool::new(false)), Some(hook))
}

pub fn params() -> HapticParams {
    HapticParams::default().with_scene(VOXEL, RADIUS).unwrap()
}

/// Free-running, [`FRAMES`] frames; the watchdog is far above any frame's compute so that no
/// frame is zeroed, and replies are awaited up to half of it.
pub fn config() -> LoopConfig {
    config_frames(FRAMES)
}

/// [`config`] with `frames` frames.
pub fn config_frames(frames: u64) -> LoopConfig {
    LoopConfig {
        frames: Some(frames),
        free_running: true,
        watchdog: Duration::from_millis(200),
        ..LoopConfig::default()
    }
}

/// The standard test session's setup: [`params`], the part at rest at [`START`],
/// [`config_frames`]`(frames)`, `device`, no feed, never stopped.
pub fn standard_setup(device: Box<dyn HapticDevice>, frames: u64) -> SessionSetup {
    SessionSetup {
        params: params(),
        device,
        initial: PartState::at_rest(START, DQuat::IDENTITY),
        config: config_frames(frames),
        feed: None,
        stop: Arc::new(AtomicBool::new(false)),
    }
}

/// The standard test session over `coordinator`'s workers: [`params`], the part at rest at
/// [`START`], [`config_frames`]`(frames)`, `device`, with `gather` made exact (no stale
/// stand-ins, whatever the timing: these sessions are compared write by write with the
/// one-process run). Panics on error.
pub fn exact_cluster_session(
    coordinator: &Coordinator,
    gather: GatherConfig,
    device: Box<dyn HapticDevice>,
    frames: u64,
) -> (LoopReport, ClusterReport) {
    run_coordinator_session(
        coordinator,
        GatherConfig {
            stale: StalePolicy::NEVER,
            ..gather
        },
        standard_setup(device, frames),
    )
    .expect("cluster session")
}

/// Every device write of the one-process run of [`FRAMES`] frames.
pub fn one_process_writes() -> Vec<Wrench> {
    one_process_writes_for(FRAMES)
}

/// Every device write of the one-process run of `frames` frames (one per frame plus the final
/// zero wrench).
pub fn one_process_writes_for(frames: u64) -> Vec<Wrench> {
    let scene = scene();
    let (device, writes) = hand(0, Arc::new(AtomicBool::new(false)));
    let report = run_loop(
        scene.map.clone(),
        scene.shell.clone(),
        standard_setup(device, frames),
    )
    .unwrap();
    assert_eq!(report.stats.frames, frames);
    assert!(
        report.stats.contact_frames > 0,
        "the session must touch the wall"
    );
    let w = writes.lock().unwrap().clone();
    w
}

/// Asserts that two write traces are the same, frame by frame, to the bit.
pub fn assert_same_writes(got: &[Wrench], want: &[Wrench]) {
    assert_eq!(got.len(), want.len(), "device write count");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        let bits =
            |w: &Wrench| [w.force.to_array(), w.torque.to_array()].map(|v| v.map(f64::to_bits));
        assert_eq!(bits(g), bits(w), "frame {i}: {g:?} != {w:?}");
    }
}
