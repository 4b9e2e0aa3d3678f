//! Builds the signed-distance band of each built-in scene and prints a digest of its directory and
//! codes with the build time: two builds of the band builder give the same band exactly when the
//! digests agree. Each band is built twice, with its own inside map and with the one the 4-bit
//! voxelization kept (`voxelize_tree_keeping_inside`): the two must be the same (asserted). Run in release:
//! `cargo run --release -p vps-voxelize --example band_digest [-- NAME:VOXEL_MM ...]`
//! (default: teapot at 1 and 2 mm, box, sphere and cylinder at 5 mm, aircraft-bay at 5 mm; each at
//! the default stand-off of half a voxel and at an eighth of a voxel).

use std::hash::{Hash, Hasher};
use vps_voxelize::{distance, voxelize_tree, voxelize_tree_keeping_inside, VoxelizeOptions};
use vps_voxmap::{TreeConfig, VoxelWidth};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenes: Vec<String> = if args.is_empty() {
        [
            "teapot:1",
            "teapot:2",
            "box:5",
            "sphere:5",
            "cylinder:5",
            "aircraft-bay:5",
        ]
        .map(String::from)
        .to_vec()
    } else {
        args
    };
    for scene in &scenes {
        let (name, mm) = scene.split_once(':').expect("NAME:VOXEL_MM");
        let voxel_size = mm.parse::<f64>().expect("voxel size in mm") * 1e-3;
        let mesh = vps_mesh::builtin::by_name(name).expect("a built-in scene name");
        let opts = VoxelizeOptions {
            voxel_size,
            width: VoxelWidth::Four,
            ..VoxelizeOptions::default()
        };
        let meshes = std::slice::from_ref(&mesh);
        let (tree, stats) = voxelize_tree(meshes, &opts, TreeConfig::default()).expect("voxelize");
        let (kept_tree, _, inside) =
            voxelize_tree_keeping_inside(meshes, &opts, TreeConfig::default()).expect("voxelize");
        assert_eq!(
            kept_tree.content_hash(),
            tree.content_hash(),
            "{scene}: the trees differ"
        );
        let digest = |band: &vps_voxmap::distance::DistanceBand| {
            let mut h = std::collections::hash_map::DefaultHasher::new();
            band.directory().hash(&mut h);
            band.slot_codes().hash(&mut h);
            h.finish()
        };
        for standoff_voxels in [0.5, 0.125] {
            let standoff = standoff_voxels * voxel_size;
            let budget = vps_voxelize::default_memory_budget();
            let t = std::time::Instant::now();
            let band = distance::distance_band(&tree, meshes, standoff, budget).expect("band");
            let build_ms = t.elapsed().as_secs_f64() * 1e3;
            let t = std::time::Instant::now();
            let (with_inside, _) =
                distance::distance_band_with_inside(&tree, &inside, meshes, standoff, budget)
                    .expect("band");
            let with_inside_ms = t.elapsed().as_secs_f64() * 1e3;
            assert_eq!(
                digest(&with_inside),
                digest(&band),
                "{scene}: the band from the kept inside map differs"
            );
            println!(
                "{name:<13} {mm:>3} mm  standoff {standoff_voxels:<5} voxel  bricks {:>6}  digest {:016x}  band {build_ms:>8.1} ms  (kept inside map {with_inside_ms:>8.1} ms)  4-bit voxelization {:>7.1} ms",
                band.brick_count(),
                digest(&band),
                stats.total_ms
            );
        }
    }
}
