//! Mesh file readers: OBJ (tobj), STL binary and ASCII (stl_io), PLY ASCII and binary (ply-rs-bw).
//!
//! The format is chosen by the file extension (case-insensitive). Every mesh is scaled to metres and
//! passed through [`validate`] before it is returned. Every failure is a [`MeshError`] naming the
//! file, and the line where the parser reports one. Loading allocates and blocks on file I/O: it is
//! setup work, never frame-path work.

mod obj;
mod ply;
mod stl;

use std::path::Path;

use glam::DVec3;

use crate::validate::{validate, MeshError, ValidationReport};
use crate::TriMesh;

/// A loaded, validated mesh with its validation report.
#[derive(Clone, Debug)]
pub struct LoadedMesh {
    /// The mesh (m).
    pub mesh: TriMesh,
    /// What validation dropped or noticed.
    pub report: ValidationReport,
}

/// The mesh file formats understood by [`load_mesh`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MeshFormat {
    /// Wavefront OBJ (polygons are fan-triangulated by tobj).
    Obj,
    /// STL, binary or ASCII (detected from the content).
    Stl,
    /// Stanford PLY, ASCII or binary; faces as `vertex_indices` or `vertex_index` lists.
    Ply,
}

impl MeshFormat {
    /// The format for `path`'s extension (case-insensitive), or [`MeshError::UnknownFormat`].
    pub fn from_path(path: &Path) -> Result<Self, MeshError> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match extension.as_str() {
            "obj" => Ok(Self::Obj),
            "stl" => Ok(Self::Stl),
            "ply" => Ok(Self::Ply),
            _ => Err(MeshError::UnknownFormat {
                file: path.display().to_string(),
                extension,
            }),
        }
    }
}

/// The largest mesh file read, in bytes (4 GiB: a binary STL of about 80 million triangles). A
/// larger file is refused before it is read, naming its size and this bound.
pub const MAX_MESH_FILE_BYTES: u64 = 4 * vps_files::GIB;

/// Loads a mesh file whose coordinates are already metres. See [`load_mesh_scaled`].
pub fn load_mesh(path: &Path) -> Result<LoadedMesh, MeshError> {
    load_mesh_scaled(path, 1.0)
}

/// Loads a mesh file, multiplies every coordinate by `scale` (metres per file unit, e.g. `0.001` for
/// a file in millimetres), then validates it; validation (including the size check) sees metres.
/// A `scale` that is not finite and positive is [`MeshError::InvalidScale`].
pub fn load_mesh_scaled(path: &Path, scale: f64) -> Result<LoadedMesh, MeshError> {
    let file = path.display().to_string();
    if !(scale.is_finite() && scale > 0.0) {
        return Err(MeshError::InvalidScale { file, scale });
    }
    let format = MeshFormat::from_path(path)?;
    let bytes =
        vps_files::read_regular(path, MAX_MESH_FILE_BYTES).map_err(|source| MeshError::Io {
            file: file.clone(),
            source,
        })?;
    let mut mesh = parse_mesh(&bytes, format, &file)?;
    if scale != 1.0 {
        for v in &mut mesh.vertices {
            *v *= scale;
        }
    }
    let (mesh, report) = validate(mesh, &file)?;
    Ok(LoadedMesh { mesh, report })
}

/// Parses the bytes of a mesh file of a known format into an unvalidated mesh in file units.
/// `file` names the source in errors.
///
/// The third-party parsers are fed untrusted bytes, so each runs under
/// [`std::panic::catch_unwind`]: a panic inside a parser crate becomes a [`MeshError::Parse`]
/// instead of taking the process down (the panic message is still printed by the panic hook).
pub fn parse_mesh(bytes: &[u8], format: MeshFormat, file: &str) -> Result<TriMesh, MeshError> {
    if bytes.is_empty() {
        return Err(parse_error(
            file,
            None,
            "the file is empty (0 bytes): was the export interrupted?",
        ));
    }
    let parse = || match format {
        MeshFormat::Obj => obj::parse(bytes, file),
        MeshFormat::Stl => stl::parse(bytes, file),
        MeshFormat::Ply => ply::parse(bytes, file),
    };
    std::panic::catch_unwind(parse).unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        Err(parse_error(file, None, format!("parser panicked: {what}")))
    })
}

/// A [`MeshError::Parse`] for `file`.
fn parse_error(file: &str, line: Option<usize>, message: impl Into<String>) -> MeshError {
    MeshError::Parse {
        file: file.to_string(),
        line,
        message: message.into(),
    }
}

/// Converts a flat `[x, y, z, x, y, z, ...]` f32 list to points.
fn points_from_f32(flat: &[f32]) -> impl Iterator<Item = DVec3> + '_ {
    flat.chunks_exact(3)
        .map(|c| DVec3::new(f64::from(c[0]), f64::from(c[1]), f64::from(c[2])))
}

#[cfg(test)]
mod tests;
