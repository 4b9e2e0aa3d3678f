//! Counting what arrives on an endpoint's UDP socket before quinn sees it, so that garbage sent
//! to a coordinator or a worker is counted, not only dropped.
//!
//! quinn drops a datagram that is not a QUIC packet of a known connection, or that fails
//! decryption, inside its endpoint and exposes no counter for it. [`CountingSocket`] wraps the
//! endpoint's socket and classifies each received datagram by its first packet's header
//! (RFC 9000 §17), see [`classify`]:
//!
//! - **not QUIC** ([`UdpCounts::not_quic`]): shorter than the 16-byte AEAD tag every protected
//!   packet carries, or a first byte without the Fixed Bit (0x40) that is not a Version
//!   Negotiation packet (long header, version 0). Both vps endpoints turn off fixed-bit greasing
//!   (RFC 9287), so their own packets always carry the bit.
//! - **foreign** ([`UdpCounts::foreign`]): shaped like QUIC, but no connection of this endpoint
//!   can own it: a long header with a version quinn does not speak, or a destination connection
//!   ID this endpoint did not issue. The endpoint issues its IDs with quinn's
//!   `HashedConnectionIdGenerator` under a key the socket also holds, so every ID it ever issued
//!   is recognised without a table (a random 8-byte ID passes with odds 2^-40). The one packet a
//!   server cannot check is a client's Initial or 0-RTT packet, whose destination ID the client
//!   chose. A stateless reset (what a peer that lost its state sends) is counted here too.
//!
//! Together these count random garbage whatever its bytes. Both kinds are still handed to quinn,
//! which drops them. Not counted: a packet that names one of this endpoint's connection IDs but
//! fails authentication (a truncated or altered copy of a genuine packet, which takes an on-path
//! sender); quinn counts those per connection in a private field only.

use quinn::udp::{RecvMeta, Transmit};
use quinn::{AsyncUdpSocket, ConnectionId, ConnectionIdGenerator, Runtime, UdpPoller};
use quinn_proto::HashedConnectionIdGenerator;
use std::fmt;
use std::io::{self, IoSliceMut};
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::task::{Context, Poll};

/// Datagrams received on one endpoint's socket. Lock-free; read from any thread.
#[derive(Debug, Default)]
pub struct UdpCounts {
    datagrams: AtomicU64,
    not_quic: AtomicU64,
    foreign: AtomicU64,
}

impl UdpCounts {
    /// Every datagram received (GRO segments counted one by one).
    pub fn datagrams(&self) -> u64 {
        self.datagrams.load(Ordering::Relaxed)
    }

    /// Datagrams that cannot be QUIC packets by their shape (see the module docs).
    pub fn not_quic(&self) -> u64 {
        self.not_quic.load(Ordering::Relaxed)
    }

    /// Datagrams shaped like QUIC that no connection of this endpoint can own (see the module
    /// docs).
    pub fn foreign(&self) -> u64 {
        self.foreign.load(Ordering::Relaxed)
    }

    fn count(&self, shape: DatagramShape) {
        self.datagrams.fetch_add(1, Ordering::Relaxed);
        match shape {
            DatagramShape::NotQuic => self.not_quic.fetch_add(1, Ordering::Relaxed),
            DatagramShape::Foreign => self.foreign.fetch_add(1, Ordering::Relaxed),
            DatagramShape::Plausible => 0,
        };
    }
}

/// The smallest protected QUIC packet: a 16-byte AEAD tag alone.
const MIN_QUIC_LEN: usize = 16;

/// Whether `datagram` can be a QUIC v1 packet by its shape (RFC 9000 §17).
pub fn looks_like_quic(datagram: &[u8]) -> bool {
    let Some(&first) = datagram.first() else {
        return false;
    };
    let version_negotiation = first & 0x80 != 0 && datagram.get(1..5) == Some(&[0, 0, 0, 0][..]);
    datagram.len() >= MIN_QUIC_LEN && (first & 0x40 != 0 || version_negotiation)
}

/// What a received datagram is to this endpoint; see the module docs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DatagramShape {
    /// Cannot be a QUIC packet.
    NotQuic,
    /// Shaped like QUIC, but no connection of this endpoint can own it.
    Foreign,
    /// May belong to one of this endpoint's connections, or open one.
    Plausible,
}

/// Recognises the connection IDs one endpoint issues: the key of its
/// `HashedConnectionIdGenerator`, and whether it accepts connections (a server).
pub struct IssuedIds {
    generator: HashedConnectionIdGenerator,
    server: bool,
}

impl fmt::Debug for IssuedIds {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("IssuedIds")
            .field("server", &self.server)
            .finish_non_exhaustive()
    }
}

/// Length of the IDs a `HashedConnectionIdGenerator` issues (bytes).
const ISSUED_ID_LEN: usize = 8;

impl IssuedIds {
    /// The IDs issued under `key`, by a server endpoint when `server`.
    pub fn new(key: u64, server: bool) -> IssuedIds {
        IssuedIds {
            generator: HashedConnectionIdGenerator::from_key(key),
            server,
        }
    }

    fn issued(&self, id: &[u8]) -> bool {
        id.len() == ISSUED_ID_LEN && self.generator.validate(&ConnectionId::new(id)).is_ok()
    }
}

/// Classifies one datagram by its first packet's header (RFC 9000 §17) for the endpoint whose
/// IDs `ids` recognises.
pub fn classify(datagram: &[u8], ids: &IssuedIds) -> DatagramShape {
    if !looks_like_quic(datagram) {
        return DatagramShape::NotQuic;
    }
    let first = datagram[0];
    let destination = if first & 0x80 == 0 {
        // Short header: the ID follows the first byte, at the length this endpoint issues.
        datagram.get(1..1 + ISSUED_ID_LEN)
    } else {
        let version = u32::from_be_bytes([datagram[1], datagram[2], datagram[3], datagram[4]]);
        if version != 0 && !quinn_proto::DEFAULT_SUPPORTED_VERSIONS.contains(&version) {
            return DatagramShape::Foreign;
        }
        let packet_type = (first >> 4) & 0x3;
        // A client's Initial (0) or 0-RTT (1) names an ID the client chose.
        if ids.server && version != 0 && packet_type <= 1 {
            return DatagramShape::Plausible;
        }
        let len = usize::from(datagram[5]);
        datagram.get(6..6 + len)
    };
    match destination {
        Some(id) if ids.issued(id) => DatagramShape::Plausible,
        _ => DatagramShape::Foreign,
    }
}

/// An [`AsyncUdpSocket`] that counts what it receives, then hands it on unchanged.
pub struct CountingSocket {
    inner: Arc<dyn AsyncUdpSocket>,
    ids: IssuedIds,
    counts: Arc<UdpCounts>,
}

impl fmt::Debug for CountingSocket {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CountingSocket")
            .field("inner", &self.inner)
            .field("ids", &self.ids)
            .field("counts", &self.counts)
            .finish()
    }
}

impl AsyncUdpSocket for CountingSocket {
    fn create_io_poller(self: Arc<Self>) -> Pin<Box<dyn UdpPoller>> {
        self.inner.clone().create_io_poller()
    }

    fn try_send(&self, transmit: &Transmit) -> io::Result<()> {
        self.inner.try_send(transmit)
    }

    fn poll_recv(
        &self,
        cx: &mut Context,
        bufs: &mut [IoSliceMut<'_>],
        meta: &mut [RecvMeta],
    ) -> Poll<io::Result<usize>> {
        let poll = self.inner.poll_recv(cx, bufs, meta);
        if let Poll::Ready(Ok(n)) = &poll {
            for (buf, m) in bufs.iter().zip(meta.iter()).take(*n) {
                let data = &buf[..m.len.min(buf.len())];
                // GRO may pack several datagrams of `stride` bytes (the last one shorter).
                let stride = if m.stride == 0 { data.len() } else { m.stride };
                let mut count = |segment: &[u8]| self.counts.count(classify(segment, &self.ids));
                if data.is_empty() {
                    count(data);
                } else {
                    data.chunks(stride.max(1)).for_each(&mut count);
                }
            }
        }
        poll
    }

    fn local_addr(&self) -> io::Result<SocketAddr> {
        self.inner.local_addr()
    }

    fn max_transmit_segments(&self) -> usize {
        self.inner.max_transmit_segments()
    }

    fn max_receive_segments(&self) -> usize {
        self.inner.max_receive_segments()
    }

    fn may_fragment(&self) -> bool {
        self.inner.may_fragment()
    }
}

/// A quinn endpoint on a UDP socket bound to `addr`, whose received datagrams are counted in
/// `counts`; a server when `server` is given. Must be called inside a tokio runtime.
pub fn counting_endpoint(
    addr: SocketAddr,
    server: Option<quinn::ServerConfig>,
    counts: Arc<UdpCounts>,
) -> io::Result<quinn::Endpoint> {
    let socket = std::net::UdpSocket::bind(addr)?;
    let runtime: Arc<dyn Runtime> = Arc::new(quinn::TokioRuntime);
    let inner = runtime.wrap_udp_socket(socket)?;
    let key: u64 = rand::random();
    let ids = IssuedIds::new(key, server.is_some());
    let mut config = quinn::EndpointConfig::default();
    // The socket recognises every ID the endpoint issues.
    config.cid_generator(move || -> Box<dyn ConnectionIdGenerator> {
        Box::new(HashedConnectionIdGenerator::from_key(key))
    });
    // No greasing of the fixed bit (RFC 9287): our endpoints do not invite peers to clear it, so
    // every packet between vps endpoints carries it and the shape test above holds.
    config.grease_quic_bit(false);
    let counting = Arc::new(CountingSocket { inner, ids, counts });
    quinn::Endpoint::new_with_abstract_socket(config, server, counting, runtime)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quic_shapes_pass_and_garbage_shapes_do_not() {
        // A short-header (1-RTT) packet: fixed bit set.
        let mut short = vec![0x40 | 0x01; 40];
        assert!(looks_like_quic(&short));
        // A long-header Initial: 0xC0 (long form + fixed bit), version 1.
        let mut initial = vec![0xC0, 0, 0, 0, 1];
        initial.resize(1200, 0);
        assert!(looks_like_quic(&initial));
        // Version Negotiation: long form, version 0, fixed bit unspecified (here clear).
        let mut vn = vec![0x80, 0, 0, 0, 0];
        vn.resize(40, 7);
        assert!(looks_like_quic(&vn));
        // Fixed bit clear, not version negotiation.
        short[0] = 0x05;
        assert!(!looks_like_quic(&short));
        initial[0] = 0x80;
        assert!(!looks_like_quic(&initial));
        // Too short for any protected packet, empty.
        assert!(!looks_like_quic(&[0x41; 15]));
        assert!(!looks_like_quic(&[]));
    }

    /// A packet of `len` bytes whose header is `header` and whose rest is `fill`.
    fn packet(header: &[u8], len: usize, fill: u8) -> Vec<u8> {
        let mut p = header.to_vec();
        p.resize(len, fill);
        p
    }

    fn long_header(first: u8, version: u32, destination: &[u8]) -> Vec<u8> {
        let mut h = vec![first];
        h.extend(version.to_be_bytes());
        h.push(destination.len() as u8);
        h.extend(destination);
        h
    }

    #[test]
    fn ids_the_endpoint_issued_are_plausible_and_others_foreign() {
        let key = 0x5eed;
        let ids = IssuedIds::new(key, false);
        let mut generator = HashedConnectionIdGenerator::from_key(key);
        let ours: Vec<ConnectionId> = (0..100).map(|_| generator.generate_cid()).collect();
        let theirs = HashedConnectionIdGenerator::from_key(key + 1).generate_cid();
        for id in &ours {
            let short = packet(&[&[0x41], &id[..]].concat(), 60, 0);
            assert_eq!(classify(&short, &ids), DatagramShape::Plausible);
            // Handshake (type 2) and Initial (type 0) from a server name the client's ID.
            for first in [0xE0, 0xC0] {
                let long = packet(&long_header(first, 1, id), 60, 0);
                assert_eq!(classify(&long, &ids), DatagramShape::Plausible);
            }
        }
        let short = packet(&[&[0x41], &theirs[..]].concat(), 60, 0);
        assert_eq!(classify(&short, &ids), DatagramShape::Foreign);
        let handshake = packet(&long_header(0xE0, 1, &theirs), 60, 0);
        assert_eq!(classify(&handshake, &ids), DatagramShape::Foreign);
        // A client never receives an Initial naming an ID it did not issue; a server does.
        let initial = packet(&long_header(0xC0, 1, &theirs), 1200, 0);
        assert_eq!(classify(&initial, &ids), DatagramShape::Foreign);
        let server = IssuedIds::new(key, true);
        assert_eq!(classify(&initial, &server), DatagramShape::Plausible);
        // ... but not a Handshake packet, nor any version quinn does not speak.
        assert_eq!(classify(&handshake, &server), DatagramShape::Foreign);
        let unknown_version = packet(&long_header(0xC0, 0x0a0a_0a0a, &ours[0]), 1200, 0);
        assert_eq!(classify(&unknown_version, &server), DatagramShape::Foreign);
        // An ID length running past the datagram, or of a length never issued.
        let mut overlong = packet(&long_header(0xE0, 1, &ours[0]), 20, 0);
        overlong[5] = 20;
        assert_eq!(classify(&overlong, &ids), DatagramShape::Foreign);
        let short_id = packet(&long_header(0xE0, 1, &ours[0][..4]), 60, 0);
        assert_eq!(classify(&short_id, &ids), DatagramShape::Foreign);
        assert_eq!(classify(&[0x41; 15], &ids), DatagramShape::NotQuic);
    }

    proptest::proptest! {
        /// Any bytes at all: no panic, and "not QUIC" exactly when the shape test fails.
        #[test]
        fn classifying_any_bytes_never_panics(
            datagram in proptest::collection::vec(proptest::num::u8::ANY, 0..64),
            first in proptest::num::u8::ANY,
            server in proptest::bool::ANY,
        ) {
            let mut datagram = datagram;
            if let Some(b) = datagram.first_mut() {
                *b = first;
            }
            let ids = IssuedIds::new(7, server);
            let shape = classify(&datagram, &ids);
            proptest::prop_assert_eq!(shape == DatagramShape::NotQuic, !looks_like_quic(&datagram));
        }
    }

    #[test]
    fn random_garbage_is_always_counted() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2026);
        for server in [false, true] {
            let ids = IssuedIds::new(rng.gen(), server);
            let mut plausible = 0;
            for _ in 0..20_000 {
                let len = rng.gen_range(0..1500);
                let mut datagram = vec![0u8; len];
                rng.fill(&mut datagram[..]);
                if classify(&datagram, &ids) == DatagramShape::Plausible {
                    plausible += 1;
                }
            }
            // A random long header would need one of quinn's 7 versions (odds 7 / 2^32).
            assert_eq!(plausible, 0, "server: {server}");
        }
    }
}
