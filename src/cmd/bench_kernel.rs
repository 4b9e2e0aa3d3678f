//! `vps bench kernel`: nanoseconds per point of the sampling kernel on one core, tree lookup
//! included, for 10k, 100k and 1M points (by default), in free space and in full contact: the
//! current kernel (per-point fixed point, AVX2 blocks) and the previous one (per-class f64 sums,
//! `vps_haptic::previous`), alternated batch by batch in one run so that their ratio holds on a
//! loaded machine.
//!
//! The synthetic case: a spherical point shell of radius R voxels (Fibonacci lattice, inward
//! normals, ≈ one point per voxel of area, so R = √(n / 4π) voxels) and a voxmap holding, in one
//! slot, a spherical Surface band of 3 voxels around radius R (Interior inside, Proximity outside)
//! and, in a second slot of the same size, nothing. Full contact: the shell centred in the band slot,
//! every point in a Surface voxel of a mixed (non-tile) leaf. Free space: the same shell centred in
//! the empty slot, every point in Free tiles. Both poses read the same tree in the same run.

use crate::host::load_average;
use anyhow::Result;
use glam::{DQuat, DVec3, Vec3};
use rayon::prelude::*;
use serde::Serialize;
use std::hint::black_box;
use std::time::Instant;
use vps_haptic::{sample_all, ClassedShell, KernelPose, PartState, PartialSums};
use vps_voxmap::{DenseGrid, GridSpec, MassProperties, PointShell, Voxel, VoxelLookup};
use vps_voxmap::{TreeConfig, VoxelTree};

/// Voxel size of the synthetic scene (m); only the counts matter to the kernel.
const VOXEL_SIZE: f64 = 0.005;

/// Batches per case and kernel (alternated: previous, current, current, previous, …).
const BATCHES: usize = 6;

/// One kernel's figures for one shell size.
#[derive(Serialize)]
pub struct KernelTimes {
    /// ns per point, full contact, tree lookup (median of the batches).
    pub contact_ns_per_point: f64,
    /// ns per point, free space, tree lookup (median of the batches).
    pub free_ns_per_point: f64,
    /// Worst over best of the two cases.
    pub worst_over_best: f64,
}

/// One measured configuration.
#[derive(Serialize)]
pub struct KernelFigure {
    /// Points in the shell.
    pub points: usize,
    /// The current kernel.
    pub current: KernelTimes,
    /// The previous kernel (per-class f64 sums, `vps_haptic::previous`), measured alternately.
    pub previous: KernelTimes,
    /// Previous over current ns per point in contact (median of the per-round ratios; > 1: the
    /// current kernel is faster).
    pub contact_speedup: f64,
    /// Previous over current ns per point in free space (median of the per-round ratios).
    pub free_speedup: f64,
    /// ns per point, full contact, dense-grid lookup (the current kernel with a trivial lookup).
    pub contact_dense_ns_per_point: f64,
    /// Fraction of points that landed in Surface voxels in the contact pose (should be 1).
    pub contact_surface_fraction: f64,
    /// Tree memory of the synthetic scene (bytes).
    pub tree_bytes: usize,
}

/// The host while the benchmark ran: read the figures against its load.
#[derive(Serialize)]
pub struct HostLoad {
    /// Logical CPUs available to this process.
    pub cpus: usize,
    /// 1-minute load average before the first measurement (Linux; null elsewhere).
    pub load_before: Option<f64>,
    /// 1-minute load average after the last measurement.
    pub load_after: Option<f64>,
    /// Whether the CPU has AVX2 (both kernels have an AVX2 copy; without it both run their
    /// baseline copies).
    pub avx2: bool,
}

/// The whole report.
#[derive(Serialize)]
pub struct KernelReport {
    /// What was measured and how.
    pub method: &'static str,
    /// The host's load while measuring.
    pub host: HostLoad,
    /// One entry per shell size.
    pub figures: Vec<KernelFigure>,
}

/// Runs the benchmark for each point count and returns the report.
pub fn run(point_counts: &[usize], batch_seconds: f64) -> Result<KernelReport> {
    let load_before = load_average();
    let mut figures = Vec::new();
    for &n in point_counts {
        figures.push(measure(n, batch_seconds)?);
    }
    Ok(KernelReport {
        method: "single thread, class_count 1, sample_all over the whole shell repeated; per case, 6 \
                 batches of the previous kernel and 6 of the current one alternated (order swapped every round), medians and the \
                 median of per-round ratios; synthetic sphere shell and spherical Surface band (see \
                 src/cmd/bench_kernel.rs)",
        host: HostLoad {
            cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
            load_before,
            load_after: load_average(),
            avx2: has_avx2(),
        },
        figures,
    })
}

fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

fn fibonacci_shell(n: usize, radius: f64) -> PointShell {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let mut points = Vec::with_capacity(n);
    let mut normals = Vec::with_capacity(n);
    for i in 0..n {
        let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
        let r = (1.0 - z * z).sqrt();
        let dir = DVec3::new(
            r * (golden * i as f64).cos(),
            r * (golden * i as f64).sin(),
            z,
        );
        points.push((dir * radius).as_vec3());
        normals.push((-dir).as_vec3());
    }
    // Morton order by voxel, as real shells are (the Fibonacci index order jumps across the sphere).
    let key = |p: &Vec3| {
        let v = (*p / VOXEL_SIZE as f32 + Vec3::splat(1e6)).as_uvec3();
        vps_voxelize::shell::morton_key([v.x, v.y, v.z])
    };
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&i| key(&points[i]));
    let points: Vec<Vec3> = order.iter().map(|&i| points[i]).collect();
    let normals: Vec<Vec3> = order.iter().map(|&i| normals[i]).collect();
    PointShell {
        points,
        normals,
        voxel_size: VOXEL_SIZE,
        method: vps_voxmap::shell::ShellMethod::VoxelCentres,
        mass: MassProperties {
            volume: 0.0,
            center_of_mass: DVec3::ZERO,
            bounding_radius: radius,
        },
    }
}

fn band_scene(radius_vox: f64) -> DenseGrid {
    let margin = 4.0;
    let slot = (2.0 * (radius_vox + margin)).ceil() as u32;
    let spec = GridSpec {
        origin: DVec3::ZERO,
        voxel_size: VOXEL_SIZE,
        dims: [2 * slot, slot, slot],
    };
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

/// A whole-shell kernel: `vps_haptic::sample_all` or `vps_haptic::previous::sample_all`.
type Kernel<L> = fn(&L, &ClassedShell, &KernelPose) -> PartialSums;

/// Repetitions of `kernel` that take about `secs`.
fn calibrate<L: VoxelLookup>(
    kernel: Kernel<L>,
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    secs: f64,
) -> usize {
    let start = Instant::now();
    black_box(kernel(map, shell, pose));
    let once = start.elapsed().as_secs_f64().max(1e-7);
    ((secs / once) as usize).clamp(1, 1_000_000)
}

/// ns per point of one batch of `reps` repetitions.
fn batch<L: VoxelLookup>(
    kernel: Kernel<L>,
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    reps: usize,
) -> f64 {
    let t = Instant::now();
    for _ in 0..reps {
        black_box(kernel(black_box(map), shell, black_box(pose)));
    }
    t.elapsed().as_secs_f64() * 1e9 / (reps * shell.len().max(1)) as f64
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

/// ns per point of `map` alone (median of the batches).
fn ns_per_point<L: VoxelLookup>(
    map: &L,
    shell: &ClassedShell,
    pose: &KernelPose,
    secs: f64,
) -> f64 {
    let reps = calibrate(sample_all, map, shell, pose, secs);
    median(
        (0..BATCHES)
            .map(|_| batch(sample_all, map, shell, pose, reps))
            .collect(),
    )
}

/// Previous and current ns per point (medians) and the median of the per-round ratios
/// previous / current, batches alternated with the same repetition count.
fn alternated(
    tree: &VoxelTree,
    shell: &ClassedShell,
    pose: &KernelPose,
    secs: f64,
) -> (f64, f64, f64) {
    let previous: Kernel<VoxelTree> = vps_haptic::previous::sample_all;
    let current: Kernel<VoxelTree> = sample_all;
    let reps = calibrate(previous, tree, shell, pose, secs);
    // Which kernel goes first alternates too, so that neither always runs on a cache the other
    // warmed.
    let rounds: Vec<(f64, f64)> = (0..BATCHES)
        .map(|round| {
            if round % 2 == 0 {
                let old = batch(previous, tree, shell, pose, reps);
                (old, batch(current, tree, shell, pose, reps))
            } else {
                let new = batch(current, tree, shell, pose, reps);
                (batch(previous, tree, shell, pose, reps), new)
            }
        })
        .collect();
    (
        median(rounds.iter().map(|r| r.0).collect()),
        median(rounds.iter().map(|r| r.1).collect()),
        median(rounds.iter().map(|r| r.0 / r.1).collect()),
    )
}

fn pose_at(spec: &GridSpec, centre_vox: DVec3) -> KernelPose {
    let state = PartState::at_rest(spec.origin + centre_vox * spec.voxel_size, DQuat::IDENTITY);
    KernelPose::from_state(&state)
}

fn measure(n: usize, batch_seconds: f64) -> Result<KernelFigure> {
    let radius_vox = (n as f64 / (4.0 * std::f64::consts::PI)).sqrt().max(3.0);
    let dense = band_scene(radius_vox);
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default())?;
    let shell = ClassedShell::new(&fibonacci_shell(n, radius_vox * VOXEL_SIZE), 1);
    let slot = dense.spec.dims[1] as f64;
    let contact = pose_at(&dense.spec, DVec3::splat(slot / 2.0));
    let free = pose_at(&dense.spec, DVec3::new(slot * 1.5, slot / 2.0, slot / 2.0));
    let sums = sample_all(&tree, &shell, &contact);
    // The same voxels and contributions, rounded per point instead of per class: the counts agree
    // exactly and the sums to within one LSB per point.
    let old = vps_haptic::previous::sample_all(&tree, &shell, &contact);
    let slack = n as i128;
    anyhow::ensure!(
        (old.surface, old.contacts, old.non_free) == (sums.surface, sums.contacts, sums.non_free)
            && (0..3).all(
                |k| (old.depth_normal[k] - sums.depth_normal[k]).abs() <= slack
                    && (old.depth_torque[k] - sums.depth_torque[k]).abs() <= slack
            ),
        "the previous and current kernels disagree"
    );
    let (old_contact, new_contact, contact_speedup) =
        alternated(&tree, &shell, &contact, batch_seconds);
    let (old_free, new_free, free_speedup) = alternated(&tree, &shell, &free, batch_seconds);
    let dense_ns = ns_per_point(&dense, &shell, &contact, batch_seconds);
    let times = |contact: f64, free: f64| KernelTimes {
        contact_ns_per_point: contact,
        free_ns_per_point: free,
        worst_over_best: contact.max(free) / contact.min(free),
    };
    Ok(KernelFigure {
        points: n,
        current: times(new_contact, new_free),
        previous: times(old_contact, old_free),
        contact_speedup,
        free_speedup,
        contact_dense_ns_per_point: dense_ns,
        contact_surface_fraction: sums.surface as f64 / n as f64,
        tree_bytes: tree.memory_bytes(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_pose_puts_every_point_in_surface_and_free_pose_in_free() {
        let n = 400;
        let radius_vox = (n as f64 / (4.0 * std::f64::consts::PI)).sqrt().max(3.0);
        let dense = band_scene(radius_vox);
        let shell = ClassedShell::new(&fibonacci_shell(n, radius_vox * VOXEL_SIZE), 1);
        let slot = dense.spec.dims[1] as f64;
        let contact = pose_at(&dense.spec, DVec3::splat(slot / 2.0));
        let free = pose_at(&dense.spec, DVec3::new(slot * 1.5, slot / 2.0, slot / 2.0));
        assert_eq!(sample_all(&dense, &shell, &contact).surface, n as u64);
        let free_sums = sample_all(&dense, &shell, &free);
        assert_eq!(free_sums.surface + free_sums.interior, 0);
    }
}
