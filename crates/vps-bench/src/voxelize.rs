//! `vps bench voxelize` and `vps bench tree-memory`: voxelization time, peak memory, voxmap memory,
//! tree lookup cost against the dense grid, and the paper's Figure 6 (memory against N).

use anyhow::{Context, Result};
use glam::IVec3;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;
use vps_app::output::print_report;
use vps_session::mesh_source;
use vps_voxelize::{voxelize_tree, voxelize_with_stats, VoxelizeOptions, VoxelizeStats};
use vps_voxmap::{DenseGrid, TreeConfig, VoxelLookup, VoxelTree, VoxelWidth};

#[derive(Serialize)]
struct VoxelizeBench {
    source: String,
    triangles: usize,
    voxel_size_m: f64,
    dims: [u32; 3],
    threads: usize,
    repeats: u32,
    voxelize_ms_median: f64,
    voxelize_ms_all: Vec<f64>,
    phases_ms_last: Phases,
    tree_build_ms: f64,
    tree_bytes: usize,
    dense_one_byte_bytes: u64,
    dense_two_bit_bytes: u64,
    peak_rss_bytes: Option<u64>,
    lookup_queries: usize,
    tree_ns_per_get: f64,
    dense_ns_per_get: f64,
    tree_over_dense: f64,
    /// The sparse (chunked) pipeline, measured first in the same process.
    sparse: SparseBench,
}

/// Figures of the sparse pipeline (`voxelize_tree`), 2-bit, and of its 4- and 8-bit maps.
#[derive(Serialize)]
struct SparseBench {
    /// Median wall time of the whole 2-bit voxelization including the tree build (ms).
    voxelize_ms_median: f64,
    voxelize_ms_all: Vec<f64>,
    phases_ms_last: Phases,
    /// Chunks where Proximity and offset were computed.
    active_chunks: usize,
    /// The voxelizer's own count of its peak working bytes.
    peak_work_bytes: u64,
    /// Peak RSS of the process after the sparse runs, before the dense ones.
    peak_rss_bytes: Option<u64>,
    tree_bytes: usize,
    /// True when the sparse tree's content hash equals the dense pipeline's.
    same_tree_as_dense: bool,
    /// Dense median over sparse median (both include the tree build).
    dense_over_sparse_time: f64,
    /// Wider voxels: one run each.
    widths: Vec<WidthBench>,
    /// The signed-distance band (the `distance` force model, the default stand-off of half a voxel) built on the
    /// 4-bit map, against that map.
    distance_band: DistanceBandBench,
}

/// The distance band's cost beside the 4-bit map it belongs to.
#[derive(Serialize)]
struct DistanceBandBench {
    /// Time to build the band from the 4-bit tree, the inside map its voxelization kept and the
    /// triangles (ms), as a session builds it.
    build_ms: f64,
    /// Bricks (cubes of 8³ voxels stored near the surface).
    bricks: usize,
    /// The band's memory (bytes: directory and bricks).
    band_bytes: usize,
    /// The 4-bit map's tree memory (bytes).
    four_bit_tree_bytes: usize,
    /// (tree + band) over the 4-bit tree alone: the distance voxmap's memory relative to the
    /// 4-bit map.
    memory_ratio: f64,
    /// (4-bit voxelization + band build) over the 4-bit voxelization alone.
    build_time_ratio: f64,
    /// Where the band build's time went (ms).
    phases_ms: BandPhases,
}

/// [`vps_voxelize::distance::BandBuildPhases`] (ms); `inside_map` is 0 here (the voxelization's
/// own map serves).
#[derive(Serialize)]
struct BandPhases {
    lists: f64,
    exact_scene: f64,
    inside_map: f64,
    scene_and_inside: f64,
    samples: f64,
    assemble: f64,
}

impl From<vps_voxelize::distance::BandBuildPhases> for BandPhases {
    fn from(p: vps_voxelize::distance::BandBuildPhases) -> BandPhases {
        BandPhases {
            lists: p.lists_ms,
            exact_scene: p.exact_scene_ms,
            inside_map: p.inside_map_ms,
            scene_and_inside: p.scene_and_inside_ms,
            samples: p.samples_ms,
            assemble: p.assemble_ms,
        }
    }
}

#[derive(Serialize)]
struct WidthBench {
    bits: u32,
    voxelize_ms: f64,
    tree_bytes: usize,
    peak_work_bytes: u64,
    surface_layers: usize,
    proximity_layers: usize,
}

#[derive(Serialize)]
struct Phases {
    scan: f64,
    fill: f64,
    merge: f64,
    offset: f64,
    output: f64,
}

/// Peak resident set size of this process (bytes), from /proc (Linux only).
fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

fn voxelize_once(
    mesh: &vps_mesh::TriMesh,
    voxel_size: f64,
) -> Result<(DenseGrid, vps_voxelize::VoxelizeStats)> {
    let opts = VoxelizeOptions {
        voxel_size,
        ..VoxelizeOptions::default()
    };
    Ok(voxelize_with_stats(std::slice::from_ref(mesh), &opts)?)
}

/// Mean nanoseconds per `get` over `queries`, best of three passes.
fn ns_per_get<L: VoxelLookup>(map: &L, queries: &[IVec3]) -> f64 {
    (0..3)
        .map(|_| {
            let t = Instant::now();
            let mut acc = 0u32;
            for &q in queries {
                acc = acc.wrapping_add(black_box(map).get(q) as u32);
            }
            black_box(acc);
            t.elapsed().as_secs_f64() * 1e9 / queries.len() as f64
        })
        .fold(f64::INFINITY, f64::min)
}

/// Random in-grid query indices, half of them next to non-Free voxels (where contacts happen).
fn lookup_queries(dense: &DenseGrid, count: usize) -> Vec<IVec3> {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let d = dense.spec.dims;
    let busy: Vec<usize> = dense
        .data
        .iter()
        .enumerate()
        .filter(|(_, &v)| v != 0)
        .map(|(i, _)| i)
        .step_by(97)
        .collect();
    (0..count)
        .map(|k| {
            if k % 2 == 0 && !busy.is_empty() {
                let i = busy[rng.gen_range(0..busy.len())];
                let (x, y, z) = (
                    i % d[0] as usize,
                    (i / d[0] as usize) % d[1] as usize,
                    i / (d[0] * d[1]) as usize,
                );
                IVec3::new(x as i32, y as i32, z as i32)
            } else {
                IVec3::new(
                    rng.gen_range(0..d[0] as i32),
                    rng.gen_range(0..d[1] as i32),
                    rng.gen_range(0..d[2] as i32),
                )
            }
        })
        .collect()
}

fn phases(stats: &VoxelizeStats) -> Phases {
    Phases {
        scan: stats.scan_ms,
        fill: stats.fill_ms,
        merge: stats.merge_ms,
        offset: stats.offset_ms,
        output: stats.output_ms,
    }
}

fn median(times: &[f64]) -> f64 {
    let mut sorted = times.to_vec();
    sorted.sort_by(f64::total_cmp);
    sorted[sorted.len() / 2]
}

fn sparse_once(
    mesh: &vps_mesh::TriMesh,
    voxel_size: f64,
    width: VoxelWidth,
) -> Result<(VoxelTree, VoxelizeStats)> {
    let opts = VoxelizeOptions {
        voxel_size,
        width,
        ..VoxelizeOptions::default()
    };
    Ok(voxelize_tree(
        std::slice::from_ref(mesh),
        &opts,
        TreeConfig::default(),
    )?)
}

/// `vps bench voxelize`: prints JSON. The sparse pipeline runs first, so the peak RSS read after it
/// is its own; then the dense reference pipeline (with the lookup benchmark).
pub fn run_voxelize(source: &str, voxel_size: f64, repeat: u32, json: bool) -> Result<()> {
    let scene = mesh_source::load(source)?;
    let mut sparse_times = Vec::new();
    let mut sparse_last = None;
    for _ in 0..repeat.max(1) {
        let (tree, stats) = sparse_once(&scene.mesh, voxel_size, VoxelWidth::Two)
            .with_context(|| format!("voxelizing {} (sparse)", scene.source))?;
        sparse_times.push(stats.total_ms);
        sparse_last = Some((tree, stats));
    }
    let (sparse_tree, sparse_stats) = sparse_last.expect("at least one repetition");
    let sparse_rss = peak_rss_bytes();
    let mut widths = Vec::new();
    let mut distance_band = None;
    for width in [VoxelWidth::Four, VoxelWidth::Eight] {
        // The 4-bit run as a session makes a distance voxmap: the band takes its signs from the
        // inside map the voxelization kept (its peak working bytes include that map).
        let (tree, stats, inside) = if width == VoxelWidth::Four {
            let opts = VoxelizeOptions {
                voxel_size,
                width,
                ..VoxelizeOptions::default()
            };
            let (tree, stats, inside) = vps_voxelize::voxelize_tree_keeping_inside(
                std::slice::from_ref(&scene.mesh),
                &opts,
                TreeConfig::default(),
            )?;
            (tree, stats, Some(inside))
        } else {
            let (tree, stats) = sparse_once(&scene.mesh, voxel_size, width)?;
            (tree, stats, None)
        };
        if let Some(inside) = &inside {
            let t = Instant::now();
            let (band, phases_ms) = vps_voxelize::distance::distance_band_with_inside(
                &tree,
                inside,
                std::slice::from_ref(&scene.mesh),
                voxel_size * vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS,
                vps_voxelize::default_memory_budget(),
            )?;
            let build_ms = t.elapsed().as_secs_f64() * 1e3;
            distance_band = Some(DistanceBandBench {
                build_ms,
                bricks: band.brick_count(),
                band_bytes: band.memory_bytes(),
                four_bit_tree_bytes: tree.memory_bytes(),
                memory_ratio: (tree.memory_bytes() + band.memory_bytes()) as f64
                    / tree.memory_bytes() as f64,
                build_time_ratio: (stats.total_ms + build_ms) / stats.total_ms,
                phases_ms: phases_ms.into(),
            });
        }
        let layers = tree.layer_counts();
        let count = |k: vps_voxmap::Voxel| layers.iter().filter(|(v, _)| v.kind == k).count();
        widths.push(WidthBench {
            bits: width.bits(),
            voxelize_ms: stats.total_ms,
            tree_bytes: tree.memory_bytes(),
            peak_work_bytes: stats.peak_work_bytes,
            surface_layers: count(vps_voxmap::Voxel::Surface),
            proximity_layers: count(vps_voxmap::Voxel::Proximity),
        });
    }

    let mut times = Vec::new();
    let mut last = None;
    for _ in 0..repeat.max(1) {
        let (dense, stats) = voxelize_once(&scene.mesh, voxel_size)
            .with_context(|| format!("voxelizing {}", scene.source))?;
        times.push(stats.total_ms);
        last = Some((dense, stats));
    }
    let (dense, stats) = last.expect("at least one repetition");
    let t = Instant::now();
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default())?;
    let tree_build_ms = t.elapsed().as_secs_f64() * 1e3;
    let dense_median = median(&times);
    let sparse_median = median(&sparse_times);
    let queries = lookup_queries(&dense, 4_000_000);
    let dense_ns = ns_per_get(&dense, &queries);
    let tree_ns = ns_per_get(&tree, &queries);
    let report = VoxelizeBench {
        source: scene.source,
        triangles: stats.triangles,
        voxel_size_m: voxel_size,
        dims: stats.dims,
        threads: rayon::current_num_threads(),
        repeats: repeat.max(1),
        voxelize_ms_median: dense_median,
        voxelize_ms_all: times,
        phases_ms_last: phases(&stats),
        tree_build_ms,
        tree_bytes: tree.memory_bytes(),
        dense_one_byte_bytes: dense.spec.voxel_count(),
        dense_two_bit_bytes: tree.dense_equivalent_bytes(),
        peak_rss_bytes: peak_rss_bytes(),
        lookup_queries: queries.len(),
        tree_ns_per_get: tree_ns,
        dense_ns_per_get: dense_ns,
        tree_over_dense: tree_ns / dense_ns,
        sparse: SparseBench {
            voxelize_ms_median: sparse_median,
            voxelize_ms_all: sparse_times,
            phases_ms_last: phases(&sparse_stats),
            active_chunks: sparse_stats.active_chunks,
            peak_work_bytes: sparse_stats.peak_work_bytes,
            peak_rss_bytes: sparse_rss,
            tree_bytes: sparse_tree.memory_bytes(),
            same_tree_as_dense: sparse_tree.content_hash() == tree.content_hash(),
            dense_over_sparse_time: (dense_median + tree_build_ms) / sparse_median,
            widths,
            distance_band: distance_band.context("the 4-bit run")?,
        },
    };
    print_report(
        "bench voxelize: time, peak memory and voxmap memory of voxelizing a scene",
        &report,
        json,
    )
}

#[derive(Serialize)]
struct TreeMemoryRow {
    n: u8,
    children_per_node: u64,
    tree_bytes: usize,
    leaves: usize,
    lower_nodes: usize,
    upper_nodes: usize,
}

#[derive(Serialize)]
struct TreeMemoryReport {
    source: String,
    voxel_size_m: f64,
    dims: [u32; 3],
    dense_two_bit_bytes: u64,
    rows: Vec<TreeMemoryRow>,
}

/// `vps bench tree-memory`: the paper's Figure 6 study; prints JSON, optionally plots SVG.
pub fn run_tree_memory(
    source: &str,
    voxel_size: f64,
    plot: Option<&Path>,
    json: bool,
) -> Result<()> {
    let scene = mesh_source::load(source)?;
    let (dense, stats) = voxelize_once(&scene.mesh, voxel_size)?;
    let mut rows = Vec::new();
    let mut dense_two_bit_bytes = 0;
    for n in 1..=5u8 {
        let tree = VoxelTree::from_dense(&dense, TreeConfig::uniform(n))?;
        let nodes = tree.node_counts();
        dense_two_bit_bytes = tree.dense_equivalent_bytes();
        rows.push(TreeMemoryRow {
            n,
            children_per_node: 1u64 << (3 * n as u64),
            tree_bytes: tree.memory_bytes(),
            leaves: nodes.leaves,
            lower_nodes: nodes.lower,
            upper_nodes: nodes.upper,
        });
    }
    let report = TreeMemoryReport {
        source: scene.source,
        voxel_size_m: voxel_size,
        dims: stats.dims,
        dense_two_bit_bytes,
        rows,
    };
    if let Some(path) = plot {
        plot_tree_memory(&report, path)?;
    }
    print_report(
        "bench tree-memory: total tree memory against N (the paper's Figure 6)",
        &report,
        json,
    )
}

fn plot_tree_memory(report: &TreeMemoryReport, path: &Path) -> Result<()> {
    use plotters::prelude::*;
    let mib: Vec<(f64, f64)> = report
        .rows
        .iter()
        .map(|r| (r.n as f64, r.tree_bytes as f64 / (1024.0 * 1024.0)))
        .collect();
    let top = mib.iter().map(|p| p.1).fold(0.0, f64::max) * 1.15;
    let root = SVGBackend::new(path, (640, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!(
                "Voxmap memory of {} at {} mm vs N (2^(3N)-tree)",
                report.source,
                report.voxel_size_m * 1e3
            ),
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5f64..5.5f64, 0f64..top)?;
    chart
        .configure_mesh()
        .x_desc("N")
        .y_desc("total memory (MiB)")
        .x_labels(5)
        .draw()?;
    chart.draw_series(LineSeries::new(mib.clone(), &BLUE))?;
    chart.draw_series(mib.iter().map(|&p| Circle::new(p, 4, BLUE.filled())))?;
    root.present()
        .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}
