//! A file-based scene watched in headless Chromium (Debian's `chromium`; the test prints
//! `SKIPPED ...` and passes when it is not installed).
//!
//! The static scene (a floor plate, two beams and three pipes) is written as a binary STL and the
//! part (a sphere) as an OBJ in a temporary directory, loaded back with `vps_mesh::load_mesh`,
//! voxelized with `vps_voxelize` and served with [`ViewerContent::with_meshes`] and a live feed
//! holding the part at one pose. The page must draw the meshes shaded: the voxel overlay is off,
//! the view has many colours off the background, and turning the overlay on adds the overlay's
//! orange where there was almost none. The 2D-canvas fallback must draw a non-blank view too.
//! Screenshots: `viewer-mesh-webgl.png`, `viewer-mesh-overlay.png` and `viewer-mesh-2d.png` in
//! Cargo's test temporary directory (printed).

use glam::{DQuat, DVec3};
use std::io::Write;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;
use vps_mesh::builtin::{cuboid, cylinder, uv_sphere};
use vps_mesh::{load_mesh, TriMesh};
use vps_runtime::{state_feed, FeedFrame};
use vps_view::browser::{canvas_content, Browser, CHROMIUM};
use vps_view::{SceneLimits, ViewerContent, ViewerServer};
use vps_voxelize::{point_shell, voxelize_tree, ShellMethod, VoxelizeOptions};
use vps_voxmap::TreeConfig;

/// Width of the 3D view in the 800 px window (the side panel is 300 px).
const VIEW_WIDTH: u32 = 500;

/// A floor plate, two beams along x and three pipes along y between them (m).
fn pipes_and_beams() -> TriMesh {
    let mut scene = cuboid(DVec3::new(0.3, 0.2, 0.01));
    for y in [-0.15, 0.15] {
        let beam = cuboid(DVec3::new(0.3, 0.02, 0.02));
        scene.append(&beam.transformed(1.0, DQuat::IDENTITY, DVec3::new(0.0, y, 0.2)));
    }
    for x in [-0.2, 0.0, 0.2] {
        let pipe = cylinder(0.03, 0.18, 48);
        let along_y = DQuat::from_rotation_x(std::f64::consts::FRAC_PI_2);
        scene.append(&pipe.transformed(1.0, along_y, DVec3::new(x, 0.0, 0.1)));
    }
    scene
}

/// `mesh` as a binary STL (80-byte header, count, then normal, corners and attribute per triangle).
fn write_binary_stl(path: &Path, mesh: &TriMesh) {
    let mut bytes = vec![0u8; 80];
    bytes.extend_from_slice(&(mesh.triangle_count() as u32).to_le_bytes());
    for i in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(i);
        let n = (b - a).cross(c - a).normalize_or_zero();
        for v in [n, a, b, c] {
            for x in v.to_array() {
                bytes.extend_from_slice(&(x as f32).to_le_bytes());
            }
        }
        bytes.extend_from_slice(&[0, 0]);
    }
    std::fs::write(path, bytes).unwrap();
}

/// `mesh` as a Wavefront OBJ (`v` and `f` lines, 1-based indices).
fn write_obj(path: &Path, mesh: &TriMesh) {
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    for v in &mesh.vertices {
        writeln!(f, "v {} {} {}", v.x, v.y, v.z).unwrap();
    }
    for t in &mesh.triangles {
        writeln!(f, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1).unwrap();
    }
}

/// Pixels of the overlay's orange (red well above blue, green between) in the view.
fn orange_pixels(png_bytes: &[u8]) -> usize {
    let decoder = png::Decoder::new(std::io::Cursor::new(png_bytes));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let channels = info.color_type.samples();
    let mut n = 0;
    for y in 0..info.height as usize {
        for x in 0..VIEW_WIDTH.min(info.width) as usize {
            let i = (y * info.width as usize + x) * channels;
            let [r, g, b] = [buf[i], buf[i + 1], buf[i + 2]].map(i32::from);
            n += (r > g && g > b && r - b > 100) as usize;
        }
    }
    n
}

/// How many times the page has drawn.
fn draws(browser: &mut Browser) -> u64 {
    let n = browser.eval("Number(document.getElementById('view').dataset.draws || 0)");
    n.as_u64().unwrap_or(0)
}

/// Runs `action` in the page, then waits for the page to draw again.
fn act_and_redraw(browser: &mut Browser, action: &str) {
    let before = draws(browser);
    browser.eval(action);
    browser.wait_for("a redraw", Duration::from_secs(60), |b| {
        (draws(b) > before).then_some(())
    });
}

#[test]
fn a_mesh_file_scene_is_drawn_shaded_in_headless_chromium() {
    if !Path::new(CHROMIUM).exists() {
        eprintln!(
            "SKIPPED a_mesh_file_scene_is_drawn_shaded_in_headless_chromium: {CHROMIUM} is not \
             installed (Debian: apt-get install chromium; .ci/run installs it)"
        );
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (stl, obj) = (dir.path().join("bay.stl"), dir.path().join("part.obj"));
    write_binary_stl(&stl, &pipes_and_beams());
    write_obj(&obj, &uv_sphere(0.04, 32, 16));
    let statics = load_mesh(&stl).unwrap().mesh;
    let part = load_mesh(&obj).unwrap().mesh;

    let opts = VoxelizeOptions {
        voxel_size: 0.01,
        ..VoxelizeOptions::default()
    };
    let (tree, _) =
        voxelize_tree(std::slice::from_ref(&statics), &opts, TreeConfig::default()).unwrap();
    let shell = point_shell(&part, 0.01, ShellMethod::VoxelCentres).unwrap();
    // The shell's frame has its origin at the part's centre of mass.
    let part_in_shell_frame = part.transformed(1.0, DQuat::IDENTITY, -shell.mass.center_of_mass);
    let scene = ViewerContent::new(
        "bay.stl + part.obj",
        Arc::new(tree),
        Some(Arc::new(shell)),
        SceneLimits::default(),
    )
    .with_meshes(vec![statics.clone()], Some(part_in_shell_frame))
    // A hand's path across the scene at the part's height, drawn as a line by both renderers.
    .with_hand(
        &(0..=100)
            .map(|k| DVec3::new(-0.3 + 0.008 * k as f64, -0.05, 0.32))
            .collect::<Vec<_>>(),
        (DVec3::new(-0.3, -0.05, 0.32), DQuat::IDENTITY),
    );
    assert_eq!(scene.meta.mesh_triangles, statics.triangle_count());
    assert_eq!(scene.meta.hand_path_m.len(), 101);
    let (tx, rx) = state_feed();
    let viewer = ViewerServer::start("127.0.0.1:0".parse().unwrap(), scene, Some(rx)).unwrap();
    tx.publish(FeedFrame::at_rest(1, DVec3::new(0.1, -0.05, 0.32)));

    let profile = tempfile::tempdir().unwrap();
    let mut browser = Browser::open(profile.path(), &viewer.url());
    let patience = Duration::from_secs(120);
    browser.wait_for("a draw of the scene with the part", patience, |b| {
        let info = b.text("scene-info");
        let pose = b.text("pose");
        (info.contains("meshes") && pose.starts_with("frame ") && draws(b) >= 1).then_some(())
    });
    let renderer = browser.text("render-mode");
    assert!(
        browser.eval("document.getElementById('voxels').checked") == false,
        "the voxel overlay should start off when there are meshes"
    );
    // The whole scene, not the close-up that follows the part.
    act_and_redraw(&mut browser, "document.getElementById('follow').click()");
    let shaded = browser.screenshot();
    let shots = Path::new(env!("CARGO_TARGET_TMPDIR"));
    std::fs::write(shots.join("viewer-mesh-webgl.png"), &shaded).unwrap();
    let (colours, share) = canvas_content(&shaded, VIEW_WIDTH);
    let orange_off = orange_pixels(&shaded);

    act_and_redraw(&mut browser, "document.getElementById('voxels').click()");
    let overlay = browser.screenshot();
    std::fs::write(shots.join("viewer-mesh-overlay.png"), &overlay).unwrap();
    let orange_on = orange_pixels(&overlay);
    eprintln!(
        "mesh scene: renderer {renderer}; {colours} colours, {:.0} % off the background; overlay \
         orange pixels off {orange_off}, on {orange_on} (screenshots in {})",
        share * 100.0,
        shots.display()
    );
    assert!(colours > 200, "a flat or blank view: {colours} colours");
    assert!(share > 0.1, "the view is mostly background: {share}");
    let view_pixels = (VIEW_WIDTH * 600) as usize;
    assert!(
        orange_off < view_pixels / 100,
        "overlay colours with the overlay off: {orange_off}"
    );
    assert!(
        orange_on > orange_off + 2000,
        "the overlay added {orange_on} vs {orange_off}"
    );

    // The 2D-canvas fallback draws the meshes too.
    browser.open_page(&format!("{}?renderer=2d", viewer.url()));
    browser.wait_for("a 2D draw", patience, |b| {
        let mode = b.text("render-mode");
        (mode == "canvas2d" && draws(b) >= 1).then_some(())
    });
    act_and_redraw(&mut browser, "document.getElementById('follow').click()");
    let flat = browser.screenshot();
    std::fs::write(shots.join("viewer-mesh-2d.png"), &flat).unwrap();
    let (colours, share) = canvas_content(&flat, VIEW_WIDTH);
    eprintln!(
        "  2D fallback: {colours} colours, {:.0} % off the background",
        share * 100.0
    );
    assert!(colours > 20 && share > 0.1, "{colours} colours, {share}");
    let console = browser.console_lines();
    assert!(
        !console.iter().any(|l| l.starts_with("exception")),
        "the page threw: {console:?}"
    );
    assert_eq!(
        orange_pixels(&flat),
        0,
        "the 2D view drew the overlay while it is off"
    );
}
