//! STL via stl_io, binary or ASCII. Vertices are welded by exact position (stl_io does this).

use std::io::Cursor;

use super::parse_error;
use crate::{MeshError, TriMesh};
use glam::DVec3;

/// Bytes in a binary STL header (80-byte comment + u32 triangle count).
const BINARY_HEADER_LEN: usize = 84;
/// Bytes per binary STL triangle record.
const BINARY_RECORD_LEN: usize = 50;

/// Parses STL bytes, binary or ASCII.
///
/// stl_io decides "ASCII" when the file starts with `solid `, which many binary exporters also
/// write into the 80-byte comment. A file whose length is exactly `84 + 50 * count` (count read from
/// the header) is binary whatever its comment says, so its comment is blanked before parsing.
pub(super) fn parse(bytes: &[u8], file: &str) -> Result<TriMesh, MeshError> {
    let mut data = bytes.to_vec();
    if is_binary_by_length(&data) && data.starts_with(b"solid") {
        data[..5].copy_from_slice(b"     ");
    }
    let looks_ascii = data.starts_with(b"solid ");
    if !looks_ascii && data.len() < BINARY_HEADER_LEN {
        return Err(parse_error(
            file,
            None,
            format!(
                "{} bytes: shorter than a binary STL's {BINARY_HEADER_LEN}-byte header (80-byte \
                 comment, then the triangle count), and not ASCII STL (which starts with `solid `)",
                data.len()
            ),
        ));
    }
    if !looks_ascii && data.len() >= BINARY_HEADER_LEN && !is_binary_by_length(&data) {
        let declared = binary_triangle_count(&data);
        return Err(parse_error(
            file,
            None,
            format!(
                "binary STL declares {declared} triangles ({} bytes expected) but the file has {} bytes",
                BINARY_HEADER_LEN as u64 + BINARY_RECORD_LEN as u64 * declared as u64,
                data.len()
            ),
        ));
    }
    let indexed = stl_io::read_stl(&mut Cursor::new(&data)).map_err(|e| {
        let kind = if looks_ascii { "ASCII" } else { "binary" };
        // stl_io names no line; for ASCII, the first `vertex` or `facet normal` line whose
        // numbers do not read as three finite f32 is the likely culprit.
        let line = looks_ascii.then(|| first_bad_number_line(&data)).flatten();
        parse_error(file, line, format!("{kind} STL: {e}"))
    })?;
    let vertices = indexed
        .vertices
        .iter()
        .map(|v| DVec3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2])))
        .collect();
    let triangles = indexed
        .faces
        .iter()
        .map(|f| f.vertices.map(|i| i as u32))
        .collect();
    Ok(TriMesh::new(vertices, triangles))
}

/// The 1-based line of the first `vertex x y z` or `facet normal x y z` line of an ASCII STL whose
/// three numbers are not all finite f32 (or are not three), if any.
fn first_bad_number_line(data: &[u8]) -> Option<usize> {
    let text = String::from_utf8_lossy(data);
    text.lines().enumerate().find_map(|(index, line)| {
        let words: Vec<&str> = line.split_whitespace().collect();
        let numbers = match words.as_slice() {
            ["vertex", numbers @ ..] => numbers,
            ["facet", "normal", numbers @ ..] => numbers,
            _ => return None,
        };
        let finite = |w: &&str| w.parse::<f32>().is_ok_and(f32::is_finite);
        (numbers.len() != 3 || !numbers.iter().all(finite)).then_some(index + 1)
    })
}

/// The triangle count in a binary STL header; the caller checks the length.
fn binary_triangle_count(data: &[u8]) -> u32 {
    u32::from_le_bytes([data[80], data[81], data[82], data[83]])
}

/// True when the byte length matches the triangle count a binary header declares.
fn is_binary_by_length(data: &[u8]) -> bool {
    data.len() >= BINARY_HEADER_LEN
        && (data.len() - BINARY_HEADER_LEN) as u64
            == BINARY_RECORD_LEN as u64 * u64::from(binary_triangle_count(data))
}
