//! The sampling kernel (DESIGN §3): transform each point of a class by the part's pose, look up its
//! voxel and add its contribution to [`PartialSums`]. No allocation, no locks, no I/O.

use crate::classed::ClassedShell;
use crate::state::KernelPose;
use crate::sums::{PartialSums, AREA_SCALE, LENGTH_SCALE};
use glam::{DVec3, IVec3, Mat3, Vec3};
use vps_voxmap::{Voxel, VoxelLookup};

/// The sums of class `class` of `shell` at `pose` against `map`.
///
/// Per point: `P = R p + x`; `ijk = floor((P − origin) / s)` in f32 (indices outside the grid read
/// as Free through [`VoxelLookup::get`]). Surface: depth `d = max(0, N·(C − P))` with `N = R n`
/// and `C` the voxel centre, computed in voxel coordinates so that `C − P` is exact to f32 rounding
/// of the point's own position; adds `d N` and `(P − x) × d N`. Proximity with `V·N < 0`
/// (`V = v + w × (P − x)`): adds to the braking sums. Interior: counted. Every contribution is
/// quantised to integers before it is added (see [`crate::sums`]).
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
    let mut sums = PartialSums::default();
    if let Some(range) = shell.class_range(class) {
        sums.sampled = range.len() as u64;
        if pose.is_sane() {
            let frame = GridFrame::new(map, pose);
            accumulate(map, shell, &frame, range, &mut sums);
        }
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
    let mut sums = PartialSums::default();
    for &class in classes {
        sums.merge(&sample_class(map, shell, pose, class));
    }
    sums
}

/// The merged sums of every class of `shell`. Does not allocate or block.
pub fn sample_all<L: VoxelLookup>(map: &L, shell: &ClassedShell, pose: &KernelPose) -> PartialSums {
    let mut sums = PartialSums::default();
    for class in 0..shell.class_count() {
        sums.merge(&sample_class(map, shell, pose, class));
    }
    sums
}

/// The pose expressed in grid coordinates (voxel units, origin at the grid's minimum corner).
struct GridFrame {
    rotation: Mat3,
    /// `(x − origin) / s`.
    translation_grid: Vec3,
    inv_voxel: f32,
    voxel: f32,
    linear_velocity: Vec3,
    angular_velocity: Vec3,
}

impl GridFrame {
    #[inline]
    fn new<L: VoxelLookup>(map: &L, pose: &KernelPose) -> Self {
        let spec = map.spec();
        let inv = 1.0 / spec.voxel_size;
        Self {
            rotation: pose.rotation,
            translation_grid: ((pose.translation.as_dvec3() - spec.origin) * inv).as_vec3(),
            inv_voxel: inv as f32,
            voxel: spec.voxel_size as f32,
            linear_velocity: pose.linear_velocity,
            angular_velocity: pose.angular_velocity,
        }
    }
}

/// Floating-point running sums of one class, accumulated in f64 in ascending point order and
/// quantised once at the end of the class (see [`accumulate`]).
#[derive(Default)]
struct ClassAccumulator {
    depth_normal: DVec3,
    depth_torque: DVec3,
    brake_sq: f64,
    brake_force: DVec3,
    brake_torque: DVec3,
}

impl ClassAccumulator {
    /// Adds the rounded class totals to `sums`.
    fn quantise_into(&self, sums: &mut PartialSums) {
        let q3 = |acc: &mut [i128; 3], v: DVec3, scale: f64| {
            acc[0] += quantise(v.x, scale);
            acc[1] += quantise(v.y, scale);
            acc[2] += quantise(v.z, scale);
        };
        q3(&mut sums.depth_normal, self.depth_normal, LENGTH_SCALE);
        q3(&mut sums.depth_torque, self.depth_torque, AREA_SCALE);
        sums.brake_sq += quantise(self.brake_sq, LENGTH_SCALE);
        q3(&mut sums.brake_force, self.brake_force, LENGTH_SCALE);
        q3(&mut sums.brake_torque, self.brake_torque, AREA_SCALE);
    }
}

/// The hot loop over one class's index range.
///
/// Exactness (DESIGN §4): within a class, contributions are added in f64 in one canonical order
/// (ascending point index), so a class's total is the same bits wherever it is computed (IEEE
/// arithmetic, no fused multiply-add); the total is then quantised to integers once. Classes are
/// the unit of work, and integers merge exactly, so any grouping of classes gives identical sums.
/// Quantising once per class instead of once per point keeps the inner loop in floating point.
#[inline]
fn accumulate<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    frame: &GridFrame,
    range: std::ops::Range<usize>,
    sums: &mut PartialSums,
) {
    let (px, py, pz) = (
        &shell.px[range.clone()],
        &shell.py[range.clone()],
        &shell.pz[range.clone()],
    );
    let (nx, ny, nz) = (
        &shell.nx[range.clone()],
        &shell.ny[range.clone()],
        &shell.nz[range],
    );
    let rot = frame.rotation;
    let mut acc = ClassAccumulator::default();
    for i in 0..px.len() {
        // (P − x) in metres, then P in grid coordinates.
        let lever = rot * Vec3::new(px[i], py[i], pz[i]);
        let grid = lever * frame.inv_voxel + frame.translation_grid;
        let index = floor_to_ivec3(grid);
        let kind = map.get(index);
        if kind == Voxel::Free {
            continue;
        }
        sums.non_free += 1;
        let normal = rot * Vec3::new(nx[i], ny[i], nz[i]);
        match kind {
            Voxel::Surface => {
                sums.surface += 1;
                let cell = index.as_vec3();
                let depth = normal.dot(cell + Vec3::splat(0.5) - grid).max(0.0) * frame.voxel;
                sums.contacts += (depth > 0.0) as u64;
                let force_dir = normal * depth;
                acc.depth_normal += force_dir.as_dvec3();
                acc.depth_torque += lever.cross(force_dir).as_dvec3();
            }
            Voxel::Proximity => {
                let velocity = frame.linear_velocity + frame.angular_velocity.cross(lever);
                let approach = velocity.dot(normal);
                if approach < 0.0 {
                    sums.approaching += 1;
                    acc.brake_sq += (approach * approach) as f64;
                    let brake_dir = normal * approach;
                    acc.brake_force += brake_dir.as_dvec3();
                    acc.brake_torque += lever.cross(brake_dir).as_dvec3();
                }
            }
            _ => sums.interior += 1,
        }
    }
    acc.quantise_into(sums);
}

/// `floor(v)` per component as integers, without a libm call: on baseline x86-64 (no SSE4.1)
/// `f32::floor` is a function call that cost more than the whole voxel lookup. Truncate, then step
/// down where truncation rounded a negative value up. A value beyond the i32 range (or NaN) gives
/// `i32::MIN` or `i32::MAX`, which lies outside any grid (dims are at most `i32::MAX`): read as
/// Free.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn floor_to_ivec3(v: Vec3) -> IVec3 {
    use std::arch::x86_64::{
        __m128i, _mm_add_epi32, _mm_castps_si128, _mm_cmplt_ps, _mm_cvtepi32_ps, _mm_cvttps_epi32,
        _mm_set_ps, _mm_storeu_si128,
    };
    // All three axes in one SSE2 register: the scalar `as i32` saturates and checks NaN per axis
    // (a compare, a branch and a conditional move each), where `cvttps2dq` gives `i32::MIN` for
    // every out-of-range or NaN lane in one instruction.
    let mut out = [0i32; 4];
    // SAFETY: SSE and SSE2 are part of the x86-64 baseline, so these instructions exist on every
    // x86-64 CPU; `out` is 16 writable bytes and `storeu` has no alignment requirement.
    unsafe {
        let x = _mm_set_ps(0.0, v.z, v.y, v.x);
        let truncated = _mm_cvttps_epi32(x);
        // All ones (−1) where truncation rounded up, i.e. `x < trunc(x)`; adding steps down by one.
        let rounded_up = _mm_castps_si128(_mm_cmplt_ps(x, _mm_cvtepi32_ps(truncated)));
        let floored = _mm_add_epi32(truncated, rounded_up);
        _mm_storeu_si128(out.as_mut_ptr().cast::<__m128i>(), floored);
    }
    IVec3::new(out[0], out[1], out[2])
}

/// Portable form of the x86-64 [`floor_to_ivec3`]: the same results (out-of-range values
/// saturate, outside any grid).
#[cfg(not(target_arch = "x86_64"))]
#[inline(always)]
fn floor_to_ivec3(v: Vec3) -> IVec3 {
    #[inline(always)]
    fn floor(x: f32) -> i32 {
        let t = x as i32;
        t - (x < t as f32) as i32
    }
    IVec3::new(floor(v.x), floor(v.y), floor(v.z))
}

/// `value · scale` truncated toward zero, saturating (NaN → 0). `scale` is a power of two, so the
/// product is exact unless it overflows.
#[inline(always)]
fn quantise(value: f64, scale: f64) -> i128 {
    (value * scale) as i128
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn floor_matches_f32_floor_and_sends_huge_values_outside_any_grid() {
        for &x in &[
            0.0f32,
            -0.0,
            0.5,
            -0.5,
            1.0,
            -1.0,
            2.999_999,
            -2.000_001,
            16_777_215.0,
        ] {
            let got = floor_to_ivec3(Vec3::new(x, -x, x * 0.25));
            let want = IVec3::new(
                x.floor() as i32,
                (-x).floor() as i32,
                (x * 0.25).floor() as i32,
            );
            assert_eq!(got, want, "x = {x}");
        }
        for &x in &[3e9f32, -3e9, f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            let got = floor_to_ivec3(Vec3::splat(x));
            for c in got.to_array() {
                assert!(c < 0 || c == i32::MAX, "x = {x} gave {c}");
            }
        }
    }
}
