//! Handle traces: record the [`HandleSample`] of every frame, save and load them as JSON lines, and
//! replay them bit-exactly through [`ReplayDevice`].
//!
//! File format (UTF-8, one JSON object per line):
//! - line 1, the header: `{"format":"vps-trace","version":2,"device":"…","period":0.001,"frames":N,
//!   "part_start":{"position":[x,y,z],"orientation":[x,y,z,w]}}`; `part_start` (version 2) is where
//!   the session's part started, at rest: a replay or a study starts it there. Version 1 files
//!   (no `part_start`) are read too; their part starts at the first handle sample.
//! - lines 2..=N+1, one per frame: `{"frame":i,"time":t,"sample":{…}}` with `frame` = 0, 1, 2, … and
//!   `time` (s) non-decreasing. Vectors are `[x,y,z]`, quaternions `[x,y,z,w]`.
//!
//! Floats are written in shortest round-trip form and parsed exactly, so load(save(t)) == t bit for
//! bit.

use crate::device::{check_sample, DeviceError, DeviceLimits, HapticDevice};
use std::io::{BufRead, BufReader, Read, Write};
use std::path::{Path, PathBuf};
use vps_haptic::{HandleSample, Wrench};

/// The `format` field of a trace header.
pub const TRACE_FORMAT: &str = "vps-trace";
/// What a [`ReplayDevice`] puts before the recorded device's name to name itself.
pub const REPLAY_PREFIX: &str = "replay of ";

/// The device a replay named `name` plays back (`Some("simulated-hand")` for `"replay of
/// simulated-hand"`); `None` when `name` is not a replay's.
pub fn replayed_device(name: &str) -> Option<&str> {
    name.strip_prefix(REPLAY_PREFIX)
}

/// The trace format version this crate writes.
pub const TRACE_VERSION: u32 = 2;
/// The oldest trace format version this crate reads (version 1: no `part_start`).
pub const OLDEST_TRACE_VERSION: u32 = 1;

/// Where a recorded session's part started (at rest).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartStart {
    /// The part's grip position (m).
    pub position: glam::DVec3,
    /// The part's orientation (unit quaternion, `[x, y, z, w]` in the file).
    pub orientation: glam::DQuat,
}

/// Why a trace could not be recorded, saved or loaded.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// Reading or writing the file failed.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        source: std::io::Error,
    },
    /// A line is not valid JSON of the expected shape, or breaks a format rule.
    #[error("{path}:{line}: {message}")]
    Malformed {
        /// The file.
        path: PathBuf,
        /// 1-based line number (the line after the last one for a truncated file).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// [`TraceRecorder::record`] was given frames out of sequence.
    #[error("trace frame {got} recorded where frame {expected} was due")]
    OutOfSequence {
        /// The next frame index the recorder expected.
        expected: u64,
        /// The index passed.
        got: u64,
    },
    /// [`TraceRecorder::record`] was given a non-finite sample or time.
    #[error("trace frame {frame}: non-finite time or sample")]
    NonFinite {
        /// The frame index.
        frame: u64,
    },
}

/// One recorded frame.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TraceFrame {
    /// Frame index (0-based, consecutive).
    pub frame: u64,
    /// Time passed to the device's read (s since start).
    pub time: f64,
    /// What the device returned.
    pub sample: HandleSample,
}

/// A recorded session. Invariants (enforced by [`TraceRecorder`] and [`load_trace`]): frames numbered
/// 0, 1, 2, …, times finite and non-decreasing, samples finite.
#[derive(Clone, Debug, PartialEq)]
pub struct Trace {
    /// Name of the device that produced it.
    pub device: String,
    /// Nominal frame period (s).
    pub period: f64,
    /// The frames, in order.
    pub frames: Vec<TraceFrame>,
    /// Where the session's part started, when recorded (version 2 files).
    pub part_start: Option<PartStart>,
}

#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Header {
    format: String,
    version: u32,
    device: String,
    period: f64,
    frames: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    part_start: Option<PartStart>,
}

/// Records one [`HandleSample`] per frame. `record` allocates only when the reserved capacity is
/// exceeded (reserve with [`TraceRecorder::with_capacity`] on a frame path); it never blocks.
#[derive(Clone, Debug)]
pub struct TraceRecorder {
    trace: Trace,
}

impl TraceRecorder {
    /// An empty recorder for `device` at nominal `period` (s), with room for `frames` frames.
    pub fn with_capacity(device: &str, period: f64, frames: usize) -> TraceRecorder {
        TraceRecorder {
            trace: Trace {
                device: device.to_string(),
                period,
                frames: Vec::with_capacity(frames),
                part_start: None,
            },
        }
    }

    /// Records that the session's part started at rest at `start`.
    pub fn with_part_start(mut self, start: PartStart) -> TraceRecorder {
        self.trace.part_start = Some(start);
        self
    }

    /// Appends frame `frame` (must be the next index) read at `time` (s, ≥ the previous time).
    pub fn record(
        &mut self,
        frame: u64,
        time: f64,
        sample: HandleSample,
    ) -> Result<(), TraceError> {
        let expected = self.trace.frames.len() as u64;
        if frame != expected {
            return Err(TraceError::OutOfSequence {
                expected,
                got: frame,
            });
        }
        let previous = self
            .trace
            .frames
            .last()
            .map_or(f64::NEG_INFINITY, |f| f.time);
        if !time.is_finite() || check_sample("", &sample).is_err() || time < previous {
            return Err(TraceError::NonFinite { frame });
        }
        self.trace.frames.push(TraceFrame {
            frame,
            time,
            sample,
        });
        Ok(())
    }

    /// Number of frames recorded.
    pub fn len(&self) -> usize {
        self.trace.frames.len()
    }

    /// True before the first frame.
    pub fn is_empty(&self) -> bool {
        self.trace.frames.is_empty()
    }

    /// The recorded trace.
    pub fn finish(self) -> Trace {
        self.trace
    }
}

/// Writes `trace` to `path` in the JSON-lines format. The bytes go to a temporary file in the same
/// directory, renamed over `path` only once complete, so a failed write (full disk, killed process)
/// never leaves a truncated trace behind.
pub fn save_trace(path: &Path, trace: &Trace) -> Result<(), TraceError> {
    let io = |source| TraceError::Io {
        path: path.to_path_buf(),
        source,
    };
    vps_files::atomic::write_atomically(
        path,
        |out| write_trace(out, trace, path),
        |_, source| io(source),
    )
}

/// Writes `trace` in the JSON-lines format to `out`; `path` names the destination in errors.
pub fn write_trace(out: &mut impl Write, trace: &Trace, path: &Path) -> Result<(), TraceError> {
    let io = |source| TraceError::Io {
        path: path.to_path_buf(),
        source,
    };
    let header = Header {
        format: TRACE_FORMAT.to_string(),
        version: TRACE_VERSION,
        device: trace.device.clone(),
        period: trace.period,
        frames: trace.frames.len() as u64,
        part_start: trace.part_start,
    };
    let json = |e: serde_json::Error, line| TraceError::Malformed {
        path: path.to_path_buf(),
        line,
        message: format!("cannot encode: {e}"),
    };
    serde_json::to_writer(&mut *out, &header).map_err(|e| json(e, 1))?;
    out.write_all(b"\n").map_err(io)?;
    for (i, frame) in trace.frames.iter().enumerate() {
        serde_json::to_writer(&mut *out, frame).map_err(|e| json(e, i + 2))?;
        out.write_all(b"\n").map_err(io)?;
    }
    out.flush().map_err(io)
}

/// Reads a trace written by [`save_trace`], checking every format rule; errors name the file and
/// line.
pub fn load_trace(path: &Path) -> Result<Trace, TraceError> {
    let (file, _) = vps_files::open_regular(path).map_err(|source| TraceError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_trace(BufReader::new(file), path)
}

/// Frames reserved up front from a header's promise; more grow the vector as lines arrive, so a
/// header promising billions of frames in a short file cannot ask for a huge allocation.
const MAX_RESERVED_FRAMES: u64 = 4096;

/// The longest line read, in bytes. A frame line is about 300 bytes and a header under 1 KiB; a
/// longer line (a file with no line breaks, or not a trace at all) is refused once this many bytes
/// are read, before more memory is taken for it.
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Reads a trace in the JSON-lines format from `reader`, checking every format rule; `path` names
/// the source in errors (with the line). Memory grows with the lines actually read, each at most
/// [`MAX_LINE_BYTES`].
pub fn read_trace(mut reader: impl BufRead, path: &Path) -> Result<Trace, TraceError> {
    let malformed = |line: usize, message: String| TraceError::Malformed {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut line = 0;
    let mut next_line = |what: &str| -> Result<Option<(usize, String)>, TraceError> {
        line += 1;
        let mut bytes = Vec::new();
        let read = (&mut reader)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut bytes)
            .map_err(|e| malformed(line, format!("cannot read {what}: {e}")))?;
        if read == 0 {
            return Ok(None);
        }
        if bytes.last() == Some(&b'\n') {
            bytes.pop();
            if bytes.last() == Some(&b'\r') {
                bytes.pop();
            }
        } else if bytes.len() > MAX_LINE_BYTES {
            return Err(malformed(
                line,
                format!("cannot read {what}: the line is longer than {MAX_LINE_BYTES} bytes"),
            ));
        }
        let text = String::from_utf8(bytes)
            .map_err(|_| malformed(line, format!("cannot read {what}: not UTF-8 text")))?;
        Ok(Some((line, text)))
    };
    let (_, text) =
        next_line("header")?.ok_or_else(|| malformed(1, "empty file: no header".into()))?;
    let header: Header =
        serde_json::from_str(&text).map_err(|e| malformed(1, format!("bad header: {e}")))?;
    let known = OLDEST_TRACE_VERSION..=TRACE_VERSION;
    if header.format != TRACE_FORMAT || !known.contains(&header.version) {
        return Err(malformed(
            1,
            format!(
                "format {:?} version {} is not {TRACE_FORMAT:?} version {OLDEST_TRACE_VERSION} \
                 to {TRACE_VERSION}",
                header.format, header.version
            ),
        ));
    }
    if header.version < 2 && header.part_start.is_some() {
        return Err(malformed(1, "`part_start` needs version 2 or later".into()));
    }
    if let Some(start) = &header.part_start {
        let unit = (start.orientation.length() - 1.0).abs() < 1e-6;
        if !(start.position.is_finite() && start.orientation.is_finite() && unit) {
            return Err(malformed(
                1,
                "`part_start`: position must be finite and orientation a finite unit quaternion"
                    .into(),
            ));
        }
    }
    if !(header.period.is_finite() && header.period > 0.0) {
        return Err(malformed(
            1,
            format!("period {} must be finite and > 0", header.period),
        ));
    }
    let mut recorder = TraceRecorder::with_capacity(
        &header.device,
        header.period,
        header.frames.min(MAX_RESERVED_FRAMES) as usize,
    );
    if let Some(start) = header.part_start {
        recorder = recorder.with_part_start(start);
    }
    while let Some((n, text)) = next_line("frame")? {
        let frame: TraceFrame =
            serde_json::from_str(&text).map_err(|e| malformed(n, format!("bad frame: {e}")))?;
        recorder
            .record(frame.frame, frame.time, frame.sample)
            .map_err(|e| malformed(n, e.to_string()))?;
    }
    if recorder.len() as u64 != header.frames {
        return Err(malformed(
            recorder.len() + 2,
            format!(
                "header promises {} frames, file holds {}",
                header.frames,
                recorder.len()
            ),
        ));
    }
    Ok(recorder.finish())
}

/// Plays a [`Trace`] back: the n-th `read` returns the n-th recorded sample exactly, whatever time is
/// passed; written wrenches are checked for finiteness and otherwise ignored. After the last frame,
/// `read` fails with [`DeviceError::TraceExhausted`] (which ends a haptic session). Never blocks or
/// allocates.
#[derive(Clone, Debug)]
pub struct ReplayDevice {
    trace: std::sync::Arc<Trace>,
    next: usize,
    limits: DeviceLimits,
    name: String,
}

impl ReplayDevice {
    /// Replays `trace` (owned, or shared with whoever else reads it), reporting `limits` to the
    /// loop.
    pub fn new(trace: impl Into<std::sync::Arc<Trace>>, limits: DeviceLimits) -> ReplayDevice {
        let trace = trace.into();
        let name = format!("{REPLAY_PREFIX}{}", trace.device);
        ReplayDevice {
            trace,
            next: 0,
            limits,
            name,
        }
    }

    /// Frames not yet read.
    pub fn remaining(&self) -> usize {
        self.trace.frames.len() - self.next
    }
}

impl HapticDevice for ReplayDevice {
    fn read(&mut self, _t: f64) -> Result<HandleSample, DeviceError> {
        let frame =
            self.trace
                .frames
                .get(self.next)
                .ok_or_else(|| DeviceError::TraceExhausted {
                    device: self.name.clone(),
                    frames: self.trace.frames.len() as u64,
                })?;
        self.next += 1;
        Ok(frame.sample)
    }

    fn write(&mut self, wrench: &Wrench) -> Result<(), DeviceError> {
        if wrench.force.is_finite() && wrench.torque.is_finite() {
            Ok(())
        } else {
            Err(DeviceError::NonFinite {
                device: self.name.clone(),
                what: "written wrench",
            })
        }
    }

    crate::limits_and_name_from_fields!();
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::script::ScriptBuilder;
    use crate::sim_hand::{HandParams, SimulatedHand};
    use glam::{DQuat, DVec3};

    /// A trace of a simulated hand pushed around by a varying wrench: awkward floats everywhere.
    fn recorded() -> Trace {
        let script = ScriptBuilder::start(DVec3::new(0.1, 0.2, 0.3), DQuat::IDENTITY)
            .move_to(DVec3::new(-0.1, 0.25, 0.3), 0.3)
            .rotate_to(DQuat::from_rotation_y(0.7), 3.0)
            .build()
            .unwrap();
        let mut hand = SimulatedHand::new(script, HandParams::default()).unwrap();
        let mut rec =
            TraceRecorder::with_capacity(hand.name(), 1e-3, 500).with_part_start(PartStart {
                position: DVec3::new(0.1, 0.2, 0.3 + 1e-17),
                orientation: DQuat::from_rotation_z(0.3),
            });
        for n in 0..500u64 {
            let t = n as f64 * 1e-3;
            let s = hand.read(t).unwrap();
            rec.record(n, t, s).unwrap();
            let f = (n as f64 * 0.1).sin() * 3.0;
            hand.write(&Wrench {
                force: DVec3::new(f, 0.1 * f, 1e-300),
                torque: DVec3::splat(f * 1e-3),
            })
            .unwrap();
        }
        rec.finish()
    }

    fn bits(s: &HandleSample) -> Vec<u64> {
        let mut v: Vec<f64> = Vec::new();
        v.extend(s.position.to_array());
        v.extend(s.orientation.to_array());
        v.extend(s.linear_velocity.to_array());
        v.extend(s.angular_velocity.to_array());
        v.into_iter().map(f64::to_bits).collect()
    }

    #[test]
    fn save_load_replay_is_bit_exact() {
        let trace = recorded();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.jsonl");
        save_trace(&path, &trace).unwrap();
        let loaded = load_trace(&path).unwrap();
        assert_eq!(loaded.device, trace.device);
        assert_eq!(loaded.part_start, trace.part_start);
        assert_eq!(loaded.frames.len(), 500);
        let mut replay = ReplayDevice::new(loaded, DeviceLimits::PAPER);
        for f in &trace.frames {
            let s = replay.read(f.time + 123.0).unwrap();
            assert_eq!(bits(&s), bits(&f.sample), "frame {}", f.frame);
            replay
                .write(&Wrench {
                    force: DVec3::X * 1e6,
                    torque: DVec3::ZERO,
                })
                .unwrap();
        }
        assert_eq!(replay.remaining(), 0);
        assert!(matches!(
            replay.read(1.0),
            Err(DeviceError::TraceExhausted { frames: 500, .. })
        ));
    }

    /// Version 1 files (no part start) still load; a part start in one, or a part start that is
    /// not a finite unit pose, is refused naming the header line.
    #[test]
    fn version_one_traces_load_and_bad_part_starts_are_refused() {
        let v1 = r#"{"format":"vps-trace","version":1,"device":"d","period":0.001,"frames":0}"#;
        let trace = load_text(&format!("{v1}\n")).unwrap();
        assert_eq!(trace.part_start, None);
        let start = r#""part_start":{"position":[0,0,0],"orientation":[0,0,0,1]}"#;
        let v1_with_start = v1.replace(r#""frames":0"#, &format!(r#""frames":0,{start}"#));
        expect_malformed(&format!("{v1_with_start}\n"), 1, "needs version 2");
        let v2 = v1_with_start.replace(r#""version":1"#, r#""version":2"#);
        let trace = load_text(&format!("{v2}\n")).unwrap();
        assert_eq!(trace.part_start.unwrap().orientation, DQuat::IDENTITY);
        let skewed = v2.replace("[0,0,0,1]", "[0,0,0,2]");
        expect_malformed(&format!("{skewed}\n"), 1, "unit quaternion");
    }

    #[test]
    fn recorder_rejects_gaps_and_non_finite() {
        let s = HandleSample {
            position: DVec3::ZERO,
            orientation: DQuat::IDENTITY,
            linear_velocity: DVec3::ZERO,
            angular_velocity: DVec3::ZERO,
        };
        let mut rec = TraceRecorder::with_capacity("x", 1e-3, 4);
        rec.record(0, 0.0, s).unwrap();
        assert!(matches!(
            rec.record(2, 0.1, s),
            Err(TraceError::OutOfSequence {
                expected: 1,
                got: 2
            })
        ));
        let bad = HandleSample {
            position: DVec3::new(f64::NAN, 0.0, 0.0),
            ..s
        };
        assert!(matches!(
            rec.record(1, 0.1, bad),
            Err(TraceError::NonFinite { frame: 1 })
        ));
        assert_eq!(rec.len(), 1);
    }

    fn load_text(text: &str) -> Result<Trace, TraceError> {
        read_trace(text.as_bytes(), Path::new("mem.jsonl"))
    }

    fn expect_malformed(text: &str, line: usize, needle: &str) {
        match load_text(text) {
            Err(TraceError::Malformed {
                line: l,
                message,
                path,
            }) => {
                assert_eq!(l, line, "{message}");
                assert!(message.contains(needle), "{message:?} lacks {needle:?}");
                assert_eq!(path, Path::new("mem.jsonl"));
            }
            other => panic!("expected a malformed error, got {other:?}"),
        }
    }

    #[test]
    fn malformed_files_name_the_line() {
        let header = r#"{"format":"vps-trace","version":1,"device":"d","period":0.001,"frames":2}"#;
        let f0 = r#"{"frame":0,"time":0.0,"sample":{"position":[0,0,0],"orientation":[0,0,0,1],"linear_velocity":[0,0,0],"angular_velocity":[0,0,0]}}"#;
        let f1 = f0.replace("\"frame\":0", "\"frame\":1");
        let f5 = f0.replace("\"frame\":0", "\"frame\":5");
        assert_eq!(
            load_text(&format!("{header}\n{f0}\n{f1}\n"))
                .unwrap()
                .frames
                .len(),
            2
        );
        expect_malformed("", 1, "no header");
        expect_malformed("{not json", 1, "bad header");
        expect_malformed(&header.replace("vps-trace", "other"), 1, "is not");
        expect_malformed(
            &header.replace("\"version\":1", "\"version\":9"),
            1,
            "version 9",
        );
        expect_malformed(&header.replace("0.001", "-1"), 1, "period");
        expect_malformed(&format!("{header}\n{f0}\n{f5}\n"), 3, "frame 5");
        expect_malformed(&format!("{header}\n{f0}\n[1,2]\n"), 3, "bad frame");
        expect_malformed(&format!("{header}\n{f0}\n"), 3, "promises 2");
        let missing_field = f1.replace("\"time\":0.0,", "");
        expect_malformed(&format!("{header}\n{f0}\n{missing_field}\n"), 3, "time");
        assert_eq!(
            load_text(&format!("{header}\r\n{f0}\r\n{f1}\r\n"))
                .unwrap()
                .frames
                .len(),
            2,
            "CRLF line ends read as LF"
        );
        let latin1 = [format!("{header}\n{f0}\n").into_bytes(), vec![0xe9, b'\n']].concat();
        match read_trace(&latin1[..], Path::new("mem.jsonl")) {
            Err(TraceError::Malformed {
                line: 3, message, ..
            }) => {
                assert!(message.contains("not UTF-8"), "{message}")
            }
            other => panic!("expected a malformed line 3, got {other:?}"),
        }
    }

    #[test]
    fn a_line_without_end_is_refused_after_max_line_bytes() {
        // An endless stream of bytes with no line break: only MAX_LINE_BYTES + 1 are read.
        let endless = std::io::BufReader::new(std::io::repeat(b'x'));
        match read_trace(endless, Path::new("zeros")) {
            Err(TraceError::Malformed {
                line: 1, message, ..
            }) => {
                assert!(message.contains("longer than 65536 bytes"), "{message}")
            }
            other => panic!("expected a malformed line 1, got {other:?}"),
        }
        let header = r#"{"format":"vps-trace","version":1,"device":"d","period":0.001,"frames":0}"#;
        let exactly_max = format!("{header}{}", " ".repeat(MAX_LINE_BYTES - header.len()));
        assert_eq!(load_text(&exactly_max).unwrap().frames.len(), 0);
    }

    #[test]
    fn missing_file_names_the_path() {
        let e = load_trace(Path::new("/nonexistent/dir/x.jsonl")).unwrap_err();
        assert!(e.to_string().contains("/nonexistent/dir/x.jsonl"), "{e}");
    }
}
