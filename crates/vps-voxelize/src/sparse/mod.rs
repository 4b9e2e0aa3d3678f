//! The sparse voxelizer: the same result as the dense pipeline (docs/architecture.md#voxmaps-and-point-shells), computed chunk by chunk
//! (64³-voxel cubes, the default tree's lower node) so that working memory and the voxmap follow the
//! scene's surface, not its bounding volume.
//!
//! 1. Per object (module `object`): triangles binned to chunks, occupied chunks scan-converted, Free space
//!    flooded from the object window's walls across chunks with a worklist.
//! 2. Objects merged chunk by chunk with the precedence Interior > Surface > Free.
//! 3. Per chunk that holds Surface, or touches one that does (module `finish`): Proximity, the `k`-layer
//!    offset and the distance layers in a halo box read from the neighbours.
//! 4. The tree is built straight from the finished chunks (module `source`).
//!
//! Empty space costs one small enum per chunk; only chunks with Surface hold bit planes.

mod chunk;
mod finish;
mod object;
mod source;

use crate::error::VoxelizeError;
use crate::stats::VoxelizeStats;
use chunk::{ChunkGrid, CHUNK};
use finish::{finish_chunk, Final, Merged, Plan};
use object::{voxelize_object, ObjectChunk};
use rayon::prelude::*;
use std::time::Instant;
use vps_mesh::TriMesh;
use vps_voxmap::{GridSpec, TreeConfig, Voxel, VoxelTree, VoxelWidth};

/// Most distance layers per side the sparse voxelizer labels in an 8-bit map (the code table holds
/// 64): each layer widens every chunk's halo box by one voxel on each side.
pub const MAX_COMPUTED_LAYERS: u8 = 16;

/// The layer plan of `width` with offset `k`; errors when the halo would exceed one chunk.
pub(crate) fn plan_for(width: VoxelWidth, offset: u32) -> Result<Plan, VoxelizeError> {
    let plan = Plan {
        offset,
        width,
        surface_layers: width.surface_layers().min(MAX_COMPUTED_LAYERS),
        proximity_layers: width.proximity_layers().min(MAX_COMPUTED_LAYERS),
    };
    if plan.halo() > CHUNK {
        return Err(VoxelizeError::InvalidOptions {
            reason: format!(
                "offset_layers {offset} plus {} distance layers needs a halo of {} voxels; the \
                 sparse voxelizer allows at most {CHUNK}",
                plan.surface_layers.max(plan.proximity_layers),
                plan.halo()
            ),
        });
    }
    Ok(plan)
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Bytes of a merged chunk's planes.
fn merged_bytes(m: &Merged) -> usize {
    match m {
        Merged::Mixed { interior, surface } => interior.bytes() + surface.bytes(),
        _ => 0,
    }
}

/// Which voxels of a grid lie wholly inside the scene's solids, which a triangle crosses and
/// which lie wholly outside, before proximity and any force-layer offset: the sparse
/// voxelizer's merged chunks. A 2-bit map with `offset_layers = 0` classifies every voxel the
/// same way (Proximity aside); the distance band takes its signs from it
/// ([`crate::distance::distance_band_with_inside`]).
#[derive(Debug)]
pub struct InsideMap {
    spec: GridSpec,
    grid: ChunkGrid,
    chunks: Vec<Merged>,
}

impl InsideMap {
    /// The grid.
    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// [`Voxel::Interior`] for a voxel wholly inside a solid and clear of every triangle,
    /// [`Voxel::Surface`] for one a triangle crosses, else [`Voxel::Free`] (outside the grid
    /// too). Pure, no allocation.
    pub fn get(&self, ijk: glam::IVec3) -> Voxel {
        if !self.spec.contains(ijk) {
            return Voxel::Free;
        }
        let v = ijk.as_uvec3().to_array().map(|x| x as usize);
        let c = v.map(|x| x / CHUNK);
        match &self.chunks[self.grid.index(c)] {
            Merged::Free => Voxel::Free,
            Merged::Interior => Voxel::Interior,
            Merged::Mixed { interior, surface } => {
                let [x, y, z] = [0, 1, 2].map(|a| v[a] - c[a] * CHUNK);
                if interior.get(x, y, z) {
                    Voxel::Interior
                } else if surface.get(x, y, z) {
                    Voxel::Surface
                } else {
                    Voxel::Free
                }
            }
        }
    }

    /// Heap bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.chunks.capacity() * std::mem::size_of::<Merged>()
            + self.chunks.iter().map(merged_bytes).sum::<usize>()
    }
}

/// The scene merged: every object scan-converted and flooded, merged chunk by chunk, Surface
/// inside another object's Interior cleared. Fills `stats`' scan, fill and merge times; returns
/// the chunks, the bytes of the chunk table, of the planes held, and the peak so far.
fn merge_objects(
    objects: &[TriMesh],
    spec: &GridSpec,
    grid: &ChunkGrid,
    stats: &mut VoxelizeStats,
) -> (Vec<Merged>, usize, usize, usize) {
    let mut map: Vec<Merged> = (0..grid.count()).map(|_| Merged::Free).collect();
    let map_meta = map.capacity() * std::mem::size_of::<Merged>();
    let mut held = 0usize; // bytes of merged planes
    let mut peak = map_meta;

    for part in crate::winding::split_open(objects) {
        let mut times = [0.0; 2];
        let (chunks, work) = voxelize_object(&part.mesh, part.open, spec, grid, &mut times);
        stats.scan_ms += times[0];
        stats.fill_ms += times[1];
        let result_bytes: usize = chunks
            .iter()
            .map(|(_, c)| match c {
                ObjectChunk::Mixed { interior, surface } => interior.bytes() + surface.bytes(),
                ObjectChunk::Interior => 0,
            })
            .sum();
        peak = peak.max(map_meta + held + work.max(result_bytes));
        let t = Instant::now();
        for (index, content) in chunks {
            held -= merged_bytes(&map[index]);
            merge(&mut map[index], content);
            held += merged_bytes(&map[index]);
        }
        stats.merge_ms += ms(t);
    }
    let t = Instant::now();
    for m in map.iter_mut() {
        if let Merged::Mixed { interior, surface } = m {
            surface.combine(interior, |s, i| s & !i);
        }
    }
    stats.merge_ms += ms(t);
    (map, map_meta, held, peak)
}

/// The [`InsideMap`] of checked `objects` on checked `spec` (scan, fill and merge only), filling
/// `stats`' phases and peak working bytes.
pub(crate) fn inside_map(
    objects: &[TriMesh],
    spec: &GridSpec,
    stats: &mut VoxelizeStats,
) -> InsideMap {
    let grid = ChunkGrid::new(spec.dims);
    let (chunks, _, _, peak) = merge_objects(objects, spec, &grid, stats);
    stats.peak_work_bytes = peak as u64;
    InsideMap {
        spec: *spec,
        grid,
        chunks,
    }
}

/// Voxelizes checked `objects` on checked `spec` into a tree of `config` and `opts.width`, filling
/// `stats` (phases, peak working bytes; counts are left to the caller); with `keep_inside`, also
/// the [`InsideMap`] it was computed from (held beside the tree: counted in the peak).
pub(crate) fn voxelize_sparse(
    objects: &[TriMesh],
    spec: &GridSpec,
    plan: &Plan,
    config: TreeConfig,
    stats: &mut VoxelizeStats,
    keep_inside: bool,
) -> Result<(VoxelTree, Option<InsideMap>), VoxelizeError> {
    let grid = ChunkGrid::new(spec.dims);
    let (map, map_meta, held, mut peak) = merge_objects(objects, spec, &grid, stats);
    let t = Instant::now();

    // Chunks that hold Surface and their 26 neighbours change; the rest keep their uniform value.
    let mut active = vec![false; grid.count()];
    for (i, m) in map.iter().enumerate() {
        if matches!(m, Merged::Mixed { .. }) {
            let c = grid.coords(i);
            for z in c[2].saturating_sub(1)..=(c[2] + 1).min(grid.n[2] - 1) {
                for y in c[1].saturating_sub(1)..=(c[1] + 1).min(grid.n[1] - 1) {
                    for x in c[0].saturating_sub(1)..=(c[0] + 1).min(grid.n[0] - 1) {
                        active[grid.index([x, y, z])] = true;
                    }
                }
            }
        }
    }
    let active: Vec<usize> = (0..grid.count()).filter(|&i| active[i]).collect();
    let computed: Vec<(usize, Final)> = active
        .par_iter()
        .map(|&i| (i, finish_chunk(&map, &grid, grid.coords(i), plan)))
        .collect();
    let final_bytes: usize = computed.iter().map(|(_, f)| f.bytes()).sum();
    let scratch = finish::scratch_bytes(plan) * rayon::current_num_threads();
    let mut finals: Vec<Final> = map
        .iter()
        .map(|m| match m {
            Merged::Interior => Final::Uniform(vps_voxmap::Voxel::Interior as u8),
            _ => Final::Uniform(0),
        })
        .collect();
    let finals_meta = finals.capacity() * std::mem::size_of::<Final>();
    peak = peak.max(map_meta + held + final_bytes + scratch + finals_meta);
    // The map stays for the caller, or goes before the tree is built.
    let (inside, kept_bytes) = if keep_inside {
        let inside = InsideMap {
            spec: *spec,
            grid,
            chunks: map,
        };
        let bytes = inside.memory_bytes();
        (Some(inside), bytes)
    } else {
        drop(map);
        (None, 0)
    };
    for (i, f) in computed {
        finals[i] = f;
    }
    stats.offset_ms += ms(t);
    stats.active_chunks = active.len();

    let t = Instant::now();
    let source = source::ChunkSource {
        grid,
        chunks: &finals,
    };
    let tree = VoxelTree::from_source(*spec, plan.width, config, &source).map_err(|e| {
        VoxelizeError::InvalidGrid {
            reason: format!("building the tree: {e}"),
        }
    })?;
    let cube = (config.extent(1) as usize).pow(3) * rayon::current_num_threads();
    peak = peak.max(finals_meta + final_bytes + cube + tree.memory_bytes() + kept_bytes);
    stats.output_ms += ms(t);
    stats.peak_work_bytes = peak as u64;
    Ok((tree, inside))
}

/// Merges one object's chunk into the scene's (Interior > Surface > Free; Surface inside another
/// object's Interior is cleared when all objects are in).
fn merge(into: &mut Merged, content: ObjectChunk) {
    match (&mut *into, content) {
        (Merged::Interior, _) => {}
        (_, ObjectChunk::Interior) => *into = Merged::Interior,
        (Merged::Free, ObjectChunk::Mixed { interior, surface }) => {
            *into = Merged::Mixed { interior, surface }
        }
        (
            Merged::Mixed {
                interior: gi,
                surface: gs,
            },
            ObjectChunk::Mixed { interior, surface },
        ) => {
            gi.combine(&interior, |a, b| a | b);
            gs.combine(&surface, |a, b| a | b);
        }
    }
}
