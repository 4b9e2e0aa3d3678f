//! Parsing of lengths given on the command line: plain metres (`0.005`) or with a unit suffix
//! (`5mm`, `0.5cm`, `0.005m`, `500um`).

/// Parses a length in metres. Accepts a bare number (metres) or a number followed by `m`, `cm`, `mm`
/// or `um`. The result is finite and strictly positive, or an error saying what was wrong.
pub fn parse_length(text: &str) -> Result<f64, String> {
    let t = text.trim();
    let (number, scale) = [("mm", 1e-3), ("cm", 1e-2), ("um", 1e-6), ("m", 1.0)]
        .iter()
        .find_map(|(suffix, scale)| t.strip_suffix(suffix).map(|n| (n.trim(), *scale)))
        .unwrap_or((t, 1.0));
    let value: f64 = number
        .parse()
        .map_err(|_| format!("'{text}' is not a length (examples: 0.005, 5mm, 0.5cm)"))?;
    let metres = value * scale;
    if !metres.is_finite() || metres <= 0.0 {
        return Err(format!("'{text}' must be a positive, finite length"));
    }
    Ok(metres)
}

#[cfg(test)]
mod tests {
    use super::parse_length;

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
}
