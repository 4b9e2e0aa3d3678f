//! `vps inspect`: statistics of a `.vmap` or `.vshell` file (chosen by the file's magic bytes).

use crate::cli::InspectArgs;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::io::Read;
use vps_app::output::{hex, mib, print_summary, KindCounts, ShellFigures};
use vps_voxmap::VoxelTree;

#[derive(Serialize)]
struct VoxmapInfo {
    file: String,
    kind: &'static str,
    voxel_size_m: f64,
    origin_m: [f64; 3],
    max_corner_m: [f64; 3],
    dims: [u32; 3],
    voxel_count: u64,
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
    /// The signed-distance band of the `distance` force model, when the map carries one.
    #[serde(skip_serializing_if = "Option::is_none")]
    distance_band: Option<BandInfo>,
    /// Present when a dense copy of the grid would not fit the memory budget (an absurd grid).
    #[serde(skip_serializing_if = "Option::is_none")]
    note: Option<String>,
}

/// A map's signed-distance band (`vps_voxmap::distance`).
#[derive(Serialize)]
struct BandInfo {
    /// The stand-off baked into the band (m).
    standoff_m: f64,
    /// Cubes of 8³ voxels stored (near a surface).
    bricks: usize,
    /// The band's memory: directory and bricks (bytes).
    band_bytes: usize,
}

/// The note for a grid whose dense copy (`dense_bytes`) exceeds the default memory budget.
fn dense_note(dense_bytes: u64) -> Option<String> {
    let budget = vps_voxelize::default_memory_budget();
    (dense_bytes > budget).then(|| {
        format!(
            "a dense copy of this grid ({}) would exceed the memory budget ({}, half of physical \
             memory); vps reads such maps from the tree only",
            mib(dense_bytes as f64),
            mib(budget as f64)
        )
    })
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
    method: String,
    #[serde(flatten)]
    figures: ShellFigures,
}

/// Runs the command.
pub fn run(args: &InspectArgs) -> Result<()> {
    let name = args.file.display();
    let (mut file, len) =
        vps_files::open_regular(&args.file).with_context(|| format!("opening {name}"))?;
    if len < 8 {
        bail!(
            "{name}: the file is {} ({len} bytes; a .vmap or .vshell starts with 8 magic bytes)",
            if len == 0 { "empty" } else { "truncated" }
        );
    }
    let mut magic = [0u8; 8];
    file.read_exact(&mut magic)
        .with_context(|| format!("reading {name}"))?;
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
        voxel_count: spec.voxel_count(),
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
        distance_band: tree.distance_band().map(|band| BandInfo {
            standoff_m: band.standoff_m(),
            bricks: band.brick_count(),
            band_bytes: band.memory_bytes(),
        }),
        note: dense_note(tree.dense_equivalent_bytes()),
    };
    print_summary(&info, args.json)
}

impl std::fmt::Display for VoxmapInfo {
    /// The file's figures, one topic per line (no final newline).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "{} (voxmap)", self.file)?;
        writeln!(
            f,
            "  voxel size {} m, dims {:?} ({} voxels), log2 dims {:?}, {}-bit voxels",
            self.voxel_size_m, self.dims, self.voxel_count, self.tree_log2_dims, self.width_bits
        )?;
        writeln!(
            f,
            "  bounds {:?} .. {:?} m",
            self.origin_m, self.max_corner_m
        )?;
        writeln!(f, "  {}", self.counts)?;
        if self.width_bits > 2 {
            let list: Vec<String> = self
                .layers
                .iter()
                .filter(|l| l.kind == "surface" || l.kind == "proximity")
                .map(|l| format!("{} {}: {}", l.kind, l.layer, l.voxels))
                .collect();
            writeln!(f, "  layers: {}", list.join(", "))?;
        }
        writeln!(
            f,
            "  tree memory {} ({} leaves, {} lower, {} upper nodes); dense equivalent {}",
            mib(self.tree_bytes as f64),
            self.leaves,
            self.lower_nodes,
            self.upper_nodes,
            mib(self.dense_equivalent_bytes as f64)
        )?;
        writeln!(
            f,
            "  lookup directory {} (built when loaded, not stored)",
            mib(self.directory_bytes as f64)
        )?;
        if let Some(band) = &self.distance_band {
            writeln!(
                f,
                "  distance band (force_model = \"distance\"): stand-off {} mm, {} cubes of 8³ \
                 voxels stored, {}",
                band.standoff_m * 1e3,
                band.bricks,
                mib(band.band_bytes as f64)
            )?;
        }
        write!(f, "  content hash {}", self.hash)?;
        if let Some(note) = &self.note {
            write!(f, "\n  note: {note}")?;
        }
        Ok(())
    }
}

fn inspect_shell(args: &InspectArgs) -> Result<()> {
    let shell = vps_voxmap::file::load_shell(&args.file)?;
    let info = ShellInfo {
        file: args.file.display().to_string(),
        kind: "point-shell",
        method: format!("{:?}", shell.method),
        figures: ShellFigures::of(&shell),
    };
    print_summary(&info, args.json)
}

impl std::fmt::Display for ShellInfo {
    /// "FILE (point shell, METHOD): FIGURES".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} (point shell, {}): {}",
            self.file, self.method, self.figures
        )
    }
}
