//! The sampling kernel (docs/architecture.md#the-haptic-frame): transform each point of a class by the part's pose, look up its
//! voxel and add its contribution to [`PartialSums`]. No allocation, no locks, no I/O.
//!
//! Points go through in blocks of `LANES` (8, module `lanes`): (1) transform, floor and look
//! up the whole block; (2) only if some point of the block is not Free, rotate the normals; (3) the
//! contact arithmetic only if some point is in a Surface voxel, the braking arithmetic only if some
//! point is in a Proximity voxel, each for all lanes at once with the other lanes masked to zero.
//! A block in free space therefore costs its transform and lookups only.
//!
//! Three copies of a block, the same bits, one file each, and one dispatcher here
//! (`sample_class_with` picks by the CPU's features, `accumulate_lanes` runs the class's blocks):
//! - `kernel/portable.rs`: lane loops over the arrays of module `lanes` (baseline x86-64 and
//!   other targets, and the zero-padded tail block of every class);
//! - `kernel/avx2.rs`: where the CPU has AVX2, full blocks of 8 written with AVX2 intrinsics
//!   (`avx2::sample_block`);
//! - `kernel/avx512.rs`: where it also has AVX-512F, AVX-512DQ and POPCNT (`accumulate_avx512`),
//!   full blocks of 16 points in 512-bit registers (`avx512::sample_blocks`, lookups through
//!   [`VoxelLookup::get_wide_block`]), then the class's last full block of 8 on the AVX2
//!   intrinsics compiled with those features (rounding each sum's eight lanes to `i64` in one
//!   `vcvtps2qq`, counting with `popcnt`), then the portable tail.
//!
//! The same IEEE operations in the same order, no fused multiply-add. The AVX2 copy is also the
//! kernel on at most AVX2 ([`crate::avx2_only`]), so the AVX-512 copy's own choices sit behind its
//! `AVX512` flag rather than in the shared code. The `distance` force model's block loop is
//! `kernel/distance.rs` (portable and AVX2 copies) and `kernel/distance/avx512.rs` (its AVX-512
//! copy).
//!
//! Exactness (docs/architecture.md#exact-sums-and-the-cluster): each point's contribution is
//! computed in f32 (IEEE basic operations only, no fused multiply-add, so the same bits on every
//! instruction set), rounded to an integer multiple of the sums' LSB (2^-40 m, 2^-48 m², see
//! [`crate::sums`]) as soon as it is computed, and added in integers. Integer addition is exact in
//! any order, so any split of the shell, in any grouping, gives the same sums bit for bit.
//!
//! Fixed point per point: the f32 value `y` (already scaled to LSB units, a power-of-two scaling
//! folded into the arithmetic, hence exact) is widened to f64 and rounded to the nearest integer
//! by adding `1.5 · 2^52`; the sum's bits minus those of `1.5 · 2^52` are the integer (the
//! AVX-512 copy converts `y` to the same integer directly and adds those bits itself). This is
//! exact for `|y| < 2^51`; every point is kept within `|y| ≤ 2^50` (`Y_MAX`): when the frame's
//! bounds (`GridFrame::needs_clamp`) cannot rule out a larger value, each value is clamped
//! first, which changes nothing for a value already in range, so both paths give the same bits.
//! Lanes are `i64`; a lane adds at most `CHUNK_BLOCKS` values (≤ 2^11 · 2^50 = 2^61 < 2^63)
//! before it is flushed into the class's `i128` totals.

use crate::classed::ClassedShell;
use crate::lanes::{F32s, Vec3s, LANES};
use crate::state::KernelPose;
use crate::sums::{PartialSums, AREA_SCALE, LENGTH_SCALE};
use glam::Mat3;
use vps_voxmap::{LookupTask, VoxelLookup};

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
/// Each contribution is rounded to the sums' LSB as it is computed and added in integers (see the
/// module docs and [`crate::sums`]).
///
/// A class that does not exist gives the empty sum. A pose failing [`KernelPose::is_sane`] samples
/// nothing: only `sampled` is set. Does not allocate or block; cost is linear in the class size.
#[inline]
pub fn sample_class<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    class: u32,
) -> PartialSums {
    sample_class_on(map, shell, pose, class, Widest::Avx512)
}

/// The widest copy of the block loop that [`sample_class_on`] may run where the CPU has it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Widest {
    /// AVX-512 (F, DQ) with POPCNT, else AVX2, else portable: the current kernel.
    Avx512,
    /// AVX2, else portable: the kernel before the AVX-512 copy ([`crate::avx2_only`]).
    Avx2,
}

/// A pose prepared for sampling one shell against one map, once per frame: the pose in grid
/// coordinates with the fixed point's scalings folded in, whether contributions must be clamped,
/// and the map's stand-off in voxels. [`sample_class_in`] then samples any class with it, the same
/// bits as [`sample_class`]. Building it costs a few tens of nanoseconds; a frame of 64 classes
/// builds it once instead of 64 times. Made for one map and one shell: use it with those only.
#[derive(Clone, Copy)]
pub struct KernelFrame {
    /// `None`: the pose failed [`KernelPose::is_sane`] (classes sample nothing).
    grid: Option<GridFrame>,
    /// The distance band's stand-off in voxels, when the map has a band.
    standoff_voxels: Option<f32>,
}

impl KernelFrame {
    /// `pose` prepared for `shell` against `map`. Does not allocate or block.
    #[inline]
    pub fn new<L: VoxelLookup>(map: &L, shell: &ClassedShell, pose: &KernelPose) -> KernelFrame {
        KernelFrame {
            grid: pose.is_sane().then(|| GridFrame::new(map, pose, shell)),
            standoff_voxels: map
                .distance_band()
                .map(|band| (band.standoff_m() / map.spec().voxel_size) as f32),
        }
    }
}

/// [`sample_class`] with the pose prepared once ([`KernelFrame::new`] for this `map` and
/// `shell`): the same bits. Does not allocate or block.
#[inline]
pub fn sample_class_in<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    frame: &KernelFrame,
    class: u32,
) -> PartialSums {
    sample_class_with(map, shell, frame, class, Widest::Avx512)
}

/// [`sample_class`] on at most the `widest` copy of the block loop. Every copy gives the same
/// bits. Does not allocate or block.
#[inline]
pub(crate) fn sample_class_on<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    class: u32,
    widest: Widest,
) -> PartialSums {
    sample_class_with(
        map,
        shell,
        &KernelFrame::new(map, shell, pose),
        class,
        widest,
    )
}

/// One class with a prepared frame, on at most the `widest` copy of the block loop.
#[inline]
fn sample_class_with<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    prepared: &KernelFrame,
    class: u32,
    widest: Widest,
) -> PartialSums {
    let mut sums = PartialSums::default();
    if let Some(range) = shell.class_range(class) {
        sums.sampled = range.len() as u64;
        if let Some(frame) = &prepared.grid {
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
            match (map.distance_band(), prepared.standoff_voxels) {
                (Some(band), Some(standoff_voxels)) => distance::accumulate(
                    distance::BandClass {
                        band,
                        standoff_voxels,
                        frame,
                        points,
                        normals,
                    },
                    &mut sums,
                    widest,
                ),
                _ => accumulate(map, frame, points, normals, &mut sums, widest),
            }
        }
    }
    sums
}

/// The merged sums of the classes whose bits are set in `mask` (classes 0..64), the pose
/// prepared once. Does not allocate or block.
pub fn sample_mask<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    mask: u64,
) -> PartialSums {
    let frame = KernelFrame::new(map, shell, pose);
    let mut sums = PartialSums::default();
    let mut rest = mask;
    while rest != 0 {
        let class = rest.trailing_zeros();
        rest &= rest - 1;
        sums.merge(&sample_class_in(map, shell, &frame, class));
    }
    sums
}

/// The merged sums of `classes` (duplicates are sampled twice; unknown classes add nothing). Does
/// not allocate or block.
pub fn sample_classes<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    classes: &[u32],
) -> PartialSums {
    let frame = KernelFrame::new(map, shell, pose);
    let mut sums = PartialSums::default();
    for &class in classes {
        sums.merge(&sample_class_in(map, shell, &frame, class));
    }
    sums
}

/// The merged sums of every class of `shell`. Does not allocate or block.
pub fn sample_all<L: VoxelLookup>(map: &L, shell: &ClassedShell, pose: &KernelPose) -> PartialSums {
    sample_all_on(map, shell, pose, Widest::Avx512)
}

/// [`sample_all`] on at most the `widest` copy of the block loop (the same bits). Does not
/// allocate or block.
pub(crate) fn sample_all_on<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    widest: Widest,
) -> PartialSums {
    let frame = KernelFrame::new(map, shell, pose);
    let mut sums = PartialSums::default();
    for class in 0..shell.class_count() {
        sums.merge(&sample_class_with(map, shell, &frame, class, widest));
    }
    sums
}

/// Largest magnitude of a point's contribution in LSB units: `round` via `1.5 · 2^52` is exact
/// below 2^51, and [`CHUNK_BLOCKS`] such values fit an `i64` lane.
const Y_MAX: f32 = (1u64 << 50) as f32;

/// Blocks of [`LANES`] points a chunk holds: each lane adds at most this many values (one per
/// 8-lane block, two per wide block of twice the points) before it is flushed into `i128`:
/// `2^11 · 2^50 = 2^61 < 2^63`.
const CHUNK_BLOCKS: usize = 1 << 11;

/// `1.5 · 2^52`: adding it to an f64 of magnitude below 2^51 rounds it to an integer (nearest,
/// ties to even) held in the low mantissa bits.
const ROUNDER: f64 = 6_755_399_441_055_744.0;

/// The bits of [`ROUNDER`] as an integer: each value added to a lane brings this along.
const ROUNDER_BITS: i64 = ROUNDER.to_bits() as i64;

/// `2^40`: the length-like sums' LSB is 2^-40 (m, m/s, m²/s²).
const LENGTH_Q: f32 = LENGTH_SCALE as f32;

/// `2^8`: levers are carried in units of 2^-8 m so that `lever × (2^-40 units)` lands in the area
/// sums' 2^-48 units.
const LEVER_Q: f32 = (AREA_SCALE / LENGTH_SCALE) as f32;

/// The pose expressed in grid coordinates (voxel units, origin at the grid's minimum corner), with
/// the power-of-two scalings of the fixed point folded in (exact).
#[derive(Clone, Copy)]
struct GridFrame {
    /// `R · 2^8`: gives the lever `P − x` in units of 2^-8 m.
    rotation_lever: Mat3,
    /// `R`, for the normals.
    rotation: Mat3,
    /// `(x − origin) / s`.
    translation_grid: [f32; 3],
    /// `2^-8 / s`: lever units to voxel units.
    inv_voxel_lever: f32,
    /// `s · 2^40`: voxel units to length LSBs.
    voxel_q: f32,
    linear_velocity: [f32; 3],
    /// `ω · 2^-8`, against levers in 2^-8 m.
    angular_velocity_lever: [f32; 3],
    /// Some point's contribution could exceed [`Y_MAX`] (absurd speeds or sizes): clamp each.
    needs_clamp: bool,
}

impl GridFrame {
    #[inline]
    fn new<L: VoxelLookup>(map: &L, pose: &KernelPose, shell: &ClassedShell) -> Self {
        let spec = map.spec();
        let inv = 1.0 / spec.voxel_size;
        Self {
            rotation_lever: pose.rotation * LEVER_Q,
            rotation: pose.rotation,
            translation_grid: ((pose.translation.as_dvec3() - spec.origin) * inv)
                .as_vec3()
                .to_array(),
            inv_voxel_lever: inv as f32 / LEVER_Q,
            voxel_q: spec.voxel_size as f32 * LENGTH_Q,
            linear_velocity: pose.linear_velocity.to_array(),
            angular_velocity_lever: (pose.angular_velocity / LEVER_Q).to_array(),
            needs_clamp: Self::needs_clamp(pose, spec.voxel_size, shell),
        }
    }

    /// False when no point of `shell` at `pose` can contribute more than `Y_MAX / 2` LSB to any
    /// sum (a factor 2 covers f32 rounding): `|N| ≤ ‖R‖ n_max`, `|P − x| ≤ ‖R‖ r_max`,
    /// `d ≤ (|N| + 256) s` (half a diagonal, at most 255 layers), `|V| ≤ |v| + |ω| |P − x|`, with
    /// `‖R‖² ≤` the largest absolute row sum of `RᵀR` (Gershgorin; ≈ 1 for a rotation). True for
    /// absurd sizes or speeds: for a 5 mm voxel, a 10 cm part and unit normals, from about 20 m/s;
    /// and for a shell with a point or normal that is not finite (whose NaN contributions the clamp
    /// sends to `-Y_MAX` in every copy of the block loop alike).
    fn needs_clamp(pose: &KernelPose, voxel: f64, shell: &ClassedShell) -> bool {
        let r = pose.rotation.as_dmat3();
        let gram = r.transpose() * r;
        let rows = [gram.row(0), gram.row(1), gram.row(2)];
        let largest_row = rows
            .iter()
            .map(|row| row.abs().element_sum())
            .fold(0.0, f64::max);
        let r_norm = largest_row.sqrt() * (1.0 + 1e-6);
        let normal = r_norm * shell.max_normal();
        let lever = r_norm * shell.max_radius();
        let depth = (normal + 256.0) * voxel;
        let speed = f64::from(pose.linear_velocity.length())
            + f64::from(pose.angular_velocity.length()) * lever;
        let approach = speed * normal;
        let (l, a) = (LENGTH_SCALE, AREA_SCALE);
        let worst = [
            depth * normal * l,
            lever * depth * normal * a,
            approach * approach * l,
            approach * normal * l,
            lever * approach * normal * a,
        ];
        !(shell.points_finite() && worst.iter().all(|w| *w <= f64::from(Y_MAX) / 2.0))
    }
}

/// Per-lane integer sums of one chunk of a class (lane `l` holds points `l, l + 8, …`), each value
/// carrying [`ROUNDER_BITS`] along (subtracted at the flush), and the class's counters.
#[derive(Clone, Debug, Default, PartialEq)]
struct ClassAccumulator {
    depth_normal: [I64s; 3],
    depth_torque: [I64s; 3],
    brake_sq: I64s,
    brake_force: [I64s; 3],
    brake_torque: [I64s; 3],
    /// Values each depth lane added since the last flush (one per 8-lane block, two per wide
    /// block).
    depth_blocks: i64,
    /// Values each braking lane added since the last flush (as `depth_blocks`).
    brake_blocks: i64,
    surface: u64,
    contacts: u64,
    approaching: u64,
    interior: u64,
    non_free: u64,
}

/// One `i64` per lane.
type I64s = [i64; LANES];

/// `acc += round(y)` per lane, in the carried form `acc += bits(y + 1.5 · 2^52)`; with `CLAMP`, `y`
/// is first clamped to `±Y_MAX` (NaN to `-Y_MAX`).
#[inline(always)]
fn add_fixed<const CLAMP: bool>(acc: &mut I64s, y: &F32s) {
    for l in 0..LANES {
        // `max` then `min`, not `clamp`: NaN goes to `-Y_MAX`, as in the AVX2 copy.
        #[allow(clippy::manual_clamp)]
        let v = if CLAMP {
            y[l].max(-Y_MAX).min(Y_MAX)
        } else {
            y[l]
        };
        acc[l] = acc[l].wrapping_add((f64::from(v) + ROUNDER).to_bits() as i64);
    }
}

/// `acc += round(y)` per component and lane.
#[inline(always)]
fn add3_fixed<const CLAMP: bool>(acc: &mut [I64s; 3], y: &Vec3s) {
    for (a, v) in acc.iter_mut().zip(y) {
        add_fixed::<CLAMP>(a, v);
    }
}

/// The exact total of lanes that each added `blocks` carried values, as `i128`.
#[inline]
fn lanes_total(lanes: &I64s, blocks: i64) -> i128 {
    let carried = blocks.wrapping_mul(ROUNDER_BITS);
    lanes
        .iter()
        .map(|&x| i128::from(x.wrapping_sub(carried)))
        .sum()
}

impl ClassAccumulator {
    /// Adds the lanes' exact totals to `sums` and clears them (counters stay). Lanes no block
    /// wrote are skipped (they hold 0). Always inlined: a call would let the block loop's
    /// [`ClassLoop`] escape.
    #[inline(always)]
    fn flush(&mut self, sums: &mut PartialSums) {
        if self.depth_blocks > 0 {
            let b = self.depth_blocks;
            for k in 0..3 {
                sums.depth_normal[k] += lanes_total(&self.depth_normal[k], b);
                sums.depth_torque[k] += lanes_total(&self.depth_torque[k], b);
            }
            self.depth_normal = Default::default();
            self.depth_torque = Default::default();
            self.depth_blocks = 0;
        }
        if self.brake_blocks > 0 {
            let b = self.brake_blocks;
            sums.brake_sq += lanes_total(&self.brake_sq, b);
            for k in 0..3 {
                sums.brake_force[k] += lanes_total(&self.brake_force[k], b);
                sums.brake_torque[k] += lanes_total(&self.brake_torque[k], b);
            }
            self.brake_sq = Default::default();
            self.brake_force = Default::default();
            self.brake_torque = Default::default();
            self.brake_blocks = 0;
        }
    }

    /// Flushes the lanes and adds the counters to `sums`.
    fn finish_into(mut self, sums: &mut PartialSums) {
        self.flush(sums);
        sums.surface += self.surface;
        sums.contacts += self.contacts;
        sums.approaching += self.approaching;
        sums.interior += self.interior;
        sums.non_free += self.non_free;
    }
}

/// Body-frame point coordinates (`px, py, pz`) or normals of one class.
type Soa<'a> = [&'a [f32]; 3];

/// The hot loop over one class: adds the class's sums to `sums`, on the widest copy of the block
/// loop up to `widest` that the CPU runs, compiled per lookup format
/// ([`VoxelLookup::specialised`]: for the tree, one copy for its 2-bit 512-tree path and one for
/// its general path, so neither tests the format per lookup).
#[inline]
fn accumulate<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
    widest: Widest,
) {
    map.specialised(ClassTask {
        frame,
        points,
        normals,
        sums,
        widest,
    })
}

/// The arguments of [`accumulate`] but the lookup; [`VoxelLookup::specialised`] runs it on the
/// lookup it hands over, on the widest copy of the block loop up to `widest` that the CPU runs.
struct ClassTask<'a> {
    frame: &'a GridFrame,
    points: Soa<'a>,
    normals: Soa<'a>,
    sums: &'a mut PartialSums,
    widest: Widest,
}

impl LookupTask for ClassTask<'_> {
    type Output = ();

    #[inline(always)]
    fn run<L: VoxelLookup>(self, map: &L) {
        let ClassTask {
            frame,
            points,
            normals,
            sums,
            widest,
        } = self;
        #[cfg(target_arch = "x86_64")]
        {
            if widest == Widest::Avx512 && cpu_has_avx512() {
                // SAFETY: the CPU supports AVX2, AVX-512F, AVX-512DQ and POPCNT (checked just
                // above).
                return unsafe { accumulate_avx512(map, frame, points, normals, sums) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked just above).
                return unsafe { accumulate_avx2(map, frame, points, normals, sums) };
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = widest;
        accumulate_any::<L, false, false>(map, frame, points, normals, sums)
    }
}

/// Whether the CPU runs [`accumulate_avx512`]: AVX2, AVX-512F, AVX-512DQ and POPCNT.
#[cfg(target_arch = "x86_64")]
#[inline]
fn cpu_has_avx512() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512dq")
        && std::arch::is_x86_feature_detected!("popcnt")
}

/// Whether [`sample_class`] runs its AVX-512 copy of the block loop on this CPU (x86-64 with
/// AVX2, AVX-512F, AVX-512DQ and POPCNT); otherwise its AVX2 copy or its portable one, as the
/// previous kernel does. Same sums either way.
pub fn runs_avx512_copy() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        cpu_has_avx512()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The AVX-512 copy: full blocks of 16 points in 512-bit registers (`avx512::sample_blocks`), then
/// [`accumulate_avx2`]'s block for a last full block of 8, with each sum's eight lanes rounded to
/// `i64` by one AVX-512DQ conversion (`vcvtps2qq`, to nearest, ties to even: the same integers as
/// the f64 rounding of the AVX2 copy) and counts by POPCNT. The same bits as the other copies.
///
/// # Safety
/// The CPU must support AVX2, AVX-512F, AVX-512DQ and POPCNT ([`cpu_has_avx512`]).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,avx512f,avx512dq,popcnt")]
unsafe fn accumulate_avx512<L: VoxelLookup>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    accumulate_any::<L, true, true>(map, frame, points, normals, sums)
}

/// [`accumulate_any`] compiled for AVX2, full blocks written with AVX2 intrinsics ([`avx2`]): the
/// same operations in the same order as the portable lane loops (no fused multiply-add), so the
/// same bits.
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
    sums: &mut PartialSums,
) {
    accumulate_any::<L, true, false>(map, frame, points, normals, sums)
}

/// Picks the clamping or the plain copy of the block loop (the same bits; see the module docs).
/// `AVX2`: full blocks through [`avx2::sample_block`] (only where the CPU has AVX2); `AVX512`: with
/// its AVX-512 rounding (only where the CPU has AVX-512F and DQ, and with `AVX2`).
#[inline(always)]
fn accumulate_any<L: VoxelLookup, const AVX2: bool, const AVX512: bool>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    if frame.needs_clamp {
        accumulate_lanes::<L, true, AVX2, AVX512>(map, frame, points, normals, sums)
    } else {
        accumulate_lanes::<L, false, AVX2, AVX512>(map, frame, points, normals, sums)
    }
}

/// One class's block loop: its inputs, the same for every block (the lookup, the prepared frame,
/// the class's body-frame points and normals), and its running state (the voxel looked up last,
/// the lane sums). Each copy's block function takes it with the block's start.
///
/// Built in [`accumulate_lanes`], inside the functions compiled per instruction set, from their
/// arguments, and never escapes (hence [`ClassAccumulator::flush`] is always inlined): LLVM then
/// keeps its fields in registers and knows the frame aliases nothing the loop writes. Bundled
/// outside them (map, frame, points, normals), the inputs cost 5 % more instructions in contact
/// (AVX-512 copy, 1k points: 16,396 → 17,287); escaping through a call to `flush`, the frame was
/// read again every block (AVX2 copy, free space: 25 % more; both the `kernel_ir` example).
struct ClassLoop<'a, L> {
    map: &'a L,
    frame: &'a GridFrame,
    points: Soa<'a>,
    normals: Soa<'a>,
    last: LastVoxel,
    acc: ClassAccumulator,
}

/// The block loop (see the module docs); full blocks (with `AVX512`, blocks of 16 points while a
/// chunk has them, then blocks of 8), then one zero-padded tail block; the lanes flushed every
/// [`CHUNK_BLOCKS`] blocks of 8 points.
#[inline(always)]
fn accumulate_lanes<L: VoxelLookup, const CLAMP: bool, const AVX2: bool, const AVX512: bool>(
    map: &L,
    frame: &GridFrame,
    points: Soa,
    normals: Soa,
    sums: &mut PartialSums,
) {
    let n = points[0].len().min(points[1].len()).min(points[2].len());
    let n = n
        .min(normals[0].len())
        .min(normals[1].len())
        .min(normals[2].len());
    let full = n - n % LANES;
    let mut class = ClassLoop {
        map,
        frame,
        points,
        normals,
        last: LastVoxel::NONE,
        acc: ClassAccumulator::default(),
    };
    let chunk = CHUNK_BLOCKS * LANES;
    let mut begin = 0;
    while begin < full {
        let end = (begin + chunk).min(full);
        #[allow(unused_mut)] // mutated on x86-64 only
        let mut begin_8 = begin;
        #[cfg(target_arch = "x86_64")]
        if AVX512 {
            // Pairs of wide blocks first (`avx512::sample_blocks`; a chunk is a whole number of
            // pairs), then at most one wide block and one 8-lane block at the class's end.
            while begin_8 + 2 * avx512::WIDE_LANES <= end {
                // SAFETY: as below, with `begin_8 + 2 · WIDE_LANES ≤ end`.
                unsafe { avx512::sample_blocks::<L, CLAMP, true>(&mut class, begin_8) };
                begin_8 += 2 * avx512::WIDE_LANES;
            }
            // After the pairs fewer than two wide blocks are left: this runs at most once (a
            // `while`, as it was measured: an `if` here moved the loop's register allocation,
            // +3 % instructions on the loop's fine 4-bit shell).
            while begin_8 + avx512::WIDE_LANES <= end {
                // SAFETY: `AVX512` is only requested from `accumulate_avx512`, which runs only where
                // the CPU has AVX-512F and DQ; `begin_8 + WIDE_LANES ≤ end ≤ n`, the shortest of
                // the six arrays.
                unsafe { avx512::sample_blocks::<L, CLAMP, false>(&mut class, begin_8) };
                begin_8 += avx512::WIDE_LANES;
            }
        }
        for start in (begin_8..end).step_by(LANES) {
            #[cfg(target_arch = "x86_64")]
            if AVX2 {
                // SAFETY: AVX2 is only requested from `accumulate_avx2` and
                // `accumulate_avx512`, which run only where the CPU has it (and, for `AVX512`, the
                // AVX-512 features of the latter); this is inlined into them.
                unsafe { avx2::sample_block::<L, CLAMP, AVX512>(&mut class, start) };
                continue;
            }
            sample_block::<L, CLAMP>(&mut class, start, LANES);
        }
        class.acc.flush(sums);
        begin = end;
    }
    if full < n {
        sample_block::<L, CLAMP>(&mut class, full, n - full);
    }
    class.acc.finish_into(sums);
}

/// `0x01` in every byte.
const BYTE_ONES: u64 = 0x0101_0101_0101_0101;

/// Number of set bytes in `x`, whose bytes are each 0 or 1.
#[inline(always)]
fn count_bytes(x: u64) -> u64 {
    x.wrapping_mul(BYTE_ONES) >> 56
}

/// A block's Surface, Proximity and Interior lanes as byte masks: `0x01` in the byte of each lane
/// of that kind, `0` elsewhere (from the AVX-512 copy: bit `l` for lane `l`).
struct KindMasks {
    surface: u64,
    proximity: u64,
    interior: u64,
}

impl ClassAccumulator {
    /// Adds a block's non-Free and Interior lanes to the counters and returns its kinds as masks,
    /// or `None` when no lane is Surface, Proximity or Interior (the block adds nothing more).
    /// `kinds`: one [`Voxel::bits`] per lane. Frame path: no allocation.
    #[inline(always)]
    fn count_kinds(&mut self, kinds: [u8; LANES]) -> Option<KindMasks> {
        // Kinds as bit planes, one byte per lane: Free 00, Interior 01, Surface 10, Proximity 11.
        let word = u64::from_le_bytes(kinds);
        if word == 0 {
            return None;
        }
        let (low, high) = (word & BYTE_ONES, (word >> 1) & BYTE_ONES);
        self.non_free += count_bytes(low | high);
        let interior = low & !high;
        self.interior += count_bytes(interior);
        let (surface, proximity) = (high & !low, high & low);
        if surface | proximity | interior == 0 {
            return None;
        }
        Some(KindMasks {
            surface,
            proximity,
            interior,
        })
    }
}

/// The vector helpers of one SIMD copy of the block — `mat_vec`, `dot`, `cross`, `scale`,
/// `add_cross_uniform` and `to_centre` over `[$f; 3]` — written once for both widths (`__m256` in
/// [`avx2`], `__m512` in `avx512`): the same IEEE operations in the same order as their namesakes in
/// `lanes` and `surface_block`'s centre offset, so every copy gives the same bits.
/// The AVX2 ones also serve the `distance` model's AVX2 block (`distance::avx2`), hence
/// `pub(super)`. Arguments: the target feature, the f32 and i32 vector types, and the zero,
/// broadcast, add, subtract, multiply and i32 → f32 conversion intrinsics.
#[cfg(target_arch = "x86_64")]
macro_rules! vec3_ops {
    (
        $feature:literal,
        $f:ty,
        $i:ty,
        $zero:ident,
        $set1:ident,
        $add:ident,
        $sub:ident,
        $mul:ident,
        $to_f:ident
    ) => {
        /// `m · v`: `(c0 v.x + c1 v.y) + c2 v.z`, as `lanes::mat_vec`.
        #[inline]
        #[target_feature(enable = $feature)]
        pub(super) fn mat_vec(m: &Mat3, v: &[$f; 3]) -> [$f; 3] {
            let c = [m.x_axis, m.y_axis, m.z_axis];
            let mut out = [$zero(); 3];
            for r in 0..3 {
                let a = $mul($set1(c[0][r]), v[0]);
                let b = $mul($set1(c[1][r]), v[1]);
                let z = $mul($set1(c[2][r]), v[2]);
                out[r] = $add($add(a, b), z);
            }
            out
        }

        /// `(a.x b.x + a.y b.y) + a.z b.z`, as `lanes::dot`.
        #[inline]
        #[target_feature(enable = $feature)]
        pub(super) fn dot(a: &[$f; 3], b: &[$f; 3]) -> $f {
            let xy = $add($mul(a[0], b[0]), $mul(a[1], b[1]));
            $add(xy, $mul(a[2], b[2]))
        }

        /// `a × b` with glam's formula, as `lanes::cross`.
        #[inline]
        #[target_feature(enable = $feature)]
        pub(super) fn cross(a: &[$f; 3], b: &[$f; 3]) -> [$f; 3] {
            let mut out = [$zero(); 3];
            for (r, o) in out.iter_mut().enumerate() {
                let (i, j) = ((r + 1) % 3, (r + 2) % 3);
                *o = $sub($mul(a[i], b[j]), $mul(b[i], a[j]));
            }
            out
        }

        /// `v · s` per lane, as `lanes::scale`.
        #[inline]
        #[target_feature(enable = $feature)]
        pub(super) fn scale(v: &[$f; 3], s: $f) -> [$f; 3] {
            [$mul(v[0], s), $mul(v[1], s), $mul(v[2], s)]
        }

        /// `u + w × lever` with `u` and `w` the same in every lane, as
        /// `lanes::add_cross_uniform`.
        #[inline]
        #[target_feature(enable = $feature)]
        pub(super) fn add_cross_uniform(u: [f32; 3], w: [f32; 3], lever: &[$f; 3]) -> [$f; 3] {
            let mut out = [$zero(); 3];
            for (r, o) in out.iter_mut().enumerate() {
                let (i, j) = ((r + 1) % 3, (r + 2) % 3);
                *o = $add(
                    $set1(u[r]),
                    $sub($mul($set1(w[i]), lever[j]), $mul(lever[i], $set1(w[j]))),
                );
            }
            out
        }

        /// `(cell + 0.5) − grid` per axis: from each point (grid coordinates) to the centre of
        /// its voxel `cell`, in voxels.
        #[inline]
        #[target_feature(enable = $feature)]
        pub(super) fn to_centre(cell: &[$i; 3], grid: &[$f; 3]) -> [$f; 3] {
            let half = $set1(0.5);
            let mut out = [$zero(); 3];
            for r in 0..3 {
                out[r] = $sub($add($to_f(cell[r]), half), grid[r]);
            }
            out
        }
    };
}

#[cfg(target_arch = "x86_64")]
mod avx512;
mod distance;
mod portable;
use portable::{brake_block, load, look_up_fresh, place, sample_block, LastVoxel};

#[cfg(target_arch = "x86_64")]
mod avx2;

/// Tests: a one-class shell of the `n` points and normals in `soa` (x, y, z of the points, then
/// of the normals), voxel-centre method, bounding radius `radius` (m).
#[cfg(test)]
fn soa_shell(soa: &[Vec<f32>; 6], n: usize, voxel_size: f64, radius: f64) -> ClassedShell {
    use glam::{DVec3, Vec3};
    ClassedShell::new(
        &vps_voxmap::PointShell {
            points: (0..n)
                .map(|i| Vec3::new(soa[0][i], soa[1][i], soa[2][i]))
                .collect(),
            normals: (0..n)
                .map(|i| Vec3::new(soa[3][i], soa[4][i], soa[5][i]))
                .collect(),
            voxel_size,
            method: vps_voxmap::shell::ShellMethod::VoxelCentres,
            mass: vps_voxmap::MassProperties {
                volume: 0.0,
                center_of_mass: DVec3::ZERO,
                bounding_radius: radius,
            },
        },
        1,
    )
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use glam::{DVec3, Vec3};
    use vps_voxmap::{DenseGrid, GridSpec, Voxel};

    /// The AVX2 and AVX-512 copies and the baseline copy of the hot loop give the same bits.
    #[test]
    fn simd_and_baseline_copies_agree_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        let spec = GridSpec {
            origin: DVec3::splat(-0.1),
            voxel_size: 0.005,
            dims: [40, 40, 40],
        };
        let mut grid = DenseGrid::new(spec);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for b in grid.data.iter_mut() {
            *b = (next() % 4) as u8;
        }
        let n = 1003;
        let mut soa = [(); 6].map(|_| Vec::with_capacity(n));
        for _ in 0..n {
            for (k, a) in soa.iter_mut().enumerate() {
                let u = (next() % 2001) as f32 / 1000.0 - 1.0;
                a.push(if k < 3 { 0.06 * u } else { u });
            }
        }
        let pose = KernelPose {
            rotation: Mat3::from_euler(glam::EulerRot::XYZ, 0.4, -0.9, 2.2),
            translation: Vec3::new(0.013, -0.021, 0.004),
            linear_velocity: Vec3::new(0.3, -0.7, 0.2),
            angular_velocity: Vec3::new(-4.0, 2.5, 7.0),
        };
        let shell_of = |soa: &[Vec<f32>; 6]| soa_shell(soa, n, spec.voxel_size, 0.1);
        let shell = shell_of(&soa);
        // The frame's bound is loose (normals up to √3 long here, fast spin) and asks for
        // clamping; the actual values are far below Y_MAX, so both copies must agree.
        let frame = GridFrame {
            needs_clamp: false,
            ..GridFrame::new(&grid, &pose, &shell)
        };
        // The portable copy's sums, after checking that the AVX2 and (where the CPU has it) the
        // AVX-512 copies give the same bits.
        let every_copy = |frame: &GridFrame, soa: &[Vec<f32>; 6]| {
            let points = [&soa[0][..], &soa[1][..], &soa[2][..]];
            let normals = [&soa[3][..], &soa[4][..], &soa[5][..]];
            let mut base = PartialSums::default();
            accumulate_any::<DenseGrid, false, false>(&grid, frame, points, normals, &mut base);
            let mut avx2 = PartialSums::default();
            // SAFETY: AVX2 was detected above.
            unsafe { accumulate_avx2(&grid, frame, points, normals, &mut avx2) };
            assert_eq!(avx2, base);
            if cpu_has_avx512() {
                let mut avx512 = PartialSums::default();
                // SAFETY: AVX2, AVX-512F, AVX-512DQ and POPCNT were detected just above.
                unsafe { accumulate_avx512(&grid, frame, points, normals, &mut avx512) };
                assert_eq!(avx512, base);
            }
            base
        };
        // The sums of the points `indices`, each sampled on its own (portable copy).
        let point_by_point = |indices: Box<dyn Iterator<Item = usize>>| {
            let mut sums = PartialSums::default();
            for i in indices {
                let pts = [&soa[0][i..=i], &soa[1][i..=i], &soa[2][i..=i]];
                let nrm = [&soa[3][i..=i], &soa[4][i..=i], &soa[5][i..=i]];
                accumulate_any::<DenseGrid, false, false>(&grid, &frame, pts, nrm, &mut sums);
            }
            sums
        };
        let base = every_copy(&frame, &soa);
        assert!(base.surface > 50 && base.approaching > 20 && base.contacts > 20);
        // Shorter shells reach every way a class ends in the AVX-512 copy: pairs of wide blocks
        // only, then a lone wide block, an 8-lane block and a tail, alone or together.
        for len in [5, 8, 16, 24, 32, 40, 48, 59, 987] {
            let prefix = soa.clone().map(|mut v| {
                v.truncate(len);
                v
            });
            assert_eq!(
                every_copy(&frame, &prefix),
                point_by_point(Box::new(0..len)),
                "{len} points"
            );
        }
        // The clamping copy gives the same bits when nothing needs clamping.
        let clamping = GridFrame {
            needs_clamp: true,
            ..frame
        };
        assert_eq!(every_copy(&clamping, &soa), base);
        // A point or a normal that is not finite: the frame clamps, and every copy sends the NaN
        // contributions to -Y_MAX alike.
        for (array, index, value) in [(0, 17, f32::NAN), (4, 40, f32::INFINITY)] {
            let mut poisoned = soa.clone();
            poisoned[array][index] = value;
            let frame_poisoned = GridFrame::new(&grid, &pose, &shell_of(&poisoned));
            assert!(frame_poisoned.needs_clamp);
            assert_ne!(every_copy(&frame_poisoned, &poisoned), base);
        }
        // Each point on its own, in reverse order: the same bits (per-point rounding).
        assert_eq!(point_by_point(Box::new((0..n).rev())), base);
    }

    /// Absurd speeds clamp each contribution instead of wrapping: the braking sums stay within
    /// `Y_MAX` per point and keep their sign.
    #[test]
    fn absurd_speeds_clamp_per_point() {
        let spec = GridSpec {
            origin: DVec3::splat(-0.1),
            voxel_size: 0.005,
            dims: [40, 40, 40],
        };
        let mut grid = DenseGrid::new(spec);
        grid.data.fill(Voxel::Proximity.bits());
        let shell = ClassedShell::new(
            &vps_voxmap::PointShell {
                points: vec![Vec3::ZERO; 3],
                normals: vec![Vec3::Z; 3],
                voxel_size: spec.voxel_size,
                method: vps_voxmap::shell::ShellMethod::VoxelCentres,
                mass: vps_voxmap::MassProperties {
                    volume: 0.0,
                    center_of_mass: DVec3::ZERO,
                    bounding_radius: 0.0,
                },
            },
            1,
        );
        let pose = KernelPose {
            rotation: Mat3::IDENTITY,
            translation: Vec3::ZERO,
            linear_velocity: Vec3::new(0.0, 0.0, -1.0e5),
            angular_velocity: Vec3::ZERO,
        };
        let sums = sample_all(&grid, &shell, &pose);
        assert_eq!(sums.approaching, 3);
        let cap = 3 * (1i128 << 50);
        assert_eq!(sums.brake_sq, cap);
        assert_eq!(sums.brake_force, [0, 0, -cap]);
    }
}
