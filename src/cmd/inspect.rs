//! `vps inspect`: statistics of a `.vmap` or `.vshell` file (chosen by the file's magic bytes).

use super::output::{hex, mib, print_json};
use crate::cli::InspectArgs;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::io::Read;
use vps_voxmap::{Voxel, VoxelTree};

/// Voxel counts by kind.
#[derive(Serialize, Clone, Copy)]
pub struct KindCounts {
    /// Free voxels.
    pub free: u64,
    /// Interior voxels.
    pub interior: u64,
    /// Surface (force layer) voxels.
    pub surface: u64,
    /// Proximity voxels.
    pub proximity: u64,
}

impl From<[u64; 4]> for KindCounts {
    fn from(c: [u64; 4]) -> Self {
        Self {
            free: c[Voxel::Free as usize],
            interior: c[Voxel::Interior as usize],
            surface: c[Voxel::Surface as usize],
            proximity: c[Voxel::Proximity as usize],
        }
    }
}

impl std::fmt::Display for KindCounts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "voxels: free {}, interior {}, surface {}, proximity {}",
            self.free, self.interior, self.surface, self.proximity
        )
    }
}

#[derive(Serialize)]
struct VoxmapInfo {
    file: String,
    kind: &'static str,
    voxel_size_m: f64,
    origin_m: [f64; 3],
    max_corner_m: [f64; 3],
    dims: [u32; 3],
    tree_log2_dims: [u8; 3],
    width_bits: u32,
    counts: KindCounts,
    layers: Vec<LayerCount>,
    tree_bytes: usize,
    /// The lookup directory built beside the tree when loaded (not part of `tree_bytes`).
    directory_bytes: usize,
    dense_equivalent_bytes: u64,
    leaves: usize,
    lower_nodes: usize,
    upper_nodes: usize,
    hash: String,
}

/// Voxels of one kind and distance layer.
#[derive(Serialize)]
struct LayerCount {
    kind: &'static str,
    layer: u8,
    voxels: u64,
}

#[derive(Serialize)]
struct ShellInfo {
    file: String,
    kind: &'static str,
    points: usize,
    voxel_size_m: f64,
    method: String,
    volume_m3: f64,
    center_of_mass_m: [f64; 3],
    max_radius_m: f64,
}

/// Runs the command.
pub fn run(args: &InspectArgs) -> Result<()> {
    let mut magic = [0u8; 8];
    std::fs::File::open(&args.file)
        .and_then(|mut f| f.read_exact(&mut magic))
        .with_context(|| format!("reading {}", args.file.display()))?;
    match &magic {
        b"VPSVMAP\0" => inspect_voxmap(args),
        b"VPSSHEL\0" => inspect_shell(args),
        _ => bail!(
            "{}: not a vps file (unknown magic bytes)",
            args.file.display()
        ),
    }
}

fn inspect_voxmap(args: &InspectArgs) -> Result<()> {
    let tree: VoxelTree = vps_voxmap::file::load_voxmap(&args.file)?;
    let spec = *tree.spec();
    let nodes = tree.node_counts();
    let info = VoxmapInfo {
        file: args.file.display().to_string(),
        kind: "voxmap",
        voxel_size_m: spec.voxel_size,
        origin_m: spec.origin.to_array(),
        max_corner_m: spec.max_corner().to_array(),
        dims: spec.dims,
        tree_log2_dims: tree.config().log2_dims,
        width_bits: tree.width().bits(),
        counts: tree.counts().into(),
        layers: tree
            .layer_counts()
            .into_iter()
            .map(|(v, voxels)| LayerCount {
                kind: v.kind.name(),
                layer: v.layer,
                voxels,
            })
            .collect(),
        tree_bytes: tree.memory_bytes(),
        directory_bytes: tree.directory_bytes(),
        dense_equivalent_bytes: tree.dense_equivalent_bytes(),
        leaves: nodes.leaves,
        lower_nodes: nodes.lower,
        upper_nodes: nodes.upper,
        hash: hex(&tree.content_hash()),
    };
    if args.json {
        return print_json(&info);
    }
    println!("{} (voxmap)", info.file);
    println!(
        "  voxel size {} m, dims {:?}, log2 dims {:?}, {}-bit voxels",
        info.voxel_size_m, info.dims, info.tree_log2_dims, info.width_bits
    );
    println!("  bounds {:?} .. {:?} m", info.origin_m, info.max_corner_m);
    println!("  {}", info.counts);
    if info.width_bits > 2 {
        let list: Vec<String> = info
            .layers
            .iter()
            .filter(|l| l.kind == "surface" || l.kind == "proximity")
            .map(|l| format!("{} {}: {}", l.kind, l.layer, l.voxels))
            .collect();
        println!("  layers: {}", list.join(", "));
    }
    println!(
        "  tree memory {} ({} leaves, {} lower, {} upper nodes); dense equivalent {}",
        mib(info.tree_bytes as f64),
        info.leaves,
        info.lower_nodes,
        info.upper_nodes,
        mib(info.dense_equivalent_bytes as f64)
    );
    println!(
        "  lookup directory {} (built when loaded, not stored)",
        mib(info.directory_bytes as f64)
    );
    println!("  content hash {}", info.hash);
    Ok(())
}

fn inspect_shell(args: &InspectArgs) -> Result<()> {
    let shell = vps_voxmap::file::load_shell(&args.file)?;
    let info = ShellInfo {
        file: args.file.display().to_string(),
        kind: "point-shell",
        points: shell.len(),
        voxel_size_m: shell.voxel_size,
        method: format!("{:?}", shell.method),
        volume_m3: shell.mass.volume,
        center_of_mass_m: shell.mass.center_of_mass.to_array(),
        max_radius_m: shell.max_radius(),
    };
    if args.json {
        return print_json(&info);
    }
    println!(
        "{} (point shell): {} points ({}), voxel size {} m, volume {:.3e} m³, max radius {:.4} m",
        info.file, info.points, info.method, info.voxel_size_m, info.volume_m3, info.max_radius_m
    );
    Ok(())
}
