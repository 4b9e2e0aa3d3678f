//! Resolves a mesh source named on the command line: a file path, or `builtin:NAME`.

use anyhow::{anyhow, Context, Result};
use vps_mesh::TriMesh;

/// A loaded mesh and a short human-readable description of where it came from.
pub struct SceneMesh {
    /// The mesh (m).
    pub mesh: TriMesh,
    /// `builtin:NAME` or the file path.
    pub source: String,
    /// Degenerate triangles dropped while loading.
    pub degenerate_dropped: usize,
}

/// Loads `source`: `builtin:NAME` for a built-in scene, anything else is a mesh file path.
pub fn load(source: &str) -> Result<SceneMesh> {
    if let Some(name) = source.strip_prefix("builtin:") {
        let mesh = vps_mesh::builtin::by_name(name).ok_or_else(|| {
            anyhow!(
                "unknown built-in scene '{name}'; available: {}",
                vps_mesh::builtin::BUILTIN_NAMES.join(", ")
            )
        })?;
        return Ok(SceneMesh {
            mesh,
            source: source.to_string(),
            degenerate_dropped: 0,
        });
    }
    let loaded = vps_mesh::load_mesh(std::path::Path::new(source))
        .with_context(|| format!("loading mesh {source}"))?;
    Ok(SceneMesh {
        mesh: loaded.mesh,
        source: source.to_string(),
        degenerate_dropped: loaded.report.degenerate_dropped,
    })
}
