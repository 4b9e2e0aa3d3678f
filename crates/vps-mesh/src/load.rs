//! Mesh file readers: OBJ (tobj), STL binary and ASCII (stl_io), PLY ASCII and binary (ply-rs-bw),
//! and STEP B-rep solids tessellated by `vps-step` (truck).
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
    /// For a STEP file: its unit, solids and tessellation.
    pub step: Option<StepSummary>,
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
    /// STEP (ISO 10303-21, `.step` / `.stp`): B-rep solids tessellated to a chord tolerance, in
    /// the file's own length unit converted to metres.
    Step,
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
            "step" | "stp" => Ok(Self::Step),
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

/// How a STEP file is tessellated.
#[derive(Clone, Debug, PartialEq)]
pub struct StepSettings {
    /// Largest distance between a triangle and the exact surface (m), > 0.
    pub chord_tolerance: f64,
    /// Read only the solids with these names (a solid's or its product's name); `None`: all.
    pub solids: Option<Vec<String>>,
    /// The most triangles one solid may need ([`DEFAULT_STEP_MAX_TRIANGLES`]): what bounds the
    /// tessellator's memory.
    pub max_triangles: usize,
}

/// The most triangles one STEP solid may be tessellated into by default: 20 million (about 1 GB
/// while tessellating).
pub const DEFAULT_STEP_MAX_TRIANGLES: usize = 20_000_000;

/// The chord tolerance a STEP file is read at when nothing sets one (m): 0.5 mm. A scene sets a
/// quarter of its voxel size instead.
pub const DEFAULT_STEP_CHORD_TOLERANCE: f64 = 0.5e-3;

impl StepSettings {
    /// The settings a scene reads a STEP file with at `voxel_size` (m) when it sets no
    /// `chord_tolerance`: a quarter voxel, every solid.
    pub fn quarter_voxel(voxel_size: f64) -> Self {
        Self {
            chord_tolerance: voxel_size / 4.0,
            ..Self::default()
        }
    }
}

impl Default for StepSettings {
    fn default() -> Self {
        Self {
            chord_tolerance: DEFAULT_STEP_CHORD_TOLERANCE,
            solids: None,
            max_triangles: DEFAULT_STEP_MAX_TRIANGLES,
        }
    }
}

/// What reading a STEP file found, for reports.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StepSummary {
    /// The file's length unit (`millimetre`, `inch`, ...).
    pub unit: String,
    /// The chord tolerance used (m).
    pub chord_tolerance: f64,
    /// The placed solids read, by name, with their triangle counts (one entry per placed copy).
    pub solids: Vec<(String, usize)>,
    /// Every solid of the file by name (selected or not).
    pub available: Vec<String>,
    /// Wall time of parsing and tessellating (s).
    pub seconds: f64,
}

/// Loads a mesh file whose coordinates are already metres. See [`load_mesh_scaled`].
pub fn load_mesh(path: &Path) -> Result<LoadedMesh, MeshError> {
    load_mesh_scaled(path, 1.0)
}

/// Loads a mesh file, multiplies every coordinate by `scale` (metres per file unit, e.g. `0.001` for
/// a file in millimetres), then validates it; validation (including the size check) sees metres.
/// A `scale` that is not finite and positive is [`MeshError::InvalidScale`].
pub fn load_mesh_scaled(path: &Path, scale: f64) -> Result<LoadedMesh, MeshError> {
    load_mesh_with(path, scale, &StepSettings::default())
}

/// [`load_mesh_scaled`] with the settings a STEP file is read with. A STEP file carries its own
/// length unit, so `scale` must be 1 for one ([`MeshError::InvalidScale`] otherwise).
pub fn load_mesh_with(
    path: &Path,
    scale: f64,
    step: &StepSettings,
) -> Result<LoadedMesh, MeshError> {
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
    if format == MeshFormat::Step {
        if scale != 1.0 {
            return Err(parse_error(
                &file,
                None,
                format!(
                    "a STEP file carries its own length unit: it cannot also be read in a unit \
                     ({scale} m per unit); remove the units setting"
                ),
            ));
        }
        let (mesh, summary) = parse_step(&bytes, &file, step)?;
        let (mesh, report) = validate(mesh, &file)?;
        return Ok(LoadedMesh {
            mesh,
            report,
            step: Some(summary),
        });
    }
    let mut mesh = parse_mesh(&bytes, format, &file)?;
    if scale != 1.0 {
        for v in &mut mesh.vertices {
            *v *= scale;
        }
    }
    let (mesh, report) = validate(mesh, &file)?;
    Ok(LoadedMesh {
        mesh,
        report,
        step: None,
    })
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
        MeshFormat::Step => parse_step(bytes, file, &StepSettings::default()).map(|(m, _)| m),
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

/// Reads a STEP file's selected solids into one mesh (m), every placed solid a closed shell.
/// Errors name `file` and, where the reader knows it, the line.
pub fn parse_step(
    bytes: &[u8],
    file: &str,
    settings: &StepSettings,
) -> Result<(TriMesh, StepSummary), MeshError> {
    let start = std::time::Instant::now();
    let options = vps_step::StepOptions {
        chord_tolerance: settings.chord_tolerance,
        solids: settings.solids.clone(),
        max_triangles: settings.max_triangles,
        ..vps_step::StepOptions::new(settings.chord_tolerance)
    };
    let model = vps_step::read_step(bytes, &options)
        .map_err(|e| parse_error(file, e.line(), e.detail()))?;
    let mut mesh = TriMesh::default();
    for s in &model.solids {
        let base = mesh.vertices.len() as u32;
        mesh.vertices.extend(&s.vertices);
        mesh.triangles
            .extend(s.triangles.iter().map(|t| t.map(|i| i + base)));
    }
    let summary = StepSummary {
        unit: model.unit.name.clone(),
        chord_tolerance: settings.chord_tolerance,
        solids: model
            .solids
            .iter()
            .map(|s| (s.name.clone(), s.triangles.len()))
            .collect(),
        available: model.names.clone(),
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((mesh, summary))
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
