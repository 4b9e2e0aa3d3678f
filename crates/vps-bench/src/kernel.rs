//! `vps bench kernel`: nanoseconds per point of the sampling kernel on one core, tree lookup
//! included, for 10k, 100k and 1M points (by default), in free space and in full contact: the
//! current kernel (per-point fixed point; AVX-512 blocks where the CPU has AVX-512F and DQ) and the
//! previous one (the same kernel on at most AVX2, `vps_haptic::avx2_only`), alternated batch by
//! batch in one run so that their ratio holds on a loaded machine. Both give the same sums, bit
//! for bit (checked before timing).
//!
//! The synthetic case: a spherical point shell of radius R voxels (Fibonacci lattice, inward
//! normals, ≈ one point per voxel of area, so R = √(n / 4π) voxels) and a voxmap holding, in one
//! slot, a spherical Surface band of 3 voxels around radius R (Interior inside, Proximity outside)
//! and, in a second slot of the same size, nothing. Full contact: the shell centred in the band slot,
//! every point in a Surface voxel of a mixed (non-tile) leaf. Free space: the same shell centred in
//! the empty slot, every point in Free tiles. Both poses read the same tree in the same run. The
//! case is built by `vps_app::kernel_timing` (`vps scene check` times the same contact case).

use crate::machine::load_average;
use anyhow::Result;
use glam::{DQuat, DVec3};
use serde::Serialize;
use std::hint::black_box;
use std::time::Instant;
use vps_app::kernel_timing::{band_scene, shell_radius_vox, sphere_band, sphere_shell, VOXEL_SIZE};
use vps_haptic::{sample_all, ClassedShell, KernelPose, PartState, PartialSums};
use vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS;
use vps_voxmap::{GridSpec, VoxelLookup};
use vps_voxmap::{TreeConfig, VoxelTree};

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
    /// The previous kernel (the current one on at most AVX2, `vps_haptic::avx2_only`), measured
    /// alternately.
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
    /// The `distance` force model on the same tree carrying a signed-distance band of the same
    /// sphere (a ball half a voxel beyond the shell, the default stand-off), alternated batch by
    /// batch with the current tangent-plane kernel.
    pub distance: KernelTimes,
    /// Distance over tangent-plane ns per point in contact (median of the per-round ratios; < 1:
    /// the distance model is faster).
    pub distance_over_tangent_contact: f64,
    /// Distance over tangent-plane ns per point in free space (median of the per-round ratios).
    pub distance_over_tangent_free: f64,
    /// The tangent-plane kernel on at most AVX2 (`vps_haptic::avx2_only`), alternated batch by
    /// batch with [`KernelFigure::distance_avx2`]: what a CPU without AVX-512 runs.
    pub tangent_avx2: KernelTimes,
    /// The `distance` force model on at most AVX2, alternated with
    /// [`KernelFigure::tangent_avx2`].
    pub distance_avx2: KernelTimes,
    /// Distance over tangent-plane ns per point in contact, both on at most AVX2 (median of the
    /// per-round ratios).
    pub distance_over_tangent_contact_avx2: f64,
    /// Distance over tangent-plane ns per point in free space, both on at most AVX2.
    pub distance_over_tangent_free_avx2: f64,
    /// Points in contact with the distance model in the contact pose (should be all).
    pub distance_contact_fraction: f64,
    /// Memory of the distance band (bytes), beside `tree_bytes`.
    pub distance_band_bytes: usize,
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
    /// Whether the current kernel runs its AVX-512 copy here (AVX-512F, DQ and POPCNT besides
    /// AVX2); without it the two kernels run the same code.
    pub avx512: bool,
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
            avx2: vps_voxmap::cpu::has_avx2(),
            avx512: vps_haptic::kernel::runs_avx512_copy(),
        },
        figures,
    })
}

/// A whole-shell kernel: `vps_haptic::sample_all` or `vps_haptic::avx2_only::sample_all`.
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
    let previous: Kernel<VoxelTree> = vps_haptic::avx2_only::sample_all;
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

/// Tangent-plane and distance ns per point (medians) and the median of the per-round ratios
/// distance / tangent-plane: `kernel` on `tree` and on `band_tree` alternated.
fn alternated_models(
    kernel: Kernel<VoxelTree>,
    tree: &VoxelTree,
    band_tree: &VoxelTree,
    shell: &ClassedShell,
    pose: &KernelPose,
    secs: f64,
) -> (f64, f64, f64) {
    let reps = calibrate(kernel, tree, shell, pose, secs);
    let rounds: Vec<(f64, f64)> = (0..BATCHES)
        .map(|round| {
            if round % 2 == 0 {
                let tangent = batch(kernel, tree, shell, pose, reps);
                (tangent, batch(kernel, band_tree, shell, pose, reps))
            } else {
                let distance = batch(kernel, band_tree, shell, pose, reps);
                (batch(kernel, tree, shell, pose, reps), distance)
            }
        })
        .collect();
    (
        median(rounds.iter().map(|r| r.0).collect()),
        median(rounds.iter().map(|r| r.1).collect()),
        median(rounds.iter().map(|r| r.1 / r.0).collect()),
    )
}

fn pose_at(spec: &GridSpec, centre_vox: DVec3) -> KernelPose {
    let state = PartState::at_rest(spec.origin + centre_vox * spec.voxel_size, DQuat::IDENTITY);
    KernelPose::from_state(&state)
}

fn measure(n: usize, batch_seconds: f64) -> Result<KernelFigure> {
    let radius_vox = shell_radius_vox(n);
    let dense = band_scene(radius_vox, true);
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default())?;
    let shell = ClassedShell::new(&sphere_shell(n, radius_vox * VOXEL_SIZE), 1);
    let slot = dense.spec.dims[1] as f64;
    let contact = pose_at(&dense.spec, DVec3::splat(slot / 2.0));
    let free = pose_at(&dense.spec, DVec3::new(slot * 1.5, slot / 2.0, slot / 2.0));
    let sums = sample_all(&tree, &shell, &contact);
    // The same kernel on another copy of the block loop: the same bits.
    let old = vps_haptic::avx2_only::sample_all(&tree, &shell, &contact);
    anyhow::ensure!(old == sums, "the previous and current kernels disagree");
    let (old_contact, new_contact, contact_speedup) =
        alternated(&tree, &shell, &contact, batch_seconds);
    let (old_free, new_free, free_speedup) = alternated(&tree, &shell, &free, batch_seconds);
    let dense_ns = ns_per_point(&dense, &shell, &contact, batch_seconds);
    let band = sphere_band(&dense.spec, radius_vox, DEFAULT_STANDOFF_VOXELS)?;
    let band_bytes = band.memory_bytes();
    let band_tree = tree.clone().with_distance_band(band);
    let band_sums = sample_all(&band_tree, &shell, &contact);
    anyhow::ensure!(
        sample_all(&band_tree, &shell, &free).non_free == 0,
        "the distance model's free pose touches"
    );
    anyhow::ensure!(
        vps_haptic::avx2_only::sample_all(&band_tree, &shell, &contact) == band_sums,
        "the distance model's copies disagree"
    );
    let current_kernel: Kernel<VoxelTree> = sample_all;
    let avx2_kernel: Kernel<VoxelTree> = vps_haptic::avx2_only::sample_all;
    let (_, distance_contact, distance_over_tangent_contact) = alternated_models(
        current_kernel,
        &tree,
        &band_tree,
        &shell,
        &contact,
        batch_seconds,
    );
    let (_, distance_free, distance_over_tangent_free) = alternated_models(
        current_kernel,
        &tree,
        &band_tree,
        &shell,
        &free,
        batch_seconds,
    );
    let (tangent_avx2_contact, distance_avx2_contact, distance_over_tangent_contact_avx2) =
        alternated_models(
            avx2_kernel,
            &tree,
            &band_tree,
            &shell,
            &contact,
            batch_seconds,
        );
    let (tangent_avx2_free, distance_avx2_free, distance_over_tangent_free_avx2) =
        alternated_models(avx2_kernel, &tree, &band_tree, &shell, &free, batch_seconds);
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
        distance: times(distance_contact, distance_free),
        distance_over_tangent_contact,
        distance_over_tangent_free,
        tangent_avx2: times(tangent_avx2_contact, tangent_avx2_free),
        distance_avx2: times(distance_avx2_contact, distance_avx2_free),
        distance_over_tangent_contact_avx2,
        distance_over_tangent_free_avx2,
        distance_contact_fraction: band_sums.contacts as f64 / n as f64,
        distance_band_bytes: band_bytes,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn contact_pose_puts_every_point_in_surface_and_free_pose_in_free() {
        let n = 400;
        let radius_vox = shell_radius_vox(n);
        let dense = band_scene(radius_vox, true);
        let shell = ClassedShell::new(&sphere_shell(n, radius_vox * VOXEL_SIZE), 1);
        let slot = dense.spec.dims[1] as f64;
        let contact = pose_at(&dense.spec, DVec3::splat(slot / 2.0));
        let free = pose_at(&dense.spec, DVec3::new(slot * 1.5, slot / 2.0, slot / 2.0));
        assert_eq!(sample_all(&dense, &shell, &contact).surface, n as u64);
        let free_sums = sample_all(&dense, &shell, &free);
        assert_eq!(free_sums.surface + free_sums.interior, 0);
        let tree = VoxelTree::from_dense(&dense, TreeConfig::default()).unwrap();
        let band = sphere_band(&dense.spec, radius_vox, DEFAULT_STANDOFF_VOXELS).unwrap();
        let band_tree = tree.with_distance_band(band);
        assert_eq!(sample_all(&band_tree, &shell, &contact).contacts, n as u64);
        assert_eq!(sample_all(&band_tree, &shell, &free).non_free, 0);
    }
}
