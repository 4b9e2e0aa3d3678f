//! Pure parser for 3Dconnexion SpaceMouse-family HID input reports.
//!
//! Two report layouts exist in the field:
//! - [`Layout::Split`] (older models, vendor 0x046d): report id 1 = translation (3 × i16 LE,
//!   7 bytes with the id), report id 2 = rotation (3 × i16 LE, 7 bytes), report id 3 = buttons.
//! - [`Layout::Combined`] (newer models, vendor 0x256f): report id 1 = translation then rotation
//!   (6 × i16 LE, 13 bytes with the id), report id 3 = buttons.
//!
//! [`Layout::Auto`] accepts both and decides an id-1 report by its length (7 → translation,
//! 13 → translation and rotation). Buttons (id 3) are 1 to 8 little-endian bitmask bytes after the
//! id (bit 0 = left button, bit 1 = right button). Raw axis values are device counts (about ±350 at
//! full deflection on most models); scaling happens in [`crate::spacemouse::rate_control`].
//!
//! Nothing here allocates, blocks or panics, whatever the input bytes.

/// Report id of a translation (split layout) or combined motion (combined layout) report.
pub const REPORT_ID_MOTION: u8 = 1;
/// Report id of a rotation report (split layout only).
pub const REPORT_ID_ROTATION: u8 = 2;
/// Report id of a button report (both layouts).
pub const REPORT_ID_BUTTONS: u8 = 3;
/// Length in bytes (id included) of a 3-axis report.
pub const LEN_THREE_AXES: usize = 7;
/// Length in bytes (id included) of a combined 6-axis report.
pub const LEN_SIX_AXES: usize = 13;
/// Largest number of bitmask bytes accepted in a button report (64 buttons).
pub const MAX_BUTTON_BYTES: usize = 8;

/// Which report layout a device sends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// Separate translation (id 1) and rotation (id 2) reports of 7 bytes each.
    Split,
    /// One 13-byte report (id 1) holding translation then rotation.
    Combined,
    /// Unknown device: an id-1 report is decided by its length (7 or 13 bytes); id 2 is accepted.
    Auto,
}

/// One decoded input report. Axis values are raw device counts (dimensionless).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Report {
    /// Translation counts `[x, y, z]` in the device's raw axes (split layout, id 1).
    Translation([i16; 3]),
    /// Rotation counts `[rx, ry, rz]` in the device's raw axes (split layout, id 2).
    Rotation([i16; 3]),
    /// Translation and rotation counts together (combined layout, id 1).
    Motion {
        /// `[x, y, z]` counts.
        translation: [i16; 3],
        /// `[rx, ry, rz]` counts.
        rotation: [i16; 3],
    },
    /// Button bitmask: bit `i` set while button `i` is pressed (bit 0 = left, bit 1 = right).
    Buttons(u64),
}

/// Why a report could not be decoded. Every variant names the report id (where there is one) and
/// the received length in bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum ReportError {
    /// Zero bytes were received.
    #[error("empty HID report")]
    Empty,
    /// Fewer bytes than the report id needs.
    #[error("report id {id}: {len} bytes is too short, expected {expected}")]
    Short {
        /// Report id (first byte).
        id: u8,
        /// Received length (bytes, id included).
        len: usize,
        /// Expected length (bytes, id included; the minimum for button reports).
        expected: usize,
    },
    /// More bytes than the report id allows.
    #[error("report id {id}: {len} bytes is oversized, expected at most {max}")]
    Oversized {
        /// Report id (first byte).
        id: u8,
        /// Received length (bytes, id included).
        len: usize,
        /// Largest accepted length (bytes, id included).
        max: usize,
    },
    /// A report id this parser does not know for the layout (e.g. battery or LED reports).
    #[error("unknown report id {id} ({len} bytes) for the {layout:?} layout")]
    UnknownId {
        /// Report id (first byte).
        id: u8,
        /// Received length (bytes, id included).
        len: usize,
        /// The layout the report was parsed with.
        layout: Layout,
    },
}

/// Decodes one HID input report (`bytes[0]` is the report id) with the given layout.
/// Does not allocate, block or panic.
pub fn parse_report(bytes: &[u8], layout: Layout) -> Result<Report, ReportError> {
    let (&id, body) = bytes.split_first().ok_or(ReportError::Empty)?;
    let len = bytes.len();
    match (id, layout) {
        (REPORT_ID_MOTION, Layout::Split) => {
            exact_len(id, len, LEN_THREE_AXES)?;
            Ok(Report::Translation(three_axes(body)))
        }
        (REPORT_ID_MOTION, Layout::Combined) => {
            exact_len(id, len, LEN_SIX_AXES)?;
            Ok(motion(body))
        }
        (REPORT_ID_MOTION, Layout::Auto) => match len {
            LEN_THREE_AXES => Ok(Report::Translation(three_axes(body))),
            LEN_SIX_AXES => Ok(motion(body)),
            l if l < LEN_THREE_AXES => Err(ReportError::Short {
                id,
                len,
                expected: LEN_THREE_AXES,
            }),
            l if l < LEN_SIX_AXES => Err(ReportError::Short {
                id,
                len,
                expected: LEN_SIX_AXES,
            }),
            _ => Err(ReportError::Oversized {
                id,
                len,
                max: LEN_SIX_AXES,
            }),
        },
        (REPORT_ID_ROTATION, Layout::Split | Layout::Auto) => {
            exact_len(id, len, LEN_THREE_AXES)?;
            Ok(Report::Rotation(three_axes(body)))
        }
        (REPORT_ID_BUTTONS, _) => buttons(id, body),
        _ => Err(ReportError::UnknownId { id, len, layout }),
    }
}

/// Checks `len == expected`, naming the id and length otherwise.
fn exact_len(id: u8, len: usize, expected: usize) -> Result<(), ReportError> {
    if len < expected {
        Err(ReportError::Short { id, len, expected })
    } else if len > expected {
        Err(ReportError::Oversized {
            id,
            len,
            max: expected,
        })
    } else {
        Ok(())
    }
}

/// The first three little-endian i16 of `body` (caller guarantees `body.len() >= 6`).
fn three_axes(body: &[u8]) -> [i16; 3] {
    let mut axes = [0i16; 3];
    for (axis, pair) in axes.iter_mut().zip(body.chunks_exact(2)) {
        *axis = i16::from_le_bytes([pair[0], pair[1]]);
    }
    axes
}

/// A combined motion report from a 12-byte body.
fn motion(body: &[u8]) -> Report {
    Report::Motion {
        translation: three_axes(body),
        rotation: three_axes(&body[6..]),
    }
}

/// A button bitmask from 1..=[`MAX_BUTTON_BYTES`] bytes.
fn buttons(id: u8, body: &[u8]) -> Result<Report, ReportError> {
    let len = body.len() + 1;
    if body.is_empty() {
        return Err(ReportError::Short {
            id,
            len,
            expected: 2,
        });
    }
    if body.len() > MAX_BUTTON_BYTES {
        return Err(ReportError::Oversized {
            id,
            len,
            max: MAX_BUTTON_BYTES + 1,
        });
    }
    let mask = body
        .iter()
        .enumerate()
        .fold(0u64, |m, (i, &b)| m | (u64::from(b) << (8 * i)));
    Ok(Report::Buttons(mask))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn le(v: &[i16]) -> Vec<u8> {
        v.iter().flat_map(|x| x.to_le_bytes()).collect()
    }

    #[test]
    fn split_translation_and_rotation() {
        let mut t = vec![1u8];
        t.extend(le(&[100, -200, 350]));
        assert_eq!(
            parse_report(&t, Layout::Split),
            Ok(Report::Translation([100, -200, 350]))
        );
        let mut r = vec![2u8];
        r.extend(le(&[-1, i16::MIN, i16::MAX]));
        assert_eq!(
            parse_report(&r, Layout::Split),
            Ok(Report::Rotation([-1, i16::MIN, i16::MAX]))
        );
    }

    #[test]
    fn combined_motion() {
        let mut m = vec![1u8];
        m.extend(le(&[1, 2, 3, -4, -5, -6]));
        let want = Report::Motion {
            translation: [1, 2, 3],
            rotation: [-4, -5, -6],
        };
        assert_eq!(parse_report(&m, Layout::Combined), Ok(want));
        assert_eq!(parse_report(&m, Layout::Auto), Ok(want));
        assert_eq!(
            parse_report(&m, Layout::Split),
            Err(ReportError::Oversized {
                id: 1,
                len: 13,
                max: 7
            })
        );
    }

    #[test]
    fn auto_decides_by_length() {
        let mut t = vec![1u8];
        t.extend(le(&[7, 8, 9]));
        assert_eq!(
            parse_report(&t, Layout::Auto),
            Ok(Report::Translation([7, 8, 9]))
        );
        assert_eq!(
            parse_report(&t, Layout::Combined),
            Err(ReportError::Short {
                id: 1,
                len: 7,
                expected: 13
            })
        );
        assert_eq!(
            parse_report(&[1, 0, 0, 0, 0, 0, 0, 0, 0], Layout::Auto),
            Err(ReportError::Short {
                id: 1,
                len: 9,
                expected: 13
            })
        );
    }

    #[test]
    fn buttons_bitmask() {
        assert_eq!(
            parse_report(&[3, 0b01, 0], Layout::Split),
            Ok(Report::Buttons(1))
        );
        assert_eq!(
            parse_report(&[3, 0b10, 0x80, 0, 0], Layout::Combined),
            Ok(Report::Buttons(2 | (0x80 << 8)))
        );
        assert_eq!(
            parse_report(&[3], Layout::Split),
            Err(ReportError::Short {
                id: 3,
                len: 1,
                expected: 2
            })
        );
        assert_eq!(
            parse_report(&[3; 10], Layout::Split),
            Err(ReportError::Oversized {
                id: 3,
                len: 10,
                max: 9
            })
        );
    }

    #[test]
    fn errors_name_id_and_length() {
        assert_eq!(parse_report(&[], Layout::Auto), Err(ReportError::Empty));
        let e = parse_report(&[0x17, 1, 2], Layout::Combined).unwrap_err();
        assert_eq!(
            e,
            ReportError::UnknownId {
                id: 0x17,
                len: 3,
                layout: Layout::Combined
            }
        );
        let msg = e.to_string();
        assert!(msg.contains("23") && msg.contains("3 bytes"), "{msg}");
        // Rotation reports do not exist in the combined layout.
        assert!(matches!(
            parse_report(&[2, 0, 0, 0, 0, 0, 0], Layout::Combined),
            Err(ReportError::UnknownId { id: 2, .. })
        ));
        let short = parse_report(&[2, 0, 0], Layout::Split).unwrap_err();
        assert_eq!(
            short,
            ReportError::Short {
                id: 2,
                len: 3,
                expected: 7
            }
        );
        assert!(short.to_string().contains("report id 2: 3 bytes"));
    }

    #[test]
    fn random_bytes_of_every_length_never_panic() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x5eed);
        let mut ok = 0usize;
        for len in 0..64usize {
            for round in 0..200 {
                let mut buf = vec![0u8; len];
                rng.fill(&mut buf[..]);
                if len > 0 && round % 2 == 0 {
                    // Bias half the rounds towards the known ids so the valid paths run too.
                    buf[0] = rng.gen_range(0..=4);
                }
                for layout in [Layout::Split, Layout::Combined, Layout::Auto] {
                    match parse_report(&buf, layout) {
                        Ok(_) => ok += 1,
                        Err(ReportError::Empty) => assert_eq!(len, 0),
                        Err(
                            ReportError::Short { len: l, .. }
                            | ReportError::Oversized { len: l, .. }
                            | ReportError::UnknownId { len: l, .. },
                        ) => assert_eq!(l, len),
                    }
                }
            }
        }
        assert!(ok > 0, "no random report decoded at all");
    }
}
