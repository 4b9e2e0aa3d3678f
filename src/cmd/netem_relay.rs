//! `vps netem-relay`: the userspace impairment relay (`vps_netem::relay`) between workers and a
//! coordinator, for kernels without the `netem` qdisc. Workers dial the relay's address instead
//! of the coordinator's.

use crate::cli::NetemRelayArgs;
use anyhow::Result;
use std::time::{Duration, Instant};
use vps_app::output::print_json;
use vps_netem::{Relay, RelayConfig, RelayStats};

/// How often a running relay prints its figures to stderr.
const PRINT_EVERY: Duration = Duration::from_secs(5);

/// Runs the relay for `--seconds` (or until killed), then prints its figures.
pub fn run(args: &NetemRelayArgs) -> Result<()> {
    let relay = Relay::start(RelayConfig {
        listen: args.listen,
        forward: args.forward,
        delay: args.delay,
        jitter: args.jitter,
        loss: args.loss,
        seed: args.seed,
    })?;
    eprintln!(
        "relaying {} -> {}: delay {:?} ± {:?}, loss {}, seed {}",
        relay.local_addr(),
        args.forward,
        args.delay,
        args.jitter,
        args.loss,
        args.seed
    );
    let until = args
        .seconds
        .map(|s| Instant::now() + Duration::from_secs_f64(s.max(0.0)));
    let mut next_print = Instant::now() + PRINT_EVERY;
    while until.is_none_or(|u| Instant::now() < u) {
        std::thread::sleep(Duration::from_millis(100));
        if Instant::now() >= next_print {
            eprintln!("{}", summary(&relay.stats()));
            next_print += PRINT_EVERY;
        }
    }
    let stats = relay.stop();
    if args.json {
        print_json(&stats)
    } else {
        println!("{}", summary(&stats));
        Ok(())
    }
}

/// One line per direction: counts, achieved loss and delay percentiles (µs).
fn summary(s: &RelayStats) -> String {
    let line = |name: &str, d: &vps_netem::relay::DirectionStats| {
        format!(
            "{name}: {} received, {} dropped ({:.2} %), {} sent; delay µs p50 {:.1} p99 {:.1} max {:.1} (min {:.1})",
            d.received,
            d.dropped,
            100.0 * d.achieved_loss,
            d.sent,
            d.achieved_delay_ns.p50 as f64 / 1e3,
            d.achieved_delay_ns.p99 as f64 / 1e3,
            d.achieved_delay_ns.max as f64 / 1e3,
            d.min_delay_ns as f64 / 1e3,
        )
    };
    format!(
        "{}\n{}",
        line("to coordinator", &s.to_forward),
        line("to workers", &s.to_clients)
    )
}
