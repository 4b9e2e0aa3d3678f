//! A small, deterministic driver of the sampling kernel for instruction counting under callgrind
//! (wall time on a shared VM is noisy; instruction counts repeat exactly).
//!
//! Scene: the synthetic case of `vps bench kernel` (a sphere shell of `n` points, ≈ one per voxel
//! of area, inward normals, in voxel order; a spherical Surface band of 3 voxels around it in one
//! slot of the grid, an empty slot beside it). `contact` centres the shell in the band (every point
//! in a Surface voxel of a mixed leaf), `free` in the empty slot (every point in a Free tile),
//! `dense` is the contact pose against the dense byte grid. `fine` and `fine-free` use a shell 16×
//! finer than the voxmap (≈ 256 points per voxel of area, like `vps bench loop`'s 100k-point
//! teapot) split into 64 cyclic classes, as the runtime does.
//!
//! ```sh
//! cargo build --release -p vps-haptic --example kernel_ir
//! valgrind --tool=callgrind --toggle-collect='*accumulate_avx2*' \
//!     target/release/examples/kernel_ir 10000 contact 10 previous   # previous kernel (AVX2 copy)
//! SYMS=$(nm target/release/examples/kernel_ir | grep accumulate_avx512 | awk '{print $3}' | paste -sd,) \
//!     gdb -q -batch -x crates/vps-haptic/examples/step_count.py \
//!     --args target/release/examples/kernel_ir 1000 contact 1      # current kernel (AVX-512 copy)
//! ```
//! Instructions per point = the collected `Ir` (or the counted instructions) / (`reps` · `n`).
//! Valgrind has no AVX-512 and hides it from the program, so under callgrind both kernels run the
//! AVX2 copy; the AVX-512 copy is counted by single-stepping (`step_count.py`, slow: small
//! shells).

use glam::{DQuat, DVec3, Vec3};
use std::hint::black_box;
use vps_haptic::{sample_all, ClassedShell, KernelPose, PartState};
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{DenseGrid, GridSpec, MassProperties, PointShell, TreeConfig, Voxel, VoxelTree};

const VOXEL_SIZE: f64 = 0.005;

/// Bits of `v` spread to every third bit (Morton interleave, 21 bits per axis).
fn spread(v: u32) -> u64 {
    (0..21).fold(0, |acc, b| acc | (u64::from(v >> b & 1) << (3 * b)))
}

fn sphere_shell(n: usize, radius: f64, sample: f64) -> PointShell {
    let mut pairs: Vec<(Vec3, Vec3)> = vps_testkit::shell::fibonacci_directions(n)
        .into_iter()
        .map(|dir| ((dir * radius).as_vec3(), (-dir).as_vec3()))
        .collect();
    // Morton order of the sampling voxels, as real shells are.
    pairs.sort_by_key(|(p, _)| {
        let v = (*p / sample as f32 + Vec3::splat(1e5)).as_uvec3();
        spread(v.x) | spread(v.y) << 1 | spread(v.z) << 2
    });
    PointShell {
        points: pairs.iter().map(|p| p.0).collect(),
        normals: pairs.iter().map(|p| p.1).collect(),
        voxel_size: VOXEL_SIZE,
        method: ShellMethod::VoxelCentres,
        mass: MassProperties {
            volume: 0.0,
            center_of_mass: DVec3::ZERO,
            bounding_radius: radius,
        },
    }
}

fn band_scene(radius_vox: f64) -> DenseGrid {
    let slot = (2.0 * (radius_vox + 4.0)).ceil() as u32;
    let spec = GridSpec::at_origin(VOXEL_SIZE, [2 * slot, slot, slot]);
    let centre = DVec3::splat(slot as f64 / 2.0);
    let mut grid = DenseGrid::new(spec);
    for z in 0..slot as i32 {
        for y in 0..slot as i32 {
            for x in 0..slot as i32 {
                let p = DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5);
                let d = (p - centre).length() - radius_vox;
                let v = match d {
                    d if d < -1.5 => Voxel::Interior,
                    d if d <= 1.5 => Voxel::Surface,
                    d if d <= 2.5 => Voxel::Proximity,
                    _ => Voxel::Free,
                };
                grid.set(glam::IVec3::new(x, y, z), v);
            }
        }
    }
    grid
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let mode = args.get(2).map_or("contact", String::as_str);
    let reps: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(20);
    let fine = mode.starts_with("fine");
    let per_voxel_edge = if fine { 16.0 } else { 1.0 };
    let radius_vox = (n as f64 / (4.0 * std::f64::consts::PI)).sqrt().max(3.0) / per_voxel_edge;
    let dense = band_scene(radius_vox);
    let tree = VoxelTree::from_dense(&dense, TreeConfig::default()).expect("valid scene");
    // A fourth argument `previous`: the previous kernel (the current one on at most AVX2).
    let kernel = if args.get(4).is_some_and(|a| a == "previous") {
        vps_haptic::previous::sample_all::<VoxelTree>
    } else {
        sample_all::<VoxelTree>
    };
    let sample = VOXEL_SIZE / per_voxel_edge;
    let shell = sphere_shell(n, radius_vox * VOXEL_SIZE, sample);
    let shell = ClassedShell::new(&shell, if fine { 64 } else { 1 });
    let slot = dense.spec.dims[1] as f64;
    let centre = match mode {
        "free" | "fine-free" => DVec3::new(slot * 1.5, slot / 2.0, slot / 2.0),
        _ => DVec3::splat(slot / 2.0),
    };
    let state = PartState::at_rest(dense.spec.origin + centre * VOXEL_SIZE, DQuat::IDENTITY);
    let pose = KernelPose::from_state(&state);
    let mut last = Default::default();
    let start = std::time::Instant::now();
    for _ in 0..reps {
        last = if mode == "dense" {
            sample_all(black_box(&dense), &shell, black_box(&pose))
        } else {
            kernel(black_box(&tree), &shell, black_box(&pose))
        };
    }
    let ns = start.elapsed().as_secs_f64() * 1e9 / (reps.max(1) * n) as f64;
    eprintln!("{mode} n={n} reps={reps}: {ns:.2} ns/point; {last:?}");
}
