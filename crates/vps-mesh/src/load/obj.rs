//! Wavefront OBJ via tobj: all objects merged into one mesh, polygons fan-triangulated.

use std::io::{BufRead, Read};

use tobj::LoadError;

use super::{parse_error, points_from_f32};
use crate::{MeshError, TriMesh};

/// Checks the indices of face, line and point statements before tobj sees them, as tobj's index
/// arithmetic overflows on them: a positive index must not exceed the file's length in bytes (it
/// could not name a vertex of the file), and a negative (relative) one must not reach before the
/// first `v`, `vt` or `vn` read so far. Errors name the line.
fn check_element_indices(bytes: &[u8], file: &str) -> Result<(), MeshError> {
    // Positions, texture coordinates and normals read so far.
    let mut seen = [0u64; 3];
    for (index, line) in bytes.split(|&b| b == b'\n').enumerate() {
        let line = String::from_utf8_lossy(line);
        let mut tokens = line.split_ascii_whitespace();
        match tokens.next() {
            Some("v") => seen[0] += 1,
            Some("vt") => seen[1] += 1,
            Some("vn") => seen[2] += 1,
            Some("f" | "l" | "p") => {
                for token in tokens {
                    for (kind, reference) in token.split('/').enumerate().take(3) {
                        let Ok(value) = reference.parse::<i64>() else {
                            continue; // Empty or not a number: tobj handles it.
                        };
                        if value == 0 {
                            return Err(parse_error(
                                file,
                                Some(index + 1),
                                "index 0: OBJ indices start at 1 (a negative index counts back \
                                 from the last element read)",
                            ));
                        }
                        let in_range = if value < 0 {
                            value.unsigned_abs() <= seen[kind]
                        } else {
                            value as u64 <= bytes.len() as u64
                        };
                        if !in_range {
                            let what = ["vertex", "texture coordinate", "normal"][kind];
                            let plural = ["vertices", "texture coordinates", "normals"][kind];
                            return Err(parse_error(
                                file,
                                Some(index + 1),
                                format!(
                                    "{what} index {value} is out of range ({} {plural} read so \
                                     far, {} bytes in the file)",
                                    seen[kind],
                                    bytes.len()
                                ),
                            ));
                        }
                    }
                }
            }
            _ => {}
        }
    }
    Ok(())
}

/// Parses OBJ text. Material libraries are not opened (only geometry is needed).
pub(super) fn parse(bytes: &[u8], file: &str) -> Result<TriMesh, MeshError> {
    check_element_indices(bytes, file)?;
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..Default::default()
    };
    let mut reader = LineCounter::new(bytes);
    let (models, _materials) =
        tobj::load_obj_buf(&mut reader, &options, |_| Err(LoadError::OpenFileFailed)).map_err(
            |e| {
                // Errors raised while parsing a line come back right after that line was read;
                // index and polygon errors are raised when an object is closed, so no line.
                let line = match e {
                    LoadError::FaceVertexOutOfBounds
                    | LoadError::FaceTexCoordOutOfBounds
                    | LoadError::FaceNormalOutOfBounds
                    | LoadError::FaceColorOutOfBounds
                    | LoadError::InvalidPolygon
                    | LoadError::GenericFailure
                    | LoadError::InvalidLoadOptionConfig => None,
                    _ => Some(reader.current_line()),
                };
                parse_error(file, line, e.to_string())
            },
        )?;
    let mut mesh = TriMesh::default();
    for model in &models {
        let part = TriMesh::new(
            points_from_f32(&model.mesh.positions).collect(),
            model
                .mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0], t[1], t[2]])
                .collect(),
        );
        mesh.append(&part);
    }
    Ok(mesh)
}

/// A `BufRead` over bytes that counts the lines consumed, so a parse error can name its line.
struct LineCounter<'a> {
    inner: &'a [u8],
    newlines: usize,
    partial: bool,
}

impl<'a> LineCounter<'a> {
    fn new(inner: &'a [u8]) -> Self {
        Self {
            inner,
            newlines: 0,
            partial: false,
        }
    }

    /// 1-based number of the line most recently (partly) consumed.
    fn current_line(&self) -> usize {
        self.newlines + usize::from(self.partial)
    }
}

impl Read for LineCounter<'_> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.fill_buf()?.len().min(buf.len());
        buf[..n].copy_from_slice(&self.inner[..n]);
        self.consume(n);
        Ok(n)
    }
}

impl BufRead for LineCounter<'_> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        Ok(self.inner)
    }

    fn consume(&mut self, amt: usize) {
        let (taken, rest) = self.inner.split_at(amt);
        if let Some(last) = taken.iter().rposition(|&b| b == b'\n') {
            self.newlines += taken.iter().filter(|&&b| b == b'\n').count();
            self.partial = last + 1 < taken.len();
        } else if !taken.is_empty() {
            self.partial = true;
        }
        self.inner = rest;
    }
}
