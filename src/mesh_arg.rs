//! The mesh argument of `vps voxelize` and `vps shell`: a mesh file in `--units`, or a built-in
//! mesh, and the hint an error of a file read in metres gets.

use anyhow::{bail, Result};
use vps_session::file::Units;
use vps_session::mesh_source;

/// Loads the mesh of `vps voxelize` / `vps shell`: a file in `units` (converted to metres), or a
/// built-in mesh (metres; `--units` other than m is refused for it).
pub fn load_mesh(source: &str, units: Units) -> Result<mesh_source::SceneMesh> {
    if source.starts_with("builtin:") && units != Units::Metres {
        bail!("--units applies to mesh files; {source} is in metres already");
    }
    mesh_source::load_scaled(source, units.metres())
}

/// For an error of a mesh file read in metres: its size and the `--units` a CAD export in
/// millimetres needs (empty otherwise).
pub fn units_hint(mesh: &mesh_source::SceneMesh, units: Units) -> String {
    if units != Units::Metres || mesh.source.starts_with("builtin:") {
        return String::new();
    }
    let size = mesh.mesh.bounds().size().max_element();
    format!(" (read in metres: {size:.4} m across; a file in millimetres needs --units mm)")
}
