//! Mesh validation: the checks every loaded or built-in mesh passes before use.
//!
//! Fatal problems (no triangles, non-finite coordinates, out-of-range indices, absurd size) are
//! [`MeshError`]s naming the source and the element at fault. Degenerate triangles are dropped and
//! counted in the [`ValidationReport`].

use std::fmt;

use glam::DVec3;

use crate::{Aabb, TriMesh};

/// Largest accepted bounding-box diagonal (m): anything bigger is almost surely in the wrong units.
pub const MAX_DIAGONAL_M: f64 = 1.0e4;

/// Smallest accepted bounding-box diagonal (m).
pub const MIN_DIAGONAL_M: f64 = 1.0e-6;

/// A triangle is degenerate when twice its area is at most this times its longest edge squared
/// (dimensionless; about a 1e-12 rad sliver), or when it repeats a vertex index.
pub const DEGENERATE_RELATIVE_EPSILON: f64 = 1.0e-12;

/// Everything that can go wrong loading or validating a mesh. Every variant names the source (file
/// path or built-in name) in `file`.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("{file}: cannot read: {source}")]
    Io {
        /// File path.
        file: String,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file extension is not one of the supported formats.
    #[error(
        "{file}: unsupported mesh format '{extension}' (supported: .obj, .stl, .ply, .step, .stp)"
    )]
    UnknownFormat {
        /// File path.
        file: String,
        /// The extension found (empty when there is none).
        extension: String,
    },
    /// A unit scale factor that is zero, negative or not finite.
    #[error("{file}: scale must be finite and positive, got {scale}")]
    InvalidScale {
        /// File path.
        file: String,
        /// The scale given (metres per file unit).
        scale: f64,
    },
    /// The parser rejected the content.
    #[error("{file}: {}parse error: {message}", line.map(|l| format!("line {l}: ")).unwrap_or_default())]
    Parse {
        /// File path.
        file: String,
        /// 1-based line number when the parser reports one.
        line: Option<usize>,
        /// What the parser said.
        message: String,
    },
    /// No triangles, either in the source or after dropping degenerate ones.
    #[error("{file}: mesh has no usable triangles ({degenerate_dropped} degenerate dropped)")]
    Empty {
        /// Source name.
        file: String,
        /// Degenerate triangles dropped before the mesh was found empty.
        degenerate_dropped: usize,
    },
    /// A vertex coordinate is NaN or infinite.
    #[error("{file}: vertex {vertex} has non-finite coordinate {}", Coords(*.position))]
    NonFiniteVertex {
        /// Source name.
        file: String,
        /// Zero-based vertex index.
        vertex: usize,
        /// The offending position (m).
        position: DVec3,
    },
    /// A triangle refers to a vertex that does not exist.
    #[error("{file}: triangle {triangle} refers to vertex {index}, but there are only {vertex_count} vertices")]
    IndexOutOfRange {
        /// Source name.
        file: String,
        /// Zero-based triangle index.
        triangle: usize,
        /// The out-of-range vertex index.
        index: u64,
        /// Number of vertices in the mesh.
        vertex_count: usize,
    },
    /// The bounding box diagonal is outside [`MIN_DIAGONAL_M`, `MAX_DIAGONAL_M`].
    #[error("{file}: bounding box diagonal {diagonal_m} m is outside [{MIN_DIAGONAL_M}, {MAX_DIAGONAL_M}] m (wrong units or scale?)")]
    AbsurdSize {
        /// Source name.
        file: String,
        /// The diagonal found (m).
        diagonal_m: f64,
    },
}

/// Formats a position as `(x, y, z)` with Rust's shortest float formatting (`NaN`, `inf`).
struct Coords(DVec3);

impl fmt::Display for Coords {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "({}, {}, {})", self.0.x, self.0.y, self.0.z)
    }
}

/// What validation found in a mesh that it accepted.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct ValidationReport {
    /// Degenerate triangles dropped (zero area, repeated index, or sliver; see
    /// [`DEGENERATE_RELATIVE_EPSILON`]).
    pub degenerate_dropped: usize,
    /// Triangles kept.
    pub triangle_count: usize,
    /// Vertices in the mesh (unreferenced vertices are kept, not counted separately).
    pub vertex_count: usize,
    /// Bounds of the vertices referenced by kept triangles (m).
    pub bounds: Option<Aabb>,
}

/// Checks `mesh` and drops its degenerate triangles. `source` (file name or built-in name) prefixes
/// every error message.
///
/// Errors, in the order checked: [`MeshError::Empty`], [`MeshError::NonFiniteVertex`] (first bad
/// vertex), [`MeshError::IndexOutOfRange`] (first bad triangle), [`MeshError::Empty`] again when
/// every triangle is degenerate, [`MeshError::AbsurdSize`]. Allocates nothing beyond the mesh itself.
pub fn validate(mut mesh: TriMesh, source: &str) -> Result<(TriMesh, ValidationReport), MeshError> {
    let empty = |dropped| MeshError::Empty {
        file: source.to_string(),
        degenerate_dropped: dropped,
    };
    if mesh.triangles.is_empty() {
        return Err(empty(0));
    }
    if let Some((vertex, &position)) = mesh
        .vertices
        .iter()
        .enumerate()
        .find(|(_, v)| !v.is_finite())
    {
        return Err(MeshError::NonFiniteVertex {
            file: source.to_string(),
            vertex,
            position,
        });
    }
    let vertex_count = mesh.vertices.len();
    for (triangle, t) in mesh.triangles.iter().enumerate() {
        if let Some(&index) = t.iter().find(|&&i| i as usize >= vertex_count) {
            return Err(MeshError::IndexOutOfRange {
                file: source.to_string(),
                triangle,
                index: u64::from(index),
                vertex_count,
            });
        }
    }

    let before = mesh.triangles.len();
    let vertices = &mesh.vertices;
    mesh.triangles
        .retain(|t| !is_degenerate(t, [0, 1, 2].map(|k| vertices[t[k] as usize])));
    let degenerate_dropped = before - mesh.triangles.len();
    if mesh.triangles.is_empty() {
        return Err(empty(degenerate_dropped));
    }

    let mut bounds = Aabb::EMPTY;
    for t in &mesh.triangles {
        for &i in t {
            bounds.grow(mesh.vertices[i as usize]);
        }
    }
    let diagonal_m = bounds.size().length();
    if !(MIN_DIAGONAL_M..=MAX_DIAGONAL_M).contains(&diagonal_m) {
        return Err(MeshError::AbsurdSize {
            file: source.to_string(),
            diagonal_m,
        });
    }
    let report = ValidationReport {
        degenerate_dropped,
        triangle_count: mesh.triangles.len(),
        vertex_count,
        bounds: Some(bounds),
    };
    Ok((mesh, report))
}

/// True for a triangle with a repeated index or (near-)zero area relative to its longest edge.
pub fn is_degenerate(indices: &[u32; 3], corners: [DVec3; 3]) -> bool {
    let [a, b, c] = *indices;
    if a == b || b == c || a == c {
        return true;
    }
    let [p, q, r] = corners;
    let twice_area = (q - p).cross(r - p).length();
    let longest_sq = (q - p)
        .length_squared()
        .max((r - q).length_squared())
        .max((p - r).length_squared());
    twice_area <= DEGENERATE_RELATIVE_EPSILON * longest_sq
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![DVec3::ZERO, DVec3::X * 0.1, DVec3::Y * 0.1, DVec3::Z * 0.1],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn accepts_a_good_mesh_and_reports_counts() {
        let (m, r) = validate(tetra(), "t.obj").unwrap();
        assert_eq!(m, tetra());
        assert_eq!(r.triangle_count, 4);
        assert_eq!(r.vertex_count, 4);
        assert_eq!(r.degenerate_dropped, 0);
        assert_eq!(r.bounds.unwrap().max, DVec3::splat(0.1));
    }

    #[test]
    fn empty_mesh_is_an_error_naming_the_file() {
        let err = validate(TriMesh::default(), "part.obj").unwrap_err();
        assert!(matches!(err, MeshError::Empty { .. }));
        assert!(err.to_string().starts_with("part.obj: "), "{err}");
    }

    #[test]
    fn nan_vertex_is_named() {
        let mut m = tetra();
        m.vertices.extend([DVec3::ZERO; 9]);
        m.vertices[12] = DVec3::new(f64::NAN, 0.0, 1.0);
        let err = validate(m, "part.obj").unwrap_err().to_string();
        assert_eq!(
            err,
            "part.obj: vertex 12 has non-finite coordinate (NaN, 0, 1)"
        );
    }

    #[test]
    fn infinite_vertex_is_named() {
        let mut m = tetra();
        m.vertices[2].y = f64::NEG_INFINITY;
        let err = validate(m, "x.stl").unwrap_err().to_string();
        assert!(
            err.contains("x.stl") && err.contains("vertex 2") && err.contains("-inf"),
            "{err}"
        );
    }

    #[test]
    fn out_of_range_index_names_the_triangle() {
        let mut m = tetra();
        m.triangles[3] = [1, 2, 9];
        let err = validate(m, "p.ply").unwrap_err();
        assert!(matches!(
            err,
            MeshError::IndexOutOfRange {
                triangle: 3,
                index: 9,
                vertex_count: 4,
                ..
            }
        ));
        let text = err.to_string();
        assert!(
            text.starts_with("p.ply: triangle 3 ") && text.contains("vertex 9"),
            "{text}"
        );
    }

    #[test]
    fn degenerate_triangles_are_dropped_and_counted() {
        let mut m = tetra();
        m.vertices.push(DVec3::X * 0.05); // on the edge 0-1
        m.triangles.push([0, 0, 2]); // repeated index
        m.triangles.push([0, 4, 1]); // collinear: zero area
        let (m, r) = validate(m, "d.obj").unwrap();
        assert_eq!(r.degenerate_dropped, 2);
        assert_eq!(r.triangle_count, 4);
        assert_eq!(m.triangles.len(), 4);
    }

    #[test]
    fn all_degenerate_is_empty() {
        let m = TriMesh::new(vec![DVec3::ZERO, DVec3::X], vec![[0, 1, 1], [0, 0, 0]]);
        let err = validate(m, "flat.stl").unwrap_err();
        assert!(matches!(
            err,
            MeshError::Empty {
                degenerate_dropped: 2,
                ..
            }
        ));
        assert!(err.to_string().contains("flat.stl"));
    }

    #[test]
    fn absurd_sizes_are_rejected() {
        for (scale, name) in [(1.0e6, "huge.obj"), (1.0e-8, "tiny.obj")] {
            let mut m = tetra();
            m.transform(scale, glam::DQuat::IDENTITY, DVec3::ZERO);
            let err = validate(m, name).unwrap_err();
            assert!(matches!(err, MeshError::AbsurdSize { .. }), "{err}");
            assert!(err.to_string().starts_with(name), "{err}");
        }
    }
}
