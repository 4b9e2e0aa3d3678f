//! The standard test session (the sphere shell of [`crate::shell`] lowered onto the wall of
//! [`crate::scene`] by [`crate::hand`], logged by [`crate::device`]), run on one process and over
//! a loopback coordinator, for the cluster tests of `vps-cluster` and of the root package.

use glam::{DQuat, DVec3};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;
use vps_cluster::fallback::StalePolicy;
use vps_cluster::{
    local_cluster_certs, run_coordinator_session, ClusterAssets, ClusterReport, Coordinator,
    CoordinatorConfig, GatherConfig, LocalCerts, LocalWorkerArgs, PeerTls,
};
use vps_device::HapticDevice;
use vps_haptic::{HapticParams, KernelPose, PartState, Wrench};
use vps_runtime::{run_loop, LoopConfig, LoopReport, SessionSetup};

pub use crate::device::{assert_same_writes, WriteHook, Writes};

use crate::device::LoggingDevice;
use crate::hand::{approach_and_rest_on_wall, START};
use crate::scene::{wall_tree, VOXEL};
use crate::shell::{sphere_shell, SPHERE_RADIUS};

/// Classes of the shell of the cluster tests' [`assets`].
pub const CLASSES: u32 = 64;

/// Frames of the standard session.
pub const FRAMES: u64 = 400;

/// The cluster tests' assets: the wall as a tree and a 600-point sphere shell in [`CLASSES`]
/// classes.
pub fn assets() -> Arc<ClusterAssets> {
    Arc::new(
        ClusterAssets::new(Arc::new(wall_tree()), &sphere_shell(600), CLASSES).expect("assets"),
    )
}

/// [`assets`] on [`crate::scene::wall_band_tree`]: the same wall and shell, sampled with the
/// `distance` force model.
pub fn band_assets() -> Arc<ClusterAssets> {
    Arc::new(
        ClusterAssets::new(
            Arc::new(crate::scene::wall_band_tree()),
            &sphere_shell(600),
            CLASSES,
        )
        .expect("assets"),
    )
}

/// Workers [`loopback_coordinator`] makes certificates for.
pub const LOOPBACK_WORKERS: usize = 4;

/// A coordinator on loopback serving [`assets`], with fresh certificates written to `dir` and
/// pinned both ways (the [`LOOPBACK_WORKERS`] workers' are the only ones admitted, one live
/// connection each).
pub fn loopback_coordinator(dir: &std::path::Path) -> (Coordinator, LocalCerts) {
    loopback_coordinator_serving(dir, assets())
}

/// [`loopback_coordinator`] serving `assets` (e.g. [`two_part_assets`]).
pub fn loopback_coordinator_serving(
    dir: &std::path::Path,
    assets: Arc<ClusterAssets>,
) -> (Coordinator, LocalCerts) {
    let certs = local_cluster_certs(dir, LOOPBACK_WORKERS).expect("certificates");
    let coordinator = Coordinator::start(
        CoordinatorConfig {
            listen: "127.0.0.1:0".parse().expect("addr"),
            tls: PeerTls::load(
                &certs.coordinator.cert,
                &certs.coordinator.key,
                &certs.worker_pins(),
            )
            .expect("coordinator certificates"),
            keep_off: None,
        },
        assets,
    )
    .expect("coordinator starts");
    (coordinator, certs)
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

/// The logging hand ([`approach_and_rest_on_wall`]), raising `trip` at read number `trip_at`
/// (1-based; never when 0).
pub fn hand(trip_at: u64, trip: Arc<AtomicBool>) -> (Box<dyn HapticDevice>, Writes) {
    let (device, writes) = LoggingDevice::new(approach_and_rest_on_wall());
    (Box::new(device.trip_at(trip_at, trip)), writes)
}

/// The logging hand, running `hook` after every write.
pub fn hand_with_hook(hook: WriteHook) -> (Box<dyn HapticDevice>, Writes) {
    let (device, writes) = LoggingDevice::new(approach_and_rest_on_wall());
    (Box::new(device.with_hook(hook)), writes)
}

/// Default haptic parameters for [`VOXEL`] voxels and the sphere's radius.
pub fn params() -> HapticParams {
    HapticParams::default()
        .with_scene(VOXEL, SPHERE_RADIUS)
        .expect("valid parameters")
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
        parts: None,
    }
}

/// The standard test session over `coordinator`'s workers: [`params`], the part at rest at
/// [`START`], [`config_frames`]`(frames)`, `device`, with `gather` made exact (no stale
/// stand-ins, whatever the timing: these sessions are compared write by write with the
/// one-process run). Asserts that all `frames` frames ran and the watchdog never tripped; panics
/// on error.
pub fn exact_cluster_session(
    coordinator: &Coordinator,
    gather: GatherConfig,
    device: Box<dyn HapticDevice>,
    frames: u64,
) -> (LoopReport, ClusterReport) {
    let (report, cluster) = run_coordinator_session(
        coordinator,
        GatherConfig {
            stale: StalePolicy::NEVER,
            ..gather
        },
        standard_setup(device, frames),
    )
    .expect("cluster session");
    assert_eq!(report.stats.frames, frames);
    assert_eq!(report.stats.watchdog_trips, 0);
    (report, cluster)
}

/// Every device write of the one-process run of [`FRAMES`] frames.
pub fn one_process_writes() -> Vec<Wrench> {
    one_process_writes_for(FRAMES)
}

/// Every device write of the one-process run of `frames` frames (one per frame plus the final
/// zero wrench).
pub fn one_process_writes_for(frames: u64) -> Vec<Wrench> {
    let assets = assets();
    let (device, writes) = hand(0, Arc::new(AtomicBool::new(false)));
    let report = run_loop(
        assets.scene_map().clone(),
        assets.first_shell().clone(),
        standard_setup(device, frames),
    )
    .expect("one-process session");
    assert_eq!(report.stats.frames, frames);
    assert!(
        report.stats.contact_frames > 0,
        "the session must touch the wall"
    );
    let w = writes.lock().unwrap().clone();
    w
}

/// The command line of a one-thread `vps worker` dialling `coordinator` as local worker `k` of
/// `certs` (its own certificate: the coordinator admits one live connection per certificate),
/// pinning the coordinator's certificate, caching received voxmap and shell files in `cache_dir`. Panics when `certs` has
/// no worker `k`.
pub fn worker_args(
    coordinator: SocketAddr,
    certs: &LocalCerts,
    k: usize,
    cache_dir: Option<PathBuf>,
) -> LocalWorkerArgs {
    let mut args = certs
        .worker_args(k, coordinator, Some(1))
        .expect("a certificate for worker k");
    args.cache_dir = cache_dir;
    args
}

/// Starts the `vps` binary at `bin` (`env!("CARGO_BIN_EXE_vps")`) as `vps worker` with `args`,
/// stdin and stdout closed, stderr inherited.
pub fn spawn_worker(bin: &str, args: &LocalWorkerArgs) -> Child {
    Command::new(bin)
        .args(args.to_args())
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .spawn()
        .expect("start vps worker")
}

/// How far along +x the second sphere of [`two_part_setup`] starts and rests from the first (m):
/// a sphere's diameter less 5 mm, so the two spheres press into each other while both rest on
/// the wall.
pub const SECOND_OFFSET: f64 = 2.0 * SPHERE_RADIUS - 0.005;

/// The second sphere's logging hand: [`approach_and_rest_on_wall`] moved [`SECOND_OFFSET`] along
/// +x.
pub fn second_hand() -> (Box<dyn HapticDevice>, Writes) {
    let hand = crate::hand::approach_and_rest_on_wall_shifted(DVec3::X * SECOND_OFFSET);
    let (device, writes) = LoggingDevice::new(hand);
    (Box::new(device), writes)
}

/// The cluster assets of [`two_part_setup`]: the wall, both parts' 600-point sphere shells and
/// their [`sphere_body_tree`]s, in [`CLASSES`] classes.
pub fn two_part_assets() -> Arc<ClusterAssets> {
    let shell = sphere_shell(600);
    let body = Arc::new(sphere_body_tree());
    Arc::new(
        ClusterAssets::of_parts(
            Arc::new(wall_tree()),
            &[&shell, &shell],
            &[body.clone(), body],
            CLASSES,
        )
        .expect("two-part assets"),
    )
}

/// [`sphere_body`] as a voxel tree (uniform branching 2), as a session carries a body voxmap.
pub fn sphere_body_tree() -> vps_voxmap::VoxelTree {
    vps_voxmap::VoxelTree::from_dense(&sphere_body(), vps_voxmap::TreeConfig::uniform(2))
        .expect("valid tree config")
}

/// The sphere's voxmap in its own body frame: 12³ voxels of [`VOXEL`] about its centre; Interior
/// deeper than two voxels, Surface the two voxels inside its face, Proximity one voxel outside.
pub fn sphere_body() -> vps_voxmap::DenseGrid {
    use vps_voxmap::{DenseGrid, GridSpec, Voxel};
    let origin = DVec3::splat(-6.0 * VOXEL);
    let spec = GridSpec {
        origin,
        voxel_size: VOXEL,
        dims: [12, 12, 12],
    };
    DenseGrid::from_fn(spec, |ijk: glam::IVec3| {
        let r = (origin + (ijk.as_dvec3() + DVec3::splat(0.5)) * VOXEL).length();
        if r < SPHERE_RADIUS - 2.0 * VOXEL {
            Voxel::Interior
        } else if r < SPHERE_RADIUS {
            Voxel::Surface
        } else if r < SPHERE_RADIUS + VOXEL {
            Voxel::Proximity
        } else {
            Voxel::Free
        }
    })
}

/// The standard session with a second moving sphere ([`second_hand`]'s `second`) beside the
/// first: both rest on the wall pressing into each other. The second part samples the wall on
/// the frame thread (a one-thread local pool) unless the session's sampler takes every job (a
/// cluster serving [`two_part_assets`]); both carry [`sphere_body_tree`].
pub fn two_part_setup(
    device: Box<dyn HapticDevice>,
    second: Box<dyn HapticDevice>,
    frames: u64,
) -> SessionSetup {
    use vps_runtime::{ClassPool, MovingPart, PartBody, PartsSetup};
    let shell = assets().first_shell().clone();
    let body = PartBody {
        map: Arc::new(sphere_body_tree()),
        shell: shell.clone(),
        radius: 6.0 * VOXEL * 3f64.sqrt(),
    };
    let sampler = ClassPool::new(Arc::new(wall_tree()), shell, 1).expect("a pool");
    SessionSetup {
        parts: Some(PartsSetup {
            first: body.clone(),
            others: vec![MovingPart {
                name: "second".into(),
                params: params(),
                device: second,
                initial: PartState::at_rest(START + DVec3::X * SECOND_OFFSET, DQuat::IDENTITY),
                sampler: Box::new(sampler),
                body,
            }],
            margin: 2.0 * VOXEL,
        }),
        ..standard_setup(device, frames)
    }
}
