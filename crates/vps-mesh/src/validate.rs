//! Mesh validation. Work in progress.
/// Errors. Work in progress.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// Work in progress.
    #[error("unsupported")]
    Unsupported,
}
/// Validation report. Work in progress.
#[derive(Debug, Default, Clone)]
pub struct ValidationReport {
    /// Degenerate triangles dropped.
    pub degenerate_dropped: usize,
}
