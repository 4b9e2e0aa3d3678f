//! The clearance benchmark's documented grid as a table: `cargo run --release -p vps-fidelity
//! --example clearance` (`vps bench clearance` prints the same as JSON).

use vps_fidelity::clearance::{run, ClearanceGrid};

fn main() {
    let rows = run(&ClearanceGrid::full()).expect("clearance benchmark");
    println!("| model | voxel (mm) | peg | clearance (voxels) | clearance (mm) | entered | deepest (mm) | min exact separation (mm) | penetrating frames |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for r in rows {
        println!(
            "| {} | {} | {} | {} | {:.2} | {} | {:.1} | {} | {} |",
            r.model,
            r.voxel_size_mm,
            r.peg,
            r.clearance_voxels,
            r.clearance_mm,
            if r.entered { "yes" } else { "no" },
            r.deepest_mm,
            r.min_separation_mm
                .map_or("-".to_string(), |m| format!("{m:.3}")),
            r.penetrating_frames
        );
    }
}
