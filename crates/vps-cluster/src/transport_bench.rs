//! The raw UDP baseline of `vps bench transport`: a ping-pong on loopback, to compare the cluster's
//! gather round trip against in the same run. Blocking sockets and a plain echo thread: the
//! cheapest round trip this host's network stack offers.

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

/// `n` UDP round trips of `payload` bytes to an echo thread on 127.0.0.1; returns each round
/// trip's time. Blocks for the whole run; a round trip that takes over a second is an error.
pub fn raw_udp_round_trips(n: usize, payload: usize) -> std::io::Result<Vec<Duration>> {
    let echo = UdpSocket::bind("127.0.0.1:0")?;
    let client = UdpSocket::bind("127.0.0.1:0")?;
    let echo_addr = echo.local_addr()?;
    echo.set_read_timeout(Some(Duration::from_secs(1)))?;
    client.set_read_timeout(Some(Duration::from_secs(1)))?;
    client.connect(echo_addr)?;
    let echo_thread = std::thread::spawn(move || -> std::io::Result<()> {
        let mut buf = vec![0u8; 65_536];
        for _ in 0..n {
            let (len, from) = echo.recv_from(&mut buf)?;
            echo.send_to(&buf[..len], from)?;
        }
        Ok(())
    });
    let message = vec![0x5au8; payload.max(1)];
    let mut reply = vec![0u8; payload.max(1)];
    let mut times = Vec::with_capacity(n);
    for _ in 0..n {
        let start = Instant::now();
        client.send(&message)?;
        client.recv(&mut reply)?;
        times.push(start.elapsed());
    }
    echo_thread
        .join()
        .map_err(|_| std::io::Error::other("UDP echo thread panicked"))??;
    Ok(times)
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
        let times = raw_udp_round_trips(100, 200).unwrap();
        assert_eq!(times.len(), 100);
        assert!(times.iter().all(|t| !t.is_zero()));
    }
}
