//! Voxmap lookup and build cost: dense grid (1 byte/voxel) vs the 512-tree, on the same queries in
//! the same run, plus `VoxelTree::from_dense` build time.
//!
//! Scene: 512×400×300 voxels (61 M) with a floor slab and random boxes, each an Interior core in a
//! 2-voxel Surface shell and a 1-voxel Proximity shell. Query sets: uniform random over the grid
//! (cache-hostile), and a point-shell-like sweep through a 48³ region around a surface (coherent).
//!
//! Run: `cargo bench --bench voxmap`.

use criterion::{black_box, criterion_group, criterion_main, Criterion};
use glam::IVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::time::Duration;
use vps_voxmap::{DenseGrid, GridSpec, TreeConfig, Voxel, VoxelLookup, VoxelTree};

const DIMS: [u32; 3] = [512, 400, 300];
const QUERIES: usize = 1 << 20;

/// Sets voxels in `[lo, hi)` (clipped) to `v`, a row at a time.
fn fill_box(g: &mut DenseGrid, lo: IVec3, hi: IVec3, v: Voxel) {
    let d = IVec3::new(DIMS[0] as i32, DIMS[1] as i32, DIMS[2] as i32);
    let (lo, hi) = (lo.max(IVec3::ZERO), hi.min(d));
    for z in lo.z..hi.z {
        for y in lo.y..hi.y {
            let start = g.spec.linear(IVec3::new(lo.x, y, z));
            let len = (hi.x - lo.x).max(0) as usize;
            g.data[start..start + len].fill(v as u8);
        }
    }
}

/// A box with its Surface (2 voxels) and Proximity (1 voxel) shells.
fn shelled_box(g: &mut DenseGrid, lo: IVec3, hi: IVec3) {
    fill_box(g, lo - 3, hi + 3, Voxel::Proximity);
    fill_box(g, lo - 2, hi + 2, Voxel::Surface);
    fill_box(g, lo, hi, Voxel::Interior);
}

fn scene(rng: &mut ChaCha8Rng) -> DenseGrid {
    let mut g = DenseGrid::new(GridSpec::at_origin(0.005, DIMS));
    shelled_box(&mut g, IVec3::new(-10, -10, -10), IVec3::new(530, 410, 20));
    for _ in 0..40 {
        let lo = IVec3::new(
            rng.gen_range(0..480),
            rng.gen_range(0..370),
            rng.gen_range(20..270),
        );
        let size = IVec3::new(
            rng.gen_range(4..120),
            rng.gen_range(4..120),
            rng.gen_range(4..120),
        );
        shelled_box(&mut g, lo, lo + size);
    }
    g
}

/// Uniform random voxel indices over the grid.
fn random_queries(rng: &mut ChaCha8Rng) -> Vec<IVec3> {
    (0..QUERIES)
        .map(|_| {
            IVec3::new(
                rng.gen_range(0..DIMS[0] as i32),
                rng.gen_range(0..DIMS[1] as i32),
                rng.gen_range(0..DIMS[2] as i32),
            )
        })
        .collect()
}

/// A coherent sweep: x fastest through a 48³ cube straddling the floor's top surface, repeated.
fn sweep_queries() -> Vec<IVec3> {
    let base = IVec3::new(200, 150, 0);
    (0..QUERIES)
        .map(|i| {
            let i = (i % (48 * 48 * 48)) as i32;
            base + IVec3::new(i % 48, i / 48 % 48, i / (48 * 48))
        })
        .collect()
}

fn sum_lookups(lookup: &impl VoxelLookup, queries: &[IVec3]) -> u64 {
    queries.iter().map(|&q| lookup.get(q) as u64).sum()
}

fn bench_voxmap(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(1999);
    let dense = scene(&mut rng);
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default()).expect("valid scene");
    let nodes = tree.node_counts();
    eprintln!(
        "voxmap: {} voxels, counts {:?}; dense {} B (1 B/voxel), 2-bit dense {} B, 512-tree {} B \
         ({} leaves, {} lower, {} upper)",
        dense.spec.voxel_count(),
        tree.counts(),
        dense.data.len(),
        tree.dense_equivalent_bytes(),
        tree.memory_bytes(),
        nodes.leaves,
        nodes.lower,
        nodes.upper
    );
    for (name, queries) in [
        ("random", random_queries(&mut rng)),
        ("sweep", sweep_queries()),
    ] {
        let want = sum_lookups(&dense, &queries);
        assert_eq!(
            sum_lookups(&tree, &queries),
            want,
            "tree disagrees with dense"
        );
        let mut group = c.benchmark_group(format!("get_1M_{name}"));
        group.bench_function("dense", |b| {
            b.iter(|| sum_lookups(black_box(&dense), &queries))
        });
        group.bench_function("tree512", |b| {
            b.iter(|| sum_lookups(black_box(&tree), &queries))
        });
        group.bench_function("tree512_accessor", |b| {
            b.iter(|| {
                let mut acc = black_box(&tree).accessor();
                queries.iter().map(|&q| acc.get(q) as u64).sum::<u64>()
            })
        });
        group.finish();
    }
    let mut group = c.benchmark_group("from_dense_61M");
    for n in [3u8, 1, 5] {
        group.bench_function(format!("N{n}"), |b| {
            b.iter(|| VoxelTree::from_dense(black_box(&dense), TreeConfig::uniform(n)))
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_secs(3));
    targets = bench_voxmap
}
criterion_main!(benches);
