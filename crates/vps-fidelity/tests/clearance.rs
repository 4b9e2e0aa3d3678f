//! The clearance benchmark on a reduced grid (2 mm voxels), no shell point ever inside the exact
//! walls: with the distance model at a stand-off of 1/16 voxel both pegs enter a quarter voxel of
//! clearance a side; at 1/8 voxel the round peg enters a quarter voxel and the square peg half a
//! voxel (its corners catch on the rim at a quarter); at the default stand-off (half a voxel)
//! the round peg enters half a voxel and the square peg a voxel; with the tangent-plane model
//! (2 offset layers) neither peg enters even a voxel of clearance a side (its force layer closes
//! the gap). docs/fidelity.md has the full grid.

use vps_fidelity::clearance::{run, ClearanceGrid};

#[test]
fn the_distance_model_lets_a_fitting_peg_in_without_touching_the_walls() {
    // The full grid's pegs and force models, at 2 mm voxels and three of its clearances.
    let rows = run(&ClearanceGrid {
        voxel_sizes_m: vec![0.002],
        clearances_voxels: vec![0.25, 0.5, 1.0],
        ..ClearanceGrid::full()
    })
    .unwrap();
    for r in &rows {
        println!("{r:?}");
        assert_eq!(r.penetrating_frames, 0, "{r:?}");
        if let Some(m) = r.min_separation_mm {
            assert!(m >= 0.0, "{r:?}");
        }
        let c = r.clearance_voxels;
        let expected = match (r.model, r.peg) {
            ("tangent-plane", _) => false,
            ("distance", _) if r.standoff_voxels < 0.1 => true,
            ("distance", "round") if r.standoff_voxels < 0.25 => true,
            ("distance", "square") if r.standoff_voxels < 0.25 => c >= 0.5,
            ("distance", "round") => c >= 0.5,
            ("distance", "square") => c >= 1.0,
            _ => unreachable!(),
        };
        assert_eq!(r.entered, expected, "{r:?}");
    }
}
