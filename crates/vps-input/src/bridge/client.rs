//! [`BridgeClient`]: the sending side of the bridge, for scripts, tools and tests.

use std::io::ErrorKind;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

use vps_haptic::{HandleSample, Wrench};

use super::error::BridgeError;
use super::protocol::{tokens_equal, Datagram, Message, Token, MAX_DATAGRAM};

/// A wrench received from a [`BridgeDevice`](super::BridgeDevice).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WrenchReply {
    /// Force (N) and torque (N·m), world frame, already saturated by the device.
    pub wrench: Wrench,
    /// The device's write counter.
    pub frame: u64,
}

/// Streams poses to one bridge device and receives its wrenches. Uses a connected UDP socket, so
/// only datagrams from the device address are received. Sequence numbers start at 1.
pub struct BridgeClient {
    socket: UdpSocket,
    token: Token,
    sequence: u64,
    buf: [u8; MAX_DATAGRAM + 1],
}

impl BridgeClient {
    /// Binds an ephemeral port (loopback when `device` is loopback, otherwise the unspecified
    /// address of its family) and connects it to `device`. `token` must equal the device's
    /// configured token, or be `None` when the device has none (it then sends an all-zero token,
    /// and replies are accepted only with an all-zero token). Blocks only for the socket calls.
    pub fn connect(device: SocketAddr, token: Option<Token>) -> Result<Self, BridgeError> {
        let local: SocketAddr = match (device, device.ip().is_loopback()) {
            (SocketAddr::V4(_), true) => (Ipv4Addr::LOCALHOST, 0).into(),
            (SocketAddr::V4(_), false) => (Ipv4Addr::UNSPECIFIED, 0).into(),
            (SocketAddr::V6(_), true) => (Ipv6Addr::LOCALHOST, 0).into(),
            (SocketAddr::V6(_), false) => (Ipv6Addr::UNSPECIFIED, 0).into(),
        };
        let socket = UdpSocket::bind(local).map_err(|e| BridgeError::Bind {
            addr: local,
            message: e.to_string(),
        })?;
        socket
            .connect(device)
            .map_err(|e| BridgeError::io("connect", e))?;
        Ok(Self {
            socket,
            token: token.unwrap_or([0; 16]),
            sequence: 0,
            buf: [0; MAX_DATAGRAM + 1],
        })
    }

    /// This client's local address.
    pub fn local_addr(&self) -> Result<SocketAddr, BridgeError> {
        self.socket
            .local_addr()
            .map_err(|e| BridgeError::io("local address", e))
    }

    /// Sends `sample` as the next PoseIn and returns its sequence number. Values are not checked
    /// here (the device rejects non-finite ones).
    pub fn send_pose(&mut self, sample: &HandleSample) -> Result<u64, BridgeError> {
        self.sequence += 1;
        self.send_pose_with_sequence(sample, self.sequence)?;
        Ok(self.sequence)
    }

    /// Sends `sample` with an explicit sequence number (to test reordering, or resume a stream).
    pub fn send_pose_with_sequence(
        &self,
        sample: &HandleSample,
        sequence: u64,
    ) -> Result<(), BridgeError> {
        self.send_message(sequence, Message::PoseIn(*sample))
    }

    /// Sends `sample` as the next PoseInFlags (e.g. with [`FLAG_CLUTCH`](super::protocol::FLAG_CLUTCH)
    /// while the clutch is held) and returns its sequence number.
    pub fn send_pose_flags(
        &mut self,
        sample: &HandleSample,
        flags: u32,
    ) -> Result<u64, BridgeError> {
        self.sequence += 1;
        let message = Message::PoseInFlags {
            sample: *sample,
            flags,
        };
        self.send_message(self.sequence, message)?;
        Ok(self.sequence)
    }

    fn send_message(&self, sequence: u64, message: Message) -> Result<(), BridgeError> {
        let datagram = Datagram {
            token: self.token,
            sequence,
            message,
        };
        let mut out = [0u8; MAX_DATAGRAM];
        let n = datagram.encode(&mut out);
        self.send_raw(&out[..n])
    }

    /// Sends arbitrary bytes to the device (for tests of its input handling).
    pub fn send_raw(&self, bytes: &[u8]) -> Result<(), BridgeError> {
        self.socket
            .send(bytes)
            .map(|_| ())
            .map_err(|e| BridgeError::io("send", e))
    }

    /// Waits up to `timeout` for the next valid WrenchOut with this client's token; invalid
    /// datagrams are skipped. `Ok(None)` on timeout. `Duration::ZERO` polls without blocking.
    pub fn recv_wrench(&mut self, timeout: Duration) -> Result<Option<WrenchReply>, BridgeError> {
        let deadline = Instant::now() + timeout;
        loop {
            let now = Instant::now();
            if now >= deadline {
                self.socket
                    .set_nonblocking(true)
                    .map_err(|e| BridgeError::io("set non-blocking", e))?;
            } else {
                self.socket
                    .set_nonblocking(false)
                    .map_err(|e| BridgeError::io("set blocking", e))?;
                self.socket
                    .set_read_timeout(Some(deadline - now))
                    .map_err(|e| BridgeError::io("set read timeout", e))?;
            }
            match self.socket.recv(&mut self.buf) {
                Ok(len) => {
                    if let Some(reply) = self.wrench_from(len) {
                        return Ok(Some(reply));
                    }
                }
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => {
                    if now >= deadline {
                        return Ok(None);
                    }
                }
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                // Includes "connection refused": nothing listens at the device address.
                Err(e) => return Err(BridgeError::io("receive", e)),
            }
        }
    }

    fn wrench_from(&self, len: usize) -> Option<WrenchReply> {
        let d = Datagram::decode(&self.buf[..len]).ok()?;
        if !tokens_equal(&d.token, &self.token) {
            return None;
        }
        match d.message {
            Message::WrenchOut { wrench, frame } => Some(WrenchReply { wrench, frame }),
            Message::PoseIn(_) | Message::PoseInFlags { .. } => None,
        }
    }
}
