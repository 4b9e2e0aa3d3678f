//! One object, chunk by chunk: triangles binned to chunks, only chunks that a triangle overlaps are
//! scan-converted, and Free space is flooded from the walls of the object's chunk window across
//! chunks with a worklist. An empty chunk is one 6-connected box, so it is either wholly reached or
//! not; an occupied chunk runs the span fill of [`crate::flood_fill`] from seeds handed over by its
//! reached face neighbours, and is re-queued whenever a neighbour hands it new seeds. Memory: two
//! bit planes per occupied chunk, nothing per voxel of empty space.

use super::chunk::{ChunkGrid, CHUNK};
use crate::bitgrid::BitGrid;
use crate::flood_fill::{fill_from, push_runs};
use crate::scan_convert::{for_each_overlap, Window};
use crate::winding::PartClass;
use rayon::prelude::*;
use std::collections::VecDeque;
use vps_mesh::TriMesh;
use vps_voxmap::GridSpec;

/// One chunk of one object after the fill.
#[derive(Debug)]
pub(crate) enum ObjectChunk {
    /// Every voxel unreached and not Surface.
    Interior,
    /// Some Surface: the chunk's Interior and Surface planes (disjoint, chunk dims).
    Mixed { interior: BitGrid, surface: BitGrid },
}

/// Fill state of one chunk of the window.
enum FillChunk {
    /// No Surface voxel in the chunk.
    Empty { reached: bool },
    /// Surface voxels; `open` holds the non-Surface voxels not reached yet.
    Mixed {
        surface: BitGrid,
        open: BitGrid,
        seeds: Vec<(u32, u32)>,
        queued: bool,
    },
}

/// The object's chunks that are not all Free, as (global chunk index, content), and the peak bytes
/// of this object's working planes. `mesh` must be validated.
pub(crate) fn voxelize_object(
    mesh: &TriMesh,
    open: bool,
    spec: &GridSpec,
    grid: &ChunkGrid,
    times: &mut [f64; 2],
) -> (Vec<(usize, ObjectChunk)>, usize) {
    let Some((lo, hi)) = chunk_window(mesh, spec, grid) else {
        return (Vec::new(), 0);
    };
    let Some(class) = PartClass::new(mesh, open, spec) else {
        return (Vec::new(), 0);
    };
    let wn: [usize; 3] = std::array::from_fn(|a| hi[a] - lo[a] + 1);
    let local = |c: [usize; 3]| (c[0] - lo[0]) + wn[0] * ((c[1] - lo[1]) + wn[1] * (c[2] - lo[2]));
    let global_of = |i: usize| {
        let c = [i % wn[0], i / wn[0] % wn[1], i / (wn[0] * wn[1])];
        [c[0] + lo[0], c[1] + lo[1], c[2] + lo[2]]
    };

    let t = std::time::Instant::now();
    let bins = bin_triangles(mesh, spec, grid, lo, hi, wn);
    let surfaces: Vec<Option<BitGrid>> = bins
        .par_iter()
        .enumerate()
        .map(|(i, tris)| scan_chunk(mesh, spec, grid, global_of(i), tris))
        .collect();
    drop(bins);
    times[0] += t.elapsed().as_secs_f64() * 1e3;

    let t = std::time::Instant::now();
    let mut chunks: Vec<FillChunk> = surfaces
        .into_iter()
        .map(|s| match s {
            None => FillChunk::Empty { reached: false },
            Some(surface) => FillChunk::Mixed {
                open: BitGrid::neither(&surface, &BitGrid::zeros(surface.dims)),
                surface,
                seeds: Vec::new(),
                queued: false,
            },
        })
        .collect();
    let work_bytes = chunks
        .iter()
        .map(|c| match c {
            FillChunk::Mixed { surface, open, .. } => surface.bytes() + open.bytes(),
            FillChunk::Empty { .. } => 0,
        })
        .sum::<usize>()
        + chunks.capacity() * std::mem::size_of::<FillChunk>();

    // Seeds on the window's walls.
    let mut queue = VecDeque::new();
    for (i, chunk) in chunks.iter_mut().enumerate() {
        let c = global_of(i);
        for face in 0..6 {
            let (axis, high) = (face / 2, face % 2 == 1);
            let on_wall = if high {
                c[axis] == hi[axis]
            } else {
                c[axis] == lo[axis]
            };
            if on_wall {
                let seeds = if class.is_cut() {
                    wall_seeds(&class, grid, c, face, chunk)
                } else {
                    Some(None)
                };
                if let Some(mask) = seeds {
                    receive(chunk, face, mask.as_deref(), &mut queue, i);
                }
            }
        }
    }
    // Worklist: a chunk hands its reached face voxels to its six neighbours until nothing changes.
    while let Some(i) = queue.pop_front() {
        let c = global_of(i);
        let masks: Vec<(usize, Option<Vec<u64>>)> = match &mut chunks[i] {
            FillChunk::Empty { .. } => (0..6).map(|f| (f, None)).collect(),
            FillChunk::Mixed {
                surface,
                open,
                seeds,
                queued,
            } => {
                *queued = false;
                fill_from(open, seeds);
                (0..6)
                    .map(|f| (f, Some(reached_face(surface, open, f))))
                    .filter(|(_, m)| m.as_ref().is_some_and(|m| m.iter().any(|&w| w != 0)))
                    .collect()
            }
        };
        for (face, mask) in masks {
            let (axis, high) = (face / 2, face % 2 == 1);
            let mut n = c;
            if high {
                if c[axis] == hi[axis] {
                    continue;
                }
                n[axis] += 1;
            } else {
                if c[axis] == lo[axis] {
                    continue;
                }
                n[axis] -= 1;
            }
            let j = local(n);
            receive(&mut chunks[j], face ^ 1, mask.as_deref(), &mut queue, j);
        }
    }

    let out = chunks
        .into_par_iter()
        .enumerate()
        .filter_map(|(i, chunk)| {
            let c = global_of(i);
            let content = match chunk {
                FillChunk::Empty { reached: true } if class.open => {
                    let dims = grid.chunk_dims(c);
                    let surface = BitGrid::zeros(dims);
                    let mut interior = BitGrid::zeros(dims);
                    class.add_by_winding(&surface, &mut interior, grid.origin(c));
                    match interior.count() {
                        0 => return None,
                        n if n == dims.iter().product::<usize>() as u64 => ObjectChunk::Interior,
                        _ => ObjectChunk::Mixed { interior, surface },
                    }
                }
                FillChunk::Empty { reached: true } => return None,
                FillChunk::Empty { reached: false } => ObjectChunk::Interior,
                FillChunk::Mixed {
                    surface, mut open, ..
                } => {
                    if class.open {
                        class.add_by_winding(&surface, &mut open, grid.origin(c));
                    }
                    ObjectChunk::Mixed {
                        interior: open,
                        surface,
                    }
                }
            };
            Some((grid.index(c), content))
        })
        .collect();
    times[1] += t.elapsed().as_secs_f64() * 1e3;
    (out, work_bytes)
}

/// The seeds that window wall `face` of chunk `c` may give a part cut by the grid
/// ([`PartClass::may_seed`]): `None` for none at all, `Some(None)` for the whole face, or a mask in
/// [`reached_face`]'s layout. An empty chunk is one connected box: it seeds when its centre is
/// outside.
fn wall_seeds(
    class: &PartClass,
    grid: &ChunkGrid,
    c: [usize; 3],
    face: usize,
    chunk: &FillChunk,
) -> Option<Option<Vec<u64>>> {
    let o = grid.origin(c);
    let [nx, ny, nz] = grid.chunk_dims(c);
    if let FillChunk::Empty { .. } = chunk {
        let centre = [o[0] + nx / 2, o[1] + ny / 2, o[2] + nz / 2];
        return (!class.inside(centre)).then_some(None);
    }
    let high = face % 2 == 1;
    let at = |n: usize| if high { n - 1 } else { 0 };
    let ok = |x: usize, y: usize, z: usize| class.may_seed([o[0] + x, o[1] + y, o[2] + z]);
    let mask: Vec<u64> = match face / 2 {
        0 => (0..nz)
            .map(|z| (0..ny).fold(0u64, |m, y| m | (ok(at(nx), y, z) as u64) << y))
            .collect(),
        1 => (0..nz)
            .map(|z| (0..nx).fold(0u64, |m, x| m | (ok(x, at(ny), z) as u64) << x))
            .collect(),
        _ => (0..ny)
            .map(|y| (0..nx).fold(0u64, |m, x| m | (ok(x, y, at(nz)) as u64) << x))
            .collect(),
    };
    Some(Some(mask))
}

/// The inclusive chunk range of the object's window: its voxels plus two on every side (one for
/// touching triangles, one Free wall), clipped to the grid. `None` when it misses the grid.
fn chunk_window(
    mesh: &TriMesh,
    spec: &GridSpec,
    grid: &ChunkGrid,
) -> Option<([usize; 3], [usize; 3])> {
    let b = mesh.bounds();
    let lo = ((b.min - spec.origin) / spec.voxel_size).floor() - glam::DVec3::splat(2.0);
    let hi = ((b.max - spec.origin) / spec.voxel_size).floor() + glam::DVec3::splat(2.0);
    let mut clo = [0; 3];
    let mut chi = [0; 3];
    for a in 0..3 {
        let n = grid.dims[a] as f64;
        if hi[a] < 0.0 || lo[a] >= n {
            return None;
        }
        clo[a] = lo[a].max(0.0) as usize / CHUNK;
        chi[a] = hi[a].min(n - 1.0) as usize / CHUNK;
    }
    Some((clo, chi))
}

/// Triangle indices per window chunk: every chunk that the triangle's voxel bounds (widened by one
/// voxel against rounding) meet.
fn bin_triangles(
    mesh: &TriMesh,
    spec: &GridSpec,
    grid: &ChunkGrid,
    lo: [usize; 3],
    hi: [usize; 3],
    wn: [usize; 3],
) -> Vec<Vec<u32>> {
    let mut bins = vec![Vec::new(); wn.iter().product()];
    let inv = 1.0 / spec.voxel_size;
    for t in 0..mesh.triangle_count() {
        let tri = mesh.triangle(t).map(|p| (p - spec.origin) * inv);
        let tmin = tri[0].min(tri[1]).min(tri[2]).floor() - glam::DVec3::splat(2.0);
        let tmax = tri[0].max(tri[1]).max(tri[2]).floor() + glam::DVec3::splat(1.0);
        let mut range = [(0usize, 0usize); 3];
        let mut miss = false;
        for a in 0..3 {
            let first = (lo[a] * CHUNK) as f64;
            let last = ((hi[a] * CHUNK + CHUNK).min(grid.dims[a]) - 1) as f64;
            if tmax[a] < first || tmin[a] > last {
                miss = true;
                break;
            }
            let v0 = tmin[a].max(first) as usize / CHUNK;
            let v1 = tmax[a].min(last) as usize / CHUNK;
            range[a] = (v0 - lo[a], v1 - lo[a]);
        }
        if miss {
            continue;
        }
        for z in range[2].0..=range[2].1 {
            for y in range[1].0..=range[1].1 {
                for x in range[0].0..=range[0].1 {
                    bins[x + wn[0] * (y + wn[1] * z)].push(t as u32);
                }
            }
        }
    }
    bins
}

/// The Surface plane of chunk `c`, or `None` when no triangle overlaps it.
fn scan_chunk(
    mesh: &TriMesh,
    spec: &GridSpec,
    grid: &ChunkGrid,
    c: [usize; 3],
    tris: &[u32],
) -> Option<BitGrid> {
    if tris.is_empty() {
        return None;
    }
    let window = Window {
        offset: grid.origin(c),
        dims: grid.chunk_dims(c),
    };
    let mut plane = BitGrid::zeros(window.dims);
    let mut hits = Vec::new();
    for &t in tris {
        hits.clear();
        for_each_overlap(
            &mesh.triangle(t as usize),
            spec,
            &window,
            |v| plane.get(v[0], v[1], v[2]),
            |v| hits.push(v),
        );
        for &v in &hits {
            plane.set(v[0], v[1], v[2]);
        }
    }
    (!plane.is_empty()).then_some(plane)
}

/// Reached voxels (neither Surface nor open) of face `face` (axis `face / 2`, high side when odd)
/// as lines of bits: x faces give line z, bit y; y faces line z, bit x; z faces line y, bit x.
fn reached_face(surface: &BitGrid, open: &BitGrid, face: usize) -> Vec<u64> {
    let [nx, ny, nz] = surface.dims;
    let reached = |row: usize| !(surface.words[row] | open.words[row]) & surface.valid_mask(0);
    match face / 2 {
        0 => {
            let x = if face % 2 == 1 { nx - 1 } else { 0 };
            (0..nz)
                .map(|z| (0..ny).fold(0u64, |m, y| m | (reached(y + ny * z) >> x & 1) << y))
                .collect()
        }
        1 => {
            let y = if face % 2 == 1 { ny - 1 } else { 0 };
            (0..nz).map(|z| reached(y + ny * z)).collect()
        }
        _ => {
            let z = if face % 2 == 1 { nz - 1 } else { 0 };
            (0..ny).map(|y| reached(y + ny * z)).collect()
        }
    }
}

/// Hands chunk `chunk` (window index `index`) the reached voxels `mask` of the neighbour across its
/// face `face` (`None`: the whole face, for a reached empty neighbour or a window wall), queueing
/// it when that reaches something new.
fn receive(
    chunk: &mut FillChunk,
    face: usize,
    mask: Option<&[u64]>,
    queue: &mut VecDeque<usize>,
    index: usize,
) {
    match chunk {
        FillChunk::Empty { reached } => {
            if !*reached {
                *reached = true;
                queue.push_back(index);
            }
        }
        FillChunk::Mixed {
            open,
            seeds,
            queued,
            ..
        } => {
            let before = seeds.len();
            seed_face(open, face, mask, seeds);
            if seeds.len() > before && !*queued {
                *queued = true;
                queue.push_back(index);
            }
        }
    }
}

/// Pushes the open voxels of face `face` selected by `mask` (see [`reached_face`]; `None` = all) as
/// span-fill seeds.
fn seed_face(open: &BitGrid, face: usize, mask: Option<&[u64]>, seeds: &mut Vec<(u32, u32)>) {
    let [nx, ny, nz] = open.dims;
    let line = |i: usize| mask.map_or(!0, |m| m[i]);
    match face / 2 {
        0 => {
            let x = if face % 2 == 1 { nx - 1 } else { 0 };
            for z in 0..nz {
                let m = line(z);
                for y in 0..ny {
                    let row = y + ny * z;
                    if m >> y & 1 == 1 && open.words[row] >> x & 1 == 1 {
                        seeds.push((row as u32, x as u32));
                    }
                }
            }
        }
        axis => {
            let (fixed, lines) = if axis == 1 { (ny, nz) } else { (nz, ny) };
            let at = if face % 2 == 1 { fixed - 1 } else { 0 };
            for l in 0..lines {
                let row = if axis == 1 { at + ny * l } else { l + ny * at };
                let w = open.words[row] & line(l);
                push_runs(&[w], row, 0, nx - 1, seeds);
            }
        }
    }
}
