//! The cluster over an impaired network: `vps worker` processes reach the coordinator through the
//! userspace impairment relay (`vps_netem::relay`, what `vps netem-relay` runs) adding
//! 100 µs ± 50 µs one-way delay and 1 % loss in each direction — on loopback, and with each worker
//! on its own simulated host (a network namespace joined by its own veth pair) when this runs as
//! root with `ip netns` (skipped with a message otherwise). Lost requests and replies only move shares to the local fallback: no device
//! write is missed and every write is bit-identical, frame by frame, to the one-process run; also
//! for a session of two moving parts pressing into each other (both devices' writes).

use std::net::{IpAddr, SocketAddr};
use std::process::{Command, Stdio};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;
use vps_cluster::fallback::StalePolicy;
use vps_cluster::{run_coordinator_session, ClusterAssets, ClusterReport, GatherConfig};
use vps_haptic::Wrench;
use vps_netem::{Relay, RelayConfig, RelayStats};
use vps_runtime::{run_loop, LoopReport, SessionSetup};
use vps_testkit::cluster::*;
use vps_testkit::process::Children;

const WORKERS: usize = 2;

/// Where one worker runs: the relay address it dials, and the command prefix that starts it
/// on its host (empty: this one; `ip netns exec NS`: a namespace).
struct WorkerHost {
    relay_ip: IpAddr,
    launcher: Vec<String>,
}

/// One session of one worker per host, each dialling the relay bound to `listen_ip`.
fn session_behind_relay(
    listen_ip: IpAddr,
    hosts: &[WorkerHost],
) -> (Vec<Wrench>, ClusterReport, RelayStats) {
    let (device, writes) = hand(0, Arc::new(AtomicBool::new(false)));
    let (_, cluster, relay) = session_of_behind_relay(listen_ip, hosts, assets(), || {
        (standard_setup(device, FRAMES), vec![writes])
    });
    let writes = relay.1[0].lock().unwrap().clone();
    (writes, cluster, relay.0)
}

/// The session `make` sets up (with the logs of its devices' writes) over one worker per host,
/// each dialling the relay bound to `listen_ip`, gathering exactly (no stale stand-ins): the
/// loop's and the cluster's reports, and the relay's figures with the logs.
fn session_of_behind_relay(
    listen_ip: IpAddr,
    hosts: &[WorkerHost],
    assets: Arc<ClusterAssets>,
    make: impl FnOnce() -> (SessionSetup, Vec<Writes>),
) -> (LoopReport, ClusterReport, (RelayStats, Vec<Writes>)) {
    let dir = tempfile::tempdir().unwrap();
    let (coordinator, certs) = loopback_coordinator_serving(dir.path(), assets);
    let relay = Relay::start(RelayConfig {
        listen: SocketAddr::new(listen_ip, 0),
        forward: coordinator.local_addr().unwrap(),
        delay: Duration::from_micros(100),
        jitter: Duration::from_micros(50),
        loss: 0.01,
        seed: 2026,
    })
    .unwrap();
    let _children = Children(
        hosts
            .iter()
            .enumerate()
            .map(|(k, host)| {
                let relay_addr = SocketAddr::new(host.relay_ip, relay.local_addr().port());
                let args = worker_args(relay_addr, &certs, k, None);
                let mut cmd = match host.launcher.split_first() {
                    Some((program, prefix)) => {
                        let mut cmd = Command::new(program);
                        cmd.args(prefix).arg(env!("CARGO_BIN_EXE_vps"));
                        cmd
                    }
                    None => Command::new(env!("CARGO_BIN_EXE_vps")),
                };
                cmd.args(args.to_args())
                    .stdin(Stdio::null())
                    .stdout(Stdio::null())
                    .spawn()
                    .expect("start vps worker")
            })
            .collect(),
    );
    coordinator
        .wait_for_workers(hosts.len(), Duration::from_secs(30))
        .unwrap();
    let (setup, writes) = make();
    let (report, cluster) = run_coordinator_session(
        &coordinator,
        GatherConfig {
            log_every: None,
            // These tests exercise the split itself (`--split always`).
            predict: false,
            stale: StalePolicy::NEVER,
            ..GatherConfig::default()
        },
        setup,
    )
    .expect("cluster session");
    assert_eq!(report.stats.watchdog_trips, 0);
    let relay_stats = relay.stop();
    (report, cluster, (relay_stats, writes))
}

fn check(writes: &[Wrench], cluster: &ClusterReport, relay: &RelayStats) {
    eprintln!("{cluster:#?}\n{relay:#?}");
    // One write per frame plus the final zero wrench, each bit-identical.
    assert_eq!(writes.len() as u64, FRAMES + 1, "no missed device write");
    assert_same_writes(writes, &one_process_writes());
    assert_eq!(cluster.peers.len(), WORKERS);
    assert_eq!(relay.clients, WORKERS as u64, "{relay:?}");
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

/// Two moving spheres pressing into each other on the wall: every job's shares (both parts in
/// the scene, both directions of the pair) go over the lossy relay, and both devices' writes are
/// bit-identical, frame by frame, to the one-process run.
#[test]
fn two_parts_behind_a_lossy_relay_change_no_bit() {
    let one_process = {
        let (first, a) = hand(0, Arc::new(AtomicBool::new(false)));
        let (second, b) = second_hand();
        let assets = assets();
        let report = run_loop(
            assets.scene_map().clone(),
            assets.first_shell().clone(),
            two_part_setup(first, second, FRAMES),
        )
        .expect("one-process session");
        assert!(
            report.pair_contact_frames > 100,
            "the spheres press: {report:?}"
        );
        [a, b].map(|w| w.lock().unwrap().clone())
    };
    let (loopback, hosts) = loopback_hosts();
    let (report, cluster, (relay, writes)) =
        session_of_behind_relay(loopback, &hosts, two_part_assets(), || {
            let (first, a) = hand(0, Arc::new(AtomicBool::new(false)));
            let (second, b) = second_hand();
            (two_part_setup(first, second, FRAMES), vec![a, b])
        });
    assert!(report.pairs.sampled > 100, "{:?}", report.pairs);
    assert_eq!(
        cluster.job_samples,
        2 * FRAMES + 2 * report.pairs.sampled,
        "the workers were given every job"
    );
    assert_eq!(
        report.pair_contact_frames,
        report.other_parts[0].pair_contact_frames
    );
    for (got, want) in writes.iter().zip(&one_process) {
        let got = got.lock().unwrap().clone();
        assert_eq!(got.len() as u64, FRAMES + 1, "no missed device write");
        assert_same_writes(&got, want);
    }
    assert!(cluster.peers.iter().all(|p| p.merged > 0), "{cluster:?}");
    assert!(
        relay.to_forward.dropped + relay.to_clients.dropped > 0,
        "1 % loss over this many datagrams drops some: {relay:?}"
    );
}

#[test]
fn workers_behind_a_lossy_jittery_relay_on_loopback_change_no_bit() {
    let (loopback, hosts) = loopback_hosts();
    let (writes, cluster, relay) = session_behind_relay(loopback, &hosts);
    check(&writes, &cluster, &relay);
}

/// The loopback address and [`WORKERS`] workers on this host reaching the relay there.
fn loopback_hosts() -> (IpAddr, Vec<WorkerHost>) {
    let loopback: IpAddr = [127, 0, 0, 1].into();
    let hosts = (0..WORKERS)
        .map(|_| WorkerHost {
            relay_ip: loopback,
            launcher: Vec::new(),
        })
        .collect();
    (loopback, hosts)
}

/// A network namespace joined to this one by a veth pair; removed on drop.
struct Namespace {
    name: String,
    host_ip: IpAddr,
}

impl Namespace {
    /// Namespace `index` of this test process (at most 9), on its own /30 subnet; the reason
    /// where namespaces cannot be made: not root, no `ip`, no veth.
    fn create(index: u32) -> Result<Namespace, String> {
        if effective_uid() != 0 {
            return Err("not running as root".into());
        }
        let id = std::process::id();
        let name = format!("vpsnetem{id}n{index}");
        let (outer, inner) = (
            format!("vn{}{index}a", id % 100_000),
            format!("vn{}{index}b", id % 100_000),
        );
        let subnet = format!("10.{}.{}", 190 + index, id % 250 + 1);
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
fn workers_on_separate_simulated_hosts_behind_the_relay_change_no_bit() {
    let namespaces: Result<Vec<Namespace>, String> =
        (0..WORKERS as u32).map(Namespace::create).collect();
    let namespaces = match namespaces {
        Ok(ns) => ns,
        Err(why) => {
            eprintln!(
                "SKIPPED: network namespaces unavailable ({why}); the loopback test still ran"
            );
            return;
        }
    };
    // The relay listens on every address; each worker dials the host side of its own veth pair.
    let hosts: Vec<WorkerHost> = namespaces
        .iter()
        .map(|ns| WorkerHost {
            relay_ip: ns.host_ip,
            launcher: ["ip", "netns", "exec", &ns.name].map(String::from).to_vec(),
        })
        .collect();
    let (writes, cluster, relay) = session_behind_relay([0, 0, 0, 0].into(), &hosts);
    check(&writes, &cluster, &relay);
}
