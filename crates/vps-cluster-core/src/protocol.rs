//! Wire formats, all hand-written fixed-layout little-endian with strict decoding (exact length,
//! magic, kind, version, finite floats, every field in its range). Nothing here trusts a length field
//! beyond the caller's limit, and no decoder panics on any input.
//!
//! Per-frame datagrams (unreliable):
//!
//! | bytes | [`FrameRequest`] (96 B) | [`FrameReply`] (280 B) |
//! |---|---|---|
//! | 0..3 | `b"VPS"` | `b"VPS"` |
//! | 3 | kind 1 | kind 2 |
//! | 4..6 | [`PROTOCOL_VERSION`] u16 | same |
//! | 6 | the job's shell (a part index) | echoed |
//! | 7 | the job's voxmap (0 the scene, `1 + k` part `k`'s body) | echoed |
//! | 8..16 | seq u64 | seq u64 (echoed) |
//! | 16..24 | class mask u64 | class mask u64 (echoed) |
//! | 24.. | 18 × f32: rotation (9, column-major), translation (m), linear velocity (m/s), angular velocity (rad/s) | 13 × i128 then 6 × u64: the [`PartialSums`] fields in declaration order |
//!
//! A frame of several jobs ([`vps_haptic::job`]) sends one request per job to a worker, all with
//! the same class mask; the worker answers each on its own.
//!
//! Join messages (reliable stream): each is a frame `len: u64` + body, see [`JoinMessage`]; the
//! asset files (the voxmap and shell files of `vps_cluster::ClusterAssets`) travel as
//! frames of their own (raw file bytes).

use glam::{Mat3, Vec3};
use vps_haptic::{JobTarget, KernelPose, PartialSums};
use vps_wire::SliceWriter;

/// Version of the datagram and join formats and of what a class is; a worker with another version
/// is refused. 2: classes are dealt in runs of points ([`vps_haptic::classed::run_length`]), so a
/// class mask names other points than in version 1. 3: a frame datagram names its job (shell
/// and voxmap, bytes 6 and 7, reserved in version 2), and the assets are a list of files.
pub const PROTOCOL_VERSION: u16 = 3;
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
    /// Magic, kind, version or message tag wrong.
    #[error("bad header: {0}")]
    Header(&'static str),
    /// A float field is NaN or infinite.
    #[error("non-finite value in field `{0}`")]
    NonFinite(&'static str),
    /// A field value is out of range.
    #[error("field `{0}` out of range")]
    Range(&'static str),
}

/// One frame's work order for one worker: sample the classes in `classes` of the job `job` at
/// `pose`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FrameRequest {
    /// Frame sequence number (strictly increasing per coordinator).
    pub seq: u64,
    /// Bit `c` set: sample class `c`.
    pub classes: u64,
    /// Which shell in which voxmap (a worker checks it against its assets).
    pub job: JobTarget,
    /// The shell's pose and velocities in the voxmap's frame (f32, as the kernel uses them).
    pub pose: KernelPose,
}

/// A worker's answer: the merged sums of the requested classes of one job.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameReply {
    /// The request's sequence number.
    pub seq: u64,
    /// The request's class mask.
    pub classes: u64,
    /// The request's job.
    pub job: JobTarget,
    /// The sums over those classes.
    pub sums: PartialSums,
}

fn header(out: &mut [u8], kind: u8, job: JobTarget) {
    out[..3].copy_from_slice(MAGIC);
    out[3] = kind;
    out[4..6].copy_from_slice(&PROTOCOL_VERSION.to_le_bytes());
    out[6] = job.shell;
    out[7] = job.map;
}

fn job_of(bytes: &[u8]) -> JobTarget {
    JobTarget {
        shell: bytes[6],
        map: bytes[7],
    }
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
        header(out, KIND_REQUEST, self.job);
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
        Ok(FrameRequest {
            seq,
            classes,
            job: job_of(bytes),
            pose,
        })
    }
}

impl FrameReply {
    /// Writes the 280-byte encoding into `out`. Does not allocate.
    pub fn encode(&self, out: &mut [u8; REPLY_LEN]) {
        header(out, KIND_REPLY, self.job);
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
        Ok(FrameReply {
            seq,
            classes,
            job: job_of(bytes),
            sums,
        })
    }
}

/// The classes whose bits are set in `mask`, ascending.
pub fn mask_classes(mask: u64) -> impl Iterator<Item = u32> {
    (0..MAX_CLASSES).filter(move |c| mask >> c & 1 == 1)
}

/// Messages of the join exchange on the reliable stream, in order: worker → [`JoinMessage::Hello`];
/// coordinator → [`JoinMessage::Welcome`] or [`JoinMessage::Reject`]; worker →
/// [`JoinMessage::Need`]; coordinator → the needed asset files (in [`AssetsIdentity::files`]
/// order) as raw frames; worker → [`JoinMessage::Ready`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum JoinMessage {
    /// The worker's protocol version.
    Hello {
        /// [`PROTOCOL_VERSION`] of the worker.
        version: u16,
    },
    /// The coordinator accepts the worker and names the assets (voxmaps and classed shells).
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
        /// Bit `k` set: send file `k` of [`AssetsIdentity::files`] (no bit at or past their count).
        files: u64,
    },
    /// The worker holds the assets and answers frame datagrams from now on.
    Ready,
}

/// What an asset file holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AssetKind {
    /// A voxmap (`vps_voxmap::file::write_voxmap`); its hash is `VoxelTree::content_hash`.
    Voxmap,
    /// A point shell (`vps_voxmap::file::write_shell`); its hash is BLAKE3 of the file bytes.
    Shell,
}

impl AssetKind {
    /// The word for it in messages and the cache's file extension: `voxmap` or `shell`.
    pub fn name(self) -> &'static str {
        match self {
            AssetKind::Voxmap => "voxmap",
            AssetKind::Shell => "shell",
        }
    }
}

/// One asset file, by content.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AssetFile {
    /// What it holds.
    pub kind: AssetKind,
    /// Its content hash (see [`AssetKind`]).
    pub hash: [u8; 32],
    /// Its size (bytes).
    pub len: u64,
}

/// Most moving parts the assets can hold ([`vps_haptic::job::MAX_JOB_PARTS`]).
pub const MAX_ASSET_PARTS: usize = vps_haptic::job::MAX_JOB_PARTS;

/// What `vps_cluster::ClusterAssets` are, by content: nodes with these files hold the same
/// voxmaps and shells and split every shell into the same classes.
///
/// `files` in this order, which is also the order of the transfer: the static scene's voxmap
/// (voxmap 0 of [`vps_haptic::job`]), the `parts` moving parts' shells (shell 0, 1, …), and, in a
/// session of more than one part, their body voxmaps (voxmap 1, 2, …).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AssetsIdentity {
    /// Number of classes `C` (1..=64) every shell is split into.
    pub class_count: u32,
    /// The moving parts (1..=[`MAX_ASSET_PARTS`]).
    pub parts: u8,
    /// The files (see above): `1 + parts` files for one part, `1 + 2·parts` for more.
    pub files: Vec<AssetFile>,
}

impl AssetsIdentity {
    /// How many files `parts` moving parts need (see [`AssetsIdentity`]).
    pub fn file_count(parts: u8) -> usize {
        let parts = usize::from(parts);
        if parts > 1 {
            1 + 2 * parts
        } else {
            1 + parts
        }
    }

    /// The kind file `k` must have among `file_count(parts)` files.
    fn kind_at(parts: u8, k: usize) -> AssetKind {
        if k == 0 || k > usize::from(parts) {
            AssetKind::Voxmap
        } else {
            AssetKind::Shell
        }
    }

    /// Checks the layout: class count in 1..=64, parts in 1..=[`MAX_ASSET_PARTS`], the file count
    /// and every file's kind in place.
    pub fn check(&self) -> Result<(), DecodeError> {
        if !(1..=MAX_CLASSES).contains(&self.class_count) {
            return Err(DecodeError::Range("class_count"));
        }
        if !(1..=MAX_ASSET_PARTS).contains(&usize::from(self.parts)) {
            return Err(DecodeError::Range("parts"));
        }
        if self.files.len() != Self::file_count(self.parts) {
            return Err(DecodeError::Range("file count"));
        }
        if (0..self.files.len()).any(|k| self.files[k].kind != Self::kind_at(self.parts, k)) {
            return Err(DecodeError::Range("file kind"));
        }
        Ok(())
    }

    /// The bit mask of every file (for [`JoinMessage::Need`]).
    pub fn all_files(&self) -> u64 {
        match self.files.len() {
            64.. => u64::MAX,
            n => (1u64 << n) - 1,
        }
    }
}

const TAG_HELLO: u8 = 1;
const TAG_WELCOME: u8 = 2;
const TAG_REJECT: u8 = 3;
const TAG_NEED: u8 = 4;
const TAG_READY: u8 = 5;
/// Welcome without its files: tag, worker id, class count, parts.
const WELCOME_HEAD: usize = 1 + 4 + 4 + 1;
/// One file in a welcome: kind, hash, length.
const WELCOME_FILE: usize = 1 + 32 + 8;
const KIND_VOXMAP: u8 = 1;
const KIND_SHELL: u8 = 2;

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
                let mut v = Vec::with_capacity(WELCOME_HEAD + WELCOME_FILE * assets.files.len());
                v.push(TAG_WELCOME);
                v.extend_from_slice(&worker_id.to_le_bytes());
                v.extend_from_slice(&assets.class_count.to_le_bytes());
                v.push(assets.parts);
                for file in &assets.files {
                    v.push(match file.kind {
                        AssetKind::Voxmap => KIND_VOXMAP,
                        AssetKind::Shell => KIND_SHELL,
                    });
                    v.extend_from_slice(&file.hash);
                    v.extend_from_slice(&file.len.to_le_bytes());
                }
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
            JoinMessage::Need { files } => {
                let mut v = vec![TAG_NEED];
                v.extend_from_slice(&files.to_le_bytes());
                v
            }
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
                if body.len() < WELCOME_HEAD {
                    return Err(DecodeError::Length {
                        got: body.len(),
                        expected: WELCOME_HEAD,
                    });
                }
                let parts = body[WELCOME_HEAD - 1];
                if !(1..=MAX_ASSET_PARTS).contains(&usize::from(parts)) {
                    return Err(DecodeError::Range("parts"));
                }
                let count = AssetsIdentity::file_count(parts);
                exact(WELCOME_HEAD + WELCOME_FILE * count)?;
                let mut r = Reader { bytes: rest, at: 0 };
                let worker_id = u32::from_le_bytes(r.take());
                let class_count = u32::from_le_bytes(r.take());
                r.at += 1;
                let mut files = Vec::with_capacity(count);
                for _ in 0..count {
                    let kind = match r.take::<1>()[0] {
                        KIND_VOXMAP => AssetKind::Voxmap,
                        KIND_SHELL => AssetKind::Shell,
                        _ => return Err(DecodeError::Range("file kind")),
                    };
                    files.push(AssetFile {
                        kind,
                        hash: r.take(),
                        len: r.u64(),
                    });
                }
                let assets = AssetsIdentity {
                    class_count,
                    parts,
                    files,
                };
                assets.check()?;
                Ok(JoinMessage::Welcome { worker_id, assets })
            }
            TAG_REJECT => Ok(JoinMessage::Reject {
                reason: String::from_utf8_lossy(rest).into_owned(),
            }),
            TAG_NEED => {
                exact(9)?;
                let mut r = Reader { bytes: rest, at: 0 };
                Ok(JoinMessage::Need { files: r.u64() })
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
        let job = JobTarget { shell: 2, map: 1 };
        let req = FrameRequest {
            seq,
            classes,
            job,
            pose: pose(),
        };
        let reply = FrameReply {
            seq,
            classes,
            job,
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
        for (i, name) in [(0, "magic"), (3, "kind"), (4, "version")] {
            let mut bad = rep;
            bad[i] ^= 0x40;
            assert!(
                matches!(FrameReply::decode(&bad), Err(DecodeError::Header(h)) if h == name),
                "{name}"
            );
        }
    }

    /// The job travels in bytes 6 and 7 of both datagrams, any values (the receiver checks
    /// them against its assets).
    #[test]
    fn the_job_is_carried_and_echoed() {
        let (_, mut req, _, mut rep) = encoded(9, 1);
        assert_eq!((req[6], req[7], rep[6], rep[7]), (2, 1, 2, 1));
        for buf in [&mut req[..], &mut rep[..]] {
            buf[6] = 255;
            buf[7] = 200;
        }
        let want = JobTarget {
            shell: 255,
            map: 200,
        };
        assert_eq!(FrameRequest::decode(&req).unwrap().job, want);
        assert_eq!(FrameReply::decode(&rep).unwrap().job, want);
    }

    #[test]
    fn a_non_finite_pose_is_rejected() {
        let mut bad = pose();
        bad.linear_velocity.y = f32::NAN;
        let mut buf = [0u8; REQUEST_LEN];
        FrameRequest {
            seq: 1,
            classes: 1,
            job: JobTarget::FIRST,
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
        let file = |kind, byte: u8| AssetFile {
            kind,
            hash: [byte; 32],
            len: u64::from(byte) * 100,
        };
        let assets = AssetsIdentity {
            class_count: 64,
            parts: 1,
            files: vec![file(AssetKind::Voxmap, 7), file(AssetKind::Shell, 9)],
        };
        let two_parts = AssetsIdentity {
            class_count: 8,
            parts: 2,
            files: vec![
                file(AssetKind::Voxmap, 1),
                file(AssetKind::Shell, 2),
                file(AssetKind::Shell, 3),
                file(AssetKind::Voxmap, 4),
                file(AssetKind::Voxmap, 5),
            ],
        };
        assert_eq!(two_parts.all_files(), 0b11111);
        for m in [
            JoinMessage::Hello { version: 3 },
            JoinMessage::Welcome {
                worker_id: 5,
                assets: assets.clone(),
            },
            JoinMessage::Welcome {
                worker_id: 6,
                assets: two_parts.clone(),
            },
            JoinMessage::Reject {
                reason: "nope".into(),
            },
            JoinMessage::Need { files: 0b101 },
            JoinMessage::Ready,
        ] {
            let body = m.encode();
            assert_eq!(JoinMessage::decode(&body), Ok(m.clone()));
            if !matches!(m, JoinMessage::Reject { .. }) {
                assert!(JoinMessage::decode(&body[..body.len() - 1]).is_err());
            }
        }
        let welcome_of = |assets: AssetsIdentity| JoinMessage::Welcome {
            worker_id: 1,
            assets,
        };
        let mut welcome = welcome_of(AssetsIdentity {
            class_count: 65,
            ..assets.clone()
        })
        .encode();
        assert_eq!(
            JoinMessage::decode(&welcome),
            Err(DecodeError::Range("class_count"))
        );
        welcome[0] = 99;
        assert!(JoinMessage::decode(&welcome).is_err());
        // A file out of place, a part count the files do not follow, too many parts.
        let mut swapped = two_parts.clone();
        swapped.files.swap(2, 3);
        assert_eq!(
            JoinMessage::decode(&welcome_of(swapped).encode()),
            Err(DecodeError::Range("file kind"))
        );
        let mut body = welcome_of(two_parts.clone()).encode();
        body[WELCOME_HEAD - 1] = 1;
        assert!(matches!(
            JoinMessage::decode(&body),
            Err(DecodeError::Length { .. })
        ));
        body[WELCOME_HEAD - 1] = 9;
        assert_eq!(JoinMessage::decode(&body), Err(DecodeError::Range("parts")));
        body[WELCOME_HEAD - 1] = 0;
        assert_eq!(JoinMessage::decode(&body), Err(DecodeError::Range("parts")));
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
