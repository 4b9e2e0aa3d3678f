//! Working-memory estimates made from the plan, before any voxel is computed, and the budget they
//! are checked against ([`crate::VoxelizeOptions::max_memory_bytes`]).
//!
//! The sparse voxelizer's memory follows the surface: one table entry per 64³ chunk of the grid,
//! plus bit planes for every chunk the surface crosses (the merged Interior and Surface planes and
//! the finished chunk's code planes, alive together at the peak). The number of surface chunks is
//! estimated as the smallest of three bounds: the surface area over the largest cross-section of a
//! chunk (√2 chunk faces), the chunks meeting each triangle's bounding box summed over triangles,
//! and the grid's chunk count. The estimate is therefore about a lower bound of the real peak (the
//! neighbours of surface chunks add more), so a refusal is never a false alarm for ordinary meshes.
//! The dense pipeline needs about 15/8 bytes per voxel of the grid.

use crate::error::VoxelizeError;
use std::sync::OnceLock;
use vps_mesh::TriMesh;
use vps_voxmap::{GridSpec, VoxelWidth};

/// Voxels per sparse chunk edge (the sparse voxelizer's chunk).
const CHUNK: f64 = 64.0;
/// Bytes of one bit plane over a chunk (64³ bits).
const PLANE_BYTES: u64 = 64 * 64 * 64 / 8;
/// Table bytes per chunk of the grid (the merged and finished chunk enums and the active flag).
const TABLE_BYTES_PER_CHUNK: u64 = 64;
/// Dense pipeline workspace per voxel: the one-byte grid plus about seven bit planes.
const DENSE_BYTES_PER_VOXEL_NUM: u64 = 15;
const DENSE_BYTES_PER_VOXEL_DEN: u64 = 8;
/// The budget when physical memory cannot be read (bytes, 8 GiB).
const FALLBACK_BUDGET_BYTES: u64 = 8 << 30;

/// Total physical memory (bytes) from `/proc/meminfo`, or `None` where it cannot be read.
pub fn physical_memory_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_ascii_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The default working-memory budget (bytes): half of physical memory, or 8 GiB where it cannot
/// be read. Read once per process.
pub fn default_memory_budget() -> u64 {
    static BUDGET: OnceLock<u64> = OnceLock::new();
    *BUDGET.get_or_init(|| physical_memory_bytes().map_or(FALLBACK_BUDGET_BYTES, |b| b / 2))
}

/// A plan's working-memory estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MemoryEstimate {
    /// Estimated peak working bytes.
    pub bytes: u64,
    /// Chunks of the grid (sparse pipeline; 0 for dense).
    pub chunks: u64,
    /// Estimated chunks the surface crosses (sparse pipeline; 0 for dense).
    pub surface_chunks: u64,
}

/// The sparse voxelizer's estimate for `objects` on `spec` at `width`. O(triangles), allocates
/// nothing. Objects must have finite vertices and valid indices.
pub fn estimate_sparse(objects: &[TriMesh], spec: &GridSpec, width: VoxelWidth) -> MemoryEstimate {
    let n: [f64; 3] = spec.dims.map(|d| (f64::from(d) / CHUNK).ceil());
    let chunks = n[0] * n[1] * n[2];
    let edge = CHUNK * spec.voxel_size;
    let mut area = 0.0;
    let mut boxed = 0.0;
    for mesh in objects {
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.triangle(t);
            area += 0.5 * (b - a).cross(c - a).length();
            let lo = ((a.min(b).min(c) - spec.origin) / edge).floor();
            let hi = ((a.max(b).max(c) - spec.origin) / edge).floor();
            let span: [f64; 3] = std::array::from_fn(|k| {
                let (l, h) = (lo[k].max(0.0), hi[k].min(n[k] - 1.0));
                (h - l + 1.0).max(0.0)
            });
            boxed += span[0] * span[1] * span[2];
        }
    }
    let by_area = (area / (std::f64::consts::SQRT_2 * edge * edge)).ceil();
    sparse_estimate(chunks, by_area.min(boxed).min(chunks), width)
}

/// The sparse voxelizer's estimate for a grid of `dims` voxels of `voxel_size` (m) holding
/// `area` (m²) of surface, when the triangles themselves are not at hand (a scene's estimate
/// before its placed copies are made): the area bound alone, so at least [`estimate_sparse`]'s
/// figure for the same surface. Allocation-free, O(1).
pub fn estimate_sparse_by_area(
    dims: [f64; 3],
    voxel_size: f64,
    area: f64,
    width: VoxelWidth,
) -> MemoryEstimate {
    let n: [f64; 3] = dims.map(|d| (d / CHUNK).ceil());
    let chunks = n[0] * n[1] * n[2];
    let edge = CHUNK * voxel_size;
    let by_area = (area / (std::f64::consts::SQRT_2 * edge * edge)).ceil();
    sparse_estimate(chunks, by_area.min(chunks), width)
}

/// The table of `chunks` chunks plus the planes of `surface_chunks` of them.
fn sparse_estimate(chunks: f64, surface_chunks: f64, width: VoxelWidth) -> MemoryEstimate {
    let per_surface_chunk = (2 + u64::from(width.bits())) * PLANE_BYTES;
    let bytes = chunks * TABLE_BYTES_PER_CHUNK as f64 + surface_chunks * per_surface_chunk as f64;
    MemoryEstimate {
        bytes: saturate(bytes),
        chunks: saturate(chunks),
        surface_chunks: saturate(surface_chunks),
    }
}

/// The dense pipeline's estimate for `spec` (about 15/8 bytes per voxel).
pub fn estimate_dense(spec: &GridSpec) -> MemoryEstimate {
    MemoryEstimate {
        bytes: spec.voxel_count().saturating_mul(DENSE_BYTES_PER_VOXEL_NUM)
            / DENSE_BYTES_PER_VOXEL_DEN,
        chunks: 0,
        surface_chunks: 0,
    }
}

fn saturate(x: f64) -> u64 {
    if x >= u64::MAX as f64 {
        u64::MAX
    } else {
        x as u64
    }
}

/// Errors when `estimate` exceeds `budget_bytes`.
pub(crate) fn check_budget(
    estimate: MemoryEstimate,
    spec: &GridSpec,
    budget_bytes: u64,
) -> Result<(), VoxelizeError> {
    if estimate.bytes <= budget_bytes {
        return Ok(());
    }
    Err(VoxelizeError::OverMemoryBudget {
        voxel_size: spec.voxel_size,
        dims: spec.dims,
        estimate_bytes: estimate.bytes,
        budget_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn spec_for(size_m: f64, voxel: f64) -> GridSpec {
        let n = (size_m / voxel).ceil() as u32 + 8;
        GridSpec {
            origin: DVec3::splat(-size_m / 2.0 - 4.0 * voxel),
            voxel_size: voxel,
            dims: [n; 3],
        }
    }

    #[test]
    fn a_cube_estimate_follows_its_surface() {
        let cube = vps_mesh::builtin::by_name("box").unwrap().transformed(
            100.0,
            glam::DQuat::IDENTITY,
            DVec3::ZERO,
        );
        // 10 m cube at 1 mm: 600 m² of surface over chunk cross-sections of √2·(64 mm)².
        let e = estimate_sparse(&[cube], &spec_for(10.0, 0.001), VoxelWidth::Two);
        let expected_chunks = (600.0 / (std::f64::consts::SQRT_2 * 0.064 * 0.064)).ceil() as u64;
        assert_eq!(e.surface_chunks, expected_chunks);
        assert!(
            e.bytes > 12 << 30 && e.bytes < 16 << 30,
            "{}",
            crate::error::gib(e.bytes)
        );
    }

    #[test]
    fn a_crumpled_mesh_is_bounded_by_its_grid() {
        // Many large triangles folded into one small grid: the grid's chunk count bounds it.
        let mut mesh = vps_mesh::builtin::by_name("sphere").unwrap();
        for v in &mut mesh.vertices {
            *v *= 0.01;
        }
        let e = estimate_sparse(&[mesh], &spec_for(0.001, 0.0001), VoxelWidth::Eight);
        assert_eq!(e.chunks, 1);
        assert_eq!(e.surface_chunks, 1);
    }
}
