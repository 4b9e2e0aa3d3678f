//! The sampling kernel (DESIGN §3): transform each point of a class by the part's pose, look up its
//! voxel and add its contribution to [`PartialSums`]. No allocation, no locks, no I/O.

use crate::classed::ClassedShell;
use crate::state::KernelPose;
use crate::sums::{PartialSums, AREA_SCALE_F32, LENGTH_SCALE_F32};
use glam::{Mat3, Vec3};
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

/// The hot loop over one class's index range.
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
    for i in 0..px.len() {
        // (P − x) in metres, then P in grid coordinates.
        let lever = rot * Vec3::new(px[i], py[i], pz[i]);
        let grid = lever * frame.inv_voxel + frame.translation_grid;
        let cell = grid.floor();
        let kind = map.get(cell.as_ivec3());
        if kind == Voxel::Free {
            continue;
        }
        sums.non_free += 1;
        let normal = rot * Vec3::new(nx[i], ny[i], nz[i]);
        match kind {
            Voxel::Surface => {
                sums.surface += 1;
                let depth = normal.dot(cell + Vec3::splat(0.5) - grid).max(0.0) * frame.voxel;
                sums.contacts += (depth > 0.0) as u64;
                let force_dir = normal * depth;
                add_quantised(&mut sums.depth_normal, force_dir, LENGTH_SCALE_F32);
                add_quantised(
                    &mut sums.depth_torque,
                    lever.cross(force_dir),
                    AREA_SCALE_F32,
                );
            }
            Voxel::Proximity => {
                let velocity = frame.linear_velocity + frame.angular_velocity.cross(lever);
                let approach = velocity.dot(normal);
                if approach < 0.0 {
                    sums.approaching += 1;
                    sums.brake_sq += quantise(approach * approach, LENGTH_SCALE_F32);
                    let brake_dir = normal * approach;
                    add_quantised(&mut sums.brake_force, brake_dir, LENGTH_SCALE_F32);
                    add_quantised(
                        &mut sums.brake_torque,
                        lever.cross(brake_dir),
                        AREA_SCALE_F32,
                    );
                }
            }
            _ => sums.interior += 1,
        }
    }
}

/// `value · scale` truncated toward zero (saturating; NaN → 0). `scale` is a power of two, so the
/// product is exact unless it overflows f32.
#[inline(always)]
fn quantise(value: f32, scale: f32) -> i128 {
    ((value * scale) as i64) as i128
}

#[inline(always)]
fn add_quantised(acc: &mut [i128; 3], v: Vec3, scale: f32) {
    acc[0] += quantise(v.x, scale);
    acc[1] += quantise(v.y, scale);
    acc[2] += quantise(v.z, scale);
}
