//! What one voxelization measured: [`VoxelizeStats`], filled by the dense pipeline
//! ([`crate::pipeline`]) and the sparse one ([`crate::sparse`]).

/// Timings and counts of one voxelization. Times are milliseconds; the per-object phases (scan, fill,
/// merge) are summed over objects, which run in parallel, so their sum can exceed `total_ms`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VoxelizeStats {
    /// Number of objects voxelized.
    pub objects: usize,
    /// Total triangles scan-converted.
    pub triangles: usize,
    /// Grid dimensions (voxels).
    pub dims: [u32; 3],
    /// Scan conversion (ms).
    pub scan_ms: f64,
    /// Flood fill (ms).
    pub fill_ms: f64,
    /// Merging objects into the shared planes (ms).
    pub merge_ms: f64,
    /// Proximity and offset on the merged planes (ms).
    pub offset_ms: f64,
    /// Writing the dense grid (ms).
    pub output_ms: f64,
    /// Everything, including validation and allocation (ms).
    pub total_ms: f64,
    /// Final Free voxels.
    pub free_voxels: u64,
    /// Final Interior voxels.
    pub interior_voxels: u64,
    /// Final Surface (force layer) voxels.
    pub surface_voxels: u64,
    /// Final Proximity voxels.
    pub proximity_voxels: u64,
    /// Peak bytes of the voxelizer's working data (bit planes, chunk tables, the dense output grid
    /// or the tree under construction), counted from the structures' sizes, not from the allocator.
    /// For the dense pipeline this is the planned figure of about 1.9 bytes per voxel.
    pub peak_work_bytes: u64,
    /// Chunks the sparse voxelizer computed Proximity and offset in (0 for the dense pipeline).
    pub active_chunks: usize,
}
