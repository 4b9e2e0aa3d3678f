//! The voxmap: 2-bit voxels of a static scene, stored in a fixed-depth 2^(3N) tree (McNeely et al.
//! 1999, §4.3), plus the point shell of the dynamic object.
//!
//! Module map:
//! - [`voxel`]: the four voxel kinds.
//! - [`grid`]: [`GridSpec`], the world ↔ voxel-index mapping shared by every structure.
//! - [`dense`]: [`DenseGrid`], one byte per voxel; the voxelizer's workspace and the tree's test oracle.
//! - `tree` (mask, leaf, internal, root, accessor): the fixed-depth tree, constant-cost `get`.
//! - [`shell`]: [`PointShell`], body-frame points with inward normals and mass properties.
//! - [`file`]: the versioned `.vmap` and `.vshell` binary formats with content hashes.

pub mod dense;
pub mod file;
pub mod grid;
pub mod shell;
pub mod tree;
pub mod voxel;

pub use dense::DenseGrid;
pub use file::FileError;
pub use grid::GridSpec;
pub use shell::{MassProperties, PointShell};
pub use tree::{CubeSource, NodeCounts, TreeAccessor, TreeConfig, TreeError, VoxelTree};
pub use voxel::{LayeredVoxel, Voxel, VoxelWidth};

/// Read access to a voxmap by integer voxel index: implemented by the tree (runtime) and the dense
/// grid (test oracle, benchmark baseline). The sampling kernel is generic over it.
///
/// Contract: `get` never panics, does not allocate or block, and returns [`Voxel::Free`] for any index
/// outside `spec().dims`.
pub trait VoxelLookup: Sync {
    /// The grid placement (origin, voxel size, dims).
    fn spec(&self) -> &GridSpec;
    /// The voxel at `ijk`.
    fn get(&self, ijk: glam::IVec3) -> Voxel;

    /// The voxel at `ijk` with its distance layer (see [`LayeredVoxel`]); same contract as `get`.
    /// The default reports layer 0, which is exact for 2-bit maps.
    #[inline(always)]
    fn get_layered(&self, ijk: glam::IVec3) -> LayeredVoxel {
        LayeredVoxel {
            kind: self.get(ijk),
            layer: 0,
        }
    }
}

impl VoxelLookup for DenseGrid {
    fn spec(&self) -> &GridSpec {
        &self.spec
    }
    #[inline]
    fn get(&self, ijk: glam::IVec3) -> Voxel {
        DenseGrid::get(self, ijk)
    }
}
