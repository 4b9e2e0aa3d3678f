//! `vps voxelize`: mesh → `.vmap`.

use crate::cli::VoxelizeArgs;
use crate::mesh_arg::{load_mesh_for, units_hint};
use anyhow::{bail, Context, Result};
use glam::DVec3;
use serde::Serialize;
use vps_app::output::{hex, mib, print_summary};
use vps_mesh::Aabb;
use vps_voxelize::{voxelize_tree, VoxelizeOptions};
use vps_voxmap::{TreeConfig, VoxelWidth};

/// What `vps voxelize --json` prints.
#[derive(Serialize)]
struct VoxelizeSummary {
    source: String,
    output: String,
    triangles: usize,
    degenerate_dropped: usize,
    /// Every edge has two triangles running it opposite ways: the mesh bounds a solid.
    closed: bool,
    health: vps_mesh::MeshHealth,
    voxel_size_m: f64,
    dims: [u32; 3],
    width_bits: u32,
    workspace_m: Option<[f64; 6]>,
    voxelize_ms: f64,
    tree_ms: f64,
    tree_bytes: usize,
    peak_work_bytes: u64,
    counts: vps_app::output::KindCounts,
    hash: String,
}

/// Runs the command.
pub fn run(args: &VoxelizeArgs) -> Result<()> {
    let scene = load_mesh_for(&args.mesh, &args.build, args.voxel_size)?;
    let health = vps_mesh::mesh_health(&scene.mesh);
    let Some(width) = VoxelWidth::from_bits(args.width) else {
        bail!("--width {}: must be 2, 4 or 8", args.width);
    };
    let workspace = args.workspace.as_deref().map(parse_workspace).transpose()?;
    let opts = VoxelizeOptions {
        voxel_size: args.voxel_size,
        offset_layers: args.offset,
        progress: !args.build.json,
        width,
        workspace,
        ..VoxelizeOptions::default()
    };
    let opts = VoxelizeOptions {
        max_memory_bytes: args.build.max_memory.unwrap_or(opts.max_memory_bytes),
        ..opts
    };
    let (tree, stats) = voxelize_tree(
        std::slice::from_ref(&scene.mesh),
        &opts,
        TreeConfig::uniform(args.tree_n),
    )
    .with_context(|| {
        format!(
            "voxelizing {}{}",
            scene.source,
            units_hint(&scene, args.build.units)
        )
    })?;
    let tree_ms = stats.output_ms;
    vps_voxmap::file::save_voxmap(&tree, &args.build.output)?;
    let summary = VoxelizeSummary {
        source: scene.source,
        output: args.build.output.display().to_string(),
        triangles: stats.triangles,
        degenerate_dropped: scene.degenerate_dropped,
        closed: health.closed(),
        health,
        voxel_size_m: args.voxel_size,
        dims: stats.dims,
        width_bits: width.bits(),
        workspace_m: workspace.map(|w| {
            let (a, b) = (w.min.to_array(), w.max.to_array());
            [a[0], a[1], a[2], b[0], b[1], b[2]]
        }),
        voxelize_ms: stats.total_ms,
        tree_ms,
        tree_bytes: tree.memory_bytes(),
        peak_work_bytes: stats.peak_work_bytes,
        counts: vps_app::output::KindCounts::from(tree.counts()),
        hash: hex(&tree.content_hash()),
    };
    print_summary(&summary, args.build.json)
}

impl std::fmt::Display for VoxelizeSummary {
    /// What was voxelized, the mesh's health, the counts, the memory and the hash, on five lines (no final newline).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "{}: {} triangles → {:?} {}-bit voxels of {} m in {:.0} ms (of which tree {:.0} ms)",
            self.source,
            self.triangles,
            self.dims,
            self.width_bits,
            self.voxel_size_m,
            self.voxelize_ms,
            self.tree_ms
        )?;
        let leak = if self.health.boundary_edges > 0 {
            ": where the flood fill from outside ran in through a gap, the inside is found by \
             winding number (docs/voxelize.md, Open and leaky meshes)"
        } else {
            ""
        };
        writeln!(f, "mesh: {}{leak}", self.health.summary())?;
        writeln!(f, "{}", self.counts)?;
        writeln!(
            f,
            "tree memory {}, voxelizer peak working memory {}, written to {}",
            mib(self.tree_bytes as f64),
            mib(self.peak_work_bytes as f64),
            self.output
        )?;
        write!(f, "content hash {}", self.hash)
    }
}

/// Parses `MINX,MINY,MINZ,MAXX,MAXY,MAXZ` (m) into a box.
fn parse_workspace(text: &str) -> Result<Aabb> {
    let v: Vec<f64> = text
        .split(',')
        .map(|t| t.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--workspace {text:?}: expected six numbers (m)"))?;
    if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
        bail!(
            "--workspace {text:?}: expected six finite numbers MINX,MINY,MINZ,MAXX,MAXY,MAXZ (m)"
        );
    }
    let (min, max) = (DVec3::new(v[0], v[1], v[2]), DVec3::new(v[3], v[4], v[5]));
    if min.cmpgt(max).any() {
        bail!("--workspace {text:?}: a minimum exceeds its maximum");
    }
    Ok(Aabb { min, max })
}
