//! Errors of the voxelizer and the point-shell builder.

use thiserror::Error;

/// Largest grid the voxelizer accepts (voxels). The workspace needs about 1.9 bytes per voxel (the
/// one-byte [`vps_voxmap::DenseGrid`] plus five bit planes), so this caps memory near 7.6 GB.
pub const MAX_VOXELS: u64 = 4_000_000_000;

/// Largest grid the sparse voxelizer ([`crate::voxelize_tree`]) accepts (voxels): 2^40, the `.vmap`
/// limit. Its memory follows the surface; only a table of one small entry per 64³ chunk grows with
/// the volume (about 16 bytes per 262,144 voxels).
pub const MAX_SPARSE_VOXELS: u64 = 1 << 40;

/// Why voxelization or point-shell sampling failed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum VoxelizeError {
    /// The voxel size is zero, negative, NaN or infinite.
    #[error("voxel size must be positive and finite, got {value} m")]
    InvalidVoxelSize {
        /// The rejected size (m).
        value: f64,
    },
    /// The grid would hold more than [`MAX_VOXELS`] voxels (or a dimension exceeds `i32::MAX`).
    #[error(
        "grid of {dims:?} = {voxels} voxels (about {bytes} bytes of workspace) exceeds the limit of \
         {limit} voxels; use a larger voxel size or a smaller scene"
    )]
    GridTooLarge {
        /// Requested dimensions (x, y, z), saturated at `u64::MAX`.
        dims: [u64; 3],
        /// Requested voxel count (saturating).
        voxels: u64,
        /// Estimated workspace memory (bytes, saturating).
        bytes: u64,
        /// The limit, [`MAX_VOXELS`].
        limit: u64,
    },
    /// The plan's estimated working memory exceeds the budget
    /// ([`crate::VoxelizeOptions::max_memory_bytes`]); checked before any voxel is computed.
    #[error(
        "voxel size {voxel_size} m: the grid of {dims:?} voxels needs an estimated {} of working \
         memory, over the budget of {}; use a larger voxel size, a workspace, or raise the budget \
         with --max-memory (e.g. --max-memory {})",
        gib(*estimate_bytes),
        gib(*budget_bytes),
        suggested_budget(*estimate_bytes)
    )]
    OverMemoryBudget {
        /// Voxel edge (m).
        voxel_size: f64,
        /// Grid dimensions (voxels).
        dims: [u32; 3],
        /// Estimated peak working memory (bytes).
        estimate_bytes: u64,
        /// The budget (bytes).
        budget_bytes: u64,
    },
    /// The grid specification is unusable (zero dimension or non-finite origin).
    #[error("invalid grid: {reason}")]
    InvalidGrid {
        /// What is wrong.
        reason: String,
    },
    /// An option cannot be honoured (workspace, offset depth, tree config).
    #[error("invalid options: {reason}")]
    InvalidOptions {
        /// What is wrong.
        reason: String,
    },
    /// `voxelize` was given no objects.
    #[error("no objects to voxelize")]
    NoObjects,
    /// An object (by position in the input list) has no triangles.
    #[error("object {object} has no triangles")]
    EmptyObject {
        /// Index of the object in the input slice.
        object: usize,
    },
    /// A triangle refers to a missing vertex or a vertex is not finite.
    #[error("object {object}, triangle {triangle}: {reason}")]
    InvalidMesh {
        /// Index of the object in the input slice (0 for a point-shell mesh).
        object: usize,
        /// Index of the offending triangle.
        triangle: usize,
        /// What is wrong.
        reason: String,
    },
}

/// A `--max-memory` value (whole GiB) that covers `estimate_bytes`.
fn suggested_budget(estimate_bytes: u64) -> String {
    format!("{}GiB", estimate_bytes.div_ceil(1 << 30))
}

/// `bytes` as GiB with two decimals, for messages.
pub(crate) fn gib(bytes: u64) -> String {
    format!("{:.2} GiB", bytes as f64 / (1u64 << 30) as f64)
}
