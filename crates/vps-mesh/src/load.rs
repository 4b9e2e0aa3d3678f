//! Mesh file readers. Work in progress.
/// A loaded, validated mesh with its validation report.
pub struct LoadedMesh {
    /// The mesh (m).
    pub mesh: crate::TriMesh,
    /// What validation dropped or noticed.
    pub report: crate::ValidationReport,
}
/// Loads a mesh file. Work in progress.
pub fn load_mesh(_path: &std::path::Path) -> Result<LoadedMesh, crate::MeshError> {
    Err(crate::MeshError::Unsupported)
}
