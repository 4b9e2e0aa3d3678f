//! Counting what arrives on an endpoint's UDP socket before quinn sees it, so that garbage sent
//! to a coordinator or a worker is counted, not only dropped.
//!
//! quinn drops a datagram that is not a QUIC packet of a known connection, or that fails
//! decryption, inside its endpoint and exposes no counter for it. [`CountingSocket`] wraps the
//! endpoint's socket and classifies each received datagram by its shape (RFC 9000 §17): it is
//! **not QUIC** when it is shorter than the 16-byte AEAD tag every protected packet carries, or
//! when its first byte lacks the Fixed Bit (0x40) and it is not a Version Negotiation packet
//! (long header, version 0); both vps endpoints turn off fixed-bit greasing (RFC 9287), so their
//! own packets always carry the bit. Such datagrams are counted in [`UdpCounts::not_quic`] and still
//! handed to quinn, which drops them. What passes this test but is still garbage (about half of
//! random bytes) reaches quinn and is dropped there uncounted, or, when it looks like a handshake,
//! counted by quinn's own [`quinn::EndpointStats`] (refused / ignored handshakes).

use quinn::udp::{RecvMeta, Transmit};
use quinn::{AsyncUdpSocket, Runtime, UdpPoller};
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

/// An [`AsyncUdpSocket`] that counts what it receives, then hands it on unchanged.
pub struct CountingSocket {
    inner: Arc<dyn AsyncUdpSocket>,
    counts: Arc<UdpCounts>,
}

impl fmt::Debug for CountingSocket {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("CountingSocket")
            .field("inner", &self.inner)
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
                let mut count = |segment: &[u8]| {
                    self.counts.datagrams.fetch_add(1, Ordering::Relaxed);
                    if !looks_like_quic(segment) {
                        self.counts.not_quic.fetch_add(1, Ordering::Relaxed);
                    }
                };
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
    let counting = Arc::new(CountingSocket { inner, counts });
    // No greasing of the fixed bit (RFC 9287): our endpoints do not invite peers to clear it, so
    // every packet between vps endpoints carries it and the shape test above holds.
    let mut config = quinn::EndpointConfig::default();
    config.grease_quic_bit(false);
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
}
