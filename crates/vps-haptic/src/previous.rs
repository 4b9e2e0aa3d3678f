//! The previous sampling kernel, kept only so that `vps bench kernel` and the `kernel_ir` example
//! can measure the current kernel ([`crate::kernel`]) against it in the same run. Not for the
//! frame path: its sums are rounded per class, so they match the current kernel's to within the
//! rounding (one LSB per point), not bit for bit.
//!
//! Per class: contributions added in f64 in one canonical order (eight lanes, lane `l` adding
//! points `l, l + 8, …`, lanes combined in a fixed tree) and quantised to integers once per class.
//! Exact for any grouping of a fixed class count. No allocation, no locks, no I/O.

use crate::classed::ClassedShell;
use crate::lanes::{
    add3_f64, add_cross_uniform, add_f64, cross, differs_from_previous, dot, floor_i32, mat_vec,
    reduce, scale, scale_add, F32s, F64s, Vec3s, LANES,
};
use crate::state::KernelPose;
use crate::sums::{PartialSums, AREA_SCALE, LENGTH_SCALE};
use glam::{IVec3, Mat3};
use vps_voxmap::{LayeredVoxel, Voxel, VoxelLookup};

/// The sums of class `class` of `shell` at `pose` against `map`.
///
/// Per point: `P = R p + x`; `ijk = floor((P − origin) / s)` in f32 (indices outside the grid read
/// as Free through [`VoxelLookup::get_layered`]). Surface of layer ℓ: depth
/// `d = max(0, N·(C − P) + ℓ s)` with `N = R n` and `C` the voxel centre, computed in voxel
/// coordinates so that `C − P` is exact to f32 rounding of the point's own position; adds `d N` and
/// `(P − x) × d N`. A 2-bit map reports ℓ = 0: the tangent-plane depth of docs/architecture.md#the-haptic-frame. Proximity
/// (any layer) with `V·N < 0` (`V = v + w × (P − x)`): adds to the braking sums. Interior: counted, and pushes
/// as Surface layer ℓ = 1 (one voxel behind the outermost force layer), so a point that slipped
/// past a one-voxel force layer is still pushed out instead of feeling nothing.
/// Contributions are added in f64 in one canonical order per class and quantised to integers once
/// per class (see [`crate::sums`] and [`accumulate`]).
///
/// A class that does not exist gives the empty sum. A pose failing [`KernelPose::is_sane`] samples
/// nothing: only `sampled` is set. Does not allocate or block; cost is linear in the class size.
#[inline]
fn sample_class<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    class: u32,
) -> PartialSums {
    let mut sums = PartialSums::default();
    if let Some(range) = shell.class_range(class) {
        sums.sampled = range.len() as u64;
        if pose.is_sane() {
            let frame = GridFrame::new(map, pose);
            let points = [
                &shell.px[range.clone()],
                &shell.py[range.clone()],
                &shell.pz[range.clone()],
            ];
            let normals = [
                &shell.nx[range.clone()],
                &shell.ny[range.clone()],
                &shell.nz[range],
            ];
            accumulate(map, &frame, points, normals).quantise_into(&mut sums);
        }
    }
    sums
}

/// The merged sums of every class of `shell`, by the previous kernel. Does not allocate or block.
pub fn sample_all<L: VoxelLookup>(map: &L, shell: &ClassedShell, pose: &KernelPose) -> PartialSums {
    let mut sums = PartialSums::default();
    for class in 0..shell.class_count() {
        sums.merge(&sample_class(map, shell, pose, class));
    }
    sums
}

/// The pose expressed in grid coordinates (voxel units, origin at the grid's minimum corner).
#[derive(Clone, Copy)]
struct GridFrame {
    rotation: Mat3,
    /// `(x − origin) / s`.
    translation_grid: [f32; 3],
    inv_voxel: f32,
    voxel: f32,
    linear_velocity: [f32; 3],
    angular_velocity: [f32; 3],
}

impl GridFrame {
    #[inline]
    fn new<L: VoxelLookup>(map: &L, pose: &KernelPose) -> Self {
        let spec = map.spec();
        let inv = 1.0 / spec.voxel_size;
        Self {
            rotation: pose.rotation,
            translation_grid: ((pose.translation.as_dvec3() - spec.origin) * inv)
                .as_vec3()
                .to_array(),
            inv_voxel: inv as f32,
            voxel: spec.voxel_size as f32,
            linear_velocity: pose.linear_velocity.to_array(),
            angular_velocity: pose.angular_velocity.to_array(),
        }
    }
}

/// Running sums of one class: per-lane f64 sums (lane `l` holds the points `l, l + 8, …` of the
/// class, in ascending order) and counters.
#[derive(Clone, Debug, Default, PartialEq)]
struct ClassAccumulator {
    depth_normal: [F64s; 3],
    depth_torque: [F64s; 3],
    brake_sq: F64s,
    brake_force: [F64s; 3],
    brake_torque: [F64s; 3],
    surface: u64,
    contacts: u64,
    approaching: u64,
    interior: u64,
    non_free: u64,
}

impl ClassAccumulator {
    /// Adds the counters and the rounded class totals (lanes reduced in their fixed order) to
    /// `sums`.
    ///
    /// A group of lanes that no block wrote (the contact lanes of a class without Surface points,
    /// the braking lanes of a class without Proximity points) holds +0.0 everywhere and would
    /// quantise to 0, so it is skipped: exact, and it saves the reductions and the thirteen
    /// f64 → i128 conversions of every class in free space (most classes of most frames).
    fn quantise_into(&self, sums: &mut PartialSums) {
        let q3 = |acc: &mut [i128; 3], lanes: &[F64s; 3], scale: f64| {
            for (a, l) in acc.iter_mut().zip(lanes) {
                *a += quantise(reduce(l), scale);
            }
        };
        if self.surface + self.interior > 0 {
            q3(&mut sums.depth_normal, &self.depth_normal, LENGTH_SCALE);
            q3(&mut sums.depth_torque, &self.depth_torque, AREA_SCALE);
        }
        let proximity = self.non_free - self.surface - self.interior;
        if proximity > 0 {
            sums.brake_sq += quantise(reduce(&self.brake_sq), LENGTH_SCALE);
            q3(&mut sums.brake_force, &self.brake_force, LENGTH_SCALE);
            q3(&mut sums.brake_torque, &self.brake_torque, AREA_SCALE);
        }
        sums.surface += self.surface;
        sums.contacts += self.contacts;
        sums.approaching += self.approaching;
        sums.interior += self.interior;
        sums.non_free += self.non_free;
    }
}

/// Body-frame point coordinates (`px, py, pz`) or normals of one class.
type Soa<'a> = [&'a [f32]; 3];

/// The hot loop over one class.
///
/// Exactness (docs/architecture.md#exact-sums-and-the-cluster): a class's f64 totals depend only on its points, in one canonical order
/// (lane `l` adds points `l, l + 8, l + 16, …` in ascending order; [`reduce`] combines the eight
/// lanes in a fixed tree), computed with IEEE basic operations only (no fused multiply-add), so they
/// are the same bits wherever and with whichever instruction set they are computed (the AVX2 and
/// the baseline copy below agree bit for bit; a unit test checks it). The totals are then quantised
/// to integers once, and integers merge exactly, so any grouping of classes gives identical sums.
#[inline]
fn accumulate<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
) -> ClassAccumulator {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU supports AVX2 (checked just above).
        return unsafe { accumulate_avx2(map, frame, points, normals) };
    }
    accumulate_lanes(map, frame, points, normals)
}

/// [`accumulate_lanes`] compiled for AVX2 (one register per lane array instead of two). FMA is not
/// enabled, so the arithmetic is the baseline copy's, bit for bit.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn accumulate_avx2<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
) -> ClassAccumulator {
    accumulate_lanes(map, frame, points, normals)
}

/// The block loop (see the module docs); full blocks, then one zero-padded tail block.
#[inline(always)]
fn accumulate_lanes<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
) -> ClassAccumulator {
    let mut acc = ClassAccumulator::default();
    let n = points[0].len().min(points[1].len()).min(points[2].len());
    let n = n
        .min(normals[0].len())
        .min(normals[1].len())
        .min(normals[2].len());
    let full = n - n % LANES;
    let mut last = LastVoxel::NONE;
    for start in (0..full).step_by(LANES) {
        sample_block(
            map, frame, points, normals, start, LANES, &mut last, &mut acc,
        );
    }
    if full < n {
        sample_block(
            map,
            frame,
            points,
            normals,
            full,
            n - full,
            &mut last,
            &mut acc,
        );
    }
    acc
}

/// `0x01` in every byte.
const BYTE_ONES: u64 = 0x0101_0101_0101_0101;

/// Number of set bytes in `x`, whose bytes are each 0 or 1.
#[inline(always)]
fn count_bytes(x: u64) -> u64 {
    x.wrapping_mul(BYTE_ONES) >> 56
}

/// Lanes `start..start + valid` of `xs` (`valid ≤ LANES`), zero-padded.
#[inline(always)]
fn load(xs: Soa, start: usize, valid: usize) -> Vec3s {
    let mut out = [[0.0; LANES]; 3];
    for (o, x) in out.iter_mut().zip(xs) {
        o[..valid].copy_from_slice(&x[start..start + valid]);
    }
    out
}

/// One block of `valid ≤ LANES` points starting at `start`: transform, floor, look up; then the
/// contact and braking arithmetic for the whole block if any lane needs it. Padding lanes read as
/// Free and contribute nothing.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn sample_block<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    start: usize,
    valid: usize,
    last: &mut LastVoxel,
    acc: &mut ClassAccumulator,
) {
    // (P − x) in metres, then P in grid coordinates and its voxel.
    let lever = mat_vec(&frame.rotation, &load(points, start, valid));
    let grid = scale_add(&lever, frame.inv_voxel, frame.translation_grid);
    let cell = [
        floor_i32(&grid[0]),
        floor_i32(&grid[1]),
        floor_i32(&grid[2]),
    ];
    let (kinds, layers) = look_up(map, &cell, valid, last);
    // Kinds as bit planes, one byte per lane: Free 00, Interior 01, Surface 10, Proximity 11.
    let word = u64::from_le_bytes(kinds);
    if word == 0 {
        return;
    }
    let (low, high) = (word & BYTE_ONES, (word >> 1) & BYTE_ONES);
    acc.non_free += count_bytes(low | high);
    let interior = low & !high;
    acc.interior += count_bytes(interior);
    let (surface, proximity) = (high & !low, high & low);
    if surface | proximity | interior == 0 {
        return;
    }
    let normal = mat_vec(&frame.rotation, &load(normals, start, valid));
    if surface | interior != 0 {
        acc.surface += count_bytes(surface);
        // Interior points push as if one layer deeper than Surface layer 0 (the first Interior
        // layer of a 2-bit map), instead of nothing.
        let is_pushing = kinds.map(|k| k == Voxel::Surface.bits() || k == Voxel::Interior.bits());
        let mut pushing_layers = layers;
        for (l, k) in pushing_layers.iter_mut().zip(kinds) {
            if k == Voxel::Interior.bits() {
                *l = 1;
            }
        }
        surface_block(
            frame,
            &lever,
            &grid,
            &cell,
            &normal,
            &is_pushing,
            &pushing_layers,
            acc,
        );
    }
    if proximity != 0 {
        let is_proximity = kinds.map(|k| k == Voxel::Proximity.bits());
        brake_block(frame, &lever, &normal, &is_proximity, acc);
    }
}

/// The voxel looked up last in a class, carried from block to block.
#[derive(Clone, Copy)]
struct LastVoxel {
    cell: [i32; 3],
    voxel: LayeredVoxel,
}

impl LastVoxel {
    /// Before the first lookup: a cell outside every grid, which reads as Free anyway.
    const NONE: LastVoxel = LastVoxel {
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
fn look_up<L: VoxelLookup>(
    map: &L,
    cell: &[[i32; LANES]; 3],
    valid: usize,
    last: &mut LastVoxel,
) -> ([u8; LANES], [u8; LANES]) {
    /// At most this many fresh lanes are looked up one by one.
    const FEW: u32 = 2;
    // Bit l: lane l is in another voxel than lane l − 1.
    let fresh = differs_from_previous(cell, last.cell) & ((1u32 << valid) - 1);
    let (kinds, layers) = if fresh.count_ones() > FEW {
        let mut cells = *cell;
        for axis in &mut cells {
            axis[valid..].fill(-1);
        }
        let block = map.get_block(&cells);
        (block.kinds, block.layers)
    } else {
        let mut kinds = [0u8; LANES];
        let mut layers = [0u8; LANES];
        let (mut kind, mut layer) = (last.voxel.kind.bits(), last.voxel.layer);
        for l in 0..valid {
            if fresh >> l & 1 != 0 {
                let v = map.get_layered(IVec3::new(cell[0][l], cell[1][l], cell[2][l]));
                (kind, layer) = (v.kind.bits(), v.layer);
            }
            kinds[l] = kind;
            layers[l] = layer;
        }
        (kinds, layers)
    };
    if valid > 0 {
        last.cell = [cell[0][valid - 1], cell[1][valid - 1], cell[2][valid - 1]];
        last.voxel = voxel_of(kinds[valid - 1], layers[valid - 1]);
    }
    (kinds, layers)
}

/// A [`LayeredVoxel`] from its kind bits and layer.
#[inline(always)]
fn voxel_of(kind: u8, layer: u8) -> LayeredVoxel {
    LayeredVoxel {
        kind: Voxel::from_bits(kind),
        layer,
    }
}

/// Contact arithmetic of a block: `d = max(0, N·(C − P) + ℓ) s` in Surface lanes, 0 elsewhere;
/// adds `d N` and `(P − x) × d N` and counts `d > 0`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn surface_block(
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
    let mut depth: F32s = [0.0; LANES];
    for l in 0..LANES {
        let d = plane[l] + f32::from(layers[l]);
        depth[l] = if is_surface[l] && d > 0.0 {
            d * frame.voxel
        } else {
            0.0
        };
    }
    acc.contacts += depth.iter().filter(|&&d| d > 0.0).count() as u64;
    let force_dir = scale(normal, &depth);
    add3_f64(&mut acc.depth_normal, &force_dir);
    add3_f64(&mut acc.depth_torque, &cross(lever, &force_dir));
}

/// Braking arithmetic of a block: `a = V·N` in approaching Proximity lanes (`V·N < 0`), 0
/// elsewhere; adds `a²`, `a N` and `(P − x) × a N` and counts the approaching lanes.
#[inline(always)]
fn brake_block(
    frame: &GridFrame,
    lever: &Vec3s,
    normal: &Vec3s,
    is_proximity: &[bool; LANES],
    acc: &mut ClassAccumulator,
) {
    let velocity = add_cross_uniform(frame.linear_velocity, frame.angular_velocity, lever);
    let approach = dot(&velocity, normal);
    let mut a: F32s = [0.0; LANES];
    let mut a_sq: F32s = [0.0; LANES];
    for l in 0..LANES {
        a[l] = if is_proximity[l] && approach[l] < 0.0 {
            approach[l]
        } else {
            0.0
        };
        a_sq[l] = a[l] * a[l];
    }
    acc.approaching += a.iter().filter(|&&x| x < 0.0).count() as u64;
    add_f64(&mut acc.brake_sq, &a_sq);
    let brake_dir = scale(normal, &a);
    add3_f64(&mut acc.brake_force, &brake_dir);
    add3_f64(&mut acc.brake_torque, &cross(lever, &brake_dir));
}

/// `value · scale` truncated toward zero, saturating (NaN → 0). `scale` is a power of two, so the
/// product is exact unless it overflows.
#[inline(always)]
fn quantise(value: f64, scale: f64) -> i128 {
    (value * scale) as i128
}
