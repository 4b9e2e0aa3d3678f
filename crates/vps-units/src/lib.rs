//! Numbers written with a unit suffix: `0.005`, `5mm`, `1.5 ms`, `16GiB`. Each caller names its
//! own units and scales (lengths in m, durations in s, sizes in bytes), checks the range of the
//! result and words its own error; this crate only splits the suffix off and scales the number.
//!
//! Where this crate sits in vps: `docs/architecture.md#crates` at the repository root.

#![warn(missing_docs)]

/// `text` (trimmed) as a number times the scale of its unit suffix: the first `(suffix, scale)`
/// of `units` that `text` ends with is stripped (white space between the number and the unit is
/// allowed) and the rest parsed as an `f64`; with no listed suffix the whole text is the number,
/// at scale 1. List a suffix before any suffix it ends with (`mm` before `m`). Matching is exact
/// (case-sensitive): lower-case the text first for case-insensitive units. `None` when the number
/// does not parse. The result may be negative, zero or non-finite: the caller checks its range.
pub fn scaled_number(text: &str, units: &[(&str, f64)]) -> Option<f64> {
    let t = text.trim();
    let (number, scale) = units
        .iter()
        .find_map(|(suffix, scale)| t.strip_suffix(suffix).map(|n| (n.trim(), *scale)))
        .unwrap_or((t, 1.0));
    number.parse::<f64>().ok().map(|value| value * scale)
}

#[cfg(test)]
mod tests {
    use super::scaled_number;

    const LENGTHS: [(&str, f64); 3] = [("mm", 1e-3), ("cm", 1e-2), ("m", 1.0)];

    #[test]
    fn the_first_matching_suffix_scales_the_number() {
        assert_eq!(scaled_number("5mm", &LENGTHS), Some(5.0 * 1e-3));
        assert_eq!(scaled_number(" 0.5 cm ", &LENGTHS), Some(0.5 * 1e-2));
        assert_eq!(scaled_number("2m", &LENGTHS), Some(2.0));
        assert_eq!(scaled_number("0.25", &LENGTHS), Some(0.25));
        assert_eq!(scaled_number("-3mm", &LENGTHS), Some(-3.0 * 1e-3));
    }

    #[test]
    fn text_without_a_number_is_none() {
        for bad in ["", "mm", "5 parsecs", "5MM", "1.2.3m", "m5"] {
            assert_eq!(scaled_number(bad, &LENGTHS), None, "{bad}");
        }
    }
}
