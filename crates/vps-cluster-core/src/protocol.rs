//! Wire formats, all hand-written fixed-layout little-endian with strict decoding (exact length,
//! magic, kind, version, reserved bytes zero, finite floats). Nothing here trusts a length field
//! beyond the caller's limit, and no decoder panics on any input.
//!
//! Per-frame datagrams (unreliable):
//!
//! | bytes | [`FrameRequest`] (96 B) | [`FrameReply`] (280 B) |
//! |---|---|---|
//! | 0..3 | `b"VPS"` | `b"VPS"` |
//! | 3 | kind 1 | kind 2 |
//! | 4..6 | [`PROTOCOL_VERSION`] u16 | same |
//! | 6..8 | reserved, 0 | reserved, 0 |
//! | 8..16 | seq u64 | seq u64 (echoed) |
//! | 16..24 | class mask u64 | class mask u64 (echoed) |
//! | 24.. | 18 × f32: rotation (9, column-major), translation (m), linear velocity (m/s), angular velocity (rad/s) | 13 × i128 then 6 × u64: the [`PartialSums`] fields in declaration order |
//!
//! Join messages (reliable stream): each is a frame `len: u64` + body, see [`JoinMessage`]; the
//! asset files (the voxmap and shell files of `vps_cluster::ClusterAssets`) travel as
//! frames of their own (raw file bytes).

use glam::{Mat3, Vec3};
use vps_haptic::{KernelPose, PartialSums};
use vps_wire::SliceWriter;

/// Version of the datagram and join formats and of what a class is; a worker with another version
/// is refused. 2: classes are dealt in runs of points ([`vps_haptic::classed::run_length`]), so a
/// class mask names other points than in version 1.
pub const PROTOCOL_VERSION: u16 = 2;
/// Largest class count a frame datagram can address (one bit per class).
pub const MAX_CLASSES: u32 = 64;
/// Size of an encoded [`FrameRequest`] (bytes).
pub const REQUEST_LEN: usize = 24 + 18 * 4;
/// Size of an encoded [`FrameReply`] (bytes).
pub const REPLY_LEN: usize = 24 + 13 * 16 + 6 * 8;
/// Largest join message body (bytes); asset files have their own limit
/// (`vps_cluster::assets::MAX_ASSET_FILE`).
pub const MAX_JOIN_MESSAGE: u64 = 4096;

const MAGIC: &[u8; 3] = b"VPS";
const KIND_REQUEST: u8 = 1;
const KIND_REPLY: u8 = 2;

/// Why a datagram or join message was rejected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// Wrong total length.
    #[error("length {got} bytes, expected {expected}")]
    Length {
        /// Bytes received.
        got: usize,
        /// Bytes expected.
        expected: usize,
    },
    /// Magic, kind, version or reserved bytes wrong.
    #[error("bad header: {0}")]
    Header(&'static str),
    /// A float field is NaN or infinite.
    #[error("non-finite value in field `{0}`")]
    NonFinite(&'static str),
    /// A field value is out of range.
    #[error("field `{0}` out of range")]
    Range(&'static str),
}

/// One frame's work order for one worker: sample the classes in `classes` at `pose`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRequest {
    /// Frame sequence number (strictly increasing per coordinator).
    pub seq: u64,
    /// Bit `c` set: sample class `c`.
    pub classes: u64,
    /// The part's pose and velocities (f32, as the kernel uses them).
    pub pose: KernelPose,
}

/// A worker's answer: the merged sums of the requested classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameReply {
    /// The request's sequence number.
    pub seq: u64,
    /// The request's class mask.
    pub classes: u64,
    /// The sums over those classes.
    pub sums: PartialSums,
}

fn header(out: &mut [u8], kind: u8) {
    out[..3].copy_from_slice(MAGIC);
    out[3] = kind;
    out[4..6].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    out[6..8].fill(0);
}

fn check_header(bytes: &[u8], kind: u8, expected: usize) -> Result<(), DecodeError> {
    if bytes.len() != expected {
        return Err(DecodeError::Length {
            got: bytes.len(),
            expected,
        });
    }
    if &bytes[..3] != MAGIC {
        return Err(DecodeError::Header("magic"));
    }
    if bytes[3] != kind {
        return Err(DecodeError::Header("kind"));
    }
    if bytes[4..6] != PROTOCOL_VERSION.to_le_bytes() {
        return Err(DecodeError::Header("version"));
    }
    if bytes[6..8] != [0, 0] {
        return Err(DecodeError::Header("reserved"));
    }
    Ok(())
}

/// Little-endian cursor over a slice whose length was checked beforehand.
struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        // In bounds: every caller checked the exact length first.
        out.copy_from_slice(&self.bytes[self.at..self.at + N]);
        self.at += N;
        out
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.take())
    }
    fn i128(&mut self) -> i128 {
        i128::from_le_bytes(self.take())
    }
    fn f32(&mut self) -> f32 {
        f32::from_le_bytes(self.take())
    }
    fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.f32(), self.f32(), self.f32())
    }
}

impl FrameRequest {
    /// Writes the 96-byte encoding into `out`. Does not allocate.
    pub fn encode(&self, out: &mut [u8; REQUEST_LEN]) {
        header(out, KIND_REQUEST);
        let mut w = SliceWriter::new(out, 8);
        w.put(&self.seq.to_le_bytes());
        w.put(&self.classes.to_le_bytes());
        w.f32s(&self.pose.rotation.to_cols_array());
        w.f32s(&self.pose.translation.to_array());
        w.f32s(&self.pose.linear_velocity.to_array());
        w.f32s(&self.pose.angular_velocity.to_array());
    }

    /// Strict decode: exact length, header, every float finite. Never panics; does not allocate.
    pub fn decode(bytes: &[u8]) -> Result<FrameRequest, DecodeError> {
        check_header(bytes, KIND_REQUEST, REQUEST_LEN)?;
        let mut r = Reader { bytes, at: 8 };
        let seq = r.u64();
        let classes = r.u64();
        let mut cols = [0f32; 9];
        cols.iter_mut().for_each(|c| *c = r.f32());
        let rotation = Mat3::from_cols_array(&cols);
        let pose = KernelPose {
            rotation,
            translation: r.vec3(),
            linear_velocity: r.vec3(),
            angular_velocity: r.vec3(),
        };
        if !rotation.is_finite() {
            return Err(DecodeError::NonFinite("rotation"));
        }
        for (v, name) in [
            (pose.translation, "translation"),
            (pose.linear_velocity, "linear_velocity"),
            (pose.angular_velocity, "angular_velocity"),
        ] {
            if !v.is_finite() {
                return Err(DecodeError::NonFinite(name));
            }
        }
        Ok(FrameRequest { seq, classes, pose })
    }
}

impl FrameReply {
    /// Writes the 280-byte encoding into `out`. Does not allocate.
    pub fn encode(&self, out: &mut [u8; REPLY_LEN]) {
        header(out, KIND_REPLY);
        let s = &self.sums;
        let mut w = SliceWriter::new(out, 8);
        w.put(&self.seq.to_le_bytes());
        w.put(&self.classes.to_le_bytes());
        for v in s.depth_normal.iter().chain(&s.depth_torque) {
            w.put(&v.to_le_bytes());
        }
        w.put(&s.brake_sq.to_le_bytes());
        for v in s.brake_force.iter().chain(&s.brake_torque) {
            w.put(&v.to_le_bytes());
        }
        for v in [
            s.contacts,
            s.approaching,
            s.surface,
            s.interior,
            s.non_free,
            s.sampled,
        ] {
            w.put(&v.to_le_bytes());
        }
    }

    /// Strict decode: exact length and header. Plausibility of the sums is the receiver's check
    /// (it knows the share size). Never panics; does not allocate.
    pub fn decode(bytes: &[u8]) -> Result<FrameReply, DecodeError> {
        check_header(bytes, KIND_REPLY, REPLY_LEN)?;
        let mut r = Reader { bytes, at: 8 };
        let seq = r.u64();
        let classes = r.u64();
        let mut v3 = || [r.i128(), r.i128(), r.i128()];
        let depth_normal = v3();
        let depth_torque = v3();
        let brake_sq = r.i128();
        let brake_force = [r.i128(), r.i128(), r.i128()];
        let brake_torque = [r.i128(), r.i128(), r.i128()];
        let sums = PartialSums {
            depth_normal,
            depth_torque,
            brake_sq,
            brake_force,
            brake_torque,
            contacts: r.u64(),
            approaching: r.u64(),
            surface: r.u64(),
            interior: r.u64(),
            non_free: r.u64(),
            sampled: r.u64(),
        };
        Ok(FrameReply { seq, classes, sums })
    }
}

/// The classes whose bits are set in `mask`, ascending.
pub fn mask_classes(mask: u64) -> impl Iterator<Item = u32> {
    (0..MAX_CLASSES).filter(move |c| mask >> c & 1 == 1)
}

/// Messages of the join exchange on the reliable stream, in order: worker → [`JoinMessage::Hello`];
/// coordinator → [`JoinMessage::Welcome`] or [`JoinMessage::Reject`]; worker →
/// [`JoinMessage::Need`]; coordinator → the needed asset files (voxmap first) as raw frames;
/// worker → [`JoinMessage::Ready`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum JoinMessage {
    /// The worker's protocol version.
    Hello {
        /// [`PROTOCOL_VERSION`] of the worker.
        version: u16,
    },
    /// The coordinator accepts the worker and names the assets (voxmap and classed shell).
    Welcome {
        /// The id the coordinator gave this worker (logs and statistics).
        worker_id: u32,
        /// The assets' identity.
        assets: AssetsIdentity,
    },
    /// The coordinator refuses the worker.
    Reject {
        /// Why (UTF-8, at most [`MAX_JOIN_MESSAGE`] bytes).
        reason: String,
    },
    /// Which asset files the worker lacks.
    Need {
        /// Send the voxmap file.
        voxmap: bool,
        /// Send the point shell file.
        shell: bool,
    },
    /// The worker holds the assets and answers frame datagrams from now on.
    Ready,
}

/// What `vps_cluster::ClusterAssets` are, by content: nodes with these hashes hold the
/// same voxmap and shell and split the shell into the same classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AssetsIdentity {
    /// `VoxelTree::content_hash` of the voxmap.
    pub voxmap_hash: [u8; 32],
    /// BLAKE3 of the point shell file bytes (`vps_voxmap::file::write_shell`).
    pub shell_hash: [u8; 32],
    /// Number of classes `C` (1..=64).
    pub class_count: u32,
    /// Size of the voxmap file (bytes).
    pub voxmap_len: u64,
    /// Size of the shell file (bytes).
    pub shell_len: u64,
}

const TAG_HELLO: u8 = 1;
const TAG_WELCOME: u8 = 2;
const TAG_REJECT: u8 = 3;
const TAG_NEED: u8 = 4;
const TAG_READY: u8 = 5;
const WELCOME_LEN: usize = 1 + 4 + 32 + 32 + 4 + 8 + 8;

impl JoinMessage {
    /// The message body (without the length prefix). Allocates; join path only.
    pub fn encode(&self) -> Vec<u8> {
        match self {
            JoinMessage::Hello { version } => {
                let mut v = vec![TAG_HELLO];
                v.extend_from_slice(&version.to_le_bytes());
                v
            }
            JoinMessage::Welcome { worker_id, assets } => {
                let mut v = Vec::with_capacity(WELCOME_LEN);
                v.push(TAG_WELCOME);
                v.extend_from_slice(&worker_id.to_le_bytes());
                v.extend_from_slice(&assets.voxmap_hash);
                v.extend_from_slice(&assets.shell_hash);
                v.extend_from_slice(&assets.class_count.to_le_bytes());
                v.extend_from_slice(&assets.voxmap_len.to_le_bytes());
                v.extend_from_slice(&assets.shell_len.to_le_bytes());
                v
            }
            JoinMessage::Reject { reason } => {
                let mut v = vec![TAG_REJECT];
                let max = MAX_JOIN_MESSAGE as usize - 1;
                let mut end = reason.len().min(max);
                while !reason.is_char_boundary(end) {
                    end -= 1;
                }
                v.extend_from_slice(&reason.as_bytes()[..end]);
                v
            }
            JoinMessage::Need { voxmap, shell } => vec![TAG_NEED, *voxmap as u8, *shell as u8],
            JoinMessage::Ready => vec![TAG_READY],
        }
    }

    /// Strict decode of a body. Never panics.
    pub fn decode(body: &[u8]) -> Result<JoinMessage, DecodeError> {
        let (&tag, rest) = body.split_first().ok_or(DecodeError::Length {
            got: 0,
            expected: 1,
        })?;
        let exact = |n: usize| {
            if body.len() == n {
                Ok(())
            } else {
                Err(DecodeError::Length {
                    got: body.len(),
                    expected: n,
                })
            }
        };
        match tag {
            TAG_HELLO => {
                exact(3)?;
                Ok(JoinMessage::Hello {
                    version: u16::from_le_bytes([rest[0], rest[1]]),
                })
            }
            TAG_WELCOME => {
                exact(WELCOME_LEN)?;
                let mut r = Reader { bytes: rest, at: 0 };
                let worker_id = u32::from_le_bytes(r.take());
                let voxmap_hash = r.take();
                let shell_hash = r.take();
                let class_count = u32::from_le_bytes(r.take());
                if !(1..=MAX_CLASSES).contains(&class_count) {
                    return Err(DecodeError::Range("class_count"));
                }
                Ok(JoinMessage::Welcome {
                    worker_id,
                    assets: AssetsIdentity {
                        voxmap_hash,
                        shell_hash,
                        class_count,
                        voxmap_len: r.u64(),
                        shell_len: r.u64(),
                    },
                })
            }
            TAG_REJECT => Ok(JoinMessage::Reject {
                reason: String::from_utf8_lossy(rest).into_owned(),
            }),
            TAG_NEED => {
                exact(3)?;
                let flag = |b: u8| match b {
                    0 => Ok(false),
                    1 => Ok(true),
                    _ => Err(DecodeError::Range("need flag")),
                };
                Ok(JoinMessage::Need {
                    voxmap: flag(rest[0])?,
                    shell: flag(rest[1])?,
                })
            }
            TAG_READY => {
                exact(1)?;
                Ok(JoinMessage::Ready)
            }
            _ => Err(DecodeError::Header("join message tag")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pose() -> KernelPose {
        KernelPose {
            rotation: Mat3::from_rotation_z(0.3),
            translation: Vec3::new(0.05, -0.02, 0.061),
            linear_velocity: Vec3::new(0.01, 0.0, -0.2),
            angular_velocity: Vec3::new(0.0, 1.5, -0.25),
        }
    }

    fn sums() -> PartialSums {
        PartialSums {
            depth_normal: [1, -2, i128::MAX],
            depth_torque: [i128::MIN, 5, -6],
            contacts: 7,
            brake_sq: 8,
            brake_force: [9, -10, 11],
            brake_torque: [-12, 13, 14],
            approaching: 15,
            surface: 16,
            interior: 17,
            non_free: 18,
            sampled: u64::MAX,
        }
    }

    /// Deterministic pseudo-random bytes.
    fn noise(seed: u64, len: usize) -> Vec<u8> {
        use rand::{RngCore, SeedableRng};
        let mut bytes = vec![0; len];
        rand_chacha::ChaCha8Rng::seed_from_u64(seed).fill_bytes(&mut bytes);
        bytes
    }

    /// A request and a reply for `seq` and `classes`, and their datagrams.
    fn encoded(
        seq: u64,
        classes: u64,
    ) -> (FrameRequest, [u8; REQUEST_LEN], FrameReply, [u8; REPLY_LEN]) {
        let req = FrameRequest {
            seq,
            classes,
            pose: pose(),
        };
        let reply = FrameReply {
            seq,
            classes,
            sums: sums(),
        };
        let (mut req_buf, mut reply_buf) = ([0; REQUEST_LEN], [0; REPLY_LEN]);
        req.encode(&mut req_buf);
        reply.encode(&mut reply_buf);
        (req, req_buf, reply, reply_buf)
    }

    #[test]
    fn datagrams_round_trip_bit_exactly() {
        for (seq, classes) in [
            (0x0123_4567_89ab_cdef, 0xf0f0_0000_0000_0001),
            (42, u64::MAX),
        ] {
            let (req, req_buf, reply, reply_buf) = encoded(seq, classes);
            assert_eq!(FrameRequest::decode(&req_buf), Ok(req));
            assert_eq!(FrameReply::decode(&reply_buf), Ok(reply));
        }
        let (_, _, _, buf) = encoded(42, u64::MAX);
        assert!(
            FrameRequest::decode(&buf).is_err(),
            "a reply is not a request"
        );
    }

    #[test]
    fn truncated_extended_and_garbage_datagrams_are_errors() {
        let (_, req, _, rep) = encoded(1, 3);
        for n in 0..REQUEST_LEN {
            assert!(FrameRequest::decode(&req[..n]).is_err(), "truncated to {n}");
        }
        for n in 0..REPLY_LEN {
            assert!(FrameReply::decode(&rep[..n]).is_err(), "truncated to {n}");
        }
        let mut long = rep.to_vec();
        long.push(0);
        assert!(FrameReply::decode(&long).is_err());
        for seed in 1..2000u64 {
            let bytes = noise(seed, (seed as usize * 7) % 300);
            assert!(FrameRequest::decode(&bytes).is_err());
            assert!(FrameReply::decode(&bytes).is_err());
            let _ = JoinMessage::decode(&bytes);
        }
        for (i, name) in [(0, "magic"), (3, "kind"), (4, "version"), (7, "reserved")] {
            let mut bad = rep;
            bad[i] ^= 0x40;
            assert!(
                matches!(FrameReply::decode(&bad), Err(DecodeError::Header(h)) if h == name),
                "{name}"
            );
        }
    }

    #[test]
    fn a_non_finite_pose_is_rejected() {
        let mut bad = pose();
        bad.linear_velocity.y = f32::NAN;
        let mut buf = [0u8; REQUEST_LEN];
        FrameRequest {
            seq: 1,
            classes: 1,
            pose: bad,
        }
        .encode(&mut buf);
        assert_eq!(
            FrameRequest::decode(&buf),
            Err(DecodeError::NonFinite("linear_velocity"))
        );
    }

    #[test]
    fn join_messages_round_trip_and_reject_bad_fields() {
        let assets = AssetsIdentity {
            voxmap_hash: [7; 32],
            shell_hash: [9; 32],
            class_count: 64,
            voxmap_len: 123,
            shell_len: 456,
        };
        for m in [
            JoinMessage::Hello { version: 3 },
            JoinMessage::Welcome {
                worker_id: 5,
                assets,
            },
            JoinMessage::Reject {
                reason: "nope".into(),
            },
            JoinMessage::Need {
                voxmap: true,
                shell: false,
            },
            JoinMessage::Ready,
        ] {
            let body = m.encode();
            assert_eq!(JoinMessage::decode(&body), Ok(m.clone()));
            if !matches!(m, JoinMessage::Reject { .. }) {
                assert!(JoinMessage::decode(&body[..body.len() - 1]).is_err());
            }
        }
        let mut welcome = JoinMessage::Welcome {
            worker_id: 1,
            assets: AssetsIdentity {
                class_count: 65,
                ..assets
            },
        }
        .encode();
        assert_eq!(
            JoinMessage::decode(&welcome),
            Err(DecodeError::Range("class_count"))
        );
        welcome[0] = 99;
        assert!(JoinMessage::decode(&welcome).is_err());
        assert!(JoinMessage::decode(&[TAG_NEED, 2, 0]).is_err());
        assert!(JoinMessage::decode(&[]).is_err());
        let long = JoinMessage::Reject {
            reason: "é".repeat(5000),
        }
        .encode();
        assert!(long.len() as u64 <= MAX_JOIN_MESSAGE);
        assert!(matches!(
            JoinMessage::decode(&long),
            Ok(JoinMessage::Reject { .. })
        ));
    }

    #[test]
    fn mask_classes_lists_set_bits() {
        assert_eq!(
            mask_classes(0b1010_0001 | 1 << 63).collect::<Vec<_>>(),
            vec![0, 5, 7, 63]
        );
        assert_eq!(mask_classes(0).count(), 0);
    }
}
