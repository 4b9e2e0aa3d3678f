//! The root: a dense 3-D array of slots, one per upper-node cube, covering the grid's dims. Lookup
//! indexes it directly (no hashing, unlike OpenVDB's sparse root map): the grid is bounded and the
//! array costs 4 bytes per `2^(3 * upper shift)` voxels.

use super::internal::Slot;
use glam::UVec3;

/// The root slot array.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct RootGrid {
    /// Upper-node cubes per axis: `ceil(grid dims / upper extent)`.
    pub(crate) dims: [u32; 3],
    /// log2 of the upper node's extent in voxels per axis.
    pub(crate) shift: u32,
    /// Raw [`Slot`] words, x fastest; a child indexes the upper arena.
    pub(crate) slots: Vec<u32>,
}

impl RootGrid {
    /// Root cells per axis needed to cover `grid_dims` voxels with cubes of `2^shift` voxels.
    pub(crate) fn dims_for(grid_dims: [u32; 3], shift: u32) -> [u32; 3] {
        grid_dims.map(|d| ((d as u64 + (1u64 << shift) - 1) >> shift) as u32)
    }

    /// Number of root cells for `dims`.
    pub(crate) fn cell_count(dims: [u32; 3]) -> u64 {
        dims.iter().map(|&d| d as u64).product()
    }

    /// The slot covering in-grid voxel `p`; `shift` must equal `self.shift` (passed in so a caller
    /// can make it a constant).
    #[inline(always)]
    pub(crate) fn slot(&self, p: UVec3, shift: u32) -> Slot {
        debug_assert_eq!(shift, self.shift);
        let c = p >> shift;
        let i = c.x as usize
            + self.dims[0] as usize * (c.y as usize + self.dims[1] as usize * c.z as usize);
        debug_assert!(i < self.slots.len());
        // SAFETY: `p` is inside the grid dims, so `c < dims_for(grid dims, shift) = self.dims` per
        // axis and `i < cell_count(self.dims)`, which is the slot count (`from_dense` builds one
        // slot per cell; `from_parts` checks the length).
        Slot(unsafe { *self.slots.get_unchecked(i) })
    }

    /// Voxel coordinates of the minimum corner of root cell `index`.
    pub(crate) fn cell_origin(&self, index: usize) -> UVec3 {
        Self::origin_in(self.dims, self.shift, index)
    }

    /// [`RootGrid::cell_origin`] before a `RootGrid` exists.
    pub(crate) fn origin_in(dims: [u32; 3], shift: u32, index: usize) -> UVec3 {
        let (nx, ny) = (dims[0] as usize, dims[1] as usize);
        let c = UVec3::new(
            (index % nx) as u32,
            ((index / nx) % ny) as u32,
            (index / (nx * ny)) as u32,
        );
        c << shift
    }
}
