//! The mapping between world coordinates (m) and integer voxel indices.

use glam::{DVec3, IVec3};

/// A regular grid: voxel `(i, j, k)` is the cube `[origin + s*(i,j,k), origin + s*(i+1,j+1,k+1))`.
///
/// Invariants: `voxel_size > 0` and finite, `origin` finite, every `dims` component ≥ 1. Indices
/// outside `0..dims` are outside the voxmap and read as [`crate::Voxel::Free`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GridSpec {
    /// World position of the minimum corner of voxel (0, 0, 0) (m).
    pub origin: DVec3,
    /// Edge length of one voxel (m).
    pub voxel_size: f64,
    /// Number of voxels along x, y, z.
    pub dims: [u32; 3],
}

impl GridSpec {
    /// The grid of `dims` voxels of edge `voxel_size` (m) whose voxel (0, 0, 0) has its minimum
    /// corner at the world origin.
    pub const fn at_origin(voxel_size: f64, dims: [u32; 3]) -> Self {
        Self {
            origin: DVec3::ZERO,
            voxel_size,
            dims,
        }
    }

    /// Total number of voxels, saturating at `u64::MAX` (three dims near `u32::MAX` overflow u64).
    pub fn voxel_count(&self) -> u64 {
        self.dims
            .iter()
            .fold(1u64, |n, &d| n.saturating_mul(u64::from(d)))
    }

    /// The index of the voxel containing world point `p` (may be outside `dims`).
    #[inline(always)]
    pub fn index_of(&self, p: DVec3) -> IVec3 {
        let q = ((p - self.origin) / self.voxel_size).floor();
        IVec3::new(q.x as i32, q.y as i32, q.z as i32)
    }

    /// World position of the centre of voxel `ijk` (m).
    #[inline(always)]
    pub fn center_of(&self, ijk: IVec3) -> DVec3 {
        self.origin + (ijk.as_dvec3() + DVec3::splat(0.5)) * self.voxel_size
    }

    /// True when `ijk` lies inside `0..dims` on every axis.
    #[inline(always)]
    pub fn contains(&self, ijk: IVec3) -> bool {
        ijk.x >= 0
            && ijk.y >= 0
            && ijk.z >= 0
            && (ijk.x as u32) < self.dims[0]
            && (ijk.y as u32) < self.dims[1]
            && (ijk.z as u32) < self.dims[2]
    }

    /// Linear index (x fastest) of an in-range voxel.
    #[inline(always)]
    pub fn linear(&self, ijk: IVec3) -> usize {
        (ijk.x as usize)
            + self.dims[0] as usize * ((ijk.y as usize) + self.dims[1] as usize * ijk.z as usize)
    }

    /// World-space maximum corner of the grid (m).
    pub fn max_corner(&self) -> DVec3 {
        self.origin
            + DVec3::new(
                self.dims[0] as f64,
                self.dims[1] as f64,
                self.dims[2] as f64,
            ) * self.voxel_size
    }
}
