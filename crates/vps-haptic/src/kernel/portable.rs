//! The portable copy of the block: lane loops over `[f32; LANES]` arrays (module `lanes`) that
//! any target compiles, for baseline x86-64 and other targets and for the zero-padded tail block of
//! every class. The AVX2 ([`super::avx2`]) and AVX-512 ([`super::avx512`]) copies perform the same
//! IEEE operations in the same order, so every copy gives the same bits. No allocation, no locks,
//! no I/O.

use super::{
    add3_fixed, add_fixed, count_bytes, ClassAccumulator, ClassLoop, GridFrame, KindMasks, Soa,
    LENGTH_Q,
};
use crate::lanes::{
    add_cross_uniform, cross, differs_from_previous, dot, floor_i32, mat_vec, scale, scale_add,
    F32s, Vec3s, LANES,
};
use glam::IVec3;
use vps_voxmap::{LayeredVoxel, Voxel, VoxelLookup};

/// Lanes `start..start + valid` of `xs` (`valid ≤ LANES`), zero-padded.
#[inline(always)]
pub(super) fn load(xs: Soa, start: usize, valid: usize) -> Vec3s {
    let mut out = [[0.0; LANES]; 3];
    for (o, x) in out.iter_mut().zip(xs) {
        o[..valid].copy_from_slice(&x[start..start + valid]);
    }
    out
}

/// Lanes `start..start + valid` of `points` (zero-padded) placed by `frame`: `P − x` in 2^-8 m,
/// then `P` in grid coordinates (voxels; the same bits as from metres: the scalings are powers of
/// two).
#[inline(always)]
pub(super) fn place(frame: &GridFrame, points: Soa, start: usize, valid: usize) -> (Vec3s, Vec3s) {
    let lever = mat_vec(&frame.rotation_lever, &load(points, start, valid));
    let grid = scale_add(&lever, frame.inv_voxel_lever, frame.translation_grid);
    (lever, grid)
}

/// One block of `valid ≤ LANES` points starting at `start`: transform, floor, look up; then the
/// contact and braking arithmetic for the whole block if any lane needs it. Padding lanes read as
/// Free and contribute nothing.
#[inline(always)]
pub(super) fn sample_block<L: VoxelLookup, const CLAMP: bool>(
    class: &mut ClassLoop<L>,
    start: usize,
    valid: usize,
) {
    let (lever, grid) = place(class.frame, class.points, start, valid);
    let cell = [
        floor_i32(&grid[0]),
        floor_i32(&grid[1]),
        floor_i32(&grid[2]),
    ];
    let (kinds, layers) = look_up(class.map, &cell, valid, &mut class.last);
    let Some(KindMasks {
        surface,
        proximity,
        interior,
    }) = class.acc.count_kinds(kinds)
    else {
        return;
    };
    let normal = mat_vec(&class.frame.rotation, &load(class.normals, start, valid));
    if surface | interior != 0 {
        class.acc.surface += count_bytes(surface);
        // Interior points push as if one layer deeper than Surface layer 0 (the first Interior
        // layer of a 2-bit map), instead of nothing.
        let is_pushing = kinds.map(|k| k == Voxel::Surface.bits() || k == Voxel::Interior.bits());
        let mut pushing_layers = layers;
        for (l, k) in pushing_layers.iter_mut().zip(kinds) {
            if k == Voxel::Interior.bits() {
                *l = 1;
            }
        }
        surface_block::<CLAMP>(
            class.frame,
            &lever,
            &grid,
            &cell,
            &normal,
            &is_pushing,
            &pushing_layers,
            &mut class.acc,
        );
    }
    if proximity != 0 {
        let is_proximity = kinds.map(|k| k == Voxel::Proximity.bits());
        brake_block::<CLAMP>(class.frame, &lever, &normal, &is_proximity, &mut class.acc);
    }
}

/// The voxel looked up last in a class, carried from block to block.
#[derive(Clone, Copy)]
pub(super) struct LastVoxel {
    pub(super) cell: [i32; 3],
    pub(super) voxel: LayeredVoxel,
}

impl LastVoxel {
    /// Lane `lane` of `cell`, with its kind bits and layer, as the voxel looked up last.
    #[inline(always)]
    pub(super) fn remember(&mut self, cell: &[[i32; LANES]; 3], lane: usize, kind: u8, layer: u8) {
        self.cell = [cell[0][lane], cell[1][lane], cell[2][lane]];
        self.remember_voxel(kind, layer);
    }

    /// Kind bits `kind` and layer `layer` as the voxel looked up last (its cell set apart).
    #[inline(always)]
    pub(super) fn remember_voxel(&mut self, kind: u8, layer: u8) {
        self.voxel = voxel_of(kind, layer);
    }

    /// Before the first lookup: a cell outside every grid, which reads as Free anyway.
    pub(super) const NONE: LastVoxel = LastVoxel {
        cell: [i32::MIN; 3],
        voxel: LayeredVoxel {
            kind: Voxel::Free,
            layer: 0,
        },
    };
}

/// The kinds and layers of the block's voxels (lanes `valid..` read as Free).
///
/// A lane whose voxel equals the previous lane's (lane 0: the voxel looked up last, `last`) copies
/// its result. When few lanes start a new voxel (a shell sampled finer than the voxmap), only those
/// are looked up, one by one; otherwise the whole block is looked up at once with
/// [`VoxelLookup::get_block`] (for the tree, one vectorised pass), padding lanes moved outside the
/// grid.
#[inline(always)]
pub(super) fn look_up<L: VoxelLookup>(
    map: &L,
    cell: &[[i32; LANES]; 3],
    valid: usize,
    last: &mut LastVoxel,
) -> ([u8; LANES], [u8; LANES]) {
    // Bit l: lane l is in another voxel than lane l − 1.
    let fresh = differs_from_previous(cell, last.cell) & ((1u32 << valid) - 1);
    look_up_fresh::<L, true>(map, cell, valid, fresh, last)
}

/// [`look_up`] with the lanes that start a new voxel given (bit `l` of `fresh`). `COPY`: the cells
/// of a whole-block lookup are copied (padding lanes moved outside the grid) even for a full block,
/// as the previous kernel does; the AVX-512 copy passes `false`, and a full block goes to
/// [`VoxelLookup::get_block`] as it is.
#[inline(always)]
pub(super) fn look_up_fresh<L: VoxelLookup, const COPY: bool>(
    map: &L,
    cell: &[[i32; LANES]; 3],
    valid: usize,
    fresh: u32,
    last: &mut LastVoxel,
) -> ([u8; LANES], [u8; LANES]) {
    let (kinds, layers) = if fresh.count_ones() > FEW {
        let block = if COPY || valid < LANES {
            let mut cells = *cell;
            for axis in &mut cells {
                axis[valid..].fill(-1);
            }
            map.get_block(&cells)
        } else {
            map.get_block(cell)
        };
        (block.kinds, block.layers)
    } else {
        // Lane bytes of one u64: every lane starts as the last voxel; each fresh lane, in lane
        // order, overwrites itself and the lanes after it, so a lane ends with the voxel of the
        // nearest fresh lane at or before it (lane 0: `last`). Lanes `valid..` read 0.
        const ONES: u64 = u64::from_le_bytes([1; LANES]);
        let mut kinds = ONES * u64::from(last.voxel.kind.bits());
        let mut layers = ONES * u64::from(last.voxel.layer);
        debug_assert!(fresh >> valid == 0, "fresh lanes are valid lanes");
        let mut rest = fresh;
        while rest != 0 {
            let l = rest.trailing_zeros() as usize;
            rest &= rest - 1;
            let v = map.get_layered(IVec3::new(cell[0][l], cell[1][l], cell[2][l]));
            let from_l = u64::MAX << (8 * l);
            kinds = (kinds & !from_l) | ((ONES * u64::from(v.kind.bits())) & from_l);
            layers = (layers & !from_l) | ((ONES * u64::from(v.layer)) & from_l);
        }
        // Lanes 0..valid (none when `valid` is 0).
        let in_block = u64::MAX
            .checked_shr(8 * (LANES - valid) as u32)
            .unwrap_or(0);
        (
            (kinds & in_block).to_le_bytes(),
            (layers & in_block).to_le_bytes(),
        )
    };
    if valid > 0 {
        last.remember(cell, valid - 1, kinds[valid - 1], layers[valid - 1]);
    }
    (kinds, layers)
}

/// At most this many fresh lanes are looked up one by one ([`look_up_fresh`]).
pub(super) const FEW: u32 = 2;

/// A [`LayeredVoxel`] from its kind bits and layer.
#[inline(always)]
pub(super) fn voxel_of(kind: u8, layer: u8) -> LayeredVoxel {
    LayeredVoxel {
        kind: Voxel::from_bits(kind),
        layer,
    }
}

/// Contact arithmetic of a block: `d = max(0, N·(C − P) + ℓ) s` in Surface lanes, 0 elsewhere;
/// adds `d N` (2^-40 m) and `(P − x) × d N` (2^-48 m²), each rounded per point, and counts
/// `d > 0`. `lever` is `P − x` in 2^-8 m.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn surface_block<const CLAMP: bool>(
    frame: &GridFrame,
    lever: &Vec3s,
    grid: &Vec3s,
    cell: &[[i32; LANES]; 3],
    normal: &Vec3s,
    is_surface: &[bool; LANES],
    layers: &[u8; LANES],
    acc: &mut ClassAccumulator,
) {
    // C − P in voxel units: the voxel centre (cell + 0.5) minus the grid position.
    let mut to_centre = [[0.0; LANES]; 3];
    for r in 0..3 {
        for l in 0..LANES {
            to_centre[r][l] = cell[r][l] as f32 + 0.5 - grid[r][l];
        }
    }
    let plane = dot(normal, &to_centre);
    // Depth in 2^-40 m.
    let mut depth: F32s = [0.0; LANES];
    for l in 0..LANES {
        let d = plane[l] + f32::from(layers[l]);
        depth[l] = if is_surface[l] && d > 0.0 {
            d * frame.voxel_q
        } else {
            0.0
        };
    }
    acc.contacts += depth.iter().filter(|&&d| d > 0.0).count() as u64;
    let force_dir = scale(normal, &depth);
    add3_fixed::<CLAMP>(&mut acc.depth_normal, &force_dir);
    add3_fixed::<CLAMP>(&mut acc.depth_torque, &cross(lever, &force_dir));
    acc.depth_blocks += 1;
}

/// Braking arithmetic of a block: `a = V·N` in approaching Proximity lanes (`V·N < 0`), 0
/// elsewhere; adds `a²`, `a N` (2^-40 units) and `(P − x) × a N` (2^-48 units), each rounded per
/// point, and counts the approaching lanes. `lever` is `P − x` in 2^-8 m.
#[inline(always)]
pub(super) fn brake_block<const CLAMP: bool>(
    frame: &GridFrame,
    lever: &Vec3s,
    normal: &Vec3s,
    is_proximity: &[bool; LANES],
    acc: &mut ClassAccumulator,
) {
    let velocity = add_cross_uniform(frame.linear_velocity, frame.angular_velocity_lever, lever);
    let approach = dot(&velocity, normal);
    // a · 2^40 and a² · 2^40.
    let mut a: F32s = [0.0; LANES];
    let mut a_sq: F32s = [0.0; LANES];
    for l in 0..LANES {
        let x = if is_proximity[l] && approach[l] < 0.0 {
            approach[l]
        } else {
            0.0
        };
        a[l] = x * LENGTH_Q;
        a_sq[l] = x * a[l];
    }
    acc.approaching += a.iter().filter(|&&x| x < 0.0).count() as u64;
    add_fixed::<CLAMP>(&mut acc.brake_sq, &a_sq);
    let brake_dir = scale(normal, &a);
    add3_fixed::<CLAMP>(&mut acc.brake_force, &brake_dir);
    add3_fixed::<CLAMP>(&mut acc.brake_torque, &cross(lever, &brake_dir));
    acc.brake_blocks += 1;
}
