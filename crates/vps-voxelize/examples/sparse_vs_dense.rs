//! Bay at 5 mm (or `VOXEL_SIZE` m): sparse pipeline first (its own peak RSS), then the dense
//! reference plus `VoxelTree::from_dense`; medians of `REPEAT` (default 3) runs, widths 4 and 8.
//! Run: `cargo run --release -p vps-voxelize --example sparse_vs_dense`.

use std::time::Instant;
use vps_voxelize::{voxelize_tree, voxelize_with_stats, VoxelizeOptions};
use vps_voxmap::{TreeConfig, VoxelTree, VoxelWidth};

fn peak_rss_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kib: f64 = status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))
        .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        .unwrap_or(0.0);
    kib / 1024.0
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let s: f64 = std::env::var("VOXEL_SIZE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0.005);
    let repeat: usize = std::env::var("REPEAT")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(3);
    let bay = vps_mesh::builtin::aircraft_bay();
    println!("bay loaded, rss {:.0} MB", peak_rss_mb());
    let opts = VoxelizeOptions {
        voxel_size: s,
        ..VoxelizeOptions::default()
    };
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeat {
        let r = voxelize_tree(std::slice::from_ref(&bay), &opts, TreeConfig::default()).unwrap();
        times.push(r.1.total_ms);
        last = Some(r);
    }
    let (sparse, st) = last.unwrap();
    let sparse_ms = median(times.clone());
    println!(
        "sparse 2-bit: median {sparse_ms:.0} ms {times:.0?}; scan {:.0} fill {:.0} merge {:.0} offset {:.0} tree {:.0} ms; active chunks {}; peak work {:.1} MB; tree {} B; peak RSS so far {:.0} MB",
        st.scan_ms, st.fill_ms, st.merge_ms, st.offset_ms, st.output_ms, st.active_chunks,
        st.peak_work_bytes as f64 / 1e6, sparse.memory_bytes(), peak_rss_mb()
    );
    for width in [VoxelWidth::Four, VoxelWidth::Eight] {
        let o = VoxelizeOptions { width, ..opts };
        let (t, st) = voxelize_tree(std::slice::from_ref(&bay), &o, TreeConfig::default()).unwrap();
        println!(
            "sparse {}-bit: {:.0} ms, tree {} B, peak work {:.1} MB, layer entries {}",
            width.bits(),
            st.total_ms,
            t.memory_bytes(),
            st.peak_work_bytes as f64 / 1e6,
            t.layer_counts().len()
        );
    }
    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeat {
        let t0 = Instant::now();
        let (dense, st) = voxelize_with_stats(std::slice::from_ref(&bay), &opts).unwrap();
        let tree = VoxelTree::from_dense(&dense, TreeConfig::default()).unwrap();
        times.push(t0.elapsed().as_secs_f64() * 1e3);
        last = Some((tree, st));
    }
    let (dense_tree, st) = last.unwrap();
    let dense_ms = median(times.clone());
    println!(
        "dense + from_dense: median {dense_ms:.0} ms {times:.0?} (voxelize {:.0} ms); planned work {:.1} MB; peak RSS {:.0} MB",
        st.total_ms, st.peak_work_bytes as f64 / 1e6, peak_rss_mb()
    );
    println!(
        "same tree: {}; sparse/dense time {:.2}",
        dense_tree.content_hash() == sparse.content_hash(),
        sparse_ms / dense_ms
    );
}
