//! Shared fixtures: TLS identities, in-process workers on threads, a hand-driven fake worker;
//! the scene, the standard session and the one-process run are `vps_testkit::cluster`'s.
#![allow(dead_code)]

pub use vps_testkit::cluster::*;

use vps_haptic::{sample_all, KernelPose};
use vps_runtime::FrameSampler;

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use vps_cluster::{
    run_worker_until, ClusterAssets, ClusterError, Coordinator, CoordinatorConfig, GatherConfig,
    PeerTls, RemoteShares, TlsIdentity, WorkerConfig, WorkerReport,
};

/// The gatherer's defaults, but splitting every frame (`--split always`): these tests exercise
/// the split itself, on a scene too small for the prediction ever to favour it.
pub fn split_always() -> GatherConfig {
    GatherConfig {
        predict: false,
        ..GatherConfig::default()
    }
}

pub struct Identities {
    pub coordinator: TlsIdentity,
    /// Worker 0's identity.
    pub worker: TlsIdentity,
    /// Workers 1, 2, …: the coordinator admits one live connection per certificate.
    pub others: Vec<TlsIdentity>,
}

pub fn identities() -> Identities {
    Identities {
        coordinator: TlsIdentity::generate("coordinator").expect("cert"),
        worker: TlsIdentity::generate("worker").expect("cert"),
        others: (1..3)
            .map(|k| TlsIdentity::generate(&format!("worker-{k}")).expect("cert"))
            .collect(),
    }
}

impl Identities {
    /// Worker `k`'s identity (0: [`Identities::worker`]).
    pub fn worker_k(&self, k: usize) -> &TlsIdentity {
        if k == 0 {
            &self.worker
        } else {
            &self.others[k - 1]
        }
    }
}

pub fn start_coordinator(ids: &Identities, scene: Arc<ClusterAssets>) -> Coordinator {
    Coordinator::start(
        CoordinatorConfig {
            listen: "127.0.0.1:0".parse().expect("addr"),
            tls: PeerTls {
                identity: ids.coordinator.clone(),
                pins: std::iter::once(&ids.worker)
                    .chain(&ids.others)
                    .map(|w| w.cert.clone())
                    .collect(),
            },
            keep_off: None,
        },
        scene,
    )
    .expect("coordinator starts")
}

pub fn worker_config(ids: &Identities, addr: SocketAddr) -> WorkerConfig {
    worker_config_k(ids, addr, 0)
}

/// Worker `k`'s config (its own certificate).
pub fn worker_config_k(ids: &Identities, addr: SocketAddr, k: usize) -> WorkerConfig {
    WorkerConfig {
        coordinator: addr,
        tls: PeerTls {
            identity: ids.worker_k(k).clone(),
            pins: vec![ids.coordinator.cert.clone()],
        },
        cache_dir: None,
        threads: 1,
    }
}

/// A coordinator on `scene` and `n` in-process workers on threads, all joined.
pub fn coordinator_with_thread_workers(
    ids: &Identities,
    scene: Arc<ClusterAssets>,
    n: usize,
) -> (Coordinator, Vec<ThreadWorker>) {
    let coordinator = start_coordinator(ids, scene);
    let addr = coordinator.local_addr().unwrap();
    let workers: Vec<_> = (0..n)
        .map(|k| ThreadWorker::spawn(worker_config_k(ids, addr, k)))
        .collect();
    coordinator
        .wait_for_workers(n, Duration::from_secs(8))
        .unwrap();
    (coordinator, workers)
}

/// Computes every pose of `poses` through `shares` (replies awaited until `deadline` after the
/// request) and asserts that each frame's sums equal the one-process sums, to the bit.
pub fn assert_exact_frames(
    shares: &mut RemoteShares,
    scene: &ClusterAssets,
    poses: &[KernelPose],
    deadline: Duration,
) {
    for (i, pose) in poses.iter().enumerate() {
        let want = sample_all(&**scene.scene_map(), scene.first_shell(), pose);
        let got = shares.compute(pose, Instant::now() + deadline);
        assert_eq!(got.sums, want, "frame {i}: bad shares are recomputed");
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
                &PeerTls {
                    identity: identity.clone(),
                    pins: vec![coordinator_cert.cert.clone()],
                },
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
            write_join(&mut send, &JoinMessage::Need { files: 0b11 })
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

/// Three datagrams shaped like QUIC that no vps endpoint can own: a short header naming a
/// connection ID nobody issued, a long header of a version quinn does not speak, and a Handshake
/// packet naming a stranger's ID. Each is counted as `udp_foreign` by the endpoint receiving it.
pub fn quic_shaped_garbage() -> Vec<Vec<u8>> {
    let mut short = vec![0x41];
    short.extend([0x5A; 99]);
    let mut unknown_version = vec![0xC3, 0x0a, 0x0a, 0x0a, 0x0a, 8];
    unknown_version.resize(1200, 0x33);
    let mut handshake = vec![0xE0, 0, 0, 0, 1, 8];
    handshake.resize(200, 0x77);
    vec![short, unknown_version, handshake]
}
