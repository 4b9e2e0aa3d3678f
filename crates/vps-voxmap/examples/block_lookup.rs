//! Lookup throughput of the tree alone: scalar `get_layered` per cell against the gathered
//! `get_blocks` (groups of 1 and 4 blocks of 8 cells), over cells in a spherical Surface band (the
//! kernel benchmark's contact case) and in free space. Prints ns per cell.
//!
//! `cargo run --release -p vps-voxmap --example block_lookup`

use glam::{DVec3, IVec3};
use std::hint::black_box;
use std::time::Instant;
use vps_voxmap::{BlockCells, DenseGrid, GridSpec, TreeConfig, Voxel, VoxelLookup, VoxelTree};

const R: f64 = 200.0;

fn band() -> VoxelTree {
    let n = (2.0 * R + 8.0) as u32;
    let spec = GridSpec {
        origin: DVec3::ZERO,
        voxel_size: 0.001,
        dims: [n; 3],
    };
    let mut grid = DenseGrid::new(spec);
    let c = DVec3::splat(n as f64 / 2.0);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let d = (DVec3::new(x as f64, y as f64, z as f64) + 0.5 - c).length() - R;
                let v = if d < -1.0 {
                    Voxel::Interior
                } else if d < 1.0 {
                    Voxel::Surface
                } else if d < 2.0 {
                    Voxel::Proximity
                } else {
                    Voxel::Free
                };
                grid.set(IVec3::new(x as i32, y as i32, z as i32), v);
            }
        }
    }
    VoxelTree::from_dense(&grid, TreeConfig::default()).unwrap()
}

fn cells(n: usize, radius: f64, centre: f64) -> Vec<IVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let t = golden * i as f64;
            let p = DVec3::new(r * t.cos(), r * t.sin(), z) * radius + centre;
            p.floor().as_ivec3()
        })
        .collect()
}

fn blocks(cells: &[IVec3]) -> Vec<BlockCells> {
    cells
        .chunks_exact(8)
        .map(|c| {
            let mut b = [[0; 8]; 3];
            for (l, p) in c.iter().enumerate() {
                b[0][l] = p.x;
                b[1][l] = p.y;
                b[2][l] = p.z;
            }
            b
        })
        .collect()
}

fn time(label: &str, cells: usize, mut f: impl FnMut() -> u64) {
    let mut best = f64::MAX;
    for _ in 0..7 {
        let t = Instant::now();
        let mut s = 0;
        for _ in 0..(2_000_000 / cells).max(20) {
            s += f();
        }
        black_box(s);
        best = best.min(
            t.elapsed().as_secs_f64() / (2_000_000 / cells).max(20) as f64 / cells as f64 * 1e9,
        );
    }
    println!("{label:<28} {best:6.2} ns/cell");
}

fn main() {
    let tree = band();
    let centre = R + 4.0;
    for (case, radius) in [("surface band", R), ("free inside grid", R + 3.5)] {
        let count: usize = std::env::var("CELLS")
            .ok()
            .and_then(|v| v.parse().ok())
            .unwrap_or(100_000);
        let mut cs = cells(count, radius, centre);
        if std::env::args().any(|a| a == "--sorted") {
            // Leaf-cube order, as the kernel's shells are stored: neighbours share leaves.
            cs.sort_by_key(|c| ((c.z >> 3), (c.y >> 3), (c.x >> 3), c.z, c.y, c.x));
        }
        let bs = blocks(&cs);
        println!("{case}: {} cells", cs.len());
        time("scalar get_layered", cs.len(), || {
            cs.iter().map(|&c| tree.get_layered(c).kind as u64).sum()
        });
        time("branchless scalar", cs.len(), || {
            cs.iter().map(|&c| tree.get_branchless(c) as u64).sum()
        });
        time("sum of cells (calibration)", cs.len(), || {
            cs.iter().map(|&c| (c.x ^ c.y ^ c.z) as u64).sum()
        });
        time("accessor (leaf cache)", cs.len(), || {
            let mut a = tree.accessor();
            cs.iter().map(|&c| a.get(c) as u64).sum()
        });
        time("get_blocks::<1>", cs.len(), || {
            bs.iter()
                .map(|b| tree.get_blocks(&[*b]).unwrap()[0].kinds[3] as u64)
                .sum()
        });
        time("get_blocks::<4>", cs.len(), || {
            bs.chunks_exact(4)
                .map(|b| {
                    let g: [BlockCells; 4] = [b[0], b[1], b[2], b[3]];
                    tree.get_blocks(&g).unwrap()[2].kinds[5] as u64
                })
                .sum()
        });
    }
}
