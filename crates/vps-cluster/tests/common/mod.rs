//! Shared fixtures: a wall voxmap, a sphere shell, poses that touch and brake, TLS identities,
//! in-process workers on threads.
#![allow(dead_code)]

use glam::{DQuat, DVec3, IVec3, Vec3};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::sync::Mutex;
use std::thread::JoinHandle;
use std::time::Duration;
use vps_cluster::{
    run_worker_until, ClusterError, ClusterScene, Coordinator, CoordinatorConfig, TlsIdentity,
    WorkerConfig, WorkerReport,
};
use vps_device::script::{approach_and_rest, Pace};
use vps_device::{
    DeviceError, DeviceLimits, HandParams, HapticDevice, SimulatedHand, SurfaceContact,
};
use vps_haptic::{HandleSample, HapticParams, Wrench};
use vps_haptic::{KernelPose, PartState};
use vps_runtime::{run_loop, LoopConfig};
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{DenseGrid, GridSpec, MassProperties, PointShell, TreeConfig, Voxel, VoxelTree};

pub const VOXEL: f64 = 0.005;
pub const RADIUS: f64 = 0.015;
pub const CLASSES: u32 = 64;

/// A 5 mm wall: Interior below z index 8, Surface at 8–9, Proximity at 10, face at z = 0.05 m.
pub fn wall() -> VoxelTree {
    let spec = GridSpec {
        origin: DVec3::ZERO,
        voxel_size: VOXEL,
        dims: [20, 20, 20],
    };
    let mut g = DenseGrid::new(spec);
    for z in 0..11 {
        let kind = match z {
            0..=7 => Voxel::Interior,
            8 | 9 => Voxel::Surface,
            _ => Voxel::Proximity,
        };
        for y in 0..20 {
            for x in 0..20 {
                g.set(IVec3::new(x, y, z), kind);
            }
        }
    }
    VoxelTree::from_dense(&g, TreeConfig::uniform(2)).expect("valid tree config")
}

/// `n` points on a sphere of radius [`RADIUS`] (Fibonacci lattice), inward normals.
pub fn sphere_shell(n: usize) -> PointShell {
    let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
    let (points, normals) = (0..n)
        .map(|i| {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).sqrt();
            let phi = golden * i as f32;
            let dir = Vec3::new(r * phi.cos(), y, r * phi.sin());
            (dir * RADIUS as f32, -dir)
        })
        .unzip();
    PointShell {
        points,
        normals,
        voxel_size: VOXEL,
        method: ShellMethod::ExactSurface,
        mass: MassProperties {
            volume: 4.0 / 3.0 * std::f64::consts::PI * RADIUS.powi(3),
            center_of_mass: DVec3::ZERO,
            bounding_radius: RADIUS,
        },
    }
}

pub fn scene() -> Arc<ClusterScene> {
    Arc::new(ClusterScene::new(Arc::new(wall()), &sphere_shell(600), CLASSES).expect("scene"))
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

pub struct Identities {
    pub coordinator: TlsIdentity,
    pub worker: TlsIdentity,
}

pub fn identities() -> Identities {
    Identities {
        coordinator: TlsIdentity::generate("coordinator").expect("cert"),
        worker: TlsIdentity::generate("worker").expect("cert"),
    }
}

pub fn start_coordinator(ids: &Identities, scene: Arc<ClusterScene>) -> Coordinator {
    Coordinator::start(
        CoordinatorConfig {
            listen: "127.0.0.1:0".parse().expect("addr"),
            identity: ids.coordinator.clone(),
            pins: vec![ids.worker.cert.clone()],
        },
        scene,
    )
    .expect("coordinator starts")
}

pub fn worker_config(ids: &Identities, addr: SocketAddr) -> WorkerConfig {
    WorkerConfig {
        coordinator: addr,
        identity: ids.worker.clone(),
        pins: vec![ids.coordinator.cert.clone()],
        cache_dir: None,
        threads: 1,
    }
}

/// A worker on a thread, with its stop flag.
pub struct ThreadWorker {
    pub stop: Arc<AtomicBool>,
    pub thread: JoinHandle<Result<WorkerReport, ClusterError>>,
}

impl ThreadWorker {
    pub fn spawn(config: WorkerConfig) -> ThreadWorker {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::spawn(move || run_worker_until(config, flag));
        ThreadWorker { stop, thread }
    }

    pub fn stop(self) -> Result<WorkerReport, ClusterError> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.join().expect("worker thread does not panic")
    }
}

/// Generous per-frame deadline for correctness tests (results never depend on it).
pub const DEADLINE: Duration = Duration::from_millis(100);

/// A hand-driven worker connection (for misbehaving-peer tests): connects with `identity`, runs
/// the join exchange with Hello `version`, and returns the connection (or the join error).
pub struct FakeWorker {
    pub runtime: tokio::runtime::Runtime,
    pub endpoint: quinn::Endpoint,
}

impl FakeWorker {
    pub fn new(identity: &TlsIdentity, coordinator_cert: &TlsIdentity) -> FakeWorker {
        let runtime = tokio::runtime::Builder::new_multi_thread()
            .worker_threads(1)
            .enable_all()
            .build()
            .expect("runtime");
        let mut endpoint = {
            let _g = runtime.enter();
            quinn::Endpoint::client("127.0.0.1:0".parse().expect("addr")).expect("endpoint")
        };
        endpoint.set_default_client_config(
            vps_cluster::tls::client_config(
                identity,
                vec![coordinator_cert.cert.clone()],
                Arc::new(std::sync::atomic::AtomicU64::new(0)),
            )
            .expect("client config"),
        );
        FakeWorker { runtime, endpoint }
    }

    pub fn join(&self, addr: SocketAddr, version: u16) -> Result<quinn::Connection, String> {
        use vps_cluster::protocol::{read_frame, read_join, write_join, JoinMessage};
        let endpoint = self.endpoint.clone();
        self.runtime.block_on(async move {
            let conn = endpoint
                .connect(addr, vps_cluster::tls::SERVER_NAME)
                .map_err(|e| e.to_string())?
                .await
                .map_err(|e| e.to_string())?;
            let (mut send, mut recv) = conn.open_bi().await.map_err(|e| e.to_string())?;
            write_join(&mut send, &JoinMessage::Hello { version })
                .await
                .map_err(|e| e.to_string())?;
            match read_join(&mut recv).await.map_err(|e| e.to_string())? {
                JoinMessage::Welcome { .. } => {}
                other => return Err(format!("{other:?}")),
            }
            write_join(
                &mut send,
                &JoinMessage::Need {
                    voxmap: true,
                    shell: true,
                },
            )
            .await
            .map_err(|e| e.to_string())?;
            for _ in 0..2 {
                read_frame(&mut recv, 1 << 30)
                    .await
                    .map_err(|e| e.to_string())?;
            }
            write_join(&mut send, &JoinMessage::Ready)
                .await
                .map_err(|e| e.to_string())?;
            Ok(conn)
        })
    }

    /// The next datagram from the coordinator, or None after `timeout`.
    pub fn next_datagram(
        &self,
        conn: &quinn::Connection,
        timeout: Duration,
    ) -> Option<bytes::Bytes> {
        let conn = conn.clone();
        self.runtime.block_on(async move {
            tokio::time::timeout(timeout, conn.read_datagram())
                .await
                .ok()
                .and_then(|r| r.ok())
        })
    }
}

// ---- whole-session fixtures ----

pub const START: DVec3 = DVec3::new(0.05, 0.05, 0.09);
pub const FRAMES: u64 = 400;

pub type Writes = Arc<Mutex<Vec<Wrench>>>;

/// A simulated hand that logs every write and raises `trip` at read number `trip_at`.
struct Logged {
    inner: SimulatedHand,
    writes: Writes,
    reads: u64,
    trip_at: u64,
    trip: Arc<AtomicBool>,
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
        self.writes.lock().unwrap().push(*w);
        self.inner.write(w)
    }
    fn limits(&self) -> DeviceLimits {
        self.inner.limits()
    }
    fn name(&self) -> &str {
        self.inner.name()
    }
}

pub fn hand(trip_at: u64, trip: Arc<AtomicBool>) -> (Box<dyn HapticDevice>, Writes) {
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
    };
    (Box::new(device), writes)
}

pub fn params() -> HapticParams {
    HapticParams::default().with_scene(VOXEL, RADIUS).unwrap()
}

/// Free-running; the watchdog is far above any frame's compute so that no frame is zeroed, and
/// replies are awaited up to half of it.
pub fn config() -> LoopConfig {
    LoopConfig {
        frames: Some(FRAMES),
        free_running: true,
        watchdog: Duration::from_millis(200),
        ..LoopConfig::default()
    }
}

pub fn one_process_writes() -> Vec<Wrench> {
    let scene = scene();
    let (device, writes) = hand(0, Arc::new(AtomicBool::new(false)));
    let report = run_loop(
        scene.map.clone(),
        scene.shell.clone(),
        params(),
        device,
        PartState::at_rest(START, DQuat::IDENTITY),
        config(),
        None,
        Arc::new(AtomicBool::new(false)),
    )
    .unwrap();
    assert_eq!(report.stats.frames, FRAMES);
    assert!(
        report.stats.contact_frames > 0,
        "the session must touch the wall"
    );
    let w = writes.lock().unwrap().clone();
    w
}
