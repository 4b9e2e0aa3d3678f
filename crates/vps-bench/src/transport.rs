//! `vps bench transport`: the cluster's gather round trip to 1 and 2 local worker processes beside a
//! raw UDP ping-pong on the same host, measured in the same run.
//!
//! Gather round trip: frame request datagram sent → that worker's reply datagram received by the
//! coordinator's network task, as recorded per worker by `vps-cluster` for replies that arrive
//! before the reply deadline. To measure the transport rather than this machine's deadline, the
//! session runs frames back to back with a 10 ms watchdog (5 ms reply deadline), so every reply is
//! waited for. Raw UDP: blocking sockets on 127.0.0.1, 200-byte payload, one echo thread, run in
//! three placements (unpinned, both threads on the last core, pinger on the first and echo on the
//! last), because on a VM where the two threads run decides how fast they wake each other.

use anyhow::{Context, Result};
use serde::Serialize;
use std::time::Duration;
use vps_app::output::print_report;
use vps_app::prepare::prepare;
use vps_app::{ClusterBackend, SessionRequest, Workers};
use vps_cluster::GatherConfig;
use vps_cluster::PeerReport;
use vps_netem::transport_bench::{
    percentiles, raw_udp_round_trips, TransportPercentiles, UdpPlacement,
};

/// The raw UDP ping-pong in one placement.
#[derive(Serialize)]
struct RawUdpFigure {
    placement: UdpPlacement,
    round_trips: usize,
    #[serde(flatten)]
    percentiles: TransportPercentiles,
}

/// A gather's worst p99.9 divided by each raw UDP placement's p99.9.
#[derive(Serialize)]
struct Ratios {
    unpinned: f64,
    same_core: f64,
    cross_core: f64,
}

#[derive(Serialize)]
struct GatherFigure {
    workers: usize,
    frames: u64,
    peers: Vec<PeerReport>,
    worst_p999_ns: u64,
    /// Against the unpinned ping-pong (the OS places both, as it places the gather's threads).
    worst_p999_over_raw_udp_p999: f64,
    worst_p999_over_raw_udp_p999_by_placement: Ratios,
}

#[derive(Serialize)]
struct TransportReport {
    /// The coordinator's spin margin (`--spin-us`).
    spin_us: u64,
    host_idle: crate::machine::HostIdle,
    /// The unpinned ping-pong (the headline baseline).
    raw_udp: TransportPercentiles,
    raw_udp_round_trips: usize,
    /// Unpinned, both threads on the last core, pinger on the first core and echo on the last.
    raw_udp_placements: Vec<RawUdpFigure>,
    gather: Vec<GatherFigure>,
}

/// Runs the benchmark and prints JSON.
pub fn run(frames: u64, spin_us: u64, json: bool) -> Result<()> {
    let cores = core_affinity::get_core_ids().unwrap_or_default();
    let first = cores.first().map_or(0, |c| c.id);
    let last = cores.last().map_or(0, |c| c.id);
    let mut raw_udp_placements = Vec::new();
    for placement in [
        UdpPlacement::Unpinned,
        UdpPlacement::SameCore(last),
        UdpPlacement::CrossCore(first, last),
    ] {
        let times = raw_udp_round_trips(frames as usize, 200, placement)
            .with_context(|| format!("raw UDP ping-pong, {placement:?}"))?;
        raw_udp_placements.push(RawUdpFigure {
            placement,
            round_trips: times.len(),
            percentiles: percentiles(&times),
        });
    }
    let raw_udp = raw_udp_placements[0].percentiles;
    let p999 = |i: usize| raw_udp_placements[i].percentiles.p999_ns.max(1) as f64;
    let mut gather = Vec::new();
    for workers in [1, 2] {
        let session = SessionRequest {
            seconds: Some(frames as f64 / 1000.0),
            ..SessionRequest::default()
        };
        // Equal shares, split every frame: the round trip of a fixed share is what is compared
        // with raw UDP (the predicted split would keep this small shell local and measure only
        // its rare probes).
        let gather_config = GatherConfig {
            adaptive_shares: false,
            predict: false,
            spin_margin: Duration::from_micros(spin_us),
            ..GatherConfig::default()
        };
        let mut prepared = prepare(&session)?;
        let config = &mut prepared.plan.setup.config;
        config.free_running = true;
        config.realtime = false;
        config.watchdog = Duration::from_millis(10);
        let run = prepared.run_coordinated(ClusterBackend {
            workers: Workers::Local {
                count: workers,
                threads: 1,
            },
            gather: gather_config,
        })?;
        vps_app::exit::require_complete(&run.report.end, Some(&run.signals))?;
        let worst = run
            .cluster
            .peers
            .iter()
            .map(|p| p.rtt_ns.p999)
            .max()
            .unwrap_or(0);
        gather.push(GatherFigure {
            workers,
            frames: run.report.stats.frames,
            worst_p999_ns: worst,
            worst_p999_over_raw_udp_p999: worst as f64 / p999(0),
            worst_p999_over_raw_udp_p999_by_placement: Ratios {
                unpinned: worst as f64 / p999(0),
                same_core: worst as f64 / p999(1),
                cross_core: worst as f64 / p999(2),
            },
            peers: run.cluster.peers,
        });
    }
    print_report(
        "bench transport: gather round trip to local worker processes beside a raw UDP ping-pong",
        &TransportReport {
            spin_us,
            host_idle: crate::machine::HostIdle::read(),
            raw_udp,
            raw_udp_round_trips: raw_udp_placements[0].round_trips,
            raw_udp_placements,
            gather,
        },
        json,
    )
}
