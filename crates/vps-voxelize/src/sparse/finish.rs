//! Proximity, the force-layer offset and the distance layers, one chunk at a time. A chunk is
//! computed in a box that adds a halo of `offset + max(layers)` voxels on every side (clipped to the
//! grid), read from the merged neighbour chunks; every step is a 3×3×3-local rule, so after that
//! many steps the chunk's own voxels are exactly what the whole-grid computation gives.

use super::chunk::{copy_bits, set_bits, ChunkGrid};
use crate::bitgrid::BitGrid;
use crate::offset::offset;
use crate::proximity::dilate26;
use vps_voxmap::{LayeredVoxel, Voxel, VoxelWidth};

/// One chunk of the merged scene before proximity and offset.
#[derive(Debug)]
pub(crate) enum Merged {
    /// All Free.
    Free,
    /// All Interior.
    Interior,
    /// Disjoint Interior and Surface planes (chunk dims).
    Mixed { interior: BitGrid, surface: BitGrid },
}

/// One finished chunk: the voxel codes of the map's width.
#[derive(Debug)]
pub(crate) enum Final {
    /// Every voxel holds this code.
    Uniform(u8),
    /// Bit `b` of every voxel's code, one plane per code bit (chunk dims).
    Planes(Vec<BitGrid>),
}

impl Final {
    /// Heap bytes held.
    pub fn bytes(&self) -> usize {
        match self {
            Final::Uniform(_) => 0,
            Final::Planes(p) => p.iter().map(BitGrid::bytes).sum(),
        }
    }
}

/// What to compute per chunk.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Plan {
    /// Force-layer offset `k` (voxel layers).
    pub offset: u32,
    /// Bits per voxel of the output.
    pub width: VoxelWidth,
    /// Surface layers to label (1 for 2-bit maps).
    pub surface_layers: u8,
    /// Proximity layers to label (1 for 2-bit maps).
    pub proximity_layers: u8,
}

impl Plan {
    /// Halo voxels a chunk needs: `offset + 1` for the 2-bit classification plus one per extra
    /// layer.
    pub fn halo(&self) -> usize {
        self.offset as usize + self.surface_layers.max(self.proximity_layers) as usize
    }

    /// The code of `kind` at `layer` (the plan's layer counts fit the width).
    fn code(&self, kind: Voxel, layer: u8) -> u8 {
        self.width
            .encode(LayeredVoxel { kind, layer })
            .unwrap_or(kind as u8)
    }
}

/// Bytes of scratch planes one [`finish_chunk`] call holds at most (for the memory report).
pub(crate) fn scratch_bytes(plan: &Plan) -> usize {
    let edge = super::chunk::CHUNK + 2 * plan.halo();
    let plane = edge.div_ceil(64) * edge * edge * 8;
    plane * (8 + plan.width.bits() as usize)
}

/// Computes chunk `c` from the merged map (`map[grid.index(..)]`).
pub(crate) fn finish_chunk(map: &[Merged], grid: &ChunkGrid, c: [usize; 3], plan: &Plan) -> Final {
    let h = plan.halo();
    let o = grid.origin(c);
    let d = grid.chunk_dims(c);
    let lo: [usize; 3] = std::array::from_fn(|a| o[a].saturating_sub(h));
    let hi: [usize; 3] = std::array::from_fn(|a| (o[a] + d[a] + h).min(grid.dims[a]));
    let bd: [usize; 3] = std::array::from_fn(|a| hi[a] - lo[a]);
    let (interior, surface) = gather(map, grid, lo, hi, bd);
    let layers = offset(interior, surface, plan.offset);

    let bits = plan.width.bits() as usize;
    let mut codes: Vec<BitGrid> = (0..bits).map(|_| BitGrid::zeros(bd)).collect();
    let mut add = |code: u8, plane: &BitGrid| {
        for (b, out) in codes.iter_mut().enumerate() {
            if code >> b & 1 == 1 {
                out.combine(plane, |a, p| a | p);
            }
        }
    };
    // Surface layers inward into the Interior, Proximity layers outward into Free space.
    let free = {
        let mut f = BitGrid::neither(&layers.interior, &layers.surface);
        f.combine(&layers.proximity, |f, p| f & !p);
        f
    };
    for (kind, first, mut region, count) in [
        (
            Voxel::Surface,
            layers.surface,
            layers.interior,
            plan.surface_layers,
        ),
        (
            Voxel::Proximity,
            layers.proximity,
            free,
            plan.proximity_layers,
        ),
    ] {
        add(plan.code(kind, 0), &first);
        let mut current = first;
        for layer in 1..count {
            current = dilate26(&current);
            current.combine(&region, |c, r| c & r);
            region.combine(&current, |r, c| r & !c);
            add(plan.code(kind, layer), &current);
        }
        if kind == Voxel::Surface {
            add(Voxel::Interior as u8, &region);
        }
    }
    let at: [usize; 3] = std::array::from_fn(|a| o[a] - lo[a]);
    let planes: Vec<BitGrid> = codes.iter().map(|p| extract(p, at, d)).collect();
    let mut uniform = 0u8;
    for (b, p) in planes.iter().enumerate() {
        if p.is_full() {
            uniform |= 1 << b;
        } else if !p.is_empty() {
            return Final::Planes(planes);
        }
    }
    Final::Uniform(uniform)
}

/// Interior and Surface planes of the voxel box `lo..hi` (dims `bd`) from the merged chunks.
fn gather(
    map: &[Merged],
    grid: &ChunkGrid,
    lo: [usize; 3],
    hi: [usize; 3],
    bd: [usize; 3],
) -> (BitGrid, BitGrid) {
    let mut interior = BitGrid::zeros(bd);
    let mut surface = BitGrid::zeros(bd);
    let rw = interior.row_words;
    let [cx, cy, cz] = grid.chunks_of(lo, hi.map(|v| v - 1));
    for nz in cz {
        for ny in cy.clone() {
            for nx in cx.clone() {
                let nc = [nx, ny, nz];
                let chunk = &map[grid.index(nc)];
                if matches!(chunk, Merged::Free) {
                    continue;
                }
                let co = grid.origin(nc);
                let cd = grid.chunk_dims(nc);
                let r_lo: [usize; 3] = std::array::from_fn(|a| lo[a].max(co[a]));
                let r_hi: [usize; 3] = std::array::from_fn(|a| hi[a].min(co[a] + cd[a]));
                let len = r_hi[0] - r_lo[0];
                for z in r_lo[2]..r_hi[2] {
                    for y in r_lo[1]..r_hi[1] {
                        let row = (y - lo[1]) + bd[1] * (z - lo[2]);
                        let at = r_lo[0] - lo[0];
                        let src_row = (y - co[1]) + cd[1] * (z - co[2]);
                        let from = r_lo[0] - co[0];
                        match chunk {
                            Merged::Free => {}
                            Merged::Interior => {
                                set_bits(&mut interior.words[row * rw..(row + 1) * rw], at, len)
                            }
                            Merged::Mixed {
                                interior: i,
                                surface: s,
                            } => {
                                for (src, dst) in [(i, &mut interior), (s, &mut surface)] {
                                    copy_bits(
                                        &src.words[src_row..src_row + 1],
                                        from,
                                        len,
                                        &mut dst.words[row * rw..(row + 1) * rw],
                                        at,
                                    );
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    (interior, surface)
}

/// The sub-box of `plane` at `at` with dims `d` (each row at most one word wide).
fn extract(plane: &BitGrid, at: [usize; 3], d: [usize; 3]) -> BitGrid {
    let mut out = BitGrid::zeros(d);
    let rw = plane.row_words;
    for z in 0..d[2] {
        for y in 0..d[1] {
            let row = (y + at[1]) + plane.dims[1] * (z + at[2]);
            let dst = y + d[1] * z;
            copy_bits(
                &plane.words[row * rw..(row + 1) * rw],
                at[0],
                d[0],
                &mut out.words[dst..dst + 1],
                0,
            );
        }
    }
    out
}
