//! A fixed lookup loop for instruction counting (`valgrind --tool=callgrind`): builds a synthetic
//! 2-bit scene (nested boxes) as a 512-tree and sums `get` over 1 M pseudo-random indices.
//! Prints the checksum so the loop cannot be optimised away.

use glam::IVec3;
use std::hint::black_box;
use vps_voxmap::{DenseGrid, GridSpec, TreeConfig, Voxel, VoxelLookup, VoxelTree};

fn main() {
    let n = 300u32;
    let spec = GridSpec::at_origin(0.005, [n; 3]);
    let grid = DenseGrid::from_fn(spec, |p| match (p - 150).abs().max_element() {
        0..=99 => Voxel::Interior,
        100..=101 => Voxel::Surface,
        102 => Voxel::Proximity,
        _ => Voxel::Free,
    });
    let tree = VoxelTree::from_dense(&grid, TreeConfig::default()).expect("tree");
    drop(grid);
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let queries: Vec<IVec3> = (0..1_000_000)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let c = |s: u64| (s % 310) as i32 - 5;
            IVec3::new(c(state), c(state >> 20), c(state >> 40))
        })
        .collect();
    let mut acc = 0u64;
    for &q in &queries {
        acc = acc.wrapping_add(lookup(&tree, q) as u64);
    }
    println!("checksum {acc}");
}

/// The measured call: one `VoxelLookup::get` through the trait, not inlined into the loop.
#[inline(never)]
fn lookup(tree: &VoxelTree, q: IVec3) -> Voxel {
    VoxelLookup::get(black_box(tree), q)
}
