//! Mesh sources: a file path or `builtin:NAME`, loaded in metres and placed (units, scale,
//! rotation, translation).

use anyhow::{anyhow, Result};
use glam::{DQuat, DVec3};
use std::path::Path;
use std::sync::Arc;
use vps_mesh::{Aabb, TriMesh};

/// A loaded mesh and a short human-readable description of where it came from.
pub struct SceneMesh {
    /// The mesh (m).
    pub mesh: TriMesh,
    /// `builtin:NAME` or the file path.
    pub source: String,
    /// Degenerate triangles dropped while loading.
    pub degenerate_dropped: usize,
    /// For a STEP file: its unit, solids and tessellation.
    pub step: Option<vps_mesh::StepSummary>,
}

/// Loads `source`: `builtin:NAME` for a built-in mesh, anything else is a mesh file path (m).
/// Blocking (reads the file), allocates the mesh.
pub fn load(source: &str) -> Result<SceneMesh> {
    load_scaled(source, 1.0)
}

/// [`load`] with every coordinate of a mesh file multiplied by `metres_per_unit` before the
/// loader validates it (built-in meshes are in metres already and are scaled after loading).
pub fn load_scaled(source: &str, metres_per_unit: f64) -> Result<SceneMesh> {
    load_scaled_with(source, metres_per_unit, &vps_mesh::StepSettings::default())
}

/// [`load_scaled`] reading a STEP file with `step` (a STEP file takes its unit from the file:
/// `metres_per_unit` must be 1 for one).
pub fn load_scaled_with(
    source: &str,
    metres_per_unit: f64,
    step: &vps_mesh::StepSettings,
) -> Result<SceneMesh> {
    if let Some(name) = source.strip_prefix("builtin:") {
        let mut mesh = vps_mesh::builtin::by_name(name).ok_or_else(|| {
            anyhow!(
                "unknown built-in scene '{name}'; available: {}",
                vps_mesh::builtin::BUILTIN_NAMES.join(", ")
            )
        })?;
        if metres_per_unit != 1.0 {
            mesh.vertices.iter_mut().for_each(|v| *v *= metres_per_unit);
        }
        return Ok(SceneMesh {
            mesh,
            source: source.to_string(),
            degenerate_dropped: 0,
            step: None,
        });
    }
    // Every `MeshError` names the file already.
    let loaded = vps_mesh::load_mesh_with(Path::new(source), metres_per_unit, step)?;
    Ok(SceneMesh {
        mesh: loaded.mesh,
        source: source.to_string(),
        degenerate_dropped: loaded.report.degenerate_dropped,
        step: loaded.step,
    })
}

/// How a mesh (already in metres) is placed: scaled per axis about its origin, rotated, then
/// translated (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    /// Scale per axis (dimensionless, positive).
    pub scale: DVec3,
    /// Rotation applied after scaling.
    pub rotation: DQuat,
    /// Translation (m), applied last.
    pub translate: DVec3,
}

impl Placement {
    /// Where the placement puts `p` (m): scaled, rotated, translated, each step skipped when it is
    /// the identity, so the identity placement returns `p` bit-identical.
    pub fn point(&self, p: DVec3) -> DVec3 {
        let mut p = p;
        if self.scale != DVec3::ONE {
            p *= self.scale;
        }
        if self.rotation != DQuat::IDENTITY {
            p = self.rotation * p;
        }
        if self.translate != DVec3::ZERO {
            p += self.translate;
        }
        p
    }

    /// Applies the placement to every vertex ([`Placement::point`]).
    pub fn apply(&self, mesh: &mut TriMesh) {
        for v in &mut mesh.vertices {
            *v = self.point(*v);
        }
    }

    /// The bounds (m) of `mesh` placed, without making the placed copy: from the mesh's own
    /// bounds when there is no rotation (a positive scale and a translation keep each axis's
    /// order, also in rounding), else from every vertex placed. Equal to the placed copy's bounds.
    pub fn bounds(&self, mesh: &TriMesh) -> Aabb {
        if self.rotation == DQuat::IDENTITY && self.scale.min_element() > 0.0 {
            let b = mesh.bounds();
            if b.min.cmple(b.max).all() {
                return Aabb {
                    min: self.point(b.min),
                    max: self.point(b.max),
                };
            }
            return b;
        }
        mesh.vertices.iter().fold(Aabb::EMPTY, |b, &v| {
            let p = self.point(v);
            Aabb {
                min: b.min.min(p),
                max: b.max.max(p),
            }
        })
    }
}

/// `source` resolved against `base` (the scene file's directory) unless it is builtin or absolute.
pub fn resolve(source: &str, base: &Path) -> String {
    if source.starts_with("builtin:") || Path::new(source).is_absolute() {
        source.to_string()
    } else {
        base.join(source).display().to_string()
    }
}

/// A mesh a scene names, read and parsed once however many objects name it.
pub struct SharedMesh {
    /// `builtin:NAME` or the file path (resolved against the scene file's directory) as first
    /// named.
    pub source: String,
    /// The mesh after its units (m), before any object's placement.
    pub mesh: Arc<TriMesh>,
    /// The static objects naming it.
    pub statics: usize,
    /// Whether the part names it.
    pub part: bool,
    /// Whether it is closed, and what is wrong when it is not ([`vps_mesh::mesh_health`]).
    pub health: vps_mesh::MeshHealth,
    /// Degenerate triangles the loader dropped.
    pub degenerate_dropped: usize,
    /// Triangles in its components that are not closed by the file's vertex indices, as the
    /// voxelizer splits them (`vps_reference::components`): what a winding-number tree of it
    /// holds. 0 when no static object names it.
    pub open_triangles: usize,
    /// For a STEP file: its unit, the solids read and the tessellation.
    pub step: Option<vps_mesh::StepSummary>,
}

/// A name for each static object, for reports: its source's file stem (`housing` for
/// `parts/housing.stl`, `box` for `builtin:box`), printable, with ` #i` (its index in the file)
/// added where two objects would share a name.
pub fn object_names(sources: &[String]) -> Vec<String> {
    let stems: Vec<String> = sources
        .iter()
        .map(|s| {
            let stem = match s.strip_prefix("builtin:") {
                Some(name) => name.to_string(),
                None => Path::new(s)
                    .file_stem()
                    .map_or_else(|| s.clone(), |x| x.to_string_lossy().into_owned()),
            };
            vps_files::printable(&stem).into_owned()
        })
        .collect();
    stems
        .iter()
        .enumerate()
        .map(|(i, stem)| {
            if stems.iter().filter(|&other| other == stem).count() > 1 {
                format!("{stem} #{i}")
            } else {
                stem.clone()
            }
        })
        .collect()
}
