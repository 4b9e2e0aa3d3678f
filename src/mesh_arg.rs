//! The mesh argument of `vps voxelize` and `vps shell`: a mesh file in `--units`, or a built-in
//! mesh, and the hint an error of a file read in metres gets.

use anyhow::{bail, Result};
use vps_session::file::Units;
use vps_session::mesh_source;

/// Loads the mesh of `vps voxelize` / `vps shell`: a file in `units` (converted to metres), or a
/// built-in mesh (metres; `--units` other than m is refused for it). A STEP file takes its unit
/// from the file (`--units` other than m is refused for it) and is tessellated to a quarter of
/// `voxel_size` (m), as a scene file does.
pub fn load_mesh(source: &str, units: Units, voxel_size: f64) -> Result<mesh_source::SceneMesh> {
    if source.starts_with("builtin:") && units != Units::Metres {
        bail!("--units applies to mesh files; {source} is in metres already");
    }
    if vps_session::file::is_step_source(source) {
        if units != Units::Metres {
            bail!("--units: {source} is a STEP file, which carries its own length unit");
        }
        let step = vps_mesh::StepSettings::quarter_voxel(voxel_size);
        return mesh_source::load_scaled_with(source, 1.0, &step);
    }
    mesh_source::load_scaled(source, units.metres())
}

/// [`load_mesh`] for a command that writes `build.output` (`-o`): the output path is checked
/// first, against the mesh file it must not replace.
pub fn load_mesh_for(
    source: &str,
    build: &crate::cli::BuildArgs,
    voxel_size: f64,
) -> Result<mesh_source::SceneMesh> {
    vps_app::output::check_output_path("-o", &build.output, &vps_app::output::mesh_inputs(source))?;
    load_mesh(source, build.units, voxel_size)
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
