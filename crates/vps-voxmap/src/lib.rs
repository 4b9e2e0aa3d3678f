//! The voxmap: 2-bit voxels of a static scene (4- and 8-bit with distance layers, [`VoxelWidth`]),
//! stored in a fixed-depth 2^(3N) tree (McNeely et al. 1999, §4.3), plus the point shell of the
//! dynamic object.
//!
//! Module map:
//! - [`voxel`]: the four voxel kinds, the voxel widths and layered voxels.
//! - [`grid`]: [`GridSpec`], the world ↔ voxel-index mapping shared by every structure.
//! - [`distance`]: [`DistanceBand`], sub-voxel signed distances near the surface (the `distance`
//!   force model).
//! - [`dense`]: [`DenseGrid`], one byte per voxel; the voxelizer's workspace and the tree's test oracle.
//! - `tree` (mask, leaf, internal, root, accessor): the fixed-depth tree, constant-cost `get`.
//! - [`shell`]: [`PointShell`], body-frame points with inward normals and mass properties.
//! - [`file`](mod@file): the versioned `.vmap` and `.vshell` binary formats with content hashes.
//!
//! Where this crate sits in vps: `docs/architecture.md` at the repository root.

#![warn(missing_docs)]

pub mod cpu;
pub mod dense;
pub mod distance;
pub mod file;
pub mod grid;
pub mod shell;
pub mod tree;
pub mod voxel;

pub use dense::DenseGrid;
pub use distance::DistanceBand;
pub use file::FileError;
pub use grid::GridSpec;
pub use shell::{MassProperties, PointShell};
pub use tree::{
    CubeSource, NodeCounts, TreeAccessor, TreeConfig, TreeError, VoxelTree,
    DIRECTORY_ALLOWANCE_BYTES, DIRECTORY_MAX_BYTES,
};
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

    /// The voxels of a block of [`BLOCK_LANES`] cells (`cells[axis][lane]`), lane by lane as
    /// [`VoxelLookup::get_layered`]. The default makes one `get_layered` call per lane; the tree
    /// overrides it with a lookup whose index arithmetic vectorises. Does not allocate or block.
    #[inline(always)]
    fn get_block(&self, cells: &BlockCells) -> VoxelBlock {
        block_by_lanes(self, cells)
    }

    /// The voxels of a wide block of [`WIDE_BLOCK_LANES`] cells (`cells[axis][lane]`), lane by
    /// lane as [`VoxelLookup::get_layered`]: the same voxels as [`VoxelLookup::get_block`] on each
    /// half. The default makes those two `get_block` calls; the tree overrides it with one pass
    /// over the sixteen lanes where the CPU has AVX-512F. Does not allocate or block.
    #[inline(always)]
    fn get_wide_block(&self, cells: &WideBlockCells) -> WideVoxelBlock {
        wide_block_by_halves(cells, |half| self.get_block(half))
    }

    /// The map's signed-distance band, when it has one: the sampling kernel then runs the
    /// `distance` force model instead of the tangent-plane one. The default has none.
    #[inline(always)]
    fn distance_band(&self) -> Option<&DistanceBand> {
        None
    }

    /// Runs `task` on this lookup or on an equivalent one (the same voxel at every index) whose
    /// code is fixed to this map's format, so that a hot loop compiled once per format tests the
    /// format once per task instead of once per lookup. The default runs `task` on `self`; the tree
    /// passes a view of itself that takes its 2-bit 512-tree path or its general (decoding) path
    /// without a per-lookup test.
    #[inline(always)]
    fn specialised<T: LookupTask>(&self, task: T) -> T::Output
    where
        Self: Sized,
    {
        task.run(self)
    }
}

/// Work generic over the lookup, handed to [`VoxelLookup::specialised`].
pub trait LookupTask {
    /// What the task returns.
    type Output;
    /// Runs the task on `map`.
    fn run<L: VoxelLookup>(self, map: &L) -> Self::Output;
}

/// [`VoxelLookup::get_block`] as one [`VoxelLookup::get_layered`] call per lane: the trait's
/// default, and the tree's path when it has no leaf directory.
#[allow(clippy::needless_range_loop)] // lane loops: index form vectorises and reads as lanes
#[inline(always)]
pub(crate) fn block_by_lanes<L: VoxelLookup + ?Sized>(map: &L, cells: &BlockCells) -> VoxelBlock {
    let mut block = VoxelBlock::default();
    for l in 0..BLOCK_LANES {
        let v = map.get_layered(glam::IVec3::new(cells[0][l], cells[1][l], cells[2][l]));
        block.kinds[l] = v.kind.bits();
        block.layers[l] = v.layer;
    }
    block
}

/// [`VoxelLookup::get_wide_block`] as [`VoxelLookup::get_block`] (here `block`) on each half of
/// the lanes: the trait's default, and the tree's path where its directory has no AVX-512 read.
#[inline(always)]
pub(crate) fn wide_block_by_halves(
    cells: &WideBlockCells,
    mut block: impl FnMut(&BlockCells) -> VoxelBlock,
) -> WideVoxelBlock {
    let mut wide = WideVoxelBlock::default();
    for half in 0..2 {
        let lanes = half * BLOCK_LANES..(half + 1) * BLOCK_LANES;
        let cells: BlockCells = std::array::from_fn(|a| {
            let mut axis = [0; BLOCK_LANES];
            axis.copy_from_slice(&cells[a][lanes.clone()]);
            axis
        });
        let b = block(&cells);
        wide.kinds[lanes.clone()].copy_from_slice(&b.kinds);
        wide.layers[lanes].copy_from_slice(&b.layers);
    }
    wide
}

/// Cells per block lookup ([`VoxelLookup::get_block`]).
pub const BLOCK_LANES: usize = 8;

/// The cells of a block lookup: voxel indices, `cells[axis][lane]` (any values; outside the
/// dims reads Free).
pub type BlockCells = [[i32; BLOCK_LANES]; 3];

/// Cells per wide block lookup ([`VoxelLookup::get_wide_block`]): two blocks, one 512-bit register
/// of 32-bit lanes.
pub const WIDE_BLOCK_LANES: usize = 2 * BLOCK_LANES;

/// The cells of a wide block lookup: voxel indices, `cells[axis][lane]` (any values; outside the
/// dims reads Free).
pub type WideBlockCells = [[i32; WIDE_BLOCK_LANES]; 3];

/// The voxels of a wide block lookup, lane by lane, as [`VoxelBlock`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WideVoxelBlock {
    /// [`Voxel::bits`] of each lane's kind.
    pub kinds: [u8; WIDE_BLOCK_LANES],
    /// Each lane's distance layer.
    pub layers: [u8; WIDE_BLOCK_LANES],
}

/// The voxels of a block lookup, lane by lane: the kind's bits ([`Voxel::bits`]) and the
/// distance layer (as in [`LayeredVoxel`]; 0 in a 2-bit map).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VoxelBlock {
    /// [`Voxel::bits`] of each lane's kind.
    pub kinds: [u8; BLOCK_LANES],
    /// Each lane's distance layer.
    pub layers: [u8; BLOCK_LANES],
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
