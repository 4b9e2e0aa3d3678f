//! A block pressed edge-first and corner-first onto a plane, tilted 0–45° in 5° steps: with the
//! `distance` model the force stays along the plane's normal (≤ 2°) at every tilt; the
//! tangent-plane model's angle is printed beside it (it follows the block's facets).

use glam::{DQuat, DVec3};
use vps_fidelity::measure::ForceModel;
use vps_haptic::{sample_all, ClassedShell, KernelPose, PartState};
use vps_mesh::builtin::cuboid;
use vps_voxelize::{point_shell, ShellMethod, VoxelWidth};
use vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS;
use vps_voxmap::VoxelTree;

const S: f64 = 0.005;

fn floor() -> vps_mesh::TriMesh {
    let mut slab = cuboid(DVec3::new(0.06, 0.06, 0.02));
    slab.vertices
        .iter_mut()
        .for_each(|v| *v += DVec3::new(0.0, 0.0, -0.02));
    slab
}

/// The floor's voxmap for the tangent-plane model and for the distance model (default stand-off).
fn maps() -> (VoxelTree, VoxelTree) {
    let floor = [floor()];
    let map = |model: ForceModel| model.voxmap("floor", &floor, S, VoxelWidth::Four).unwrap();
    (map(ForceModel::TangentPlane), map(ForceModel::DISTANCE))
}

/// The force direction's angle from +z (degrees) of a 30 mm block turned by `q`, its lowest
/// shell point `depth` (m) below `top` (m).
fn angle(
    map: &VoxelTree,
    shell: &ClassedShell,
    body: &[DVec3],
    q: DQuat,
    top: f64,
    depth: f64,
) -> Option<f64> {
    let lowest = body.iter().map(|v| (q * *v).z).fold(f64::MAX, f64::min);
    let position = DVec3::new(0.0013, -0.0007, top - depth - lowest);
    let sums = sample_all(
        map,
        shell,
        &KernelPose::from_state(&PartState::at_rest(position, q)),
    );
    let f = sums.depth_normal_si();
    (f.length() > 0.0).then(|| f.angle_between(DVec3::Z).to_degrees())
}

#[test]
fn edge_first_and_corner_first_presses_push_along_the_planes_normal() {
    let (layers, band) = maps();
    let part = cuboid(DVec3::splat(0.015));
    let shell = point_shell(&part, S, ShellMethod::ExactSurface).unwrap();
    let com = shell.mass.center_of_mass;
    let _ = com;
    let body: Vec<DVec3> = shell.points.iter().map(|p| p.as_dvec3()).collect();
    let classed = ClassedShell::new(&shell, 1);
    let standoff = DEFAULT_STANDOFF_VOXELS * S;
    let tangent_offset = 2.5 * S; // 2 offset layers + half a voxel
    let mut worst: f64 = 0.0;
    for tilt_deg in (0..=45).step_by(5) {
        let t = f64::from(tilt_deg).to_radians();
        let edge = DQuat::from_rotation_x(t);
        let corner = DQuat::from_rotation_y(t) * DQuat::from_rotation_x(t);
        for (name, q) in [("edge", edge), ("corner", corner)] {
            for depth_voxels in [0.05, 0.1, 0.25] {
                let d = angle(&band, &classed, &body, q, standoff, depth_voxels * S)
                    .unwrap_or_else(|| panic!("{name} {tilt_deg}°: no distance force"));
                let tp = angle(
                    &layers,
                    &classed,
                    &body,
                    q,
                    tangent_offset,
                    depth_voxels * S,
                );
                println!("{name:6} tilt {tilt_deg:2}° depth {depth_voxels:4} voxel: distance {d:5.2}°, tangent-plane {tp:?}°");
                assert!(d <= 2.0, "{name} tilt {tilt_deg}°: {d}° off the normal");
                worst = worst.max(d);
            }
        }
    }
    println!("worst distance-model angle: {worst:.3}°");
}
