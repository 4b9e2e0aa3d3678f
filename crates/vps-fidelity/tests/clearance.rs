//! The clearance benchmark on a reduced grid (2 mm voxels): with the distance model the round peg
//! enters a quarter voxel of clearance a side and both pegs enter half a voxel, with no shell point
//! ever inside the exact walls; with the tangent-plane model (2 offset layers) neither peg enters
//! even a voxel of clearance a side (its force layer closes the gap). docs/fidelity.md has the
//! full grid.

use vps_fidelity::clearance::{run, ClearanceGrid, Peg};
use vps_fidelity::measure::ForceModel;

#[test]
fn the_distance_model_lets_a_fitting_peg_in_without_touching_the_walls() {
    let rows = run(&ClearanceGrid {
        voxel_sizes_m: vec![0.002],
        clearances_voxels: vec![0.25, 0.5, 1.0],
        pegs: vec![Peg::Square, Peg::Round],
        models: vec![ForceModel::TangentPlane, ForceModel::DISTANCE],
    })
    .unwrap();
    for r in &rows {
        println!("{r:?}");
        assert_eq!(r.penetrating_frames, 0, "{r:?}");
        if let Some(m) = r.min_separation_mm {
            assert!(m >= 0.0, "{r:?}");
        }
        let expected = match (r.model, r.peg, r.clearance_voxels) {
            ("tangent-plane", _, _) => false,
            ("distance", "round", _) => true,
            ("distance", "square", c) => c >= 0.5,
            _ => unreachable!(),
        };
        assert_eq!(r.entered, expected, "{r:?}");
    }
}
