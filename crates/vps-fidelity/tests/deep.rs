//! A part pushed deep into a thick block (every shell point 2.5 to 6.5 voxels below its top face,
//! past the band's reach) is felt at every point with the `distance` model, on 2-bit and 4-bit
//! maps: each point is counted inside and pushes. (The band's builder once read the 4-bit map's
//! Surface depth layers, which run about 5 voxels into a solid, as outside: the points between
//! 2.5 and 5 voxels deep felt nothing.)

use glam::{DQuat, DVec3};
use vps_fidelity::measure::ForceModel;
use vps_haptic::{sample_all, ClassedShell, KernelPose, PartState};
use vps_mesh::builtin::cuboid;
use vps_voxelize::{point_shell, ShellMethod, VoxelWidth};

const S: f64 = 0.005;

#[test]
fn every_point_of_a_part_deep_in_a_block_pushes() {
    // A 200 mm block, its top face at z = 0.
    let mut block = cuboid(DVec3::splat(0.1));
    block
        .vertices
        .iter_mut()
        .for_each(|v| *v += DVec3::new(0.0, 0.0, -0.1));
    // A 20 mm cube, its top 2.5 voxels and its bottom 6.5 voxels below the block's top face.
    let part = cuboid(DVec3::splat(0.01));
    let shell = point_shell(&part, S, ShellMethod::ExactSurface).unwrap();
    let classed = ClassedShell::new(&shell, 1);
    let position = DVec3::new(0.0013, -0.0007, -2.5 * S - 0.01);
    let pose = KernelPose::from_state(&PartState::at_rest(position, DQuat::IDENTITY));
    for width in [VoxelWidth::Two, VoxelWidth::Four] {
        let map = ForceModel::DISTANCE
            .voxmap("block", std::slice::from_ref(&block), S, width)
            .unwrap();
        let sums = sample_all(&map, &classed, &pose);
        let points = shell.len() as u64;
        assert_eq!(sums.interior, points, "{width:?}: points counted inside");
        assert_eq!(sums.contacts, points, "{width:?}: points pushing");
        assert!(sums.depth_normal_si().is_finite(), "{width:?}");
    }
}
