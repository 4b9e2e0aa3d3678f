//! Tunnelling: a 20 mm cube driven by the hand at 1, 3 and 10 m/s into a wall two voxels thick,
//! face-on and edge-on, with the `distance` model and a stand-off of a quarter voxel. The hand goes
//! on 50 mm past the wall and holds there, so the coupling keeps pulling the part through it for
//! the rest of the run. No frame may have any shell point beyond the wall's far face.

use glam::{DQuat, DVec3};
use vps_fidelity::held::HeldPart;
use vps_fidelity::measure::ForceModel;
use vps_haptic::{HandleSample, HapticParams};
use vps_mesh::builtin::cuboid;
use vps_reference::ExactScene;
use vps_voxelize::{point_shell, ShellMethod, VoxelWidth};

const S: f64 = 0.005;
/// Near face of the wall at x = 0, far face at x = 2 voxels.
const THICKNESS: f64 = 2.0 * S;

#[test]
fn a_part_struck_into_a_thin_wall_never_passes_it() {
    let mut wall = cuboid(DVec3::new(THICKNESS / 2.0, 0.05, 0.05));
    wall.transform(1.0, DQuat::IDENTITY, DVec3::new(THICKNESS / 2.0, 0.0, 0.0));
    let walls = [wall];
    let map = ForceModel::Distance {
        standoff_voxels: 0.25,
    }
    .voxmap("tunnelling", &walls, S, VoxelWidth::Four)
    .unwrap();
    let exact = ExactScene::new(&walls).unwrap();
    let shell = point_shell(&cuboid(DVec3::splat(0.01)), S, ShellMethod::ExactSurface).unwrap();
    let params = HapticParams::default()
        .with_scene(S, shell.max_radius())
        .unwrap();
    for speed in [1.0, 3.0, 10.0] {
        for (name, q) in [
            ("face-on", DQuat::IDENTITY),
            ("edge-on", DQuat::from_rotation_z(45f64.to_radians())),
        ] {
            let start = DVec3::new(-0.03, 0.0013, -0.0007);
            let stop_x = THICKNESS + 0.05;
            let mut part = HeldPart::at_rest(&map, &exact, &shell, &params, start, q);
            let (mut through, mut penetrating, mut deepest) = (0, 0, 0.0f64);
            for k in 0..600 {
                let t = k as f64 * params.dt;
                let x = (start.x + speed * t).min(stop_x);
                let handle = HandleSample {
                    position: DVec3::new(x, start.y, start.z),
                    orientation: q,
                    linear_velocity: DVec3::new(if x < stop_x { speed } else { 0.0 }, 0.0, 0.0),
                    angular_velocity: DVec3::ZERO,
                };
                let r = part.frame(&handle, S);
                let far = part.world_points().map(|p| p.x).fold(f64::MIN, f64::max);
                through += usize::from(far > THICKNESS);
                penetrating += usize::from(r.penetrating_points > 0);
                deepest = deepest.max(r.max_penetration_m);
            }
            println!(
                "{speed} m/s {name}: {through} frames through, {penetrating} frames penetrating, deepest {:.3} mm",
                deepest * 1e3
            );
            assert_eq!(
                through, 0,
                "{speed} m/s {name}: the part went through the wall"
            );
            assert_eq!(
                penetrating, 0,
                "{speed} m/s {name}: a shell point entered the wall"
            );
        }
    }
}
