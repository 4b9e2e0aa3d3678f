//! The cluster over an impaired network: `vps worker` processes reach the coordinator through the
//! userspace impairment relay (`vps_cluster::relay`, what `vps netem-relay` runs) adding
//! 100 µs ± 50 µs one-way delay and 1 % loss in each direction — on loopback, and from inside a
//! network namespace over a veth pair when this runs as root with `ip netns` (skipped with a
//! message otherwise). Lost requests and replies only move shares to the local fallback: no device
//! write is missed and every write is bit-identical, frame by frame, to the one-process run.

#[path = "../crates/vps-cluster/tests/common/fixtures.rs"]
mod fixtures;

use fixtures::*;
use std::net::{IpAddr, SocketAddr};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;
use vps_cluster::{ClusterReport, GatherConfig, LocalWorkerArgs, Relay, RelayConfig, RelayStats};
use vps_haptic::Wrench;

const WORKERS: usize = 2;

struct Children(Vec<Child>);

impl Drop for Children {
    fn drop(&mut self) {
        for child in &mut self.0 {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// One session whose workers dial a relay bound to `relay_ip`; `launcher` prefixes the worker
/// command line (e.g. `ip netns exec NS`).
fn session_behind_relay(
    relay_ip: IpAddr,
    launcher: &[&str],
) -> (Vec<Wrench>, ClusterReport, RelayStats) {
    let dir = tempfile::tempdir().unwrap();
    let (coordinator, certs) = loopback_coordinator(dir.path());
    let relay = Relay::start(RelayConfig {
        listen: SocketAddr::new(relay_ip, 0),
        forward: coordinator.local_addr().unwrap(),
        delay: Duration::from_micros(100),
        jitter: Duration::from_micros(50),
        loss: 0.01,
        seed: 2026,
    })
    .unwrap();
    let args = LocalWorkerArgs {
        coordinator: relay.local_addr(),
        cert: certs.worker.cert.clone(),
        key: certs.worker.key.clone(),
        pins: vec![certs.coordinator.cert.clone()],
        cache_dir: None,
        threads: Some(1),
    };
    let (program, prefix) = match launcher {
        [first, rest @ ..] => (*first, rest),
        [] => (env!("CARGO_BIN_EXE_vps"), &[][..]),
    };
    let _children = Children(
        (0..WORKERS)
            .map(|_| {
                let mut cmd = Command::new(program);
                cmd.args(prefix);
                if !launcher.is_empty() {
                    cmd.arg(env!("CARGO_BIN_EXE_vps"));
                }
                cmd.args(args.to_args())
                    .stdin(Stdio::null())
                    .stdout(Stdio::null())
                    .spawn()
                    .expect("start vps worker")
            })
            .collect(),
    );
    coordinator
        .wait_for_workers(WORKERS, Duration::from_secs(30))
        .unwrap();
    let (device, writes) = hand(0, Arc::new(AtomicBool::new(false)));
    let (report, cluster) = exact_cluster_session(
        &coordinator,
        GatherConfig {
            log_every: None,
            ..GatherConfig::default()
        },
        device,
        FRAMES,
    );
    assert_eq!(report.stats.frames, FRAMES);
    assert_eq!(report.stats.watchdog_trips, 0);
    let relay_stats = relay.stop();
    let writes = writes.lock().unwrap().clone();
    (writes, cluster, relay_stats)
}

fn check(writes: &[Wrench], cluster: &ClusterReport, relay: &RelayStats) {
    eprintln!("{cluster:#?}\n{relay:#?}");
    // One write per frame plus the final zero wrench, each bit-identical.
    assert_eq!(writes.len() as u64, FRAMES + 1, "no missed device write");
    assert_same_writes(writes, &one_process_writes());
    assert_eq!(cluster.peers.len(), WORKERS);
    assert!(cluster.peers.iter().all(|p| p.merged > 0), "{cluster:?}");
    for d in [&relay.to_forward, &relay.to_clients] {
        assert!(d.sent > 0, "{relay:?}");
        assert!(
            d.min_delay_ns >= 50_000,
            "the relay never sends early: {relay:?}"
        );
    }
    assert!(
        relay.to_forward.dropped + relay.to_clients.dropped > 0,
        "1 % loss over this many datagrams drops some: {relay:?}"
    );
}

#[test]
fn workers_behind_a_lossy_jittery_relay_on_loopback_change_no_bit() {
    let (writes, cluster, relay) = session_behind_relay([127, 0, 0, 1].into(), &[]);
    check(&writes, &cluster, &relay);
}

/// A network namespace joined to this one by a veth pair; removed on drop.
struct Namespace {
    name: String,
    host_ip: IpAddr,
}

impl Namespace {
    /// The reason, where namespaces cannot be made: not root, no `ip`, no veth.
    fn create() -> Result<Namespace, String> {
        if effective_uid() != 0 {
            return Err("not running as root".into());
        }
        let id = std::process::id();
        let name = format!("vpsnetem{id}");
        let (outer, inner) = (
            format!("vn{}a", id % 100_000),
            format!("vn{}b", id % 100_000),
        );
        let subnet = format!("10.199.{}", id % 250 + 1);
        let ns = Namespace {
            name: name.clone(),
            host_ip: format!("{subnet}.1").parse().unwrap(),
        };
        let steps: [&[&str]; 8] = [
            &["netns", "add", &name],
            &[
                "link", "add", &outer, "type", "veth", "peer", "name", &inner,
            ],
            &["link", "set", &inner, "netns", &name],
            &["addr", "add", &format!("{subnet}.1/30"), "dev", &outer],
            &["link", "set", &outer, "up"],
            &[
                "-n",
                &name,
                "addr",
                "add",
                &format!("{subnet}.2/30"),
                "dev",
                &inner,
            ],
            &["-n", &name, "link", "set", &inner, "up"],
            &["-n", &name, "link", "set", "lo", "up"],
        ];
        for step in steps {
            let out = Command::new("ip")
                .args(step)
                .output()
                .map_err(|e| format!("cannot run `ip`: {e}"))?;
            if !out.status.success() {
                return Err(format!(
                    "`ip {}` failed: {}",
                    step.join(" "),
                    String::from_utf8_lossy(&out.stderr).trim()
                ));
            }
        }
        Ok(ns)
    }
}

impl Drop for Namespace {
    fn drop(&mut self) {
        // Deleting the namespace deletes the veth pair with it.
        let _ = Command::new("ip")
            .args(["netns", "del", &self.name])
            .status();
    }
}

/// The effective user id, from `/proc/self/status` (no libc dependency here).
fn effective_uid() -> u32 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix("Uid:"))
                .and_then(|l| l.split_whitespace().nth(1))
                .and_then(|v| v.parse().ok())
        })
        .unwrap_or(u32::MAX)
}

#[test]
fn workers_in_a_network_namespace_behind_the_relay_change_no_bit() {
    let ns = match Namespace::create() {
        Ok(ns) => ns,
        Err(why) => {
            eprintln!(
                "SKIPPED: network namespaces unavailable ({why}); the loopback test still ran"
            );
            return;
        }
    };
    let (writes, cluster, relay) =
        session_behind_relay(ns.host_ip, &["ip", "netns", "exec", &ns.name]);
    check(&writes, &cluster, &relay);
}
