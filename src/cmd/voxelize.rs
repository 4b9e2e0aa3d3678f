//! `vps voxelize`: mesh → `.vmap`.

use super::output::{hex, mib, print_json};
use crate::cli::VoxelizeArgs;
use crate::scene;
use anyhow::{Context, Result};
use serde::Serialize;
use vps_voxelize::{voxelize_with_stats, VoxelizeOptions};
use vps_voxmap::{TreeConfig, VoxelTree};

/// What `vps voxelize --json` prints.
#[derive(Serialize)]
struct VoxelizeSummary {
    source: String,
    output: String,
    triangles: usize,
    degenerate_dropped: usize,
    voxel_size_m: f64,
    dims: [u32; 3],
    voxelize_ms: f64,
    tree_ms: f64,
    tree_bytes: usize,
    counts: super::inspect::KindCounts,
    hash: String,
}

/// Runs the command.
pub fn run(args: &VoxelizeArgs) -> Result<()> {
    let scene = scene::load(&args.mesh)?;
    let opts = VoxelizeOptions {
        voxel_size: args.voxel_size,
        offset_layers: args.offset,
        progress: !args.json,
        ..VoxelizeOptions::default()
    };
    let (dense, stats) = voxelize_with_stats(std::slice::from_ref(&scene.mesh), &opts)
        .with_context(|| format!("voxelizing {}", scene.source))?;
    let start = std::time::Instant::now();
    let tree = VoxelTree::from_dense(&dense, TreeConfig::uniform(args.tree_n))?;
    let tree_ms = start.elapsed().as_secs_f64() * 1e3;
    drop(dense);
    vps_voxmap::file::save_voxmap(&tree, &args.output)?;
    let summary = VoxelizeSummary {
        source: scene.source,
        output: args.output.display().to_string(),
        triangles: stats.triangles,
        degenerate_dropped: scene.degenerate_dropped,
        voxel_size_m: args.voxel_size,
        dims: stats.dims,
        voxelize_ms: stats.total_ms,
        tree_ms,
        tree_bytes: tree.memory_bytes(),
        counts: super::inspect::KindCounts::from(tree.counts()),
        hash: hex(&tree.content_hash()),
    };
    if args.json {
        return print_json(&summary);
    }
    println!(
        "{}: {} triangles → {:?} voxels of {} m in {:.0} ms (+ tree {:.0} ms)",
        summary.source,
        summary.triangles,
        summary.dims,
        summary.voxel_size_m,
        summary.voxelize_ms,
        summary.tree_ms
    );
    println!("{}", summary.counts);
    println!(
        "tree memory {}, written to {}",
        mib(summary.tree_bytes as f64),
        summary.output
    );
    println!("content hash {}", summary.hash);
    Ok(())
}
