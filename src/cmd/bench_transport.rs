//! `vps bench transport`: the cluster's gather round trip to 1 and 2 local worker processes beside a
//! raw UDP ping-pong on the same host, measured in the same run.
//!
//! Gather round trip: frame request datagram sent → that worker's reply datagram received by the
//! coordinator's network task, as recorded per worker by `vps-cluster` for replies that arrive
//! before the reply deadline. To measure the transport rather than this machine's deadline, the
//! session runs frames back to back with a 10 ms watchdog (5 ms reply deadline), so every reply is
//! waited for. Raw UDP: blocking sockets on 127.0.0.1, 200-byte payload, one echo thread.

use super::cluster::run_local_cluster;
use super::output::print_json;
use crate::cli::{GatherArgs, RunArgs};
use anyhow::Result;
use serde::Serialize;
use std::time::Duration;
use vps_cluster::transport_bench::{percentiles, raw_udp_round_trips, TransportPercentiles};
use vps_cluster::PeerReport;

#[derive(Serialize)]
struct GatherFigure {
    workers: usize,
    frames: u64,
    peers: Vec<PeerReport>,
    worst_p999_ns: u64,
    worst_p999_over_raw_udp_p999: f64,
}

#[derive(Serialize)]
struct TransportReport {
    /// The coordinator's spin margin (`--spin-us`).
    spin_us: u64,
    raw_udp: TransportPercentiles,
    raw_udp_round_trips: usize,
    gather: Vec<GatherFigure>,
}

/// Runs the benchmark and prints JSON.
pub fn run(frames: u64, spin_us: u64) -> Result<()> {
    let raw = raw_udp_round_trips(frames as usize, 200)?;
    let raw_udp = percentiles(&raw);
    let mut gather = Vec::new();
    for workers in [1, 2] {
        let session = RunArgs {
            seconds: frames as f64 / 1000.0,
            ..RunArgs::default()
        };
        // Equal shares: the round trip of a fixed share is what is compared with raw UDP.
        let choice = GatherArgs {
            equal_shares: true,
            spin_us,
            ..GatherArgs::default()
        };
        let run = run_local_cluster(&session, workers, 1, choice, |config| {
            config.free_running = true;
            config.realtime = false;
            config.watchdog = Duration::from_millis(10);
        })?;
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
            worst_p999_over_raw_udp_p999: worst as f64 / raw_udp.p999_ns.max(1) as f64,
            peers: run.cluster.peers,
        });
    }
    print_json(&TransportReport {
        spin_us,
        raw_udp,
        raw_udp_round_trips: raw.len(),
        gather,
    })
}
