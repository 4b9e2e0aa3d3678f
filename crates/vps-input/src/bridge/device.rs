//! [`BridgeDevice`]: a [`HapticDevice`] fed by UDP datagrams.

use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};

use glam::DVec3;
use vps_device::{DeviceError, DeviceLimits, HapticDevice};
use vps_haptic::{HandleSample, Wrench};

use super::config::{BridgeConfig, BridgeError};
use super::protocol::{tokens_equal, Datagram, Message, Token, MAX_DATAGRAM};

/// At most this many datagrams are drained per `read`, so `read` stays bounded under a flood.
const MAX_DATAGRAMS_PER_READ: usize = 1024;

/// Counts of datagrams seen and sent by a [`BridgeDevice`] since it was bound.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BridgeCounters {
    /// Poses accepted (newer than the previous one from the same peer).
    pub accepted: u64,
    /// Valid poses dropped because their sequence was not newer.
    pub stale: u64,
    /// Datagrams that failed to decode (bad length, magic, version, kind, non-finite values), or
    /// were a WrenchOut (wrong direction).
    pub garbage: u64,
    /// Well-formed datagrams carrying the wrong token.
    pub unauthorized: u64,
    /// Wrenches sent to the peer.
    pub sent: u64,
    /// Wrench sends that failed (full buffer, unreachable peer); not fatal.
    pub send_failed: u64,
}

/// A haptic device whose handle is driven over UDP by a [`BridgeClient`](super::BridgeClient) or
/// any process speaking [`protocol`](super::protocol).
///
/// `read(t)` drains pending datagrams without blocking (at most 1024) and returns the newest
/// accepted pose; before any, the configured initial pose with zero velocity. A pose older than
/// `velocity_timeout` is held with zero velocities. Poses from one peer must carry increasing
/// sequence numbers; a pose from a new peer address starts a new stream (the newest peer wins).
/// `write` saturates the wrench and sends it to the peer of the newest pose (no peer yet: nothing
/// is sent). Neither allocates except to build an error; neither blocks.
pub struct BridgeDevice {
    socket: UdpSocket,
    config: BridgeConfig,
    local_addr: SocketAddr,
    latest: Option<Latest>,
    last_t: Option<f64>,
    frame: u64,
    last_wrench: Wrench,
    counters: BridgeCounters,
    recv_buf: [u8; MAX_DATAGRAM + 1],
    send_buf: [u8; MAX_DATAGRAM],
}

/// The newest accepted pose and where it came from.
#[derive(Clone, Copy, Debug)]
struct Latest {
    sample: HandleSample,
    sequence: u64,
    peer: SocketAddr,
    received_at: f64,
}

impl BridgeDevice {
    /// Validates `config` and binds its UDP socket (non-blocking).
    pub fn bind(config: BridgeConfig) -> Result<Self, BridgeError> {
        config.validate()?;
        let socket = UdpSocket::bind(config.bind).map_err(|e| BridgeError::Bind {
            addr: config.bind,
            message: e.to_string(),
        })?;
        socket
            .set_nonblocking(true)
            .map_err(|e| BridgeError::io("set non-blocking", e))?;
        let local_addr = socket
            .local_addr()
            .map_err(|e| BridgeError::io("local address", e))?;
        Ok(Self {
            socket,
            config,
            local_addr,
            latest: None,
            last_t: None,
            frame: 0,
            last_wrench: Wrench::ZERO,
            counters: BridgeCounters::default(),
            recv_buf: [0; MAX_DATAGRAM + 1],
            send_buf: [0; MAX_DATAGRAM],
        })
    }

    /// The bound address (with the actual port when port 0 was asked for).
    pub fn local_addr(&self) -> SocketAddr {
        self.local_addr
    }

    /// Datagram counters since binding.
    pub fn counters(&self) -> BridgeCounters {
        self.counters
    }

    /// The last wrench written, after saturation (N, N·m, world frame).
    pub fn last_wrench(&self) -> Wrench {
        self.last_wrench
    }

    /// The peer that sent the newest accepted pose, if any.
    pub fn peer(&self) -> Option<SocketAddr> {
        self.latest.map(|l| l.peer)
    }

    fn token_ok(&self, token: &Token) -> bool {
        self.config
            .token
            .as_ref()
            .is_none_or(|expected| tokens_equal(expected, token))
    }

    /// Classifies one received datagram and keeps it when it is the newest valid pose.
    fn accept(&mut self, len: usize, from: SocketAddr, t: f64) {
        let Ok(datagram) = Datagram::decode(&self.recv_buf[..len]) else {
            self.counters.garbage += 1;
            return;
        };
        if !self.token_ok(&datagram.token) {
            self.counters.unauthorized += 1;
            return;
        }
        let Message::PoseIn(sample) = datagram.message else {
            self.counters.garbage += 1;
            return;
        };
        if let Some(l) = &self.latest {
            if l.peer == from && datagram.sequence <= l.sequence {
                self.counters.stale += 1;
                return;
            }
        }
        self.latest = Some(Latest {
            sample,
            sequence: datagram.sequence,
            peer: from,
            received_at: t,
        });
        self.counters.accepted += 1;
    }

    fn hardware(&self, what: &str, e: std::io::Error) -> DeviceError {
        DeviceError::Hardware {
            device: self.config.name.clone(),
            message: format!("UDP bridge on {}: {what} failed: {e}", self.local_addr),
        }
    }
}

impl HapticDevice for BridgeDevice {
    fn read(&mut self, t: f64) -> Result<HandleSample, DeviceError> {
        let previous = self.last_t.unwrap_or(t);
        if !t.is_finite() || t < previous {
            return Err(DeviceError::TimeWentBackwards {
                device: self.config.name.clone(),
                previous,
                now: t,
            });
        }
        self.last_t = Some(t);
        for _ in 0..MAX_DATAGRAMS_PER_READ {
            match self.socket.recv_from(&mut self.recv_buf) {
                Ok((len, from)) => self.accept(len, from, t),
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                // ICMP errors from an earlier send to a vanished peer; not the socket's fault.
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::Interrupted
                            | ErrorKind::ConnectionReset
                            | ErrorKind::ConnectionRefused
                    ) => {}
                Err(e) => return Err(self.hardware("receive", e)),
            }
        }
        Ok(match &self.latest {
            None => HandleSample {
                position: self.config.initial_position,
                orientation: self.config.initial_orientation,
                linear_velocity: DVec3::ZERO,
                angular_velocity: DVec3::ZERO,
            },
            Some(l) if t - l.received_at > self.config.velocity_timeout => HandleSample {
                linear_velocity: DVec3::ZERO,
                angular_velocity: DVec3::ZERO,
                ..l.sample
            },
            Some(l) => l.sample,
        })
    }

    fn write(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        if !wrench.force.is_finite() || !wrench.torque.is_finite() {
            return Err(DeviceError::NonFinite {
                device: self.config.name.clone(),
                what: "written wrench",
            });
        }
        self.last_wrench = self.config.limits.saturate(wrench);
        self.frame += 1;
        let Some(peer) = self.latest.map(|l| l.peer) else {
            return Ok(());
        };
        let datagram = Datagram {
            token: self.config.token.unwrap_or([0; 16]),
            sequence: self.frame,
            message: Message::WrenchOut {
                wrench: self.last_wrench,
                frame: self.frame,
            },
        };
        let n = datagram.encode(&mut self.send_buf);
        match self.socket.send_to(&self.send_buf[..n], peer) {
            Ok(_) => self.counters.sent += 1,
            Err(_) => self.counters.send_failed += 1,
        }
        Ok(())
    }

    fn limits(&self) -> DeviceLimits {
        self.config.limits
    }

    fn name(&self) -> &str {
        &self.config.name
    }
}
