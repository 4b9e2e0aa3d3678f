//! A small, deterministic driver of the sampling kernel for instruction counting under callgrind
//! (wall time on a shared VM is noisy; instruction counts repeat exactly).
//!
//! Scene: the synthetic case of `vps bench kernel` (a sphere shell of `n` points, ≈ one per voxel
//! of area, inward normals, in voxel order; a spherical Surface band of 3 voxels around it in one
//! slot of the grid, an empty slot beside it). `contact` centres the shell in the band (every point
//! in a Surface voxel of a mixed leaf), `free` in the empty slot (every point in a Free tile),
//! `dense` is the contact pose against the dense byte grid. `fine` and `fine-free` use a shell 16×
//! finer than the voxmap (≈ 256 points per voxel of area, like `vps bench loop`'s 100k-point
//! teapot) split into 64 cyclic classes, as the runtime does. `fine4` and `fine4-free` are the same
//! against a 4-bit map (the loop's default scenes): the band holds every Surface layer (0..=6) and
//! Proximity layer (0..=5) of the width, Interior inside, and the slot is wide enough that the
//! empty half stays Free. `distance` and `distance-free` are `contact` and `free` with the map
//! carrying a signed-distance band (the `distance` force model): the solid ball of radius
//! `R + ½` voxel, stand-off ½ voxel, so every shell point is a contact.
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
use vps_voxmap::{
    distance::DistanceBand, CubeSource, DenseGrid, GridSpec, LayeredVoxel, MassProperties,
    PointShell, TreeConfig, Voxel, VoxelTree, VoxelWidth,
};

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

fn band_scene(radius_vox: f64, margin_vox: f64) -> DenseGrid {
    let slot = (2.0 * (radius_vox + margin_vox)).ceil() as u32;
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

/// The 4-bit code at signed distance `d` (voxels, negative inside) from the band's sphere: Surface
/// layer ℓ for `d` in (0.5 − ℓ, 1.5 − ℓ], ℓ = 0..=6, Interior deeper, Proximity layer ℓ for `d` in
/// (1.5 + ℓ, 2.5 + ℓ], ℓ = 0..=5, Free farther.
fn layered_code(d: f64) -> u8 {
    let w = VoxelWidth::Four;
    let v = if d <= 1.5 {
        let layer = (1.5 - d).floor() as i64;
        if layer >= i64::from(w.surface_layers()) {
            LayeredVoxel {
                kind: Voxel::Interior,
                layer: 0,
            }
        } else {
            LayeredVoxel {
                kind: Voxel::Surface,
                layer: layer as u8,
            }
        }
    } else {
        let layer = (d - 1.5).ceil() as i64 - 1;
        if layer < i64::from(w.proximity_layers()) {
            LayeredVoxel {
                kind: Voxel::Proximity,
                layer: layer as u8,
            }
        } else {
            LayeredVoxel {
                kind: Voxel::Free,
                layer: 0,
            }
        }
    };
    w.encode(v).expect("layers within the width")
}

/// The 4-bit band of `layered_code` around a sphere of `radius_vox` centred in the first of two
/// slots of `spec` (voxel centres).
struct LayeredBand {
    dims: [u32; 3],
    centre: DVec3,
    radius_vox: f64,
}

impl CubeSource for LayeredBand {
    fn cube(&self, origin: glam::UVec3, extent: u32, out: &mut [u8]) -> Option<u8> {
        let e = extent as usize;
        for (i, o) in out.iter_mut().enumerate() {
            let p =
                origin + glam::UVec3::new((i % e) as u32, (i / e % e) as u32, (i / (e * e)) as u32);
            let inside = (0..3).all(|a| p[a] < self.dims[a]);
            let d = (p.as_dvec3() + DVec3::splat(0.5) - self.centre).length() - self.radius_vox;
            *o = if inside { layered_code(d) } else { 0 };
        }
        None
    }
}

/// The band of the solid ball of radius `radius_vox + 0.5` voxels about the first slot's centre,
/// stand-off `standoff_voxels`, computed analytically (as `vps bench kernel` builds it).
fn sphere_band(spec: &GridSpec, radius_vox: f64, standoff_voxels: f64) -> DistanceBand {
    use vps_voxmap::distance::{self, CubeCodes, BRICK_CODES, BRICK_EDGE};
    let centre = DVec3::splat(spec.dims[1] as f64 / 2.0);
    let ball = radius_vox + 0.5;
    distance::assemble(spec, standoff_voxels * spec.voxel_size, |c| {
        let mut codes = Box::new([0i8; BRICK_CODES]);
        for (i, code) in codes.iter_mut().enumerate() {
            let (x, y, z) = (
                i % BRICK_EDGE,
                i / BRICK_EDGE % BRICK_EDGE,
                i / (BRICK_EDGE * BRICK_EDGE),
            );
            let p = DVec3::new(
                f64::from(c[0] * 8) + x as f64 + 0.5,
                f64::from(c[1] * 8) + y as f64 + 0.5,
                f64::from(c[2] * 8) + z as f64 + 0.5,
            );
            *code = distance::code_of((p - centre).length() - ball - standoff_voxels, 1.0);
        }
        CubeCodes::from_codes(codes)
    })
    .expect("a valid band")
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10_000);
    let mode = args.get(2).map_or("contact", String::as_str);
    let reps: usize = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(20);
    let fine = mode.starts_with("fine");
    let four_bit = mode.starts_with("fine4");
    let per_voxel_edge = if fine { 16.0 } else { 1.0 };
    let radius_vox = (n as f64 / (4.0 * std::f64::consts::PI)).sqrt().max(3.0) / per_voxel_edge;
    // The 4-bit band reaches 8.5 voxels out: a wider slot keeps the empty half Free.
    let dense = band_scene(radius_vox, if four_bit { 12.0 } else { 4.0 });
    let tree = if four_bit {
        let slot = dense.spec.dims[1] as f64;
        let source = LayeredBand {
            dims: dense.spec.dims,
            centre: DVec3::splat(slot / 2.0),
            radius_vox,
        };
        VoxelTree::from_source(dense.spec, VoxelWidth::Four, TreeConfig::default(), &source)
            .expect("valid scene")
    } else {
        VoxelTree::from_dense(&dense, TreeConfig::default()).expect("valid scene")
    };
    let tree = if mode.starts_with("distance") {
        tree.with_distance_band(sphere_band(&dense.spec, radius_vox, 0.5))
    } else {
        tree
    };
    // A fourth argument `previous`: the previous kernel (the current one on at most AVX2).
    let kernel = if args.get(4).is_some_and(|a| a == "previous") {
        vps_haptic::avx2_only::sample_all::<VoxelTree>
    } else {
        sample_all::<VoxelTree>
    };
    let sample = VOXEL_SIZE / per_voxel_edge;
    let shell = sphere_shell(n, radius_vox * VOXEL_SIZE, sample);
    let shell = ClassedShell::new(&shell, if fine { 64 } else { 1 });
    let slot = dense.spec.dims[1] as f64;
    let centre = match mode {
        "free" | "fine-free" | "fine4-free" | "distance-free" => {
            DVec3::new(slot * 1.5, slot / 2.0, slot / 2.0)
        }
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
