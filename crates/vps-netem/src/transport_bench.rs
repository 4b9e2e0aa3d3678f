//! The raw UDP baseline of `vps bench transport`: a ping-pong on loopback, to compare the cluster's
//! gather round trip against in the same run. Blocking sockets and a plain echo thread: the
//! cheapest round trip this host's network stack offers. Where the two threads run decides how
//! they wake each other (on one core: a local wake-up; on two: an inter-processor interrupt,
//! which in a VM may wait for the host to run a halted vCPU), so the ping-pong can be pinned
//! ([`UdpPlacement`]).

use serde::Serialize;
use std::net::UdpSocket;
use std::time::{Duration, Instant};

/// Nearest-rank percentiles of a set of durations (ns): round trips here, late starts in
/// `vps bench host`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct TransportPercentiles {
    /// Median (ns).
    pub p50_ns: u64,
    /// 99th percentile (ns).
    pub p99_ns: u64,
    /// 99.9th percentile (ns).
    pub p999_ns: u64,
    /// Largest (ns).
    pub max_ns: u64,
}

/// Nearest-rank percentiles of `samples`; all zero for no samples. Allocates a sorted copy.
pub fn percentiles(samples: &[Duration]) -> TransportPercentiles {
    if samples.is_empty() {
        return TransportPercentiles::default();
    }
    let mut ns: Vec<u64> = samples
        .iter()
        .map(|d| d.as_nanos().min(u64::MAX as u128) as u64)
        .collect();
    ns.sort_unstable();
    let rank = |q: f64| ns[((q * ns.len() as f64).ceil() as usize).clamp(1, ns.len()) - 1];
    TransportPercentiles {
        p50_ns: rank(0.5),
        p99_ns: rank(0.99),
        p999_ns: rank(0.999),
        max_ns: ns[ns.len() - 1],
    }
}

/// Where the two ends of the raw UDP ping-pong run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum UdpPlacement {
    /// Wherever the OS puts them.
    Unpinned,
    /// Both threads pinned to this core.
    SameCore(usize),
    /// The pinging thread on the first core, the echo thread on the second.
    CrossCore(usize, usize),
}

impl UdpPlacement {
    fn cores(self) -> (Option<usize>, Option<usize>) {
        match self {
            UdpPlacement::Unpinned => (None, None),
            UdpPlacement::SameCore(c) => (Some(c), Some(c)),
            UdpPlacement::CrossCore(ping, echo) => (Some(ping), Some(echo)),
        }
    }
}

/// Pins the calling thread to `core`, if one is given.
fn pin_to(core: Option<usize>) -> std::io::Result<()> {
    match core {
        Some(c) => vps_runtime::pin_current_thread(Some(c))
            .map(drop)
            .map_err(std::io::Error::other),
        None => Ok(()),
    }
}

/// `n` UDP round trips of `payload` bytes to an echo thread on 127.0.0.1, the two threads placed
/// as `placement` says (the pinging one is a new thread too, so the caller's affinity is left
/// alone); returns each round trip's time. Blocks for the whole run; a round trip that takes over
/// a second, or a core that cannot be used, is an error.
pub fn raw_udp_round_trips(
    n: usize,
    payload: usize,
    placement: UdpPlacement,
) -> std::io::Result<Vec<Duration>> {
    let (ping_core, echo_core) = placement.cores();
    let echo = UdpSocket::bind("127.0.0.1:0")?;
    let client = UdpSocket::bind("127.0.0.1:0")?;
    let echo_addr = echo.local_addr()?;
    echo.set_read_timeout(Some(Duration::from_secs(1)))?;
    client.set_read_timeout(Some(Duration::from_secs(1)))?;
    client.connect(echo_addr)?;
    let echo_thread = std::thread::spawn(move || -> std::io::Result<()> {
        pin_to(echo_core)?;
        let mut buf = vec![0u8; 65_536];
        for _ in 0..n {
            let (len, from) = echo.recv_from(&mut buf)?;
            echo.send_to(&buf[..len], from)?;
        }
        Ok(())
    });
    let ping_thread = std::thread::spawn(move || -> std::io::Result<Vec<Duration>> {
        pin_to(ping_core)?;
        let message = vec![0x5au8; payload.max(1)];
        let mut reply = vec![0u8; payload.max(1)];
        let mut times = Vec::with_capacity(n);
        for _ in 0..n {
            let start = Instant::now();
            client.send(&message)?;
            client.recv(&mut reply)?;
            times.push(start.elapsed());
        }
        Ok(times)
    });
    let times = ping_thread
        .join()
        .map_err(|_| std::io::Error::other("UDP ping thread panicked"))?;
    if times.is_err() {
        // The echo thread times out on its own; its error would only repeat this one.
        let _ = echo_thread.join();
        return times;
    }
    echo_thread
        .join()
        .map_err(|_| std::io::Error::other("UDP echo thread panicked"))??;
    times
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_of_a_known_sequence() {
        let samples: Vec<Duration> = (1..=1000).map(Duration::from_nanos).collect();
        let p = percentiles(&samples);
        assert_eq!(
            (p.p50_ns, p.p99_ns, p.p999_ns, p.max_ns),
            (500, 990, 999, 1000)
        );
        assert_eq!(percentiles(&[]), TransportPercentiles::default());
    }

    #[test]
    fn a_short_loopback_run_times_every_round_trip() {
        let cores = core_affinity::get_core_ids().unwrap_or_default();
        let first = cores.first().map_or(0, |c| c.id);
        let last = cores.last().map_or(0, |c| c.id);
        for placement in [
            UdpPlacement::Unpinned,
            UdpPlacement::SameCore(last),
            UdpPlacement::CrossCore(first, last),
        ] {
            let times = raw_udp_round_trips(100, 200, placement).unwrap();
            assert_eq!(times.len(), 100);
            assert!(times.iter().all(|t| !t.is_zero()));
        }
    }

    #[test]
    fn a_core_that_does_not_exist_is_an_error_not_a_hang() {
        let err = raw_udp_round_trips(10, 8, UdpPlacement::SameCore(usize::MAX)).unwrap_err();
        assert!(err.to_string().contains("not available"), "{err}");
    }
}
