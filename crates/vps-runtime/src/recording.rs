//! The handle traces a session records (`LoopConfig::record_trace`): one recorder per moving
//! part, each with where its part started, room reserved up front so that recording does not
//! allocate on the frame path for sessions of a known length.

use std::time::Duration;
use vps_device::trace::{PartStart, TraceRecorder};
use vps_haptic::PartState;

/// Largest number of frames a trace recorder reserves up front.
const MAX_TRACE_RESERVE: u64 = 1 << 22;

/// How a session's traces are recorded: the frame period (s) and the frames to reserve room for.
#[derive(Clone, Copy, Debug)]
pub(crate) struct TraceRecording {
    period_s: f64,
    reserve: usize,
}

impl TraceRecording {
    /// The recording of a session at `period` lasting `frames` frames (`None`: until stopped,
    /// nothing reserved); `None` unless `record`.
    pub(crate) fn of(
        record: bool,
        period: Duration,
        frames: Option<u64>,
    ) -> Option<TraceRecording> {
        record.then(|| TraceRecording {
            period_s: period.as_secs_f64(),
            reserve: frames.unwrap_or(0).min(MAX_TRACE_RESERVE) as usize,
        })
    }

    /// A recorder for the device named `device` whose part starts at rest at `start`. Allocates
    /// the reserve; setup-time only.
    pub(crate) fn recorder(&self, device: &str, start: &PartState) -> TraceRecorder {
        TraceRecorder::with_capacity(device, self.period_s, self.reserve).with_part_start(
            PartStart {
                position: start.position,
                orientation: start.orientation,
            },
        )
    }
}
