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
    /// Tree memory (bytes): leaves the band touches × leaf size. Within a factor of about three
    /// (over, for cluttered scenes: the built-in bay at 5 mm is estimated at 20 MB, built 7.4 MB).
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate is within a factor of three of the tree the voxelizer builds for a sphere, and
    /// the grid count is near the padded bounds'.
    #[test]
    fn the_estimate_is_near_the_built_tree() {
        let mesh = vps_mesh::builtin::by_name("sphere").unwrap();
        let opts = VoxelizeOptions {
            voxel_size: 0.002,
            ..VoxelizeOptions::default()
        };
        let est = estimate(std::slice::from_ref(&mesh), &opts, TreeConfig::default());
        let (tree, _) = vps_voxelize::voxelize_tree(&[mesh], &opts, TreeConfig::default()).unwrap();
        let built = tree.memory_bytes() as f64;
        assert!(
            est.tree_bytes > built / 3.0 && est.tree_bytes < built * 3.0,
            "estimate {} built {built}",
            est.tree_bytes
        );
        let dims = tree.spec().dims.map(f64::from);
        let grid = dims[0] * dims[1] * dims[2];
        assert!(
            (est.grid_voxels / grid - 1.0).abs() < 0.2,
            "{} {grid}",
            est.grid_voxels
        );
    }
}
