//! Inside and outside through the real binary (docs/voxelize.md, "Open and leaky meshes"): a
//! workspace box whose wall passes through a solid leaves that solid's inside Interior, and the
//! open (leaky) Bezier teapot keeps its inside.

use vps_testkit::process::{json, Vps};

/// `vps voxelize MESH ARGS -o OUT`, then `vps probe OUT --points` at `points`: the kinds.
fn voxelize_and_probe(mesh: &str, args: &[&str], points: &[[f64; 3]]) -> Vec<String> {
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    let vmap = vps.path("out.vmap");
    let mut cmd = vec!["voxelize", mesh];
    cmd.extend_from_slice(args);
    cmd.extend_from_slice(&["-o", &vmap]);
    let out = vps.run(&cmd);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = vps.path("points.csv");
    let lines: Vec<String> = points
        .iter()
        .map(|p| format!("{},{},{}", p[0], p[1], p[2]))
        .collect();
    std::fs::write(&csv, lines.join("\n")).unwrap();
    let kinds = json(&vps.run(&["probe", &vmap, "--points", &csv, "--json"]));
    kinds
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["kind"].as_str().unwrap().to_string())
        .collect()
}

#[test]
fn workspace_wall_through_the_box_keeps_its_inside() {
    // The built-in box spans ±0.05 m; the workspace's -x wall at 0.01 m cuts it. Before, the flood
    // fill ran in from that wall and 0.02,0,0 read free.
    let kinds = voxelize_and_probe(
        "builtin:box",
        &[
            "--voxel-size",
            "5mm",
            // The paper's kinds: 4-bit maps call the voxels a few layers in from the surface
            // by their depth layer, which probe reports as surface.
            "--width",
            "2",
            "--workspace",
            "0.01,-0.03,-0.03,0.2,0.03,0.03",
        ],
        &[[0.02, 0.0, 0.0], [0.03, 0.01, -0.01], [0.1, 0.0, 0.0]],
    );
    assert_eq!(kinds, ["interior", "interior", "free"]);
}

#[test]
fn leaky_teapot_keeps_its_inside() {
    // The tessellated Bezier teapot is open (its patches are not welded into a closed surface); at
    // 1 mm some seams are wider than a voxel. Points well inside the body, and one well outside.
    let kinds = voxelize_and_probe(
        "builtin:teapot",
        &["--voxel-size", "1mm"],
        &[[0.0, 0.0, 0.015], [0.01, 0.005, 0.02], [0.0, 0.0, 0.06]],
    );
    assert_eq!(kinds, ["interior", "interior", "free"]);
}
