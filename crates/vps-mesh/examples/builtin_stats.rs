//! Prints triangle/vertex counts, bounds and generation time of every built-in mesh.
//!
//! Run: `cargo run --release -p vps-mesh --example builtin_stats`

use std::time::Instant;

fn main() {
    for name in vps_mesh::builtin::BUILTIN_NAMES {
        let start = Instant::now();
        let mesh = vps_mesh::builtin::by_name(name).expect("listed names resolve");
        let elapsed = start.elapsed();
        let b = mesh.bounds();
        println!(
            "{name:>13}: {:>7} triangles {:>7} vertices, size {:.4?} m, area {:.4} m², {:.1} ms",
            mesh.triangle_count(),
            mesh.vertices.len(),
            b.size().to_array(),
            mesh.area(),
            elapsed.as_secs_f64() * 1e3
        );
    }
}
