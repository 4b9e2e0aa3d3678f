//! Stanford PLY via ply-rs-bw, ASCII or binary. Polygons are fan-triangulated.

use glam::DVec3;
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use super::parse_error;
use crate::{MeshError, TriMesh};

/// Parses PLY bytes: element `vertex` with scalar `x`, `y`, `z` (any numeric type) and element
/// `face` with an integer list `vertex_indices` or `vertex_index`. Other elements and properties
/// are ignored.
pub(super) fn parse(bytes: &[u8], file: &str) -> Result<TriMesh, MeshError> {
    check_header_numbers(bytes, file)?;
    let mut reader = bytes;
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut reader)
        .map_err(|e| {
            // ply-rs-bw wraps the reader's end of file in its own message.
            let text = e.to_string();
            if e.kind() == std::io::ErrorKind::UnexpectedEof
                || text.contains("UnexpectedEof")
                || text.contains("failed to fill whole buffer")
            {
                return parse_error(
                    file,
                    None,
                    "the file ends before the elements its header declares (truncated?)",
                );
            }
            let (line, message) = split_line_prefix(&text);
            parse_error(file, line, message)
        })?;

    let vertex_elements = ply.payload.get("vertex").map(Vec::as_slice).unwrap_or(&[]);
    let mut vertices = Vec::with_capacity(vertex_elements.len());
    for (index, element) in vertex_elements.iter().enumerate() {
        let coord = |axis: &str| {
            element.get(axis).and_then(scalar_as_f64).ok_or_else(|| {
                parse_error(
                    file,
                    None,
                    format!("vertex {index} has no numeric scalar property '{axis}'"),
                )
            })
        };
        vertices.push(DVec3::new(coord("x")?, coord("y")?, coord("z")?));
    }

    let face_elements = ply.payload.get("face").map(Vec::as_slice).unwrap_or(&[]);
    let mut triangles = Vec::with_capacity(face_elements.len());
    for (index, element) in face_elements.iter().enumerate() {
        let face_error = |what: &str| parse_error(file, None, format!("face {index} {what}"));
        let polygon = element
            .get("vertex_indices")
            .or_else(|| element.get("vertex_index"))
            .and_then(list_as_indices)
            .ok_or_else(|| {
                face_error("has no integer list property 'vertex_indices' or 'vertex_index'")
            })?;
        let polygon = polygon
            .into_iter()
            .map(|i| {
                u32::try_from(i).map_err(|_| face_error(&format!("has invalid vertex index {i}")))
            })
            .collect::<Result<Vec<u32>, MeshError>>()?;
        if polygon.len() < 3 {
            return Err(face_error(&format!(
                "has {} vertices (need at least 3)",
                polygon.len()
            )));
        }
        triangles.extend((1..polygon.len() - 1).map(|k| [polygon[0], polygon[k], polygon[k + 1]]));
    }
    Ok(TriMesh::new(vertices, triangles))
}

/// Checks the numbers of the header's `format` and `element` lines before ply-rs-bw sees them: it
/// panics on a number that overflows u64, and an element count above the file's length in bytes
/// (every element takes at least one byte) cannot be honest. Errors name the line.
fn check_header_numbers(bytes: &[u8], file: &str) -> Result<(), MeshError> {
    for (index, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut tokens = line.split_ascii_whitespace();
        let keyword = tokens.next().unwrap_or("");
        if keyword == "end_header" {
            break;
        }
        if keyword != "format" && keyword != "element" {
            continue;
        }
        for run in line
            .split(|c: char| !c.is_ascii_digit())
            .filter(|r| !r.is_empty())
        {
            let fits = run
                .parse::<u64>()
                .is_ok_and(|n| keyword == "format" || n <= bytes.len() as u64);
            if !fits {
                return Err(parse_error(
                    file,
                    Some(index + 1),
                    format!(
                        "{keyword} number {run} is out of range (the file holds {} bytes)",
                        bytes.len()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// ply-rs-bw reports ASCII errors as `Line N: message\n\tString: 'text'\n\tError: details` with a
/// 1-based N; returns the line and a one-line message quoting the offending text.
fn split_line_prefix(text: &str) -> (Option<usize>, String) {
    let Some((line, rest)) = text
        .strip_prefix("Line ")
        .and_then(|rest| rest.split_once(": "))
        .and_then(|(n, rest)| Some((n.parse::<usize>().ok()?, rest)))
    else {
        return (None, text.replace("\n\t", "; ").replace('\n', "; "));
    };
    let (head, quoted) = rest.split_once("\n\tString: '").unwrap_or((rest, ""));
    let quoted = quoted.split("'\n\tError").next().unwrap_or("").trim_end();
    (Some(line), format!("{head} {quoted:?}"))
}

/// A numeric scalar property as f64.
fn scalar_as_f64(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => f64::from(v),
        Property::UChar(v) => f64::from(v),
        Property::Short(v) => f64::from(v),
        Property::UShort(v) => f64::from(v),
        Property::Int(v) => f64::from(v),
        Property::UInt(v) => f64::from(v),
        Property::Float(v) => f64::from(v),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// An integer list property as i64 indices.
fn list_as_indices(p: &Property) -> Option<Vec<i64>> {
    fn widen<T: Copy + Into<i64>>(v: &[T]) -> Vec<i64> {
        v.iter().map(|&x| x.into()).collect()
    }
    Some(match p {
        Property::ListChar(v) => widen(v),
        Property::ListUChar(v) => widen(v),
        Property::ListShort(v) => widen(v),
        Property::ListUShort(v) => widen(v),
        Property::ListInt(v) => widen(v),
        Property::ListUInt(v) => widen(v),
        _ => return None,
    })
}
