//! Plans over the memory budget are refused before any voxel is computed, with a message naming
//! the estimate, the budget and the option that raises it.

use glam::{DQuat, DVec3};
use vps_voxelize::{
    point_shell_within, voxelize_tree, ShellMethod, VoxelizeError, VoxelizeOptions,
};
use vps_voxmap::TreeConfig;

/// The default options at `voxel_size` (m) within `max_memory_bytes`.
fn budgeted(voxel_size: f64, max_memory_bytes: u64) -> VoxelizeOptions {
    VoxelizeOptions {
        voxel_size,
        max_memory_bytes,
        ..VoxelizeOptions::default()
    }
}

fn ten_metre_cube() -> vps_mesh::TriMesh {
    vps_mesh::builtin::by_name("box")
        .unwrap()
        .transformed(100.0, DQuat::IDENTITY, DVec3::ZERO)
}

/// A 12-triangle 10 m cube at 1 mm (1e12 voxels, under the 2^40 cap) would need far more than 8 GiB;
/// it is refused from the plan, before any voxel is computed.
#[test]
fn a_ten_metre_cube_at_one_millimetre_is_refused_from_the_plan() {
    let opts = budgeted(0.001, 8 << 30);
    let err = voxelize_tree(&[ten_metre_cube()], &opts, TreeConfig::default()).unwrap_err();
    let VoxelizeError::OverMemoryBudget {
        estimate_bytes,
        budget_bytes,
        ..
    } = err
    else {
        panic!("{err}");
    };
    assert_eq!(budget_bytes, 8 << 30);
    assert!(estimate_bytes > budget_bytes);
    let text = err.to_string();
    for needle in ["voxel size 0.001 m", "GiB", "--max-memory", "8.00 GiB"] {
        assert!(text.contains(needle), "{needle:?} missing: {text}");
    }
}

#[test]
fn a_plan_within_the_budget_runs() {
    let opts = budgeted(0.01, 64 << 20);
    let cube = vps_mesh::builtin::by_name("box").unwrap();
    let (_, stats) = voxelize_tree(&[cube], &opts, TreeConfig::default()).unwrap();
    assert!(stats.peak_work_bytes < 64 << 20);
}

#[test]
fn a_point_shell_over_the_budget_is_refused() {
    let cube = vps_mesh::builtin::by_name("box").unwrap();
    // 0.1 m at 0.1 mm: ~1e9 voxels, ~1.9 GB of dense workspace.
    let err = point_shell_within(&cube, 0.0001, ShellMethod::VoxelCentres, 1 << 30).unwrap_err();
    assert!(
        matches!(err, VoxelizeError::OverMemoryBudget { .. }),
        "{err}"
    );
}
