//! The synthetic kernel case and a short timing of the current sampling kernel on it, for
//! estimates such as `vps scene check`'s "does a frame fit the budget": nanoseconds per point in
//! full contact, tree lookup included, one core. The case, shared with `vps bench kernel` (which
//! also times the previous kernel and free space on it): a spherical point shell of radius R
//! voxels ([`sphere_shell`]: Fibonacci lattice, inward normals, Morton order) centred in a
//! spherical Surface band of 3 voxels around radius R ([`band_scene`]), so every point reads a
//! Surface voxel of a mixed leaf. Not a subcommand.

use anyhow::Result;
use glam::{DQuat, DVec3, Vec3};
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;
use vps_haptic::{sample_all, ClassedShell, KernelPose, PartState};
use vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS;
use vps_voxmap::{DenseGrid, GridSpec, MassProperties, PointShell, TreeConfig, Voxel, VoxelTree};

/// Voxel size of the synthetic scene (m); only the counts matter to the kernel.
pub const VOXEL_SIZE: f64 = 0.005;

/// Timed batches; the figure is their median.
const BATCHES: usize = 5;

/// The most points timed: the synthetic voxmap grows as the shell's area, so larger shells are
/// timed at this size (the cost per point is flat beyond a few thousand points).
pub const MAX_TIMED_POINTS: usize = 200_000;

/// Nanoseconds per point of the current kernel in full contact with `points` points (clamped to
/// 1..=[`MAX_TIMED_POINTS`]), the median of `BATCHES` (5) batches of about `batch_seconds` (s)
/// each; with `distance`, of the `distance` force model (the same sphere carrying a
/// signed-distance band, [`sphere_band`]). Allocates the synthetic scene (about 8 bytes per point
/// of voxmap); blocks for about `(BATCHES + 1) × batch_seconds`.
pub fn contact_ns_per_point(points: usize, batch_seconds: f64, distance: bool) -> Result<f64> {
    let n = points.clamp(1, MAX_TIMED_POINTS);
    let radius_vox = shell_radius_vox(n);
    let dense = band_scene(radius_vox, false);
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default())?;
    let tree = if distance {
        let band = sphere_band(&dense.spec, radius_vox, DEFAULT_STANDOFF_VOXELS)?;
        tree.with_distance_band(band)
    } else {
        tree
    };
    let shell = ClassedShell::new(&sphere_shell(n, radius_vox * VOXEL_SIZE), 1);
    let centre = dense.spec.origin + DVec3::splat(dense.spec.dims[0] as f64 / 2.0) * VOXEL_SIZE;
    let pose = KernelPose::from_state(&PartState::at_rest(centre, DQuat::IDENTITY));
    let start = Instant::now();
    black_box(sample_all(&tree, &shell, &pose));
    let once = start.elapsed().as_secs_f64().max(1e-7);
    let reps = ((batch_seconds / once) as usize).clamp(1, 1_000_000);
    let mut batches: Vec<f64> = (0..BATCHES)
        .map(|_| {
            let t = Instant::now();
            for _ in 0..reps {
                black_box(sample_all(black_box(&tree), &shell, black_box(&pose)));
            }
            t.elapsed().as_secs_f64() * 1e9 / (reps * shell.len().max(1)) as f64
        })
        .collect();
    batches.sort_by(f64::total_cmp);
    Ok(batches[BATCHES / 2])
}

/// Radius (voxels) of the synthetic shell of `n` points: about one point per voxel of its area,
/// at least 3 voxels.
pub fn shell_radius_vox(n: usize) -> f64 {
    (n as f64 / (4.0 * std::f64::consts::PI)).sqrt().max(3.0)
}

/// `n` points on a sphere of `radius` (m) centred at the origin (Fibonacci lattice), inward
/// normals, in Morton order by [`VOXEL_SIZE`] voxel. Allocates.
pub fn sphere_shell(n: usize, radius: f64) -> PointShell {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut pairs: Vec<(Vec3, Vec3)> = (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            let dir = DVec3::new(r * a.cos(), r * a.sin(), z);
            ((dir * radius).as_vec3(), (-dir).as_vec3())
        })
        .collect();
    pairs.sort_by_key(|(p, _)| {
        let v = (*p / VOXEL_SIZE as f32 + Vec3::splat(1e6)).as_uvec3();
        vps_voxelize::shell::morton_key([v.x, v.y, v.z])
    });
    PointShell {
        points: pairs.iter().map(|p| p.0).collect(),
        normals: pairs.iter().map(|p| p.1).collect(),
        voxel_size: VOXEL_SIZE,
        method: vps_voxmap::shell::ShellMethod::VoxelCentres,
        mass: MassProperties {
            volume: 0.0,
            center_of_mass: DVec3::ZERO,
            bounding_radius: radius,
        },
    }
}

/// The synthetic scene at origin 0: a cube of side S = ceil(2 (`radius_vox` + 4)) voxels holding
/// a spherical Surface band of 3 voxels around `radius_vox` voxels from its centre (S/2 in each
/// axis), Interior inside, Proximity one voxel outside, Free beyond; with `free_slot`, a second,
/// all-Free cube of the same size beside it along x (the grid is 2S × S × S; its centre is the
/// free pose). Allocates S³ (or 2S³) bytes; parallel over z slices.
pub fn band_scene(radius_vox: f64, free_slot: bool) -> DenseGrid {
    let slot = (2.0 * (radius_vox + 4.0)).ceil() as u32;
    let spec = GridSpec::at_origin(
        VOXEL_SIZE,
        [if free_slot { 2 * slot } else { slot }, slot, slot],
    );
    let centre = DVec3::splat(slot as f64 / 2.0);
    let mut grid = DenseGrid::new(spec);
    let plane = (spec.dims[0] * spec.dims[1]) as usize;
    grid.data
        .par_chunks_mut(plane)
        .enumerate()
        .for_each(|(z, slice)| {
            for y in 0..spec.dims[1] as usize {
                for x in 0..slot as usize {
                    let p = DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5);
                    let d = (p - centre).length() - radius_vox;
                    let v = if d < -1.5 {
                        Voxel::Interior
                    } else if d <= 1.5 {
                        Voxel::Surface
                    } else if d <= 2.5 {
                        Voxel::Proximity
                    } else {
                        Voxel::Free
                    };
                    slice[x + y * spec.dims[0] as usize] = v as u8;
                }
            }
        });
    grid
}

/// The distance band of the solid ball of radius `radius_vox + 0.5` voxels about the first slot's
/// centre of `spec` (as [`band_scene`] lays it out), with stand-off `standoff_voxels`, computed
/// analytically: a shell of radius `radius_vox` there has every point half a voxel inside the
/// ball, in contact. Allocates about 729 bytes per cube near the sphere.
pub fn sphere_band(
    spec: &GridSpec,
    radius_vox: f64,
    standoff_voxels: f64,
) -> Result<vps_voxmap::DistanceBand> {
    use vps_voxmap::distance::{self, CubeCodes, BRICK_CODES, BRICK_EDGE};
    let centre = DVec3::splat(spec.dims[1] as f64 / 2.0);
    let ball = radius_vox + 0.5;
    Ok(distance::assemble(
        spec,
        standoff_voxels * spec.voxel_size,
        |c| {
            let mut codes = Box::new([0i8; BRICK_CODES]);
            for z in 0..BRICK_EDGE {
                for y in 0..BRICK_EDGE {
                    for x in 0..BRICK_EDGE {
                        let p = DVec3::new(
                            f64::from(c[0] * 8) + x as f64 + 0.5,
                            f64::from(c[1] * 8) + y as f64 + 0.5,
                            f64::from(c[2] * 8) + z as f64 + 0.5,
                        );
                        let d = (p - centre).length() - ball - standoff_voxels;
                        codes[(z * BRICK_EDGE + y) * BRICK_EDGE + x] = distance::code_of(d, 1.0);
                    }
                }
            }
            CubeCodes::from_codes(codes)
        },
    )?)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The synthetic pose puts every point in a Surface voxel (the figure is full contact).
    #[test]
    fn every_point_is_in_surface() {
        let n = 2000;
        let radius_vox = (n as f64 / (4.0 * std::f64::consts::PI)).sqrt();
        let dense = band_scene(radius_vox, false);
        let tree = VoxelTree::from_dense(&dense, TreeConfig::default()).unwrap();
        let shell = ClassedShell::new(&sphere_shell(n, radius_vox * VOXEL_SIZE), 1);
        let centre = DVec3::splat(dense.spec.dims[0] as f64 / 2.0) * VOXEL_SIZE;
        let pose = KernelPose::from_state(&PartState::at_rest(centre, DQuat::IDENTITY));
        assert_eq!(sample_all(&tree, &shell, &pose).surface, n as u64);
        assert!(contact_ns_per_point(n, 0.001, false).unwrap() > 0.0);
        assert!(contact_ns_per_point(n, 0.001, true).unwrap() > 0.0);
    }
}
