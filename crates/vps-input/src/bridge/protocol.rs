//! The bridge datagram format (version 1). All integers and floats are little-endian
//! (IEEE 754 binary64 for every f64).
//!
//! ```text
//! offset  size  field
//!      0     4  magic  b"VPSB"
//!      4     1  version = 1
//!      5     1  kind: 1 = PoseIn, 3 = PoseInFlags (client → device), 2 = WrenchOut (device → client)
//!      6    16  token  (shared secret; all zero when the device has none)
//!     22     8  sequence u64 (per sender, strictly increasing; older ones are dropped)
//!     30        payload
//! PoseIn      payload: position xyz (m), orientation quaternion xyzw (unit), linear velocity xyz
//!             (m/s), angular velocity xyz (rad/s): 13 × f64 → 134 bytes in all
//! PoseInFlags payload: the PoseIn payload, then flags u32 → 138 bytes in all.
//!             Flag bit 0 ([`FLAG_CLUTCH`]): the clutch is held. Bits 1..31 are reserved and must
//!             be zero (a datagram with any of them set is rejected).
//! WrenchOut   payload: force xyz (N), torque xyz (N·m), 6 × f64, then frame u64 (the device's
//!             write counter) → 86 bytes in all
//! ```
//!
//! Poses and wrenches are in the device's own frame; the device side maps them to and from the
//! scene (see [`crate::bridge::mapping`]).
//!
//! Kind 3 was added after the first release without a version bump: a device that predates it
//! rejects it as an unknown kind, and the WrenchOut reply is unchanged, so version-1 clients that
//! send kind 1 keep working against this device.
//!
//! Decoding checks the exact length for the kind, rejects NaN/infinite values and an orientation
//! whose norm is off 1 by more than [`UNIT_TOLERANCE`] (a near-unit one is renormalised). Nothing
//! here allocates or panics, whatever the input bytes.

use glam::{DQuat, DVec3};
use vps_haptic::{HandleSample, Wrench};
use vps_wire::SliceWriter;

/// The first four bytes of every datagram.
pub const MAGIC: [u8; 4] = *b"VPSB";
/// The protocol version this module speaks.
pub const VERSION: u8 = 1;
/// Kind byte of a [`Message::PoseIn`].
pub const KIND_POSE_IN: u8 = 1;
/// Kind byte of a [`Message::WrenchOut`].
pub const KIND_WRENCH_OUT: u8 = 2;
/// Kind byte of a [`Message::PoseInFlags`].
pub const KIND_POSE_IN_FLAGS: u8 = 3;
/// Flag bit of a [`Message::PoseInFlags`]: the clutch is held.
pub const FLAG_CLUTCH: u32 = 1;
/// Every flag bit this version defines.
pub const KNOWN_FLAGS: u32 = FLAG_CLUTCH;
/// Bytes before the payload.
pub const HEADER_LEN: usize = 30;
/// Total length of a PoseIn datagram (bytes).
pub const POSE_IN_LEN: usize = HEADER_LEN + 13 * 8;
/// Total length of a PoseInFlags datagram (bytes).
pub const POSE_IN_FLAGS_LEN: usize = POSE_IN_LEN + 4;
/// Total length of a WrenchOut datagram (bytes).
pub const WRENCH_OUT_LEN: usize = HEADER_LEN + 6 * 8 + 8;
/// The longest datagram of this version (bytes).
pub const MAX_DATAGRAM: usize = POSE_IN_FLAGS_LEN;
/// Largest accepted deviation of the orientation's norm from 1.
pub const UNIT_TOLERANCE: f64 = 1e-3;

/// A 16-byte shared secret carried by every datagram.
pub type Token = [u8; 16];

/// The payload of a datagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Message {
    /// A handle pose and velocities streamed into the device (world frame, SI units).
    PoseIn(HandleSample),
    /// A handle pose with flags ([`FLAG_CLUTCH`]).
    PoseInFlags {
        /// Pose and velocities, as in [`Message::PoseIn`].
        sample: HandleSample,
        /// Flag bits; only [`KNOWN_FLAGS`] may be set.
        flags: u32,
    },
    /// The wrench the device was commanded, sent back to the client.
    WrenchOut {
        /// Force (N) and torque (N·m), world frame.
        wrench: Wrench,
        /// The device's write counter (1 for the first write).
        frame: u64,
    },
}

/// One decoded datagram.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Datagram {
    /// The shared secret (all zero when unused).
    pub token: Token,
    /// The sender's sequence number.
    pub sequence: u64,
    /// The payload.
    pub message: Message,
}

/// Why a datagram was rejected.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ProtocolError {
    /// Shorter than the header.
    #[error("datagram of {len} bytes is shorter than the {HEADER_LEN}-byte header")]
    TooShort {
        /// Received length (bytes).
        len: usize,
    },
    /// The first four bytes are not `VPSB`.
    #[error("bad magic {found:02x?}, expected \"VPSB\"")]
    BadMagic {
        /// The first four bytes received.
        found: [u8; 4],
    },
    /// A version this module does not speak.
    #[error("unsupported protocol version {found}, expected {VERSION}")]
    UnsupportedVersion {
        /// The version byte received.
        found: u8,
    },
    /// An unknown kind byte.
    #[error("unknown message kind {kind}")]
    UnknownKind {
        /// The kind byte received.
        kind: u8,
    },
    /// The length does not match the kind.
    #[error("{kind} datagram of {len} bytes, expected exactly {expected}")]
    WrongLength {
        /// "PoseIn", "PoseInFlags" or "WrenchOut".
        kind: &'static str,
        /// Received length (bytes).
        len: usize,
        /// Expected length (bytes).
        expected: usize,
    },
    /// A NaN or infinite value.
    #[error("non-finite {field}")]
    NonFinite {
        /// Which field ("position", "orientation", "force", ...).
        field: &'static str,
    },
    /// A reserved flag bit is set.
    #[error("reserved flag bits {flags:#010x} set (only {KNOWN_FLAGS:#x} is defined)")]
    ReservedFlags {
        /// The flags received.
        flags: u32,
    },
    /// The orientation quaternion is not unit length.
    #[error("orientation quaternion has norm {norm}, expected 1 ± {UNIT_TOLERANCE}")]
    NotUnitQuaternion {
        /// Its norm.
        norm: f64,
    },
}

impl Datagram {
    /// Encodes into `out` and returns the number of bytes written ([`POSE_IN_LEN`],
    /// [`POSE_IN_FLAGS_LEN`] or [`WRENCH_OUT_LEN`]). Does not validate values (the receiver does). Does not allocate.
    pub fn encode(&self, out: &mut [u8; MAX_DATAGRAM]) -> usize {
        out[..4].copy_from_slice(&MAGIC);
        out[4] = VERSION;
        out[6..22].copy_from_slice(&self.token);
        out[22..30].copy_from_slice(&self.sequence.to_le_bytes());
        out[5] = match &self.message {
            Message::PoseIn(_) => KIND_POSE_IN,
            Message::PoseInFlags { .. } => KIND_POSE_IN_FLAGS,
            Message::WrenchOut { .. } => KIND_WRENCH_OUT,
        };
        let mut w = SliceWriter::new(out, HEADER_LEN);
        match &self.message {
            Message::PoseIn(s) => put_sample(&mut w, s),
            Message::PoseInFlags { sample, flags } => {
                put_sample(&mut w, sample);
                w.put(&flags.to_le_bytes());
            }
            Message::WrenchOut { wrench, frame } => {
                w.f64s(&wrench.force.to_array());
                w.f64s(&wrench.torque.to_array());
                w.put(&frame.to_le_bytes());
            }
        }
        w.position()
    }

    /// Decodes and validates one datagram. Does not allocate or panic.
    pub fn decode(bytes: &[u8]) -> Result<Self, ProtocolError> {
        let len = bytes.len();
        if len < HEADER_LEN {
            return Err(ProtocolError::TooShort { len });
        }
        let (header, payload) = bytes.split_at(HEADER_LEN);
        let magic = array::<4>(&header[..4]);
        if magic != MAGIC {
            return Err(ProtocolError::BadMagic { found: magic });
        }
        if header[4] != VERSION {
            return Err(ProtocolError::UnsupportedVersion { found: header[4] });
        }
        let token = array::<16>(&header[6..22]);
        let sequence = u64::from_le_bytes(array::<8>(&header[22..30]));
        let message = match header[5] {
            KIND_POSE_IN => {
                expect_len("PoseIn", len, POSE_IN_LEN)?;
                Message::PoseIn(decode_pose(payload)?)
            }
            KIND_POSE_IN_FLAGS => {
                expect_len("PoseInFlags", len, POSE_IN_FLAGS_LEN)?;
                let flags = u32::from_le_bytes(array::<4>(&payload[13 * 8..]));
                if flags & !KNOWN_FLAGS != 0 {
                    return Err(ProtocolError::ReservedFlags { flags });
                }
                Message::PoseInFlags {
                    sample: decode_pose(payload)?,
                    flags,
                }
            }
            KIND_WRENCH_OUT => {
                expect_len("WrenchOut", len, WRENCH_OUT_LEN)?;
                decode_wrench(payload)?
            }
            kind => return Err(ProtocolError::UnknownKind { kind }),
        };
        Ok(Self {
            token,
            sequence,
            message,
        })
    }
}

/// Compares two tokens in time independent of where they differ.
pub fn tokens_equal(a: &Token, b: &Token) -> bool {
    let diff = a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y));
    std::hint::black_box(diff) == 0
}

fn expect_len(kind: &'static str, len: usize, expected: usize) -> Result<(), ProtocolError> {
    if len == expected {
        Ok(())
    } else {
        Err(ProtocolError::WrongLength {
            kind,
            len,
            expected,
        })
    }
}

/// Copies `N` bytes (the caller guarantees `bytes.len() == N`; shorter input is zero-padded).
fn array<const N: usize>(bytes: &[u8]) -> [u8; N] {
    let mut a = [0u8; N];
    for (d, s) in a.iter_mut().zip(bytes) {
        *d = *s;
    }
    a
}

/// The first `N` little-endian f64 of `payload`.
fn f64s<const N: usize>(payload: &[u8]) -> [f64; N] {
    let mut v = [0.0; N];
    for (x, c) in v.iter_mut().zip(payload.chunks_exact(8)) {
        *x = f64::from_le_bytes(array::<8>(c));
    }
    v
}

fn finite_vec3(v: [f64; 3], field: &'static str) -> Result<DVec3, ProtocolError> {
    let v = DVec3::from_array(v);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(ProtocolError::NonFinite { field })
    }
}

fn decode_pose(payload: &[u8]) -> Result<HandleSample, ProtocolError> {
    let v = f64s::<13>(payload);
    let position = finite_vec3([v[0], v[1], v[2]], "position")?;
    let q = DQuat::from_xyzw(v[3], v[4], v[5], v[6]);
    if !q.is_finite() {
        return Err(ProtocolError::NonFinite {
            field: "orientation",
        });
    }
    let norm = q.length();
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(ProtocolError::NotUnitQuaternion { norm });
    }
    Ok(HandleSample {
        position,
        orientation: q / norm,
        linear_velocity: finite_vec3([v[7], v[8], v[9]], "linear_velocity")?,
        angular_velocity: finite_vec3([v[10], v[11], v[12]], "angular_velocity")?,
    })
}

fn decode_wrench(payload: &[u8]) -> Result<Message, ProtocolError> {
    let v = f64s::<6>(payload);
    let wrench = Wrench {
        force: finite_vec3([v[0], v[1], v[2]], "force")?,
        torque: finite_vec3([v[3], v[4], v[5]], "torque")?,
    };
    let frame = u64::from_le_bytes(array::<8>(payload.get(48..56).unwrap_or(&[])));
    Ok(Message::WrenchOut { wrench, frame })
}

/// Writes a handle sample: position (m), orientation quaternion `x, y, z, w`, linear velocity
/// (m/s), angular velocity (rad/s), each component an `f64`.
fn put_sample(w: &mut SliceWriter, s: &HandleSample) {
    let q = s.orientation;
    w.f64s(&s.position.to_array());
    w.f64s(&[q.x, q.y, q.z, q.w]);
    w.f64s(&s.linear_velocity.to_array());
    w.f64s(&s.angular_velocity.to_array());
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn pose() -> Datagram {
        Datagram {
            token: [7; 16],
            sequence: 42,
            message: Message::PoseIn(HandleSample {
                position: DVec3::new(0.1, -0.2, 0.3),
                orientation: DQuat::from_rotation_y(0.7),
                linear_velocity: DVec3::new(1.0, 2.0, 3.0),
                angular_velocity: DVec3::new(-0.5, 0.0, 0.25),
            }),
        }
    }

    fn wrench() -> Datagram {
        Datagram {
            token: [0; 16],
            sequence: u64::MAX,
            message: Message::WrenchOut {
                wrench: Wrench {
                    force: DVec3::new(1.5, -2.5, 15.0),
                    torque: DVec3::new(0.0, 0.1, -0.05),
                },
                frame: 123_456_789,
            },
        }
    }

    fn encoded(d: &Datagram) -> Vec<u8> {
        let mut buf = [0u8; MAX_DATAGRAM];
        let n = d.encode(&mut buf);
        buf[..n].to_vec()
    }

    #[test]
    fn round_trips_both_kinds() {
        for d in [pose(), wrench()] {
            let bytes = encoded(&d);
            let back = Datagram::decode(&bytes).unwrap();
            match (back.message, d.message) {
                (Message::PoseIn(a), Message::PoseIn(b)) => {
                    assert_eq!(a.position, b.position);
                    assert!((a.orientation - b.orientation).length() < 1e-15);
                    assert_eq!(a.linear_velocity, b.linear_velocity);
                    assert_eq!(a.angular_velocity, b.angular_velocity);
                }
                (a, b) => assert_eq!(a, b),
            }
            assert_eq!((back.token, back.sequence), (d.token, d.sequence));
        }
        assert_eq!(encoded(&pose()).len(), 134);
        assert_eq!(encoded(&wrench()).len(), 86);
        assert_eq!(&encoded(&pose())[..6], b"VPSB\x01\x01");
    }

    #[test]
    fn every_truncation_and_extension_is_rejected() {
        for d in [pose(), wrench()] {
            let bytes = encoded(&d);
            for n in 0..bytes.len() {
                assert!(Datagram::decode(&bytes[..n]).is_err(), "prefix {n}");
            }
            let mut long = bytes.clone();
            long.push(0);
            assert!(matches!(
                Datagram::decode(&long),
                Err(ProtocolError::WrongLength { .. })
            ));
        }
    }

    #[test]
    fn header_errors_are_specific() {
        let good = encoded(&pose());
        let mut b = good.clone();
        b[0] = b'X';
        assert!(matches!(
            Datagram::decode(&b),
            Err(ProtocolError::BadMagic { .. })
        ));
        let mut b = good.clone();
        b[4] = 9;
        assert_eq!(
            Datagram::decode(&b),
            Err(ProtocolError::UnsupportedVersion { found: 9 })
        );
        let mut b = good.clone();
        b[5] = 77;
        assert_eq!(
            Datagram::decode(&b),
            Err(ProtocolError::UnknownKind { kind: 77 })
        );
        let e = Datagram::decode(&good[..100]).unwrap_err();
        assert_eq!(
            e,
            ProtocolError::WrongLength {
                kind: "PoseIn",
                len: 100,
                expected: 134
            }
        );
        assert!(e.to_string().contains("100 bytes"));
    }

    #[test]
    fn non_finite_and_non_unit_values_are_rejected() {
        let good = encoded(&pose());
        // Field offsets: position 30, orientation 54, linear 86, angular 110.
        for (offset, field) in [
            (30, "position"),
            (54 + 8, "orientation"),
            (86 + 16, "linear_velocity"),
            (110, "angular_velocity"),
        ] {
            for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                let mut b = good.clone();
                b[offset..offset + 8].copy_from_slice(&bad.to_le_bytes());
                assert_eq!(
                    Datagram::decode(&b),
                    Err(ProtocolError::NonFinite { field }),
                    "{field}"
                );
            }
        }
        let mut b = good.clone();
        b[54 + 24..54 + 32].copy_from_slice(&3.0f64.to_le_bytes());
        assert!(matches!(
            Datagram::decode(&b),
            Err(ProtocolError::NotUnitQuaternion { .. })
        ));
        let mut w = encoded(&wrench());
        w[30 + 40..30 + 48].copy_from_slice(&f64::NAN.to_le_bytes());
        assert_eq!(
            Datagram::decode(&w),
            Err(ProtocolError::NonFinite { field: "torque" })
        );
    }

    #[test]
    fn random_bytes_never_panic() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let template = encoded(&pose());
        for len in 0..=160usize {
            for round in 0..100 {
                let mut b = vec![0u8; len];
                rng.fill(&mut b[..]);
                if round % 2 == 0 {
                    // Keep a valid header prefix so the payload checks run too.
                    let k = len.min(HEADER_LEN);
                    b[..k].copy_from_slice(&template[..k]);
                }
                let _ = Datagram::decode(&b);
            }
        }
    }

    #[test]
    fn pose_with_flags_round_trips_and_reserved_bits_are_rejected() {
        let Message::PoseIn(sample) = pose().message else {
            unreachable!()
        };
        let d = Datagram {
            message: Message::PoseInFlags {
                sample,
                flags: FLAG_CLUTCH,
            },
            ..pose()
        };
        let bytes = encoded(&d);
        assert_eq!(bytes.len(), 138);
        assert_eq!(&bytes[..6], b"VPSB\x01\x03");
        assert_eq!(&bytes[134..], &[1, 0, 0, 0]);
        let back = Datagram::decode(&bytes).unwrap();
        let Message::PoseInFlags { sample: s, flags } = back.message else {
            panic!("{back:?}")
        };
        assert_eq!((flags, s.position), (FLAG_CLUTCH, sample.position));
        let mut b = bytes.clone();
        b[137] = 0x80;
        assert_eq!(
            Datagram::decode(&b),
            Err(ProtocolError::ReservedFlags { flags: 0x8000_0001 })
        );
        for n in [134, 137, 139] {
            let mut b = bytes.clone();
            b.resize(n, 0);
            assert!(matches!(
                Datagram::decode(&b),
                Err(ProtocolError::WrongLength {
                    kind: "PoseInFlags",
                    ..
                })
            ));
        }
    }

    #[test]
    fn token_comparison() {
        let a = [3u8; 16];
        let mut b = a;
        assert!(tokens_equal(&a, &b));
        b[15] ^= 1;
        assert!(!tokens_equal(&a, &b));
    }
}
