//! Times the voxelizer on a synthetic aircraft-bay-sized scene: a 3 m × 2 m × 1.5 m box of random
//! tubes and spheres, about 600k triangles, at 5 mm voxels (~72M voxels). Run in release:
//! `cargo run --release -p vps-voxelize --example voxelize_timing [-- --objects]`
//! (`--objects` passes every tube and sphere as its own object instead of one merged mesh).

use glam::{DQuat, DVec3};
use rand::{Rng, SeedableRng};
use vps_mesh::builtin::{cylinder, uv_sphere};
use vps_mesh::TriMesh;
use vps_voxelize::{voxelize_with_stats, VoxelizeOptions};

fn main() {
    let separate = std::env::args().any(|a| a == "--objects");
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    let size = DVec3::new(3.0, 2.0, 1.5);
    let mut objects: Vec<TriMesh> = Vec::new();
    let place = |m: TriMesh, rng: &mut rand_chacha::ChaCha8Rng| {
        let rot = DQuat::from_euler(
            glam::EulerRot::XYZ,
            rng.gen_range(0.0..6.3),
            rng.gen_range(0.0..6.3),
            rng.gen_range(0.0..6.3),
        );
        let at = DVec3::new(
            rng.gen_range(0.0..size.x),
            rng.gen_range(0.0..size.y),
            rng.gen_range(0.0..size.z),
        );
        m.transformed(1.0, rot, at)
    };
    // 1500 tubes of 64 sides (256 triangles), 2 to 20 mm radius, 0.1 to 0.6 m long.
    for _ in 0..1500 {
        let tube = cylinder(rng.gen_range(0.002..0.02), rng.gen_range(0.05..0.3), 64);
        objects.push(place(tube, &mut rng));
    }
    // 1000 spheres of 224 triangles, 5 to 40 mm radius.
    for _ in 0..1000 {
        let ball = uv_sphere(rng.gen_range(0.005..0.04), 16, 8);
        objects.push(place(ball, &mut rng));
    }
    // Clamp into the bay by construction: corners pin the bounds.
    let triangles: usize = objects.iter().map(TriMesh::triangle_count).sum();
    let input = if separate {
        objects
    } else {
        let mut all = TriMesh::default();
        for o in &objects {
            all.append(o);
        }
        vec![all]
    };
    let opts = VoxelizeOptions {
        progress: true,
        ..Default::default()
    };
    let t = std::time::Instant::now();
    let (grid, stats) = voxelize_with_stats(&input, &opts).expect("voxelize");
    let wall = t.elapsed().as_secs_f64();
    println!(
        "{} objects, {triangles} triangles, grid {:?} = {:.1} M voxels, rayon threads {}",
        input.len(),
        grid.spec.dims,
        grid.spec.voxel_count() as f64 / 1e6,
        rayon::current_num_threads()
    );
    println!("{stats:#?}");
    println!("wall {:.3} s", wall);
}
