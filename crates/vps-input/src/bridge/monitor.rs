//! [`BridgeMonitor`]: a shared view of a [`BridgeDevice`](super::BridgeDevice)'s counters and of
//! the wrenches it sent, readable after the device has moved into the frame loop.
//!
//! Wrench log file format (text, one line per wrench sent, in sending order):
//! `FRAME FX FY FZ TX TY TZ` where FRAME is the decimal frame number carried by the WrenchOut
//! datagram and each other field is the 16 lower-case hex digits of the f64's IEEE 754 bits
//! (`f64::to_bits`), device frame, N and N·m. Equal lines mean bit-identical wrenches.

use std::io::Write;
use std::sync::{Arc, Mutex, MutexGuard};

use vps_haptic::Wrench;

/// Counts of what a [`BridgeDevice`](super::BridgeDevice) saw and did since it was bound.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct BridgeCounters {
    /// Poses accepted (newer than the previous one from the same peer).
    pub accepted: u64,
    /// Valid poses dropped because their sequence was not newer (while the peer's newest pose was
    /// fresh).
    pub stale: u64,
    /// Poses accepted although their sequence was not newer, because the peer's newest pose had
    /// timed out: a sender that restarted its sequence (or had sent a far-ahead one).
    pub restarts: u64,
    /// Datagrams that failed to decode (bad length, magic, version, kind, flags, non-finite
    /// values), or were a WrenchOut (wrong direction).
    pub garbage: u64,
    /// Well-formed datagrams carrying the wrong token.
    pub unauthorized: u64,
    /// Wrenches sent to the peer.
    pub sent: u64,
    /// Wrench sends that failed (full buffer, unreachable peer); not fatal.
    pub send_failed: u64,
    /// Times the newest pose became older than the pose timeout (one per silence).
    pub timeouts: u64,
    /// Clutch presses (a pose with the clutch flag after one without, or as the first pose).
    pub clutch_presses: u64,
    /// Frames whose wrench was replaced by zero because the device was holding (clutch held or
    /// pose timed out): `zeroed_by_timeout + zeroed_by_clutch`.
    pub zeroed_frames: u64,
    /// Of `zeroed_frames`, those while the newest pose was older than the pose timeout.
    pub zeroed_by_timeout: u64,
    /// Of `zeroed_frames`, those while the clutch was held (and the pose fresh).
    pub zeroed_by_clutch: u64,
    /// Writes before any pose arrived (one per frame, plus the session's closing zero): no peer
    /// to send to, the handle held at the start. A session whose client never came shows all its
    /// frames here.
    pub frames_before_first_pose: u64,
    /// Wrenches sent but not logged because the wrench log was full.
    pub unlogged: u64,
}

/// One wrench as sent in a WrenchOut datagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SentWrench {
    /// The datagram's frame number (the device's write counter).
    pub frame: u64,
    /// Force (N) and torque (N·m), device frame, after scaling and saturation.
    pub wrench: Wrench,
}

#[derive(Debug, Default)]
struct Shared {
    counters: BridgeCounters,
    log: Vec<SentWrench>,
}

/// A cloneable handle onto one bridge device's counters and wrench log.
#[derive(Clone, Debug, Default)]
pub struct BridgeMonitor {
    shared: Arc<Mutex<Shared>>,
}

impl BridgeMonitor {
    /// A monitor whose log holds up to `log_capacity` wrenches (reserved now, never grown).
    pub(crate) fn with_capacity(log_capacity: usize) -> Self {
        Self {
            shared: Arc::new(Mutex::new(Shared {
                counters: BridgeCounters::default(),
                log: Vec::with_capacity(log_capacity),
            })),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Shared> {
        self.shared
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner())
    }

    /// Publishes the device's counters and, when given, appends a sent wrench (dropped and
    /// counted when the log is full). Blocks only while a reader copies; does not allocate.
    pub(crate) fn publish(&self, counters: &mut BridgeCounters, sent: Option<SentWrench>) {
        let mut shared = self.lock();
        if let Some(s) = sent {
            if shared.log.len() < shared.log.capacity() {
                shared.log.push(s);
            } else {
                counters.unlogged += 1;
            }
        }
        shared.counters = *counters;
    }

    /// The counters as of the device's last write.
    pub fn counters(&self) -> BridgeCounters {
        self.lock().counters
    }

    /// A copy of the wrenches logged so far, in sending order.
    pub fn sent_wrenches(&self) -> Vec<SentWrench> {
        self.lock().log.clone()
    }

    /// Writes the wrench log to `out` in the format of this module's documentation (the caller
    /// flushes it; the CLI writes it atomically) and returns the number of lines
    /// written; every write error is returned.
    pub fn write_wrench_log(&self, out: &mut impl Write) -> std::io::Result<usize> {
        let log = self.sent_wrenches();
        for s in &log {
            writeln!(out, "{}", wrench_log_line(s))?;
        }
        Ok(log.len())
    }
}

/// One line of the wrench log format (without the newline).
pub fn wrench_log_line(s: &SentWrench) -> String {
    let f = s.wrench.force;
    let t = s.wrench.torque;
    let mut line = s.frame.to_string();
    for v in [f.x, f.y, f.z, t.x, t.y, t.z] {
        line.push_str(&format!(" {:016x}", v.to_bits()));
    }
    line
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn log_is_bounded_and_lines_carry_exact_bits() {
        let m = BridgeMonitor::with_capacity(1);
        let mut c = BridgeCounters::default();
        let w = Wrench {
            force: DVec3::new(1.0, -0.0, 0.1),
            torque: DVec3::ZERO,
        };
        m.publish(
            &mut c,
            Some(SentWrench {
                frame: 7,
                wrench: w,
            }),
        );
        m.publish(
            &mut c,
            Some(SentWrench {
                frame: 8,
                wrench: w,
            }),
        );
        assert_eq!(m.sent_wrenches().len(), 1);
        assert_eq!(m.counters().unlogged, 1);
        assert_eq!(
            wrench_log_line(&m.sent_wrenches()[0]),
            "7 3ff0000000000000 8000000000000000 3fb999999999999a \
             0000000000000000 0000000000000000 0000000000000000"
        );
    }
}
