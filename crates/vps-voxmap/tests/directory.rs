//! The leaf directory (`crates/vps-voxmap/src/tree/directory.rs`): lookups through it equal the
//! tree walk on every voxel, and block reads equal single reads, for every width and two tree
//! shapes, inside, on the border of and far outside the grid.

use crate::common;

use common::FnSource;
use glam::{IVec3, UVec3};
use vps_voxmap::{
    GridSpec, LayeredVoxel, LookupTask, TreeConfig, Voxel, VoxelLookup, VoxelTree, VoxelWidth,
    BLOCK_LANES, WIDE_BLOCK_LANES,
};

/// A tree of `width` over `dims` holding random-ish codes valid for the width in slabs (Free
/// elsewhere), so that tiles, leaves and uniform internal nodes all occur.
fn clustered_tree(dims: [u32; 3], width: VoxelWidth, config: TreeConfig, seed: u64) -> VoxelTree {
    let codes: Vec<u8> = (0..=255u8).filter(|&c| width.decode(c).is_some()).collect();
    let code = move |p: UVec3| {
        let mixed = (p.x + p.y + p.z) % 37 < 9;
        let i = u64::from(p.x + dims[0] * (p.y + dims[1] * p.z));
        let hash = lcg_step(i ^ seed);
        if mixed {
            codes[(hash >> 33) as usize % codes.len()]
        } else {
            0
        }
    };
    let spec = GridSpec::at_origin(0.01, dims);
    let tree = VoxelTree::from_source(spec, width, config, &FnSource { dims, code }).unwrap();
    assert!(tree.directory_bytes() > 0, "{width:?} {config:?}");
    tree
}

/// One step of Knuth's MMIX linear congruential generator (also the cell hash above).
fn lcg_step(state: u64) -> u64 {
    state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407)
}

/// Draws from an MMIX LCG started at `state`: each call steps it and returns a value in
/// `0..span` taken from the state's bits 20 and up.
fn draws(mut state: u64) -> impl FnMut(i64) -> i32 {
    move |span| {
        state = lcg_step(state);
        ((state >> 20) as i64).rem_euclid(span) as i32
    }
}

/// Where [`random_cells`] puts a block's cells (for a tree over the 130 × 66 × 40 voxels of the
/// block tests).
#[derive(Clone, Copy)]
enum Place {
    /// Around the grid, borders included.
    Around,
    /// A few voxels apart, so that most lanes share a leaf.
    Near,
    /// Anywhere in i32.
    Anywhere,
    /// Extremes.
    Extreme,
}

/// A block of `LANES` cells placed as `place` says, drawn from `next` lane by lane, x then y then
/// z.
fn random_cells<const LANES: usize>(
    next: &mut impl FnMut(i64) -> i32,
    place: Place,
) -> [[i32; LANES]; 3] {
    let mut cells = [[0i32; LANES]; 3];
    for l in 0..LANES {
        for (a, axis) in cells.iter_mut().enumerate() {
            axis[l] = match place {
                Place::Around => next([136, 72, 46][a]) - 3,
                Place::Near => [40, 20, 12][a] + next(12),
                Place::Anywhere => next(1 << 32) ^ i32::MIN,
                Place::Extreme => [i32::MIN, i32::MAX, -1, 0][next(4) as usize],
            };
        }
    }
    cells
}

#[test]
fn directory_and_walk_agree_on_every_voxel() {
    for width in VoxelWidth::ALL {
        for config in [TreeConfig::default(), TreeConfig::uniform(2)] {
            let tree = clustered_tree([150, 70, 45], width, config, 7);
            let walk = tree.clone().without_directory();
            assert_eq!(walk.directory_bytes(), 0);
            for z in -2..47 {
                for y in -2..72 {
                    for x in -2..152 {
                        let ijk = IVec3::new(x, y, z);
                        assert_eq!(tree.get_layered(ijk), walk.get_layered(ijk), "{ijk}");
                    }
                }
            }
        }
    }
}

#[test]
#[allow(clippy::needless_range_loop)]
fn block_reads_equal_single_reads_inside_outside_and_far_away() {
    use Place::{Anywhere, Around, Extreme};
    for width in VoxelWidth::ALL {
        let tree = clustered_tree([130, 66, 40], width, TreeConfig::default(), 11);
        let walk = tree.clone().without_directory();
        // Block reads on the portable path (no AVX2 gathers) on any host.
        let portable = tree.clone().without_gathers();
        let mut next = draws(3);
        for round in 0..20_000 {
            let place = [Around, Around, Anywhere, Extreme][round % 4];
            let cells: [[i32; BLOCK_LANES]; 3] = random_cells(&mut next, place);
            // Through the directory, and walked lane by lane without it.
            for block in [
                tree.get_block(&cells),
                walk.get_block(&cells),
                portable.get_block(&cells),
            ] {
                for l in 0..BLOCK_LANES {
                    let ijk = IVec3::new(cells[0][l], cells[1][l], cells[2][l]);
                    let one = tree.get_layered(ijk);
                    assert_eq!(
                        (block.kinds[l], block.layers[l]),
                        (one.kind.bits(), one.layer)
                    );
                }
            }
        }
    }
}

#[test]
#[allow(clippy::needless_range_loop)]
fn wide_block_reads_equal_single_reads_for_every_width_and_shape() {
    use Place::{Anywhere, Around, Extreme, Near};
    for width in VoxelWidth::ALL {
        for config in [TreeConfig::default(), TreeConfig::uniform(2)] {
            let tree = clustered_tree([130, 66, 40], width, config, 13);
            let walk = tree.clone().without_directory();
            // Wide reads as two blocks on the portable path, on any host.
            let portable = tree.clone().without_gathers();
            let mut next = draws(5);
            let mut leaf_lanes = 0;
            for round in 0..6_000 {
                let place = [Around, Around, Near, Anywhere, Extreme][round % 5];
                let cells: [[i32; WIDE_BLOCK_LANES]; 3] = random_cells(&mut next, place);
                // Through the directory (one pass where the CPU has AVX-512F), as two blocks,
                // walked lane by lane, and through the copy of the lookups for the tree's shape.
                let shaped = tree.specialised(Wide(cells));
                for block in [
                    tree.get_wide_block(&cells),
                    walk.get_wide_block(&cells),
                    portable.get_wide_block(&cells),
                    shaped,
                ] {
                    for l in 0..WIDE_BLOCK_LANES {
                        let ijk = IVec3::new(cells[0][l], cells[1][l], cells[2][l]);
                        let one = walk.get_layered(ijk);
                        leaf_lanes += usize::from(one.layer > 0);
                        assert_eq!(
                            (block.kinds[l], block.layers[l]),
                            (one.kind.bits(), one.layer),
                            "{width:?} {config:?} round {round} lane {l}"
                        );
                    }
                }
            }
            assert!(leaf_lanes > 0 || width == VoxelWidth::Two);
        }
    }
}

/// One wide block read through the lookup it is handed.
struct Wide([[i32; WIDE_BLOCK_LANES]; 3]);

impl LookupTask for Wide {
    type Output = vps_voxmap::WideVoxelBlock;

    fn run<L: VoxelLookup>(self, map: &L) -> Self::Output {
        map.get_wide_block(&self.0)
    }
}

/// Reads every cell of a box around the grid through the lookup it is handed (for the tree, the
/// copy of its lookups for its shape: `VoxelLookup::specialised`), single and in blocks.
struct ReadAll {
    lo: IVec3,
    hi: IVec3,
}

impl LookupTask for ReadAll {
    type Output = Vec<(Voxel, LayeredVoxel, u8, u8, u8, u8)>;

    #[allow(clippy::needless_range_loop)] // lane loops read as lanes
    fn run<L: VoxelLookup>(self, map: &L) -> Self::Output {
        let mut out = Vec::new();
        for z in self.lo.z..self.hi.z {
            for y in self.lo.y..self.hi.y {
                let mut cells = [[0i32; WIDE_BLOCK_LANES]; 3];
                for x in self.lo.x..self.hi.x {
                    let l = (x - self.lo.x) as usize % WIDE_BLOCK_LANES;
                    cells[0][l] = x;
                    cells[1][l] = y;
                    cells[2][l] = z;
                    if l == WIDE_BLOCK_LANES - 1 {
                        let wide = map.get_wide_block(&cells);
                        for half in 0..2 {
                            let cells: [[i32; BLOCK_LANES]; 3] = std::array::from_fn(|a| {
                                std::array::from_fn(|l| cells[a][half * BLOCK_LANES + l])
                            });
                            let block = map.get_block(&cells);
                            for l in 0..BLOCK_LANES {
                                let ijk = IVec3::new(cells[0][l], cells[1][l], cells[2][l]);
                                let w = half * BLOCK_LANES + l;
                                out.push((
                                    map.get(ijk),
                                    map.get_layered(ijk),
                                    block.kinds[l],
                                    block.layers[l],
                                    wide.kinds[w],
                                    wide.layers[w],
                                ));
                            }
                        }
                    }
                }
            }
        }
        out
    }
}

#[test]
fn specialised_lookups_equal_the_trees_for_every_width_and_shape() {
    let dims = [70, 40, 30];
    let task = || ReadAll {
        lo: IVec3::new(-3, -2, -2),
        hi: IVec3::new(-3 + 80, 42, 32),
    };
    for width in VoxelWidth::ALL {
        for config in [TreeConfig::default(), TreeConfig::uniform(2)] {
            let tree = clustered_tree(dims, width, config, 5);
            for tree in [
                tree.clone(),
                tree.clone().without_directory(),
                tree.without_gathers(),
            ] {
                let shaped = tree.specialised(task());
                let plain = task().run(&tree);
                assert_eq!(shaped.len(), 80 * 44 * 34);
                assert!(shaped.iter().any(|v| v.1.layer > 0) || width == VoxelWidth::Two);
                for (i, (s, p)) in shaped.iter().zip(&plain).enumerate() {
                    assert_eq!(s, p, "{width:?} {config:?} read {i}");
                    assert_eq!(
                        (s.1.kind.bits(), s.1.layer),
                        (s.2, s.3),
                        "{width:?} read {i}"
                    );
                    assert_eq!((s.2, s.3), (s.4, s.5), "{width:?} wide read {i}");
                    assert_eq!(s.0, s.1.kind, "{width:?} read {i}");
                }
            }
        }
    }
}
