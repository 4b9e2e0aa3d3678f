//! `vps sweep --quick` through the binary: JSON and CSV with the expected columns, plots written;
//! scene-file errors name the field.

use std::path::Path;
use std::process::Command;

const COLUMNS: &str = "scene,method,voxel_size_mm,voxelized,shell_points,voxmap_bytes,voxelize_ms,frames,compute_p50_us,compute_p999_us,penetration_ratio,compared_frames,both_force_frames,voxel_only_frames,reference_only_frames,direction_error_deg_p50,direction_error_deg_p95,magnitude_error_p50,magnitude_ratio_p50,min_separation_mm";

fn vps() -> Command {
    Command::new(env!("CARGO_BIN_EXE_vps"))
}

#[test]
fn quick_sweep_writes_json_csv_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/scenes/rig-teapot.toml");
    let config = dir.path().join("sweep.toml");
    std::fs::write(
        &config,
        format!(
            "voxel_sizes_mm = [10.0, 5.0, 2.5]\nmethods = [\"centres\", \"exact\"]\n[[run]]\nscene = {:?}\nseconds = 1.0\n",
            rig.display().to_string()
        ),
    )
    .unwrap();
    let (json, csv, plots) = (
        dir.path().join("s.json"),
        dir.path().join("s.csv"),
        dir.path().join("plots"),
    );
    let out = vps()
        .args(["sweep", "--quick", "--config"])
        .arg(&config)
        .arg("--json")
        .arg(&json)
        .arg("--csv")
        .arg(&csv)
        .arg("--plots")
        .arg(&plots)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let csv = std::fs::read_to_string(&csv).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next().unwrap(), COLUMNS);
    // --quick keeps the two coarsest sizes ≥ 5 mm: 10 and 5 mm, two methods each.
    let body: Vec<&str> = lines.collect();
    assert_eq!(body.len(), 4, "{csv}");
    let rows: Vec<serde_json::Value> =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(rows.len(), 4);
    for r in &rows {
        for c in COLUMNS.split(',') {
            assert!(r.get(c).is_some(), "column {c} missing from {r}");
        }
        assert_eq!(r["scene"], "rig-teapot");
        assert_eq!(r["voxelized"], "workspace");
        assert_eq!(r["frames"], 1000);
        assert!(r["shell_points"].as_u64().unwrap() > 50);
    }
    // Halving the voxel size gives more shell points and a larger voxmap.
    let points = |i: usize| rows[i]["shell_points"].as_u64().unwrap();
    assert!(points(2) > 2 * points(0), "{rows:?}");
    assert_eq!(rows[0]["method"], "centres");
    assert_eq!(rows[1]["method"], "exact");
    for figure in [
        "shell-points",
        "compute-p999-us",
        "direction-error-deg",
        "min-separation-mm",
    ] {
        let svg = std::fs::read_to_string(plots.join(format!("{figure}.svg"))).unwrap();
        assert!(svg.contains("<svg"), "{figure}");
    }
}

#[test]
fn bad_scene_file_names_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let rig = Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/scenes/rig-teapot.toml");
    let scene = dir.path().join("bad.toml");
    let text = std::fs::read_to_string(rig)
        .unwrap()
        .replace("offset_layers = 2", "offset_layers = 40");
    std::fs::write(&scene, text).unwrap();
    let config = dir.path().join("sweep.toml");
    std::fs::write(
        &config,
        "voxel_sizes_mm = [10.0]\nmethods = [\"centres\"]\n[[run]]\nscene = \"bad.toml\"\n",
    )
    .unwrap();
    let out = vps()
        .args(["sweep", "--quick", "--config"])
        .arg(&config)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("voxels.offset_layers"),
        "{err}"
    );
}
