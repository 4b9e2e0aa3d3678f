//! Lengths written as plain metres (`0.005`) or with a unit suffix (`5mm`, `0.5cm`, `500um`), on the
//! command line and in scene files.

use serde::{Deserialize, Deserializer};

/// Parses a length in metres. Accepts a bare number (metres) or a number followed by `m`, `cm`, `mm`
/// or `um`. The result is finite and strictly positive, or an error saying what was wrong.
pub fn parse_length(text: &str) -> Result<f64, String> {
    let units = [("mm", 1e-3), ("cm", 1e-2), ("um", 1e-6), ("m", 1.0)];
    let metres = vps_units::scaled_number(text, &units)
        .ok_or_else(|| format!("'{text}' is not a length (examples: 0.005, 5mm, 0.5cm)"))?;
    if !metres.is_finite() || metres <= 0.0 {
        return Err(format!("'{text}' must be a positive, finite length"));
    }
    Ok(metres)
}

/// `metres` as millimetres rounded up to two significant digits, with the unit (`0.0001234` →
/// `"0.13 mm"`, `0.0234` → `"24 mm"`): a size to suggest that is never finer than `metres`.
pub fn millimetres_rounded_up(metres: f64) -> String {
    let mm = metres * 1e3;
    let unit = 10f64.powi(mm.log10().floor() as i32 - 1);
    let rounded = (mm / unit).ceil() * unit;
    let decimals = (-(unit.log10().round() as i32)).max(0) as usize;
    format!("{rounded:.decimals$} mm")
}

/// Parses a length written as a string in a file (`"5mm"`): as [`parse_length`], but a string
/// without a unit (`"5"`) is refused: a file writes metres as a bare number, and a unit-less
/// string is more likely a forgotten `mm`.
pub fn parse_length_string(text: &str) -> Result<f64, String> {
    if text.trim().parse::<f64>().is_ok() {
        return Err(format!(
            "\"{text}\" has no unit: write one (\"{text}mm\", \"{text}cm\", \"{text}m\"), or a bare \
             number of metres ({text})"
        ));
    }
    parse_length(text)
}

/// Deserializes a length (m) written as a number (metres) or as a string with a unit (`"2mm"`,
/// [`parse_length_string`]). The range of a number is checked by the caller (a negative number is reported
/// with its field there).
pub(crate) fn length<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Written {
        Number(f64),
        Integer(i64),
        Text(String),
    }
    match Written::deserialize(d).map_err(|_| {
        serde::de::Error::custom(
            "expected a length: a number of metres or a string such as \"2mm\"",
        )
    })? {
        Written::Number(v) => Ok(v),
        Written::Integer(v) => Ok(v as f64),
        Written::Text(t) => parse_length_string(&t).map_err(serde::de::Error::custom),
    }
}

#[cfg(test)]
mod tests {
    use super::{millimetres_rounded_up, parse_length};

    #[test]
    fn accepts_units() {
        assert_eq!(parse_length("0.005").unwrap(), 0.005);
        assert!((parse_length("5mm").unwrap() - 0.005).abs() < 1e-15);
        assert!((parse_length("0.5cm").unwrap() - 0.005).abs() < 1e-15);
        assert!((parse_length("500um").unwrap() - 0.0005).abs() < 1e-15);
        assert_eq!(parse_length("2m").unwrap(), 2.0);
    }

    #[test]
    fn rejects_nonsense() {
        for bad in ["", "mm", "abc", "-5mm", "0", "inf", "NaN", "5 parsecs"] {
            assert!(parse_length(bad).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn suggested_sizes_round_up_to_two_digits() {
        assert_eq!(millimetres_rounded_up(0.0001234), "0.13 mm");
        assert_eq!(millimetres_rounded_up(0.0234), "24 mm");
        assert_eq!(millimetres_rounded_up(0.002), "2.0 mm");
        assert_eq!(millimetres_rounded_up(1.5), "1500 mm");
    }
}
