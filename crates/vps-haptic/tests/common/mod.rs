//! Shared fixtures for the integration tests: hand-made voxmaps, point shells and a frame loop.
#![allow(dead_code)]

use glam::{DQuat, DVec3, Vec3};
use vps_haptic::{
    sample_all, step, ClassedShell, FrameOutput, HandleSample, HapticParams, KernelPose, PartState,
};
pub use vps_testkit::scene::fill_layer;
use vps_voxmap::shell::ShellMethod;
use vps_voxmap::{
    DenseGrid, GridSpec, MassProperties, PointShell, TreeConfig, Voxel, VoxelLookup, VoxelTree,
};

/// Voxel size of the fixtures (m).
pub const S: f64 = 0.005;

/// A point shell from body-frame points and inward normals (normalised here).
pub fn shell_from(points: &[Vec3], normals: &[Vec3]) -> PointShell {
    let r = points.iter().map(|p| p.length() as f64).fold(0.0, f64::max);
    PointShell {
        points: points.to_vec(),
        normals: normals.iter().map(|n| n.normalize()).collect(),
        voxel_size: S,
        method: ShellMethod::ExactSurface,
        mass: MassProperties {
            volume: 1e-6,
            center_of_mass: DVec3::ZERO,
            bounding_radius: r,
        },
    }
}

/// A cube of half-side `half` (m) with `per_side × per_side` points on each face, inward normals.
pub fn cube_shell(half: f32, per_side: u32) -> PointShell {
    let mut points = Vec::new();
    let mut normals = Vec::new();
    let step = 2.0 * half / per_side as f32;
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            for a in 0..per_side {
                for b in 0..per_side {
                    let u = -half + step * (a as f32 + 0.5);
                    let v = -half + step * (b as f32 + 0.5);
                    let mut p = [0.0f32; 3];
                    p[axis] = sign * half;
                    p[(axis + 1) % 3] = u;
                    p[(axis + 2) % 3] = v;
                    let mut n = [0.0f32; 3];
                    n[axis] = -sign;
                    points.push(Vec3::from(p));
                    normals.push(Vec3::from(n));
                }
            }
        }
    }
    shell_from(&points, &normals)
}

/// A 40³ grid of 5 mm voxels with origin (−0.1, −0.1, −0.1): voxel k covers
/// z ∈ [−0.1 + k s, −0.1 + (k+1) s).
pub fn spec() -> GridSpec {
    GridSpec {
        origin: DVec3::splat(-0.1),
        voxel_size: S,
        dims: [40, 40, 40],
    }
}

/// A half-space wall below z = 0 on this crate's 40³ grid (`vps_testkit::scene::wall` is another
/// fixture: 20³ at the origin): Interior for z < −2s, a two-voxel Surface layer in [−2s, 0),
/// Proximity in [0, s), Free above.
pub fn half_space() -> DenseGrid {
    let mut g = DenseGrid::new(spec());
    for k in 0..18 {
        fill_layer(&mut g, k, Voxel::Interior);
    }
    fill_layer(&mut g, 18, Voxel::Surface);
    fill_layer(&mut g, 19, Voxel::Surface);
    fill_layer(&mut g, 20, Voxel::Proximity);
    g
}

/// [`half_space`] as a tree carrying a signed-distance band of the plane z = 0 (the top of its
/// force layer taken as the exact surface) with a stand-off of `standoff` (m), computed
/// analytically: the `distance` force model's counterpart of the same wall.
pub fn half_space_band(standoff: f64) -> VoxelTree {
    let tree = VoxelTree::from_dense(&half_space(), TreeConfig::default()).unwrap();
    let band = vps_testkit::scene::plane_band(tree.spec(), 0.0, standoff);
    tree.with_distance_band(band)
}

/// A thin plate (2 mm thick, voxelized at 5 mm into one Surface layer, then offset by two layers
/// as docs/architecture.md#voxmaps-and-point-shells describes): Proximity, Surface, Interior ×3, Surface, Proximity for k = 16..=22.
/// The plate's mid-plane is the centre of voxel k = 19, z = −0.0025; the layers span
/// z ∈ [−0.02, 0.015).
pub const PLATE_MID_Z: f64 = -0.0025;

/// See [`PLATE_MID_Z`].
pub fn thin_plate() -> DenseGrid {
    let mut g = DenseGrid::new(spec());
    let layers = [
        (16, Voxel::Proximity),
        (17, Voxel::Surface),
        (18, Voxel::Interior),
        (19, Voxel::Interior),
        (20, Voxel::Interior),
        (21, Voxel::Surface),
        (22, Voxel::Proximity),
    ];
    for (k, kind) in layers {
        fill_layer(&mut g, k, kind);
    }
    g
}

/// A handle at `position`, identity orientation, moving with `velocity`.
pub fn handle_at(position: DVec3, velocity: DVec3) -> HandleSample {
    HandleSample {
        position,
        orientation: DQuat::IDENTITY,
        linear_velocity: velocity,
        angular_velocity: DVec3::ZERO,
    }
}

/// One full frame: sample the whole shell at `state`, then step.
pub fn frame<L: VoxelLookup>(
    params: &HapticParams,
    map: &L,
    shell: &ClassedShell,
    state: &PartState,
    handle: &HandleSample,
) -> FrameOutput {
    let sums = sample_all(map, shell, &KernelPose::from_state(state));
    step(params, state, handle, &sums)
}

/// Energy of the part-coupling-field system (J): kinetic + clamped-spring potential + the field
/// potential `scale · K_ff Σ d_i² / 2` (per-point depths from a one-point-per-class shell).
pub fn energy<L: VoxelLookup>(
    params: &HapticParams,
    map: &L,
    per_point: &ClassedShell,
    state: &PartState,
    handle: &HandleSample,
) -> f64 {
    let g = params.gains();
    let kinetic = 0.5 * params.mass * state.linear_velocity.length_squared()
        + 0.5 * g.inertia * state.angular_velocity.length_squared();
    let stretch = (handle.position - state.position).length();
    let knee = 0.5 * params.voxel_size;
    let spring = if stretch <= knee {
        0.5 * g.k_t * stretch * stretch
    } else {
        g.k_t * knee * (stretch - 0.5 * knee)
    };
    let pose = KernelPose::from_state(state);
    let (mut sum_d2, mut contacts) = (0.0, 0u64);
    for c in 0..per_point.class_count() {
        let s = vps_haptic::sample_class(map, per_point, &pose, c);
        sum_d2 += s.depth_normal_si().length_squared();
        contacts += s.contacts;
    }
    let threshold = params.contact_average_threshold as f64;
    let scale = if contacts as f64 >= threshold {
        threshold / contacts as f64
    } else {
        1.0
    };
    kinetic + spring + 0.5 * scale * g.k_ff * sum_d2
}
