//! [`BridgeDevice`]: a [`HapticDevice`] fed by UDP datagrams.

use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};

use glam::DVec3;
use vps_device::{DeviceError, DeviceLimits, HapticDevice};
use vps_haptic::{HandleSample, Wrench};

use super::config::BridgeConfig;
use super::error::BridgeError;
use super::mapping::Anchor;
use super::monitor::{BridgeCounters, BridgeMonitor, SentWrench};
use super::protocol::{tokens_equal, Datagram, Message, Token, FLAG_CLUTCH, MAX_DATAGRAM};

/// At most this many datagrams are drained per `read`, so `read` stays bounded under a flood.
const MAX_DATAGRAMS_PER_READ: usize = 1024;

/// A haptic device whose handle is driven over UDP by a [`BridgeClient`](super::BridgeClient) or
/// any process speaking [`protocol`](super::protocol).
///
/// `read(t)` drains pending datagrams without blocking (at most 1024) and returns the newest
/// accepted pose mapped into the scene by the configured [`WorkspaceMapping`]; before any pose,
/// the configured initial pose with zero velocity. A pose older than `velocity_timeout` is
/// reported with zero velocities. Poses from one peer must carry increasing sequence numbers
/// (others are dropped as stale), except after the peer's newest accepted pose has timed out: a
/// sequence at or below it then starts the stream again (a restarted client, counted in
/// `restarts`), so no sequence number, u64::MAX included, locks a sender out for longer than the
/// pose timeout. A pose from a new peer address starts a new stream (the newest peer wins).
///
/// Holding: while the newest pose carries the clutch flag, or is older than `pose_timeout`, the
/// device holds: `read` returns the last scene pose it returned, with zero velocities (the
/// handle moves without moving the part's target), and `write` sends the zero wrench (counted in
/// `zeroed_frames`). When a fresh pose without the clutch arrives, the mapping is re-anchored so
/// that pose maps exactly onto the held scene pose: the target does not jump.
///
/// `write` maps the scene wrench into the device frame (force scale, inverse rotation),
/// saturates it to the device limits and sends it to the peer of the newest pose (no peer yet:
/// nothing is sent). Neither allocates except to build an error; neither blocks beyond a
/// [`BridgeMonitor`] reader's copy.
///
/// [`WorkspaceMapping`]: super::WorkspaceMapping
pub struct BridgeDevice {
    socket: UdpSocket,
    config: BridgeConfig,
    local_addr: SocketAddr,
    latest: Option<Latest>,
    last_t: Option<f64>,
    frame: u64,
    last_wrench: Wrench,
    counters: BridgeCounters,
    monitor: BridgeMonitor,
    anchor: Anchor,
    /// The scene sample `read` returned last (what is held while holding).
    output: HandleSample,
    /// True while the clutch is held or the pose has timed out (after at least one pose).
    holding: bool,
    /// True from a timeout until the next fresh pose (so a silence counts once); while
    /// `holding`, a timed-out pose is the reason (else the clutch is).
    timed_out: bool,
    recv_buf: [u8; MAX_DATAGRAM + 1],
    send_buf: [u8; MAX_DATAGRAM],
}

/// The newest accepted pose (device frame) and where it came from.
#[derive(Clone, Copy, Debug)]
struct Latest {
    sample: HandleSample,
    clutch: bool,
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
        let output = HandleSample {
            position: config.initial_position,
            orientation: config.initial_orientation,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
        };
        Ok(Self {
            socket,
            monitor: BridgeMonitor::with_capacity(config.wrench_log_frames),
            anchor: Anchor::new(&config.mapping),
            output,
            holding: false,
            timed_out: false,
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

    /// Counters since binding (up to date after every `read` and `write`).
    pub fn counters(&self) -> BridgeCounters {
        self.counters
    }

    /// A handle onto this device's counters (as of its last `write`) and the wrenches it sent,
    /// still readable once the device has moved into the frame loop and been dropped.
    pub fn monitor(&self) -> BridgeMonitor {
        self.monitor.clone()
    }

    /// True while the device holds (clutch held or pose timed out): see [`BridgeDevice`].
    pub fn holding(&self) -> bool {
        self.holding
    }

    /// The last wrench sent or to be sent, in the device frame after force scaling and
    /// saturation (N, N·m); zero while holding.
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
        let (sample, clutch) = match datagram.message {
            Message::PoseIn(sample) => (sample, false),
            Message::PoseInFlags { sample, flags } => (sample, flags & FLAG_CLUTCH != 0),
            Message::WrenchOut { .. } => {
                self.counters.garbage += 1;
                return;
            }
        };
        if let Some(l) = &self.latest {
            if l.peer == from && datagram.sequence <= l.sequence {
                // A sender whose stream has been silent past the pose timeout and now counts from
                // below its last number restarted (or one datagram of u64::MAX locked it out):
                // take it back rather than drop it for the rest of the session.
                if t - l.received_at > self.config.pose_timeout {
                    self.counters.restarts += 1;
                } else {
                    self.counters.stale += 1;
                    return;
                }
            }
        }
        if clutch && !self.latest.is_some_and(|l| l.clutch) {
            self.counters.clutch_presses += 1;
        }
        self.latest = Some(Latest {
            sample,
            clutch,
            sequence: datagram.sequence,
            peer: from,
            received_at: t,
        });
        self.counters.accepted += 1;
    }

    /// Sets `output` (and the holding state) for a read at `t`, after draining datagrams.
    fn update_output(&mut self, t: f64) {
        let Some(l) = self.latest else {
            return; // Still the initial pose.
        };
        let age = t - l.received_at;
        let fresh = age <= self.config.pose_timeout;
        if fresh {
            self.timed_out = false;
        } else if !self.timed_out {
            self.timed_out = true;
            self.counters.timeouts += 1;
        }
        if !fresh || l.clutch {
            self.holding = true;
            self.output.linear_velocity = DVec3::ZERO;
            self.output.angular_velocity = DVec3::ZERO;
            return;
        }
        if self.holding {
            self.anchor
                .reanchor(&l.sample, self.output.position, self.output.orientation);
            self.holding = false;
        }
        self.output = self.anchor.to_scene(&l.sample);
        if age > self.config.velocity_timeout {
            self.output.linear_velocity = DVec3::ZERO;
            self.output.angular_velocity = DVec3::ZERO;
        }
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
        self.update_output(t);
        Ok(self.output)
    }

    /// The bridge's datagram counts ([`BridgeCounters`]), as the session's report gives them
    /// for every part's device.
    fn counters(&self) -> Option<serde_json::Value> {
        serde_json::to_value(BridgeDevice::counters(self)).ok()
    }

    fn write(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        if !wrench.force.is_finite() || !wrench.torque.is_finite() {
            return Err(DeviceError::NonFinite {
                device: self.config.name.clone(),
                what: "written wrench",
            });
        }
        self.last_wrench = if self.holding {
            self.counters.zeroed_frames += 1;
            if self.timed_out {
                self.counters.zeroed_by_timeout += 1;
            } else {
                self.counters.zeroed_by_clutch += 1;
            }
            Wrench::ZERO
        } else if *wrench == Wrench::ZERO {
            // The loop's safety zero stays an exact +0.0 through the mapping.
            Wrench::ZERO
        } else {
            self.config.limits.saturate(&self.anchor.to_device(wrench))
        };
        self.frame += 1;
        let Some(peer) = self.latest.map(|l| l.peer) else {
            self.counters.frames_before_first_pose += 1;
            self.monitor.publish(&mut self.counters, None);
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
        let sent = match self.socket.send_to(&self.send_buf[..n], peer) {
            Ok(_) => {
                self.counters.sent += 1;
                Some(SentWrench {
                    frame: self.frame,
                    wrench: self.last_wrench,
                })
            }
            Err(_) => {
                self.counters.send_failed += 1;
                None
            }
        };
        self.monitor.publish(&mut self.counters, sent);
        Ok(())
    }

    fn limits(&self) -> DeviceLimits {
        self.config.limits
    }

    fn name(&self) -> &str {
        &self.config.name
    }
}
