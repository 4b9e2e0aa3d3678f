//! A userspace network impairment relay: a UDP forwarder that adds a seeded random delay, jitter
//! and loss to every datagram, for rehearsing the cluster on kernels without the `netem` qdisc.
//!
//! Clients (workers) send to [`Relay::local_addr`]; each client gets its own upstream socket
//! connected to `forward` (the coordinator), so replies find their way back. Both directions are
//! impaired independently: each datagram is dropped with probability `loss`, otherwise sent after
//! `delay + U(−jitter, +jitter)` (clamped at 0), like `netem delay D J loss L` with its default
//! uniform jitter. Datagrams are scheduled independently, so jitter can reorder them (as netem's).
//!
//! Determinism: every flow direction (clients → forward, and forward → client `k`, `k` in order
//! of first contact) draws from its own ChaCha8 stream seeded from `seed`, so the same seed and
//! the same datagram sequence per flow give the same drops and delays. The arrival order of
//! datagrams, and hence the sequence, is up to the processes on both sides.
//!
//! Honesty: the relay measures what it achieved, per direction — the time from a datagram's
//! receipt (after `recv` returned) to the return of its `send`, in an HDR histogram, and the
//! fraction dropped — and reports both in [`RelayStats`]. It never sends early; sleeping makes it
//! late by the scheduler's wake-up latency (the timer slack is set to 1 µs on Linux).
//!
//! Threads: one receiver per socket (read timeout 20 ms, to notice [`Relay::stop`]) and one
//! scheduler that owns the timing heap and sends. Not for the frame path.

use crate::NetemError;
use crossbeam::channel::{unbounded, Receiver, RecvTimeoutError, Sender};
use hdrhistogram::Histogram;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::net::{SocketAddr, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};
use vps_runtime::Percentiles;

/// Largest datagram relayed (bytes); QUIC never sends more than this on a normal path.
const MAX_DATAGRAM: usize = 65_535;
/// Receive timeout, so receivers notice a stop.
const POLL: Duration = Duration::from_millis(20);

/// How the relay impairs traffic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RelayConfig {
    /// Where clients send (port 0: any free port).
    pub listen: SocketAddr,
    /// Where their datagrams go (the coordinator).
    pub forward: SocketAddr,
    /// Mean one-way delay added per datagram.
    pub delay: Duration,
    /// Half-width of the uniform jitter around `delay` (≤ `delay` keeps the mean exact).
    pub jitter: Duration,
    /// Probability that a datagram is dropped, 0..=1.
    pub loss: f64,
    /// Seed of the decision streams.
    pub seed: u64,
}

impl RelayConfig {
    /// Checks `loss` (a probability) and that `delay + jitter` is below 10 s.
    pub fn validate(&self) -> Result<(), NetemError> {
        if !(0.0..=1.0).contains(&self.loss) {
            return Err(NetemError::Config {
                field: "loss",
                message: format!("{} is not a probability in 0..=1", self.loss),
            });
        }
        if self.delay + self.jitter > Duration::from_secs(10) {
            return Err(NetemError::Config {
                field: "delay",
                message: "delay + jitter must stay below 10 s".into(),
            });
        }
        Ok(())
    }
}

/// What the relay did in one direction.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct DirectionStats {
    /// Datagrams received.
    pub received: u64,
    /// Datagrams dropped by the loss draw.
    pub dropped: u64,
    /// Datagrams sent on.
    pub sent: u64,
    /// Sends that failed (e.g. the destination is gone).
    pub send_errors: u64,
    /// Scheduled but not sent when the relay stopped.
    pub unsent_at_stop: u64,
    /// `dropped / received` (0 before any datagram).
    pub achieved_loss: f64,
    /// Achieved delay, receipt to send (ns), of sent datagrams.
    pub achieved_delay_ns: Percentiles,
    /// Smallest achieved delay (ns).
    pub min_delay_ns: u64,
    /// Mean achieved delay (ns).
    pub mean_delay_ns: f64,
}

/// What the relay did: the configuration and both directions.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RelayStats {
    /// Configured mean one-way delay (ns).
    pub delay_ns: u64,
    /// Configured jitter half-width (ns).
    pub jitter_ns: u64,
    /// Configured loss probability.
    pub loss: f64,
    /// The seed.
    pub seed: u64,
    /// Clients seen.
    pub clients: u64,
    /// Clients → forward address.
    pub to_forward: DirectionStats,
    /// Forward address → clients.
    pub to_clients: DirectionStats,
}

/// The impairment draw for one flow direction: drop, or how long to hold.
struct Impairment {
    rng: ChaCha8Rng,
    delay_ns: f64,
    jitter_ns: f64,
    loss: f64,
}

impl Impairment {
    /// Stream `stream` of `config.seed` (0: clients → forward; `k + 1`: forward → client `k`).
    fn new(config: &RelayConfig, stream: u64) -> Impairment {
        let mut rng = ChaCha8Rng::seed_from_u64(config.seed);
        rng.set_stream(stream);
        Impairment {
            rng,
            delay_ns: config.delay.as_nanos() as f64,
            jitter_ns: config.jitter.as_nanos() as f64,
            loss: config.loss,
        }
    }

    /// `None`: drop; otherwise the delay. Two draws per datagram, always, so the stream stays
    /// aligned whatever the outcome.
    fn draw(&mut self) -> Option<Duration> {
        let lose = self.rng.gen::<f64>() < self.loss;
        let offset = self.rng.gen_range(-1.0..=1.0) * self.jitter_ns;
        (!lose).then(|| Duration::from_nanos((self.delay_ns + offset).max(0.0) as u64))
    }
}

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Direction {
    ToForward,
    ToClients,
}

/// Where a held datagram goes.
enum Target {
    /// Out of a client's upstream socket (connected to `forward`).
    Upstream(Arc<UdpSocket>),
    /// Out of the listening socket to a client.
    Client(SocketAddr),
}

struct Held {
    received: Instant,
    due: Instant,
    target: Target,
    bytes: Vec<u8>,
}

enum Event {
    Received(Direction),
    Dropped(Direction),
    Hold(Direction, Held),
    NewClient,
}

struct Shared {
    stop: AtomicBool,
    stats: Mutex<RelayStats>,
}

/// A running relay. [`Relay::stop`] (or drop) ends it.
pub struct Relay {
    local_addr: SocketAddr,
    shared: Arc<Shared>,
    threads: Vec<JoinHandle<()>>,
    clients: Arc<Mutex<Vec<JoinHandle<()>>>>,
}

fn net(what: &str, e: std::io::Error) -> NetemError {
    NetemError::Network(format!("relay: {what}: {e}"))
}

impl Relay {
    /// Binds `config.listen` and starts relaying. Spawns threads.
    pub fn start(config: RelayConfig) -> Result<Relay, NetemError> {
        config.validate()?;
        let listen = Arc::new(
            UdpSocket::bind(config.listen)
                .map_err(|e| net(&format!("bind {}", config.listen), e))?,
        );
        listen
            .set_read_timeout(Some(POLL))
            .map_err(|e| net("socket option", e))?;
        let local_addr = listen.local_addr().map_err(|e| net("local address", e))?;
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            stats: Mutex::new(RelayStats {
                delay_ns: config.delay.as_nanos() as u64,
                jitter_ns: config.jitter.as_nanos() as u64,
                loss: config.loss,
                seed: config.seed,
                ..RelayStats::default()
            }),
        });
        let (events, event_rx) = unbounded();
        let clients = Arc::new(Mutex::new(Vec::new()));
        let spawn = |name: &str, f: Box<dyn FnOnce() + Send>| {
            std::thread::Builder::new()
                .name(name.into())
                .spawn(f)
                .map_err(|e| net("spawn a thread", e))
        };
        let scheduler = {
            let (listen, shared) = (listen.clone(), shared.clone());
            spawn(
                "vps-relay-send",
                Box::new(move || schedule(&listen, &event_rx, &shared)),
            )?
        };
        let receiver = {
            let (shared, clients) = (shared.clone(), clients.clone());
            spawn(
                "vps-relay-recv",
                Box::new(move || receive_from_clients(config, &listen, &events, &shared, &clients)),
            )?
        };
        Ok(Relay {
            local_addr,
            shared,
            threads: vec![receiver, scheduler],
            clients,
        })
    }

    /// The address clients send to.
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// The figures so far. Allocates.
    pub fn stats(&self) -> RelayStats {
        self.shared
            .stats
            .lock()
            .map(|s| s.clone())
            .unwrap_or_default()
    }

    /// Stops every thread (within about 20 ms) and returns the final figures.
    pub fn stop(mut self) -> RelayStats {
        self.shutdown();
        self.stats()
    }

    fn shutdown(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let clients = std::mem::take(&mut *self.clients.lock().unwrap_or_else(|p| p.into_inner()));
        for t in clients {
            let _ = t.join();
        }
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// The listening socket's receiver: impairs client datagrams toward `forward`, making an upstream
/// socket (and its receiver thread) for each new client.
fn receive_from_clients(
    config: RelayConfig,
    listen: &Arc<UdpSocket>,
    events: &Sender<Event>,
    shared: &Arc<Shared>,
    client_threads: &Mutex<Vec<JoinHandle<()>>>,
) {
    let mut upstreams: HashMap<SocketAddr, Arc<UdpSocket>> = HashMap::new();
    let mut impair = Impairment::new(&config, 0);
    let mut buf = vec![0u8; MAX_DATAGRAM];
    while !shared.stop.load(Ordering::Relaxed) {
        let Ok((len, from)) = listen.recv_from(&mut buf) else {
            continue;
        };
        let received = Instant::now();
        let upstream = match upstreams.get(&from) {
            Some(u) => u.clone(),
            None => match open_upstream(&config, upstreams.len() as u64, from, events, shared) {
                Ok((socket, thread)) => {
                    if let Ok(mut t) = client_threads.lock() {
                        t.push(thread);
                    }
                    upstreams.insert(from, socket.clone());
                    let _ = events.send(Event::NewClient);
                    socket
                }
                Err(e) => {
                    tracing::warn!("{e}");
                    continue;
                }
            },
        };
        let target = Target::Upstream(upstream);
        impair_datagram(
            &mut impair,
            events,
            Direction::ToForward,
            received,
            target,
            &buf[..len],
        );
    }
}

/// Reports a datagram received at `received` going `direction`, and what `impair` makes of it:
/// dropped, or held (a copy of `bytes`) until its delay has passed, then sent to `target`.
fn impair_datagram(
    impair: &mut Impairment,
    events: &Sender<Event>,
    direction: Direction,
    received: Instant,
    target: Target,
    bytes: &[u8],
) {
    let _ = events.send(Event::Received(direction));
    let event = match impair.draw() {
        None => Event::Dropped(direction),
        Some(delay) => Event::Hold(
            direction,
            Held {
                received,
                due: received + delay,
                target,
                bytes: bytes.to_vec(),
            },
        ),
    };
    let _ = events.send(event);
}

/// A socket connected to `forward` for client number `index`, and the thread that impairs what
/// comes back on it.
fn open_upstream(
    config: &RelayConfig,
    index: u64,
    client: SocketAddr,
    events: &Sender<Event>,
    shared: &Arc<Shared>,
) -> Result<(Arc<UdpSocket>, JoinHandle<()>), NetemError> {
    let bind: SocketAddr = if config.forward.is_ipv4() {
        ([0, 0, 0, 0], 0).into()
    } else {
        ([0u16; 8], 0).into()
    };
    let socket = UdpSocket::bind(bind).map_err(|e| net("bind an upstream socket", e))?;
    socket
        .connect(config.forward)
        .map_err(|e| net(&format!("connect to {}", config.forward), e))?;
    socket
        .set_read_timeout(Some(POLL))
        .map_err(|e| net("socket option", e))?;
    let socket = Arc::new(socket);
    let mut impair = Impairment::new(config, index + 1);
    let (rx, events, shared) = (socket.clone(), events.clone(), shared.clone());
    let thread = std::thread::Builder::new()
        .name(format!("vps-relay-up{index}"))
        .spawn(move || {
            let mut buf = vec![0u8; MAX_DATAGRAM];
            while !shared.stop.load(Ordering::Relaxed) {
                let Ok(len) = rx.recv(&mut buf) else { continue };
                let received = Instant::now();
                let target = Target::Client(client);
                let bytes = &buf[..len];
                impair_datagram(
                    &mut impair,
                    &events,
                    Direction::ToClients,
                    received,
                    target,
                    bytes,
                );
            }
        })
        .map_err(|e| net("spawn a thread", e))?;
    Ok((socket, thread))
}

/// Per-direction tallies kept by the scheduler.
struct Tally {
    stats: DirectionStats,
    delays: Histogram<u64>,
    delay_sum_ns: u128,
}

impl Tally {
    fn new() -> Tally {
        Tally {
            stats: DirectionStats {
                min_delay_ns: u64::MAX,
                ..DirectionStats::default()
            },
            // Constant, valid bounds: 1 ns .. 100 s, 3 significant digits.
            delays: Histogram::new_with_bounds(1, 100_000_000_000, 3).expect("valid bounds"),
            delay_sum_ns: 0,
        }
    }

    fn publish(&self) -> DirectionStats {
        let mut s = self.stats.clone();
        let h = &self.delays;
        if !h.is_empty() {
            s.achieved_delay_ns = Percentiles {
                p50: h.value_at_quantile(0.5),
                p99: h.value_at_quantile(0.99),
                p999: h.value_at_quantile(0.999),
                max: h.max(),
            };
            s.mean_delay_ns = self.delay_sum_ns as f64 / h.len() as f64;
        } else {
            s.min_delay_ns = 0;
        }
        s.achieved_loss = if s.received == 0 {
            0.0
        } else {
            s.dropped as f64 / s.received as f64
        };
        s
    }
}

/// The scheduler's state: held datagrams by due time, and the tallies.
struct Schedule {
    heap: BinaryHeap<Reverse<(Instant, u64)>>,
    held: HashMap<u64, (Direction, Held)>,
    next_key: u64,
    tallies: [Tally; 2],
    clients: u64,
}

impl Schedule {
    /// Books one event; `stopping`: a datagram to hold is counted unsent instead.
    fn apply(&mut self, event: Event, stopping: bool) {
        match event {
            Event::Received(dir) => self.tallies[dir as usize].stats.received += 1,
            Event::Dropped(dir) => self.tallies[dir as usize].stats.dropped += 1,
            Event::NewClient => self.clients += 1,
            Event::Hold(dir, _) if stopping => {
                self.tallies[dir as usize].stats.unsent_at_stop += 1;
            }
            Event::Hold(dir, h) => {
                self.heap.push(Reverse((h.due, self.next_key)));
                self.held.insert(self.next_key, (dir, h));
                self.next_key += 1;
            }
        }
    }

    /// Sends every datagram due by now.
    fn send_due(&mut self, listen: &UdpSocket) {
        let now = Instant::now();
        while let Some(&Reverse((due, key))) = self.heap.peek() {
            if due > now {
                break;
            }
            self.heap.pop();
            let Some((dir, h)) = self.held.remove(&key) else {
                continue;
            };
            let sent = match &h.target {
                Target::Upstream(socket) => socket.send(&h.bytes).is_ok(),
                Target::Client(addr) => listen.send_to(&h.bytes, addr).is_ok(),
            };
            let t = &mut self.tallies[dir as usize];
            if sent {
                let ns = h.received.elapsed().as_nanos() as u64;
                let _ = t.delays.record(ns.max(1));
                t.delay_sum_ns += u128::from(ns);
                t.stats.min_delay_ns = t.stats.min_delay_ns.min(ns);
                t.stats.sent += 1;
            } else {
                t.stats.send_errors += 1;
            }
        }
    }

    fn publish(&self, shared: &Shared) {
        if let Ok(mut stats) = shared.stats.lock() {
            stats.clients = self.clients;
            stats.to_forward = self.tallies[0].publish();
            stats.to_clients = self.tallies[1].publish();
        }
    }
}

/// The scheduler thread: holds datagrams until due, sends them, tallies, publishes figures every
/// 100 ms and at stop.
fn schedule(listen: &UdpSocket, events: &Receiver<Event>, shared: &Shared) {
    lower_timer_slack();
    let mut s = Schedule {
        heap: BinaryHeap::new(),
        held: HashMap::new(),
        next_key: 0,
        tallies: [Tally::new(), Tally::new()],
        clients: 0,
    };
    let mut last_publish = Instant::now();
    loop {
        s.send_due(listen);
        if shared.stop.load(Ordering::Relaxed) {
            while let Ok(event) = events.try_recv() {
                s.apply(event, true);
            }
            for (dir, _) in s.held.values() {
                s.tallies[*dir as usize].stats.unsent_at_stop += 1;
            }
            s.publish(shared);
            return;
        }
        if last_publish.elapsed() >= Duration::from_millis(100) {
            s.publish(shared);
            last_publish = Instant::now();
        }
        let wait = match s.heap.peek() {
            Some(&Reverse((due, _))) => events.recv_deadline(due),
            None => events.recv_timeout(POLL),
        };
        match wait {
            Ok(event) => s.apply(event, false),
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => std::thread::sleep(Duration::from_millis(1)),
        }
    }
}

/// Asks Linux to wake this thread's timed sleeps within 1 µs of their deadline (default 50 µs).
fn lower_timer_slack() {
    #[cfg(target_os = "linux")]
    // SAFETY: PR_SET_TIMERSLACK takes an integer argument and affects only the calling thread.
    unsafe {
        libc::prctl(libc::PR_SET_TIMERSLACK, 1000 as libc::c_ulong, 0, 0, 0);
    }
}

/// Parses a duration with a unit: `100us`, `1.5ms`, `2s`, `250ns` (a bare number is seconds).
/// Negative, non-finite or unparsable text is an error naming the text.
pub fn parse_duration(text: &str) -> Result<Duration, String> {
    let units = [
        ("ns", 1e-9),
        ("us", 1e-6),
        ("µs", 1e-6),
        ("ms", 1e-3),
        ("s", 1.0),
    ];
    let seconds = vps_units::scaled_number(text, &units)
        .ok_or_else(|| format!("'{text}' is not a duration (examples: 100us, 1.5ms, 2s)"))?;
    if !(0.0..=1e6).contains(&seconds) {
        return Err(format!(
            "'{text}' must be a finite duration ≥ 0 (at most 10^6 s)"
        ));
    }
    Ok(Duration::from_secs_f64(seconds))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(loss: f64, seed: u64) -> RelayConfig {
        RelayConfig {
            listen: "127.0.0.1:0".parse().unwrap(),
            forward: "127.0.0.1:9".parse().unwrap(),
            delay: Duration::from_micros(100),
            jitter: Duration::from_micros(50),
            loss,
            seed,
        }
    }

    #[test]
    fn draws_are_seeded_bounded_and_lose_about_the_asked_fraction() {
        let draws = |seed| {
            let mut i = Impairment::new(&config(0.01, seed), 0);
            (0..20_000).map(|_| i.draw()).collect::<Vec<_>>()
        };
        let a = draws(7);
        assert_eq!(a, draws(7), "same seed, same decisions");
        assert_ne!(a, draws(8));
        let lost = a.iter().filter(|d| d.is_none()).count();
        assert!((120..=280).contains(&lost), "{lost} of 20000 lost at 1 %");
        for d in a.iter().flatten() {
            assert!((50_000..=150_000).contains(&(d.as_nanos() as u64)), "{d:?}");
        }
        let mut other = Impairment::new(&config(0.01, 7), 1);
        let b: Vec<_> = (0..100).map(|_| other.draw()).collect();
        assert_ne!(&a[..100], &b[..], "directions draw from separate streams");
    }

    #[test]
    fn bad_settings_are_refused() {
        assert!(config(1.5, 0).validate().is_err());
        assert!(config(-0.1, 0).validate().is_err());
        assert!(config(f64::NAN, 0).validate().is_err());
        assert!(config(0.0, 0).validate().is_ok());
    }

    #[test]
    fn durations_parse_with_units() {
        assert_eq!(parse_duration("100us"), Ok(Duration::from_micros(100)));
        assert_eq!(parse_duration("1.5ms"), Ok(Duration::from_micros(1500)));
        assert_eq!(parse_duration("2s"), Ok(Duration::from_secs(2)));
        assert_eq!(parse_duration("0"), Ok(Duration::ZERO));
        for bad in ["", "fast", "-1ms", "infs", "1e9s"] {
            assert!(parse_duration(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn a_relay_delays_and_returns_datagrams_and_counts_them() {
        let echo = UdpSocket::bind("127.0.0.1:0").unwrap();
        echo.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        let relay = Relay::start(RelayConfig {
            forward: echo.local_addr().unwrap(),
            loss: 0.0,
            ..config(0.0, 1)
        })
        .unwrap();
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        client
            .set_read_timeout(Some(Duration::from_secs(2)))
            .unwrap();
        let mut buf = [0u8; 64];
        for i in 0..20u8 {
            client.send_to(&[i; 10], relay.local_addr()).unwrap();
            let (n, from) = echo.recv_from(&mut buf).unwrap();
            assert_eq!(&buf[..n], &[i; 10]);
            echo.send_to(&buf[..n], from).unwrap();
            let n = client.recv(&mut buf).unwrap();
            assert_eq!(&buf[..n], &[i; 10]);
        }
        let stats = relay.stop();
        assert_eq!(stats.clients, 1);
        for d in [&stats.to_forward, &stats.to_clients] {
            assert_eq!((d.received, d.sent, d.dropped), (20, 20, 0), "{stats:?}");
            assert!(d.min_delay_ns >= 50_000, "never early: {stats:?}");
        }
    }

    #[test]
    fn total_loss_drops_everything_and_says_so() {
        let sink = UdpSocket::bind("127.0.0.1:0").unwrap();
        let relay = Relay::start(RelayConfig {
            forward: sink.local_addr().unwrap(),
            ..config(1.0, 3)
        })
        .unwrap();
        let client = UdpSocket::bind("127.0.0.1:0").unwrap();
        for _ in 0..10 {
            client.send_to(b"x", relay.local_addr()).unwrap();
        }
        let deadline = Instant::now() + Duration::from_secs(2);
        while relay.stats().to_forward.dropped < 10 && Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(10));
        }
        let stats = relay.stop();
        assert_eq!(stats.to_forward.dropped, 10);
        assert_eq!(stats.to_forward.sent, 0);
        assert_eq!(stats.to_forward.achieved_loss, 1.0);
    }
}
