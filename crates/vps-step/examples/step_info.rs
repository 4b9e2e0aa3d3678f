//! Prints what `vps_step::read_step` makes of STEP files: per solid its name, triangles, volume
//! (mm³), bounding box (mm) and the time taken. `cargo run --release -p vps-step --example
//! step_info -- FILE... [--tolerance-mm T]`.

fn main() {
    let mut tolerance_mm = 0.25;
    let mut files = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--tolerance-mm" {
            tolerance_mm = args
                .next()
                .and_then(|t| t.parse().ok())
                .expect("--tolerance-mm T");
        } else {
            files.push(a);
        }
    }
    for file in files {
        let bytes = std::fs::read(&file).expect("readable file");
        let start = std::time::Instant::now();
        let model = vps_step::read_step(&bytes, &vps_step::StepOptions::new(tolerance_mm * 1e-3));
        let seconds = start.elapsed().as_secs_f64();
        match model {
            Err(e) => println!("{file}: error: {e} ({seconds:.3} s)"),
            Ok(m) => {
                println!(
                    "{file}: unit {} ({} m), {} solid(s), {} unread instance(s), {seconds:.3} s",
                    m.unit.name,
                    m.unit.metres,
                    m.solids.len(),
                    m.unread_instances
                );
                for s in &m.solids {
                    let (lo, hi) = s.vertices.iter().fold(
                        (glam::DVec3::splat(f64::MAX), glam::DVec3::splat(f64::MIN)),
                        |(lo, hi), v| (lo.min(*v), hi.max(*v)),
                    );
                    println!(
                        "  {} (#{}): {} triangles, volume {:.3} mm³, bbox {:.3?} .. {:.3?} mm",
                        s.name,
                        s.id,
                        s.triangles.len(),
                        s.volume() * 1e9,
                        (lo * 1e3).to_array(),
                        (hi * 1e3).to_array()
                    );
                }
            }
        }
    }
}
