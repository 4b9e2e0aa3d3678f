//! Hand-made voxmaps.

use glam::IVec3;
use std::sync::atomic::{AtomicBool, Ordering};
use vps_voxmap::{DenseGrid, DistanceBand, GridSpec, TreeConfig, Voxel, VoxelLookup, VoxelTree};

/// Voxel size of the test wall (m).
pub const VOXEL: f64 = 0.005;

/// Height of the wall's outer face (m): Interior below z index 8, Surface at 8 and 9, Proximity at
/// 10, Free above.
pub const WALL_TOP: f64 = 0.05;

/// A 20 × 20 × 20 grid of 5 mm voxels (origin at 0) holding a horizontal wall whose face is at
/// [`WALL_TOP`].
pub fn wall() -> DenseGrid {
    let mut g = DenseGrid::new(GridSpec::at_origin(VOXEL, [20, 20, 20]));
    for z in 0..8 {
        fill_layer(&mut g, z, Voxel::Interior);
    }
    fill_layer(&mut g, 8, Voxel::Surface);
    fill_layer(&mut g, 9, Voxel::Surface);
    fill_layer(&mut g, 10, Voxel::Proximity);
    g
}

/// [`wall`] as a voxel tree (uniform branching 2).
pub fn wall_tree() -> VoxelTree {
    VoxelTree::from_dense(&wall(), TreeConfig::uniform(2)).expect("valid tree config")
}

/// [`wall_tree`] carrying a signed-distance band (the `distance` force model) of the plane
/// `z = WALL_TOP` with a stand-off of 1/8 voxel ([`plane_band`]).
pub fn wall_band_tree() -> VoxelTree {
    let tree = wall_tree();
    let band = plane_band(tree.spec(), WALL_TOP, VOXEL / 8.0);
    tree.with_distance_band(band)
}

/// The signed-distance band of the half-space below the plane `z = plane_z` (m) on the grid
/// `spec`, with stand-off `standoff` (m), computed analytically: each sample holds
/// `z − plane_z − standoff`, quantised as the band stores it. Panics on a stand-off the band
/// refuses.
pub fn plane_band(spec: &GridSpec, plane_z: f64, standoff: f64) -> DistanceBand {
    use vps_voxmap::distance::{self, CubeCodes, BRICK_CODES, BRICK_EDGE};
    let s = spec.voxel_size;
    distance::assemble(spec, standoff, |c| {
        let mut codes = Box::new([0i8; BRICK_CODES]);
        for z in 0..BRICK_EDGE {
            let zc = spec.origin.z + (f64::from(c[2] * 8) + z as f64 + 0.5) * s;
            let code = distance::code_of(zc - plane_z - standoff, s);
            codes[z * BRICK_EDGE * BRICK_EDGE..(z + 1) * BRICK_EDGE * BRICK_EDGE].fill(code);
        }
        CubeCodes::from_codes(codes)
    })
    .expect("a valid band")
}

/// An all-Free `n × n × n` grid of 1 cm voxels with its origin at 0.
pub fn empty_cm_grid(n: u32) -> DenseGrid {
    DenseGrid::new(GridSpec::at_origin(0.01, [n; 3]))
}

/// Sets every voxel whose z index is `k` to `kind`.
pub fn fill_layer(grid: &mut DenseGrid, k: i32, kind: Voxel) {
    let d = grid.spec.dims;
    for j in 0..d[1] as i32 {
        for i in 0..d[0] as i32 {
            grid.set(IVec3::new(i, j, k), kind);
        }
    }
}

/// The test [`wall`] as a lookup that, once [`ArmedWall::armed`] is set, calls `hook(&state)`
/// before every lookup: for tests that make lookups panic, stall or slow down on chosen threads.
pub struct ArmedWall<S, F> {
    /// The wall the lookups read.
    pub wall: DenseGrid,
    /// Whether the hook runs (false at first; loaded with `Acquire`).
    pub armed: AtomicBool,
    /// What the hook and the test share (flags the hook sets or waits on).
    pub state: S,
    hook: F,
}

impl<S: Sync, F: Fn(&S) + Sync> ArmedWall<S, F> {
    /// The wall, not armed, with `hook` and its `state`.
    pub fn new(state: S, hook: F) -> ArmedWall<S, F> {
        ArmedWall {
            wall: wall(),
            armed: AtomicBool::new(false),
            state,
            hook,
        }
    }
}

impl<S: Sync, F: Fn(&S) + Sync> VoxelLookup for ArmedWall<S, F> {
    fn spec(&self) -> &GridSpec {
        self.wall.spec()
    }

    fn get(&self, ijk: IVec3) -> Voxel {
        if self.armed.load(Ordering::Acquire) {
            (self.hook)(&self.state);
        }
        self.wall.get(ijk)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_wall_has_its_documented_layers() {
        let g = wall();
        let at = |z| g.get(IVec3::new(3, 17, z));
        assert_eq!(at(0), Voxel::Interior);
        assert_eq!(at(7), Voxel::Interior);
        assert_eq!((at(8), at(9)), (Voxel::Surface, Voxel::Surface));
        assert_eq!(at(10), Voxel::Proximity);
        assert_eq!(at(11), Voxel::Free);
        // Free, Interior, Surface, Proximity.
        assert_eq!(g.counts(), [400 * 9, 400 * 8, 400 * 2, 400]);
    }

    #[test]
    fn an_armed_wall_calls_its_hook_only_once_armed() {
        let map = ArmedWall::new(std::sync::atomic::AtomicU64::new(0), |calls| {
            calls.fetch_add(1, Ordering::Relaxed);
        });
        let ijk = IVec3::new(3, 17, 8);
        assert_eq!(map.get(ijk), Voxel::Surface);
        assert_eq!(map.state.load(Ordering::Relaxed), 0);
        map.armed.store(true, Ordering::Release);
        assert_eq!(map.get(ijk), Voxel::Surface);
        assert_eq!(map.get(IVec3::new(3, 17, 11)), Voxel::Free);
        assert_eq!(map.state.load(Ordering::Relaxed), 2);
        assert_eq!(map.spec(), wall().spec());
    }
}
