//! What a voxmap will cost, estimated before voxelizing: the padded grid's voxel count and the
//! sparse tree's memory, from the scene's bounds and surface area. Plans over the budget are
//! refused before anything is allocated.

use glam::DVec3;
use serde::Serialize;
use vps_mesh::{Aabb, TriMesh};
use vps_voxelize::VoxelizeOptions;
use vps_voxmap::TreeConfig;

/// The largest voxmap a scene may plan (bytes of tree, estimated): 8 GiB.
pub const VOXMAP_MEMORY_BUDGET: f64 = 8.0 * 1024.0 * 1024.0 * 1024.0;

/// The voxelizer's hard limit on the padded grid (voxels), `vps_voxelize`'s sparse cap (2^40).
pub const MAX_GRID_VOXELS: f64 = (1u64 << 40) as f64;

/// An estimate of one voxmap.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct VoxmapEstimate {
    /// Voxels in the padded grid (clipped to the workspace when one is given).
    pub grid_voxels: f64,
    /// Voxels in the band around the surfaces (Surface, force layers, Proximity).
    pub band_voxels: f64,
    /// Tree memory (bytes): leaves the band touches × leaf size. Within a factor of about two.
    pub tree_bytes: f64,
}

/// Estimates the voxmap of `objects` voxelized with `opts` into a tree of shape `tree`.
/// Allocation-free; O(triangles).
pub fn estimate(objects: &[TriMesh], opts: &VoxelizeOptions, tree: TreeConfig) -> VoxmapEstimate {
    let s = opts.voxel_size;
    let mut bounds = Aabb::EMPTY;
    let mut area = 0.0;
    for mesh in objects {
        bounds = bounds.union(&mesh.bounds());
        for i in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.triangle(i);
            if let Some(w) = &opts.workspace {
                let lo = a.min(b).min(c);
                let hi = a.max(b).max(c);
                if (lo - w.max).max_element() > 0.0 || (w.min - hi).max_element() > 0.0 {
                    continue;
                }
            }
            area += 0.5 * (b - a).cross(c - a).length();
        }
    }
    if let Some(w) = &opts.workspace {
        bounds = Aabb {
            min: bounds.min.max(w.min),
            max: bounds.max.min(w.max),
        };
    }
    let pad = f64::from(opts.effective_padding());
    let size = (bounds.max - bounds.min).max(DVec3::ZERO);
    let dims = (size / s).ceil() + DVec3::splat(2.0 * pad + 1.0);
    let grid_voxels = dims.x * dims.y * dims.z;
    let band = 2.0 * (f64::from(opts.offset_layers) + 2.0);
    let band_voxels = (area / (s * s) * band).min(grid_voxels);
    let leaf = f64::from(1u32 << tree.log2_dims[0]);
    // A surface crosses about 1.5 leaves per leaf-sized patch of its area (the mean of
    // |nx| + |ny| + |nz| over orientations), widened by the band's thickness.
    let leaves =
        (area / (leaf * s).powi(2) * 1.5 * (1.0 + band / leaf)).min(grid_voxels / leaf.powi(3));
    let leaf_bytes = leaf.powi(3) * f64::from(opts.width.bits()) / 8.0 + 16.0;
    VoxmapEstimate {
        grid_voxels,
        band_voxels,
        tree_bytes: leaves * leaf_bytes,
    }
}
