//! The ISO 10303-21 exchange structure, split into entity instances before any is parsed.
//!
//! The grammar crate (`ruststep`) parses a whole file as one recursive descent and gives up on the
//! whole file at the first construct it does not know (an empty list `()`, common in AP242 files);
//! it also recurses once per nesting level, so a hostile file of nested parentheses would overflow
//! the stack. This module therefore scans the bytes itself, in one pass with no recursion: it finds
//! the DATA sections, cuts them into `#id = ... ;` instances (strings and comments respected),
//! checks each instance's nesting depth against [`MAX_DEPTH`], and hands the grammar one instance at
//! a time ([`parse_instances`]). An instance the grammar refuses is counted and left out; if a solid
//! needs it, converting that solid fails and says so.

use std::collections::HashMap;
use std::str::FromStr;

use ruststep::ast::EntityInstance;

use crate::StepError;

/// The deepest parenthesis nesting accepted inside one entity instance. Real files nest about 5
/// deep (a B-spline surface's control points: record, list of rows, row, point); a deeper
/// instance is refused before the grammar sees it.
pub const MAX_DEPTH: usize = 32;

/// One `#id = ... ;` instance of a DATA section, as written.
#[derive(Debug)]
pub struct RawInstance<'a> {
    /// The instance's number (`#id`).
    pub id: u64,
    /// 1-based line of the `#` in the file.
    pub line: usize,
    /// The instance's text, from `#` to the closing `;` inclusive.
    pub text: &'a str,
}

/// The entity instances of a file, parsed one by one.
pub struct Instances {
    /// Every instance the grammar accepted, by id.
    pub by_id: HashMap<u64, EntityInstance>,
    /// The line of each accepted instance, by id.
    pub line_of: HashMap<u64, usize>,
    /// Instances the grammar refused (id, line), in file order.
    pub refused: Vec<(u64, usize)>,
}

/// Splits `text` (a whole STEP file) into its DATA sections' instances.
///
/// Fails when the file does not start with `ISO-10303-21;`, has no DATA section, or holds a
/// malformed instance (no `#id =`, an unterminated string or comment, unbalanced parentheses,
/// nesting deeper than [`MAX_DEPTH`], a repeated id), each error naming the line.
pub fn split_instances(text: &str) -> Result<Vec<RawInstance<'_>>, StepError> {
    let body = text.trim_start_matches('\u{feff}').trim_start();
    if !body.starts_with("ISO-10303-21") {
        return Err(StepError::format(
            Some(1),
            "not a STEP file: it does not start with ISO-10303-21;",
        ));
    }
    let bytes = text.as_bytes();
    let mut instances = Vec::new();
    let mut seen = HashMap::new();
    let mut line = 1usize;
    let mut i = 0usize;
    let mut in_data = false;
    let mut any_data = false;
    while i < bytes.len() {
        let b = bytes[i];
        match b {
            b'\n' => {
                line += 1;
                i += 1;
            }
            b'/' if bytes.get(i + 1) == Some(&b'*') => {
                i = skip_comment(bytes, i, &mut line)?;
            }
            b'\'' => {
                i = skip_string(bytes, i, &mut line)?;
            }
            b'#' if in_data => {
                let start = i;
                let start_line = line;
                let end = instance_end(bytes, i, &mut line)?;
                let text = &text[start..end];
                let id = instance_id(text).ok_or_else(|| {
                    StepError::format(
                        Some(start_line),
                        "an entity instance that does not start with #NUMBER =",
                    )
                })?;
                if let Some(first) = seen.insert(id, start_line) {
                    return Err(StepError::format(
                        Some(start_line),
                        format!("entity #{id} is defined twice (first on line {first})"),
                    ));
                }
                instances.push(RawInstance {
                    id,
                    line: start_line,
                    text,
                });
                i = end;
            }
            _ if keyword_at(bytes, i, b"DATA") && !in_data => {
                // `DATA;` or `DATA(...)`: skip to the `;`.
                in_data = true;
                any_data = true;
                i = instance_end(bytes, i, &mut line)?;
            }
            _ if keyword_at(bytes, i, b"ENDSEC") => {
                in_data = false;
                i += b"ENDSEC".len();
            }
            _ => i += 1,
        }
    }
    if !any_data {
        return Err(StepError::format(None, "the file has no DATA section"));
    }
    Ok(instances)
}

/// Parses each instance with the STEP grammar. An instance the grammar refuses is recorded in
/// [`Instances::refused`], not an error: files carry entities (PMI, presentation) the geometry
/// never needs.
pub fn parse_instances(raw: &[RawInstance<'_>]) -> Instances {
    let mut by_id = HashMap::with_capacity(raw.len());
    let mut line_of = HashMap::with_capacity(raw.len());
    let mut refused = Vec::new();
    for r in raw {
        if has_overlong_integer(r.text) || has_knots_beyond_its_points(r.text) {
            // The grammar panics on an integer beyond i64 (instead of refusing it); the geometry
            // kernel allocates a B-spline's knots as its multiplicities say, whatever they are.
            refused.push((r.id, r.line));
            continue;
        }
        let text = for_the_grammar(r.text);
        match EntityInstance::from_str(&text) {
            Ok(instance) => {
                by_id.insert(r.id, instance);
                line_of.insert(r.id, r.line);
            }
            Err(_) => refused.push((r.id, r.line)),
        }
    }
    Instances {
        by_id,
        line_of,
        refused,
    }
}

/// `text` rewritten around two gaps in the grammar crate, which refuses legal ISO 10303-21:
/// every empty list parameter `()` is written `($)` (a record's own empty argument list, such as
/// `LENGTH_UNIT()`, follows a keyword and is kept), and a quote escaped inside a string (`''`) is
/// written `"` (names are only displayed).
fn for_the_grammar(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.contains("()") && !text.contains("''") {
        return std::borrow::Cow::Borrowed(text);
    }
    let bytes = text.as_bytes();
    let mut out = String::with_capacity(text.len() + 8);
    let mut i = 0;
    let mut last_significant = b'=';
    while i < bytes.len() {
        let b = bytes[i];
        if b == b'\'' {
            // Copy a string through unchanged.
            let mut line = 0;
            let end = skip_string(bytes, i, &mut line).unwrap_or(bytes.len());
            let inner = &text[i + 1..end.saturating_sub(1).max(i + 1)];
            out.push('\'');
            out.push_str(&inner.replace("''", "\""));
            out.push('\'');
            last_significant = b'\'';
            i = end;
            continue;
        }
        if b == b'(' && matches!(last_significant, b',' | b'(') {
            let mut j = i + 1;
            while j < bytes.len() && bytes[j].is_ascii_whitespace() {
                j += 1;
            }
            if bytes.get(j) == Some(&b')') {
                out.push_str("($)");
                last_significant = b')';
                i = j + 1;
                continue;
            }
        }
        out.push(b as char);
        if !b.is_ascii_whitespace() {
            last_significant = b;
        }
        i += 1;
    }
    std::borrow::Cow::Owned(out)
}

/// Whether `text` is a B-spline record (`B_SPLINE_CURVE_WITH_KNOTS`,
/// `B_SPLINE_SURFACE_WITH_KNOTS`, alone or in a complex instance) with a negative plain integer,
/// or whose plain integers (degrees and knot multiplicities: every integer outside strings that is
/// not an `#id` or part of a real) add up to more than twice its `#` references plus 64. A valid record's multiplicities add up to its
/// control points plus degree plus 1 per direction (ISO 10303-42), so this holds for none; a
/// mutated multiplicity of 10⁹ made the geometry kernel (truck-geometry 0.5's
/// `KnotVec::from_single_multi`) ask for gigabytes (found by fuzzing).
fn has_knots_beyond_its_points(text: &str) -> bool {
    if !text.contains("_WITH_KNOTS") {
        return false;
    }
    let bytes = text.as_bytes();
    let (mut references, mut integers) = (0u64, 0u64);
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'\'' => {
                let mut line = 0;
                i = skip_string(bytes, i, &mut line).unwrap_or(bytes.len());
            }
            b'#' => {
                references += 1;
                i += 1;
                while i < bytes.len() && bytes[i].is_ascii_digit() {
                    i += 1;
                }
            }
            b'0'..=b'9' => {
                let start = i;
                while i < bytes.len() && bytes[i].is_ascii_alphanumeric() {
                    i += 1;
                }
                let before = |k: usize| start.checked_sub(k).map(|j| bytes[j]);
                let after_point = before(1) == Some(b'.');
                let signed = matches!(before(1), Some(b'-' | b'+'));
                let exponent = signed && matches!(before(2), Some(b'E' | b'e'));
                let real = after_point || exponent || bytes.get(i) == Some(&b'.');
                if !real && before(1) == Some(b'-') {
                    // A negative degree or multiplicity: the kernel reads it as a huge count.
                    return true;
                }
                let in_name = start > 0
                    && (bytes[start - 1].is_ascii_alphabetic() || bytes[start - 1] == b'_');
                if !real && !in_name {
                    // Overlong integers are refused on their own; saturate here.
                    let value = text[start..i].parse::<u64>().unwrap_or(u64::MAX);
                    integers = integers.saturating_add(value);
                }
            }
            _ => i += 1,
        }
    }
    integers > references.saturating_mul(2).saturating_add(64)
}

/// Whether `text` holds, outside strings, a run of more than 18 digits not after a decimal
/// point: an integer (an id, a count, an exponent) that may not fit an `i64`.
fn has_overlong_integer(text: &str) -> bool {
    let bytes = text.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'\'' {
            let mut line = 0;
            i = skip_string(bytes, i, &mut line).unwrap_or(bytes.len());
            continue;
        }
        if bytes[i].is_ascii_digit() {
            let start = i;
            while i < bytes.len() && bytes[i].is_ascii_digit() {
                i += 1;
            }
            if i - start > 18 && (start == 0 || bytes[start - 1] != b'.') {
                return true;
            }
            continue;
        }
        i += 1;
    }
    false
}

/// Whether `keyword` starts at `i` as a whole word followed by `;` or `(` (after spaces).
fn keyword_at(bytes: &[u8], i: usize, keyword: &[u8]) -> bool {
    if !bytes[i..].starts_with(keyword) {
        return false;
    }
    if i > 0 && (bytes[i - 1].is_ascii_alphanumeric() || bytes[i - 1] == b'_') {
        return false;
    }
    let mut j = i + keyword.len();
    while j < bytes.len() && bytes[j].is_ascii_whitespace() {
        j += 1;
    }
    matches!(bytes.get(j), Some(b';') | Some(b'('))
}

/// The index just past the `;` that ends the instance starting at `start` (depth 0, outside
/// strings and comments), counting lines.
fn instance_end(bytes: &[u8], start: usize, line: &mut usize) -> Result<usize, StepError> {
    let first_line = *line;
    let mut depth = 0usize;
    let mut i = start;
    while i < bytes.len() {
        match bytes[i] {
            b'\n' => {
                *line += 1;
                i += 1;
            }
            b'\'' => i = skip_string(bytes, i, line)?,
            b'/' if bytes.get(i + 1) == Some(&b'*') => i = skip_comment(bytes, i, line)?,
            b'(' => {
                depth += 1;
                if depth > MAX_DEPTH {
                    return Err(StepError::format(
                        Some(first_line),
                        format!("the instance nests parentheses deeper than {MAX_DEPTH}"),
                    ));
                }
                i += 1;
            }
            b')' => {
                depth = depth
                    .checked_sub(1)
                    .ok_or_else(|| StepError::format(Some(*line), "a ')' with no '(' before it"))?;
                i += 1;
            }
            b';' if depth == 0 => return Ok(i + 1),
            _ => i += 1,
        }
    }
    Err(StepError::format(
        Some(first_line),
        "an entity instance with no closing ';' before the end of the file",
    ))
}

/// The index just past the string starting at `start` (`'...'`, `''` inside is a quote).
fn skip_string(bytes: &[u8], start: usize, line: &mut usize) -> Result<usize, StepError> {
    let first_line = *line;
    let mut i = start + 1;
    while i < bytes.len() {
        match bytes[i] {
            b'\'' if bytes.get(i + 1) == Some(&b'\'') => i += 2,
            b'\'' => return Ok(i + 1),
            b'\n' => {
                *line += 1;
                i += 1;
            }
            _ => i += 1,
        }
    }
    Err(StepError::format(
        Some(first_line),
        "a string ('...') with no closing quote before the end of the file",
    ))
}

/// The index just past the comment starting at `start` (`/* ... */`).
fn skip_comment(bytes: &[u8], start: usize, line: &mut usize) -> Result<usize, StepError> {
    let first_line = *line;
    let mut i = start + 2;
    while i + 1 < bytes.len() {
        if bytes[i] == b'*' && bytes[i + 1] == b'/' {
            return Ok(i + 2);
        }
        if bytes[i] == b'\n' {
            *line += 1;
        }
        i += 1;
    }
    Err(StepError::format(
        Some(first_line),
        "a comment (/* ... */) with no end before the end of the file",
    ))
}

/// The number of `#NUMBER =` at the start of `text`.
fn instance_id(text: &str) -> Option<u64> {
    let rest = text.strip_prefix('#')?;
    let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
    let id = rest[..digits].parse().ok()?;
    rest[digits..].trim_start().starts_with('=').then_some(id)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_b_spline_whose_multiplicities_pass_its_points_is_refused() {
        let valid = "#40=B_SPLINE_CURVE_WITH_KNOTS('',3,(#41,#42,#43,#44),.UNSPECIFIED.,.F.,.F.,(4,4),(0.,1.),.UNSPECIFIED.)";
        assert!(!has_knots_beyond_its_points(valid));
        let surface = "#50=B_SPLINE_SURFACE_WITH_KNOTS('',1,1,((#51,#52),(#53,#54)),.UNSPECIFIED.,.F.,.F.,.F.,(2,2),(2,2),(0.,1.),(0.,1.),.UNSPECIFIED.)";
        assert!(!has_knots_beyond_its_points(surface));
        let rational = "#60=(BOUNDED_CURVE()B_SPLINE_CURVE(2,(#61,#62,#63),.UNSPECIFIED.,.F.,.F.)B_SPLINE_CURVE_WITH_KNOTS((3,3),(0.,1.),.UNSPECIFIED.)CURVE()GEOMETRIC_REPRESENTATION_ITEM()RATIONAL_B_SPLINE_CURVE((1.,0.7071,1.E+00))REPRESENTATION_ITEM(''))";
        assert!(!has_knots_beyond_its_points(rational));
        let mutated = valid.replace("(4,4)", "(4,1000000000)");
        assert!(has_knots_beyond_its_points(&mutated));
        // A negative multiplicity (input 451,411 of seed 2: `(4,1,1,-14)`).
        assert!(has_knots_beyond_its_points(
            &valid.replace("(4,4)", "(4,-4)")
        ));
        // Exponents are parts of reals, however many.
        let knots: Vec<String> = (0..200).map(|k| format!("{k}.E+02")).collect();
        let long = format!(
            "#70=B_SPLINE_CURVE_WITH_KNOTS('',1,(#71,#72),.UNSPECIFIED.,.F.,.F.,(2,2),({}),.UNSPECIFIED.)",
            knots.join(",")
        );
        assert!(!has_knots_beyond_its_points(&long));
        assert!(!has_knots_beyond_its_points(&long.replace("E+02", "E-02")));
        // Other records are not looked at.
        assert!(!has_knots_beyond_its_points(
            "#1=CARTESIAN_POINT('',(1000000.,2.,3.))"
        ));
    }

    const HEADER: &str = "ISO-10303-21;\nHEADER;\nFILE_SCHEMA(('X'));\nENDSEC;\n";

    #[test]
    fn instances_are_cut_at_semicolons_outside_strings_and_comments() {
        let text = format!(
            "{HEADER}DATA;\n#1=A('x;y',(1.,2.));\n/* #9=B(); */\n#2 = ( B() C('it''s') );\nENDSEC;\nEND-ISO-10303-21;\n"
        );
        let raw = split_instances(&text).unwrap();
        assert_eq!(raw.len(), 2);
        assert_eq!((raw[0].id, raw[0].line), (1, 6));
        assert_eq!(raw[0].text, "#1=A('x;y',(1.,2.));");
        assert_eq!((raw[1].id, raw[1].line), (2, 8));
        let parsed = parse_instances(&raw);
        assert_eq!(parsed.by_id.len(), 2, "refused {:?}", parsed.refused);
    }

    #[test]
    fn hostile_structure_is_refused_with_its_line() {
        let deep = format!(
            "{HEADER}DATA;\n#1=A{}{};\nENDSEC;\n",
            "(".repeat(40),
            ")".repeat(40)
        );
        let e = split_instances(&deep).unwrap_err().to_string();
        assert!(e.contains("line 6") && e.contains("deeper than 32"), "{e}");
        let open = format!("{HEADER}DATA;\n#1=A('never closed);\nENDSEC;\n");
        let e = split_instances(&open).unwrap_err().to_string();
        assert!(e.contains("line 6") && e.contains("closing quote"), "{e}");
        let twice = format!("{HEADER}DATA;\n#1=A();\n#1=B();\nENDSEC;\n");
        let e = split_instances(&twice).unwrap_err().to_string();
        assert!(e.contains("line 7") && e.contains("defined twice"), "{e}");
        let e = split_instances("solid x\nendsolid")
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a STEP file"), "{e}");
        let e = split_instances(&format!("{HEADER}END-ISO-10303-21;")).unwrap_err();
        assert!(e.to_string().contains("no DATA section"), "{e}");
    }

    #[test]
    fn integers_beyond_i64_are_refused_before_the_grammar() {
        let text = format!(
            "{HEADER}DATA;\n#1=A(99999999999999999999);\n#2=B(#99999999999999999999);\n#3=C(1.E99999999999999999999);\n#4=D(0.33333333333333333333333,'12345678901234567890');\nENDSEC;\n"
        );
        let parsed = parse_instances(&split_instances(&text).unwrap());
        assert_eq!(parsed.refused, [(1, 6), (2, 7), (3, 8)]);
        assert!(parsed.by_id.contains_key(&4));
    }

    #[test]
    fn empty_lists_and_escaped_quotes_are_read() {
        let text =
            format!("{HEADER}DATA;\n#1=A('note',(),(1,2));\n#2=(B() C('it''s'));\nENDSEC;\n");
        let parsed = parse_instances(&split_instances(&text).unwrap());
        assert!(parsed.refused.is_empty(), "{:?}", parsed.refused);
        assert_eq!(
            for_the_grammar("#1=A('()',( ),X(),'it''s','')"),
            "#1=A('()',($),X(),'it\"s','')"
        );
    }
}
