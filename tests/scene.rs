//! Scene files through the binary: a scene made only of mesh files (a binary STL and an OBJ in
//! millimetres, one object rotated and translated) runs with the simulated hand, on one process
//! and on two local workers; the voxmap cache; bad scene files.

use glam::DVec3;
use std::path::Path;
use vps_testkit::process::{json, stderr, Vps};
use vps_testkit::scene_edit::{bad_scenes, SceneEdit};

/// Corners of an axis-aligned box and its 12 triangles, wound outward: the built-in box's
/// triangles over its corners moved to `min` and `max` (exactly: each coordinate is one of the
/// two given).
fn cuboid(min: [f64; 3], max: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
    let unit = vps_mesh::builtin::cuboid(DVec3::ONE);
    let vertices = unit
        .vertices
        .iter()
        .map(|v| [0, 1, 2].map(|k| if v[k] < 0.0 { min[k] } else { max[k] }))
        .collect();
    (vertices, unit.triangles)
}

/// A binary STL of a box (coordinates as given, e.g. millimetres).
fn write_stl(path: &Path, min: [f64; 3], max: [f64; 3]) {
    let (v, t) = cuboid(min, max);
    let mut bytes = vec![0u8; 80];
    bytes.extend_from_slice(&(t.len() as u32).to_le_bytes());
    for tri in &t {
        bytes.extend_from_slice(&[0u8; 12]); // normal: readers recompute it
        for &i in tri {
            for c in v[i as usize] {
                bytes.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
        bytes.extend_from_slice(&[0u8; 2]);
    }
    std::fs::write(path, bytes).unwrap();
}

/// A Wavefront OBJ of a box.
fn write_obj(path: &Path, min: [f64; 3], max: [f64; 3]) {
    let (v, t) = cuboid(min, max);
    let mut text = String::from("# a box, millimetres\n");
    for p in &v {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for tri in &t {
        text += &format!("f {} {} {}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

/// An OBJ of the box from `min` to `max` with its top face (the two triangles at `max[2]`) left
/// out: an open cup, 4 boundary edges.
fn write_open_top_obj(path: &Path, min: [f64; 3], max: [f64; 3]) {
    let (v, t) = cuboid(min, max);
    let mut text = String::from("# a box without its top face\n");
    for p in &v {
        text += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    let top = |tri: &[u32; 3]| tri.iter().all(|&k| v[k as usize][2] == max[2]);
    assert_eq!(t.iter().filter(|tri| top(tri)).count(), 2);
    for tri in t.iter().filter(|tri| !top(tri)) {
        text += &format!("f {} {} {}\n", tri[0] + 1, tri[1] + 1, tri[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

/// A small bay in millimetres: a floor (OBJ, top at z = 0), a wall (STL) used twice: rotated 90°
/// about Z and moved to x = 0.09..0.1 m, and moved unrotated to y = -0.1..-0.09 m; a 30 mm cube
/// part (STL, given in "Y-up" and rotated back). The hand presses the part onto the floor,
/// slides it, lifts it and presses it against the rotated wall.
const SCENE: &str = r#"
name = "mm-bay"

[part]
source = "part.stl"
units = "mm"
rotate_deg = [-90, 0, 0]

[[static]]
source = "floor.obj"
units = "mm"

[[static]]
source = "wall.stl"
units = "mm"
rotate_deg = [0, 0, 90]
translate = [0.1, -0.1, 0.0]

[[static]]
source = "wall.stl"
units = "mm"
translate = [-0.1, -0.1, 0.0]

[voxels]
voxel_size = "5mm"

[hand]
waypoints = [[0.0, 0.0, 0.05], [0.0, 0.0, 0.005], [0.03, 0.0, 0.005], [0.03, 0.0, 0.03], [0.09, 0.0, 0.03], [0.03, 0.0, 0.03]]
speed = 0.08
hold_s = 0.3
"#;

/// A sandbox holding the bay: `floor.obj`, `wall.stl` and `part.stl` (in millimetres) and the
/// scene file `bay.toml` that uses them.
fn bay() -> Vps {
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    let dir = vps.dir();
    write_obj(
        &dir.join("floor.obj"),
        [-100.0, -100.0, -10.0],
        [100.0, 100.0, 0.0],
    );
    write_stl(&dir.join("wall.stl"), [0.0, 0.0, 0.0], [200.0, 10.0, 60.0]);
    write_stl(
        &dir.join("part.stl"),
        [-15.0, -15.0, -15.0],
        [15.0, 15.0, 15.0],
    );
    std::fs::write(dir.join("bay.toml"), SCENE).unwrap();
    vps
}

#[test]
fn a_scene_of_mesh_files_runs_touching_without_penetrating() {
    let bay = bay();
    let scene = bay.path("bay.toml");
    let report = json(&bay.run(&["run", "--scene", &scene, "--seconds", "5", "--json"]));
    let stats = &report["stats"];
    assert_eq!(stats["frames"], 5000, "{report}");
    assert!(
        stats["touching_frames"].as_u64().unwrap() > 0,
        "the hand presses the part on the floor and the wall: {report}"
    );
    assert_eq!(stats["penetrating_frames"], 0, "braking on: {report}");
    assert_eq!(report["end"], "frames done", "{report}");
    assert_eq!(report["complete"], true, "{report}");

    let check = json(&bay.run(&["scene", "check", &scene, "--json"]));
    assert_eq!(check["objects"].as_array().unwrap().len(), 3);
    assert_eq!(check["objects"][0]["triangles"], 12);
    // The rotated wall (x 0.09..0.1 m after rotation and translation), in metres.
    let wall = &check["objects"][1];
    let (lo, hi) = (
        wall["bounds_min_m"][0].as_f64().unwrap(),
        wall["bounds_max_m"][0].as_f64().unwrap(),
    );
    assert!(
        (lo - 0.09).abs() < 1e-9 && (hi - 0.1).abs() < 1e-9,
        "{wall}"
    );
    assert!(check["shell_points"].as_u64().unwrap() > 50, "{check}");
    assert!(check["voxmap_estimate"]["grid_voxels"].as_f64().unwrap() > 1e4);
    assert!(check["flags"].as_array().unwrap().is_empty(), "{check}");
}

/// The same scene over two local worker processes, replaying a trace recorded on it, writes the
/// same wrenches as one process: the final state, which integrates every wrench, is bit-identical.
#[test]
fn two_local_workers_replay_the_scene_bit_identically() {
    let bay = bay();
    let scene = bay.path("bay.toml");
    let trace = bay.path("trace.jsonl");
    let recorded = bay.run(&["record", "--scene", &scene, "-o", &trace, "--seconds", "2"]);
    assert!(recorded.status.success(), "{}", stderr(&recorded));
    let device = format!("replay:{trace}");
    let alone = json(&bay.run(&["run", "--scene", &scene, "--device", &device, "--json"]));
    let clustered = json(&bay.run(&[
        "cluster",
        "--local-workers",
        "2",
        "--max-stale-frames",
        "0",
        "--scene",
        &scene,
        "--device",
        &device,
        "--json",
    ]));
    assert_eq!(alone["stats"]["frames"], 2000);
    assert!(alone["stats"]["touching_frames"].as_u64().unwrap() > 0);
    assert_eq!(clustered["final_position_m"], alone["final_position_m"]);
    for key in [
        "frames",
        "contact_frames",
        "touching_frames",
        "penetrating_frames",
    ] {
        assert_eq!(clustered["stats"][key], alone["stats"][key], "{key}");
    }
    assert_eq!(clustered["cluster"]["peers"].as_array().unwrap().len(), 2);
}

#[test]
fn the_voxmap_cache_is_used_and_rebuilt_when_an_input_changes() {
    let bay = bay();
    let scene = bay.path("bay.toml");
    let start = |bay: &Vps| {
        let out = bay.run(&["run", "--scene", &scene, "--seconds", "0.1", "--json"]);
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    assert!(start(&bay).contains("voxmap: built, cached at"));
    let again = start(&bay);
    assert!(again.contains("voxmap: loaded from cache"), "{again}");
    // One byte of a mesh file: the floor 1 mm thicker.
    let floor = bay.dir().join("floor.obj");
    let text = std::fs::read_to_string(&floor)
        .unwrap()
        .replace("-10", "-11");
    std::fs::write(&floor, text).unwrap();
    assert!(start(&bay).contains("voxmap: built, cached at"));
    assert!(start(&bay).contains("voxmap: loaded from cache"));
    // A voxel setting.
    std::fs::write(
        bay.dir().join("bay.toml"),
        SCENE.replace("[voxels]", "[voxels]\noffset_layers = 1"),
    )
    .unwrap();
    assert!(start(&bay).contains("voxmap: built, cached at"));
    // A corrupt cache file is rebuilt, not fatal.
    for entry in std::fs::read_dir(bay.cache()).unwrap() {
        std::fs::write(entry.unwrap().path(), b"not a voxmap").unwrap();
    }
    let rebuilt = start(&bay);
    assert!(
        rebuilt.contains("unreadable") && rebuilt.contains("voxmap: built, cached at"),
        "{rebuilt}"
    );
    // --no-cache neither reads nor writes.
    let out = stderr(&bay.run(&["run", "--scene", &scene, "--seconds", "0.1", "--no-cache"]));
    assert!(out.contains("voxmap: built (cache off)"), "{out}");
}

/// The `.vmap` entries of a cache directory.
fn cache_maps(vps: &Vps) -> Vec<std::path::PathBuf> {
    let mut maps: Vec<_> = std::fs::read_dir(vps.cache())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "vmap"))
        .collect();
    maps.sort();
    maps
}

/// Issue 36 item 1: another valid map copied over a cache entry (the 10 mm map over the 5 mm
/// one, with and without its record) was loaded and rendered; now it is rebuilt, saying why.
#[test]
fn another_scenes_map_copied_over_a_cache_entry_is_rebuilt_saying_why() {
    let bay = bay();
    let scene = bay.path("bay.toml");
    let coarse = bay.path("coarse.toml");
    std::fs::write(&coarse, SCENE.replace("\"5mm\"", "\"10mm\"")).unwrap();
    let start = |scene: &str| {
        let out = bay.run(&["run", "--scene", scene, "--seconds", "0.1", "--json"]);
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    assert!(start(&scene).contains("voxmap: built, cached at"));
    let fine_map = cache_maps(&bay);
    assert_eq!(fine_map.len(), 1);
    let fine_map = &fine_map[0];
    assert!(start(&coarse).contains("voxmap: built, cached at"));
    let coarse_map = cache_maps(&bay)
        .into_iter()
        .find(|p| p != fine_map)
        .unwrap();
    let record = |p: &std::path::Path| {
        let mut s = p.as_os_str().to_owned();
        s.push(".record");
        std::path::PathBuf::from(s)
    };
    // The map alone, then the map with its record.
    for with_record in [false, true] {
        std::fs::copy(&coarse_map, fine_map).unwrap();
        if with_record {
            std::fs::copy(record(&coarse_map), record(fine_map)).unwrap();
        }
        let err = start(&scene);
        assert!(!err.contains("loaded from cache"), "{err}");
        assert!(
            err.contains("not using it, rebuilding it") && err.contains("voxmap: built, cached at"),
            "{err}"
        );
        let why = if with_record {
            "recorded as the map of other inputs"
        } else {
            "content hash"
        };
        assert!(err.contains(why), "{why}: {err}");
        assert!(start(&scene).contains("voxmap: loaded from cache"));
    }
    // A record forged for the 5 mm key: the 10 mm grid still differs from the inputs'.
    std::fs::copy(&coarse_map, fine_map).unwrap();
    let fine_key = fine_map.file_stem().unwrap().to_str().unwrap();
    let coarse_key = coarse_map.file_stem().unwrap().to_str().unwrap();
    let forged = std::fs::read_to_string(record(&coarse_map))
        .unwrap()
        .replace(coarse_key, fine_key);
    std::fs::write(record(fine_map), forged).unwrap();
    let err = start(&scene);
    assert!(
        err.contains("holds a grid of") && err.contains("voxmap: built, cached at"),
        "{err}"
    );
}

/// Issue 36 item 7: `vps scene check` said ok to a grip of 1e300 m, a waypoint of 1e308 m and a
/// speed of 1e-300 m/s; the session then failed with "haptic parameter `max_radius` = inf",
/// "waypoint 2: time is not finite" or a 300-digit time, naming no key. Both now refuse the file
/// at once, naming it, the key and the bound.
#[test]
fn scene_check_refuses_what_a_session_would_naming_the_file_and_key() {
    let bay = bay();
    for (from, to, key, bound) in [
        (
            "rotate_deg = [-90, 0, 0]",
            "rotate_deg = [-90, 0, 0]\ngrip = [1e300, 0, 0]",
            "`part.grip`",
            "1000000 m",
        ),
        (
            "[0.03, 0.0, 0.005]",
            "[1e308, 0.0, 0.005]",
            "`hand.waypoints[2]`",
            "1000000 m",
        ),
        ("speed = 0.08", "speed = 1e-300", "`hand.speed`", "1e6 s"),
    ] {
        let text = SCENE.replacen(from, to, 1);
        assert_ne!(text, SCENE, "{from}");
        std::fs::write(bay.dir().join("bad.toml"), text).unwrap();
        let path = bay.path("bad.toml");
        for args in [
            vec!["scene", "check", path.as_str()],
            vec!["run", "--scene", path.as_str(), "--seconds", "0.1"],
        ] {
            let err = bay.fails(&args);
            assert!(
                err.contains("bad.toml") && err.contains(key) && err.contains(bound),
                "{args:?}: {key}, {bound}: {err}"
            );
            assert!(!err.contains("voxmap:"), "{args:?}: {err}");
            assert!(err.len() < 600, "{args:?}: {err}");
        }
    }
}

#[test]
fn bad_scene_files_name_the_file_and_field_and_run_nothing() {
    let bay = bay();
    let replaced = [
        SceneEdit {
            from: "[voxels]",
            to: "[voxels]\nvoxel_sise = 0.005",
            field: "voxels.voxel_sise",
        },
        SceneEdit {
            from: "speed = 0.08",
            to: "speed = \"fast\"",
            field: "hand.speed",
        },
        SceneEdit {
            from: "voxel_size = \"5mm\"",
            to: "voxel_size = -0.005",
            field: "voxels.voxel_size",
        },
        SceneEdit {
            from: "source = \"floor.obj\"",
            to: "source = \"missing.obj\"",
            field: "static[0].source",
        },
        SceneEdit {
            from: "units = \"mm\"\nrotate_deg = [-90",
            to: "units = \"milimetres\"\nrotate_deg = [-90",
            field: "part.units",
        },
        // The part left in metres: 30 m across in a 0.2 m bay.
        SceneEdit {
            from: "units = \"mm\"\nrotate_deg = [-90",
            to: "rotate_deg = [-90",
            field: "`part`",
        },
        SceneEdit {
            from: "voxel_size = \"5mm\"",
            to: "voxel_size = \"1um\"",
            field: "voxels.voxel_size",
        },
    ];
    // (appended, field): the bay scene with `appended` after it names `field`.
    let appended = [
        (
            "[device]\nkind = \"bridge\"\n[device.mapping]\nscale = 0.0\n",
            "device.mapping.scale",
        ),
        (
            "[device]\nkind = \"bridge\"\npose_timeout_ms = 1\n",
            "device.pose_timeout_ms",
        ),
        ("[device]\nmax_force = 0.0\n", "device.max_force"),
        // The old haptic key of the device limit names where the limit lives now.
        (
            "[haptic]\ndevice_max_force = 15.0\n",
            "`[device]` key `max_force`",
        ),
    ];
    let cases = bad_scenes(SCENE, &replaced, &appended);
    for (i, (text, field)) in cases.iter().enumerate() {
        let name = format!("bad{i}.toml");
        std::fs::write(bay.dir().join(&name), text).unwrap();
        let out = bay.run(&[
            "run",
            "--scene",
            &bay.path(&name),
            "--seconds",
            "1",
            "--json",
        ]);
        let err = stderr(&out);
        assert!(!out.status.success(), "{name} ran");
        assert!(out.stdout.is_empty(), "{name} printed a report");
        assert!(err.contains(&name), "{name}: the file is not named: {err}");
        assert!(err.contains(field), "{name}: `{field}` is not named: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(!err.contains("voxmap: built"), "{name} voxelized: {err}");
    }
}

/// `vps run`'s text report and its loop-period error speak of the session (a rename once printed
/// "assets end:", "assets:" and "the assets loop").
#[test]
fn the_text_report_speaks_of_the_session() {
    let bay = bay();
    let scene = bay.path("bay.toml");
    let out = bay.run(&["run", "--scene", &scene, "--seconds", "0.1"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("session end: frames done"), "{text}");
    assert!(text.contains("\nsession:\n"), "{text}");
    assert!(!text.contains("assets"), "{text}");
    // A binary built without --release says its figures are no guide (a user running
    // target/debug/vps saw thousands of watchdog trips and zero force with no word why).
    assert_eq!(
        text.contains("this vps was built without --release"),
        cfg!(debug_assertions),
        "{text}"
    );
    // The final position at 0.1 mm (it was printed with 17 digits: 0.07500950959614927).
    let line = text
        .lines()
        .find_map(|l| l.strip_prefix("final part position (m): "))
        .unwrap_or_else(|| panic!("no final position: {text}"));
    let coords: Vec<&str> = line
        .trim_matches(|c| c == '[' || c == ']')
        .split(", ")
        .collect();
    assert_eq!(coords.len(), 3, "{line}");
    for c in coords {
        let decimals = c.split_once('.').map_or(0, |(_, d)| d.len());
        assert!(
            decimals == 4 && c.parse::<f64>().is_ok() && c != "-0.0000",
            "{line}"
        );
    }

    let haptic = bay.path("haptic.toml");
    std::fs::write(&haptic, "dt = 0.002\n").unwrap();
    let err = bay.fails(&[
        "run",
        "--scene",
        &scene,
        "--haptic",
        &haptic,
        "--seconds",
        "0.1",
    ]);
    assert!(err.contains("the session loop runs at 1000 Hz"), "{err}");
    assert!(!err.contains("assets"), "{err}");
}

/// `vps scene check` says which voxel settings the built-in defaults' reason is about: the bay sets
/// only `voxel_size`. (The reason was printed unqualified even for a scene that already sets
/// every key.) The defaults it shows are the sweep's recommendation, the distance model, 4-bit
/// voxels and exact-surface points (they were the paper's tangent-plane model on 2-bit voxel
/// centres while scene check told the user to set 4 and "exact"), and the reason says how to get
/// the paper's.
#[test]
fn scene_check_names_the_settings_left_to_the_defaults() {
    let bay = bay();
    let out = bay.run(&["scene", "check", &bay.path("bay.toml")]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains(
            "why (built-in defaults, used here for voxel_width, shell_method, offset_layers, \
             force_model): "
        ),
        "{text}"
    );
    assert!(
        text.contains(
            "width 4 bits (built-in default), shell exact (built-in default), offset 2 layers \
             (built-in default)"
        ),
        "{text}"
    );
    assert!(
        text.contains(
            "for the paper's method set voxels.force_model = \"tangent-plane\", \
             voxels.voxel_width = 2 and voxels.shell_method = \"centres\""
        ),
        "{text}"
    );
    assert!(!text.contains("-0.0000"), "{text}");
    // The default model, distance, at 5 mm: contact starts half a voxel off the exact surface.
    assert!(
        text.contains(
            "force model: distance (built-in default): contact starts 2.5 mm from the exact surface"
        ),
        "{text}"
    );

    // 5 m voxels (`voxel_size = 5`, metres) on a 30 mm part: flagged, not just "ok".
    std::fs::write(
        bay.dir().join("coarse.toml"),
        SCENE.replace("voxel_size = \"5mm\"", "voxel_size = 5"),
    )
    .unwrap();
    let check = json(&bay.run(&["scene", "check", &bay.path("coarse.toml"), "--json"]));
    let flags = check["flags"].to_string();
    assert!(
        flags.contains("voxels.voxel_size: 5 m is no finer than the part (0.0300 m across)"),
        "{check}"
    );
}

/// docs/scenes.md "Clearances": the example peg (20 mm) enters its 22 mm hole with the distance
/// model as shipped (its default stand-off, half a voxel: 0.5 mm) and with the tangent-plane model at `offset_layers = 0`,
/// and stops on the rim with the tangent-plane default of 2, whose force layer closes the 1 mm gap
/// at 1 mm voxels; none penetrates.
#[test]
fn the_peg_enters_its_hole_with_the_distance_model_or_without_offset_layers() {
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    let text = std::fs::read_to_string(example.join("peg-in-hole.toml")).unwrap();
    for file in ["peg.obj", "peg-fixture.stl"] {
        std::fs::copy(example.join(file), vps.dir().join(file)).unwrap();
    }
    assert!(text.contains("force_model = \"distance\"\n"));
    let final_z = |offset: Option<u32>| {
        let name = format!("peg-{offset:?}.toml");
        let edited = match offset {
            None => text.clone(),
            Some(offset) => text.replace(
                "force_model = \"distance\"\n",
                &format!("force_model = \"tangent-plane\"\noffset_layers = {offset}\n"),
            ),
        };
        std::fs::write(vps.dir().join(&name), edited).unwrap();
        let scene = vps.path(&name);
        let report = json(&vps.run(&["run", "--scene", &scene, "--seconds", "4", "--json"]));
        assert_eq!(report["stats"]["penetrating_frames"], 0, "{report}");
        report["final_position_m"][2].as_f64().unwrap()
    };
    let distance = final_z(None);
    assert!(
        (distance - 0.05).abs() < 0.002,
        "distance model: z {distance}"
    );
    let inside = final_z(Some(0));
    assert!((inside - 0.05).abs() < 0.002, "offset 0: z {inside}");
    let on_rim = final_z(Some(2));
    // The block's top is at 0.04 m and the grip 0.03 m above the peg's bottom.
    assert!(on_rim > 0.07, "offset 2: z {on_rim}");
}

/// A part whose first waypoint lies inside a static object is held there for the whole session
/// (every frame penetrates). `vps run` said nothing and printed a penetration ratio of 1 as if
/// the haptics had failed; it now warns before the session, naming the waypoint and the fix. The
/// bay as given (the part starts in free space) gets no such warning.
#[test]
fn a_part_starting_inside_a_static_object_is_warned_about() {
    let bay = bay();
    let warning = "the part starts inside a static object";
    let clear = bay.run(&["run", "--scene", &bay.path("bay.toml"), "--seconds", "0.1"]);
    assert!(clear.status.success(), "{}", stderr(&clear));
    assert!(!stderr(&clear).contains(warning), "{}", stderr(&clear));

    write_stl(
        &bay.dir().join("block.stl"),
        [-40.0, -40.0, 0.0],
        [40.0, 40.0, 80.0],
    );
    let inside = SCENE
        .replace(
            "[voxels]",
            "[[static]]\nsource = \"block.stl\"\nunits = \"mm\"\n\n[voxels]",
        )
        .replace("[[0.0, 0.0, 0.05],", "[[0.0, 0.0, 0.04],");
    std::fs::write(bay.dir().join("inside.toml"), inside).unwrap();
    let scene = bay.path("inside.toml");
    let out = bay.run(&["run", "--scene", &scene, "--seconds", "0.1"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains(&format!("inside.toml: warning: {warning}"))
            && err.contains("first hand waypoint [0.0000, 0.0000, 0.0400] m")
            && err.contains("`hand.waypoints[0]`"),
        "{err}"
    );

    // The same block as an open cup (its top face missing): the flood fill from outside runs in
    // through the opening, and the part inside was not warned about before the winding number
    // classified the cup's inside (issue 33's leaky housing).
    write_open_top_obj(
        &bay.dir().join("cup.obj"),
        [-40.0, -40.0, 0.0],
        [40.0, 40.0, 80.0],
    );
    std::fs::write(
        bay.dir().join("cup.toml"),
        std::fs::read_to_string(bay.dir().join("inside.toml"))
            .unwrap()
            .replace("block.stl", "cup.obj"),
    )
    .unwrap();
    let out = bay.run(&["run", "--scene", &bay.path("cup.toml"), "--seconds", "0.1"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains(&format!("cup.toml: warning: {warning}"))
            && err.contains("cup.obj is not closed: 4 boundary edges"),
        "{err}"
    );
}

/// A scene of CAD exports in millimetres with no object rotated is flagged by `vps scene check`
/// (and warned about by a session): the scene's up is +Z and most CAD exports are Y up, and a
/// user who forgot `rotate_deg = [90, 0, 0]` saw "ok" and a part lying on its side. The bay,
/// whose part is rotated, has no flag (`a_scene_of_mesh_files_runs_touching_without_penetrating`).
#[test]
fn a_cad_scene_with_nothing_rotated_is_flagged_for_y_up() {
    let bay = bay();
    let unrotated = SCENE.replace("rotate_deg = [-90, 0, 0]\n", "").replace(
        "rotate_deg = [0, 0, 90]\ntranslate = [0.1, -0.1, 0.0]\n",
        "translate = [0.1, -0.1, 0.0]\n",
    );
    assert!(!unrotated.contains("rotate_deg"), "{unrotated}");
    std::fs::write(bay.dir().join("flat.toml"), unrotated).unwrap();
    let scene = bay.path("flat.toml");
    let check = json(&bay.run(&["scene", "check", &scene, "--json"]));
    let flags = check["flags"].to_string();
    assert!(
        flags.contains("no object is rotated (`rotate_deg`) and the scene's up is +Z")
            && flags.contains("set `rotate_deg = [90, 0, 0]` in [part] and in every [[static]]"),
        "{check}"
    );
    // The text form says whether its kernel figure comes from a debug build.
    let out = bay.run(&["scene", "check", &scene]);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(
        text.contains("this vps was built without --release"),
        cfg!(debug_assertions),
        "{text}"
    );
    assert_eq!(check["debug_build"], cfg!(debug_assertions), "{check}");
}

/// Whether a part gets where the hand takes it: the report gives the hand's last position beside
/// the part's (text and JSON), so a part held back by an obstacle reads as such. (It gave only the
/// part's position, and a user could not tell "stopped by the floor" from "arrived".) Here the
/// hand ends 50 mm inside the floor and the 30 mm cube rests on it.
#[test]
fn the_report_gives_the_hands_last_position_beside_the_parts() {
    let bay = bay();
    let pressed = SCENE.replace(
        "waypoints = [[0.0, 0.0, 0.05], [0.0, 0.0, 0.005], [0.03, 0.0, 0.005], [0.03, 0.0, 0.03], [0.09, 0.0, 0.03], [0.03, 0.0, 0.03]]",
        "waypoints = [[0.0, 0.0, 0.05], [0.0, 0.0, -0.05]]",
    );
    assert!(pressed.contains("-0.05]]"), "{pressed}");
    std::fs::write(bay.dir().join("pressed.toml"), pressed).unwrap();
    let scene = bay.path("pressed.toml");
    let args = ["run", "--scene", &scene, "--seconds", "1.5"];
    let report = json(&bay.run(&[&args[..], &["--json"]].concat()));
    let hand: Vec<f64> = report["final_hand_position_m"]
        .as_array()
        .unwrap_or_else(|| panic!("no final_hand_position_m: {report}"))
        .iter()
        .map(|c| c.as_f64().unwrap())
        .collect();
    let part: Vec<f64> = report["final_position_m"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_f64().unwrap())
        .collect();
    // The simulated hand yields a little to the force it feels; it still ends deep in the floor.
    assert!(hand[2] < -0.04, "the hand ends in the floor: {report}");
    assert!(
        part[2] > 0.015,
        "the cube (half-size 15 mm) rests on the floor (top z = 0): {report}"
    );
    let out = bay.run(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let line = text
        .lines()
        .find(|l| l.starts_with("final hand position (m): "))
        .unwrap_or_else(|| panic!("no hand line: {text}"));
    let gap = line
        .split("the part's grip is ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|g| g.parse::<f64>().ok())
        .unwrap_or_else(|| panic!("no distance: {line}"));
    assert!(gap > 0.055, "the part is held on the floor: {line}");
    assert!(line.contains("held back by an obstacle"), "{line}");
}

/// A voxel edge no finer than the part was flagged only by `vps scene check`; `vps run` on such a
/// scene (here `--voxel-size 0.05` against a 30 mm cube: an 8-point shell) ran without a word and
/// the part could end metres from the hand. Every session now warns before it runs.
#[test]
fn a_session_warns_of_voxels_no_finer_than_the_part() {
    let bay = bay();
    let scene = bay.path("bay.toml");
    let out = bay.run(&[
        "run",
        "--scene",
        &scene,
        "--voxel-size",
        "0.05",
        "--seconds",
        "0.1",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(
        err.contains(
            "bay.toml: warning: voxels.voxel_size: 0.05 m is no finer than the part (0.0300 m across)"
        ),
        "{err}"
    );
    let fine = bay.run(&["run", "--scene", &scene, "--seconds", "0.1"]);
    assert!(
        !stderr(&fine).contains("no finer than the part"),
        "{}",
        stderr(&fine)
    );
}

/// Hand waypoints written in millimetres (`[0.0, 0.0, 50.0]` for 50 mm) put the hand 50 m away:
/// scene check said ok and the session touched nothing. The first such waypoint is now flagged,
/// saying waypoints are metres; the bay's own waypoints are not.
#[test]
fn waypoints_written_in_millimetres_are_flagged() {
    let bay = bay();
    let in_mm = SCENE.replace(
        "waypoints = [[0.0, 0.0, 0.05], [0.0, 0.0, 0.005],",
        "waypoints = [[0.0, 0.0, 50.0], [0.0, 0.0, 0.005],",
    );
    assert!(in_mm.contains("50.0]"), "{in_mm}");
    std::fs::write(bay.dir().join("mm.toml"), in_mm).unwrap();
    let check = json(&bay.run(&["scene", "check", &bay.path("mm.toml"), "--json"]));
    let flags = check["flags"].to_string();
    assert!(
        flags.contains("hand.waypoints[0]: [0, 0, 50] m is 49.940 m from the static objects")
            && flags.contains("waypoints are in metres whatever the meshes' `units`"),
        "{check}"
    );
    let fine = json(&bay.run(&["scene", "check", &bay.path("bay.toml"), "--json"]));
    assert!(!fine["flags"].to_string().contains("waypoints"), "{fine}");
}

/// A `grip` or a `translate` written in millimetres like the meshes (`grip = [0, 0, 15]`,
/// `translate = [-100, -100, 0]`) passed scene check as ok: the handle held the part 15 m away, and
/// the wall stood 100 m off with the voxmap's grid stretched to reach it. Both are now flagged,
/// saying they are metres; the bay as given has no flags
/// (`a_scene_of_mesh_files_runs_touching_without_penetrating`).
#[test]
fn a_grip_or_translate_written_in_millimetres_is_flagged() {
    let bay = bay();
    let in_mm = SCENE
        .replace(
            "rotate_deg = [-90, 0, 0]\n",
            "rotate_deg = [-90, 0, 0]\ngrip = [0.0, 0.0, 15.0]\n",
        )
        .replace(
            "translate = [-0.1, -0.1, 0.0]",
            "translate = [-100.0, -100.0, 0.0]",
        );
    std::fs::write(bay.dir().join("mm.toml"), in_mm).unwrap();
    let check = json(&bay.run(&["scene", "check", &bay.path("mm.toml"), "--json"]));
    let flags = check["flags"].to_string();
    assert!(
        flags.contains("part.grip: [0, 0, 15] m is 14.985 m outside the part (0.030 m across)")
            && flags.contains("static[2].translate: [-100, -100, 0] m puts it ")
            && flags.contains("`translate` is in metres whatever the mesh's `units`"),
        "{check}"
    );
}

/// A session on a scene with `force_model = "distance"` caches a voxmap that carries its band
/// (`.vmap` version 3), and `vps inspect` reports the band: its stand-off (half of the 1 mm
/// voxel here), the cubes stored and their memory.
#[test]
fn the_distance_models_band_is_cached_with_the_voxmap_and_inspect_reports_it() {
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes");
    for file in ["peg-in-hole.toml", "peg.obj", "peg-fixture.stl"] {
        std::fs::copy(example.join(file), vps.dir().join(file)).unwrap();
    }
    let scene = vps.path("peg-in-hole.toml");
    let out = vps.run(&["run", "--scene", &scene, "--seconds", "0.05"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let cached: Vec<_> = std::fs::read_dir(vps.cache())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "vmap"))
        .collect();
    assert_eq!(cached.len(), 1, "{cached:?}");
    let info = json(&vps.run(&["inspect", cached[0].to_str().unwrap(), "--json"]));
    let band = &info["distance_band"];
    assert!(
        (band["standoff_m"].as_f64().unwrap() - 0.0005).abs() < 1e-12,
        "{info}"
    );
    assert!(band["bricks"].as_u64().unwrap() > 0, "{info}");
    let text = vps.run(&["inspect", cached[0].to_str().unwrap()]);
    assert!(
        String::from_utf8_lossy(&text.stdout)
            .contains("distance band (force_model = \"distance\"): stand-off 0.5 mm"),
        "{}",
        String::from_utf8_lossy(&text.stdout)
    );
}

/// `vps scene check` reports each mesh's health: the bay's closed boxes are closed and unflagged;
/// the floor with its top face removed has 4 boundary edges and is flagged as a leak; a single
/// triangle as the part is flagged as having no inside. `[part] scale` scales the part (one
/// number or per axis).
#[test]
fn scene_check_reports_mesh_health_and_scales_the_part() {
    let bay = bay();
    let check = |vps: &Vps| json(&vps.run(&["scene", "check", &vps.path("bay.toml"), "--json"]));
    let report = check(&bay);
    let meshes = report["meshes"].as_array().unwrap();
    assert_eq!(meshes.len(), 3, "{report}");
    for m in meshes {
        assert_eq!(m["closed"], true, "{m}");
        assert_eq!(m["health"]["boundary_edges"], 0, "{m}");
    }
    let flags = report["flags"].to_string();
    assert!(!flags.contains("Mesh health"), "{flags}");
    let part_size = |r: &serde_json::Value| {
        let (min, max) = (&r["part"]["bounds_min_m"], &r["part"]["bounds_max_m"]);
        [0, 1, 2].map(|k| max[k].as_f64().unwrap() - min[k].as_f64().unwrap())
    };
    let unscaled = part_size(&report);
    assert!((unscaled[0] - 0.03).abs() < 1e-9, "{unscaled:?}");

    // The floor's top face (the cuboid's two +z triangles) removed: open, flagged as a leak.
    write_open_top_obj(
        &bay.dir().join("floor.obj"),
        [-100.0, -100.0, -10.0],
        [100.0, 100.0, 0.0],
    );
    let report = check(&bay);
    let floor = report["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["source"].as_str().unwrap().ends_with("floor.obj"))
        .unwrap()
        .clone();
    assert_eq!(floor["closed"], false, "{floor}");
    assert_eq!(floor["health"]["boundary_edges"], 4, "{floor}");
    let flags = report["flags"].to_string();
    assert!(
        flags.contains("floor.obj is not closed: 4 boundary edges")
            && flags.contains("winding number"),
        "{flags}"
    );
    let text =
        String::from_utf8(bay.run(&["scene", "check", &bay.path("bay.toml")]).stdout).unwrap();
    assert!(text.contains("not closed: 4 boundary edges"), "{text}");

    // A single triangle as the part, scaled: no inside, flagged; the scale is applied.
    std::fs::write(
        bay.dir().join("tri.obj"),
        "v 0 0 0\nv 20 0 0\nv 0 20 0\nf 1 2 3\n",
    )
    .unwrap();
    for (scale, factor) in [
        ("scale = 0.5", [0.5, 0.5]),
        ("scale = [2, 1, 1]", [2.0, 1.0]),
    ] {
        let scene = SCENE
            .replacen("source = \"part.stl\"", "source = \"tri.obj\"", 1)
            .replacen("rotate_deg = [-90, 0, 0]", scale, 1);
        std::fs::write(bay.dir().join("bay.toml"), scene).unwrap();
        let report = check(&bay);
        let size = part_size(&report);
        assert!(
            (size[0] - 0.02 * factor[0]).abs() < 1e-9 && (size[1] - 0.02 * factor[1]).abs() < 1e-9,
            "{scale}: {size:?}"
        );
        let flags = report["flags"].to_string();
        assert!(flags.contains("tri.obj has no inside"), "{flags}");
    }
}

/// The STEP example scene (a four-solid assembly in millimetres as the static scene, one solid
/// selected from a two-solid file in metres as the part) checks and runs through the real binary:
/// the report names each file's unit and solids, the session touches the assembly and never
/// penetrates; STEP-only keys on other sources, `units` on a STEP source, an unknown solid name
/// and a chord tolerance out of range are refused naming the field.
#[test]
fn a_step_scene_checks_and_runs_and_its_mistakes_are_named() {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR"));
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    let dir = vps.dir();
    let step_dir = dir.join("step");
    std::fs::create_dir_all(&step_dir).unwrap();
    for f in ["assembly_ap214_is.step", "red_cube_blue_cylinder.step"] {
        std::fs::copy(repo.join("assets/step").join(f), step_dir.join(f)).unwrap();
    }
    let scenes = dir.join("scenes");
    std::fs::create_dir_all(&scenes).unwrap();
    let text = std::fs::read_to_string(repo.join("assets/scenes/step-assembly.toml")).unwrap();
    std::fs::write(scenes.join("step.toml"), &text).unwrap();
    let scene = vps.path("scenes/step.toml");

    let check = json(&vps.run(&["scene", "check", &scene, "--json"]));
    let meshes = check["meshes"].as_array().unwrap();
    let assembly = &meshes[0]["step"];
    assert_eq!(assembly["unit"], "millimetre", "{check}");
    let solids: Vec<&str> = assembly["solids"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s[0].as_str().unwrap())
        .collect();
    assert_eq!(solids, ["Cube", "Cube", "Cylinder", "Sphere"]);
    // A quarter of the scene's 2 mm voxel.
    assert_eq!(assembly["chord_tolerance"], 0.0005);
    assert_eq!(meshes[0]["closed"], true);
    let part = &meshes[1]["step"];
    assert_eq!(part["unit"], "metre");
    assert_eq!(part["solids"][0][0], "red_cube");
    assert_eq!(part["available"].as_array().unwrap().len(), 2);
    // The placed assembly spans x -114 .. 188.3 mm (the cylinder's side within the chord
    // tolerance, 0.5 mm).
    let lo = check["objects"][0]["bounds_min_m"][0].as_f64().unwrap();
    let hi = check["objects"][0]["bounds_max_m"][0].as_f64().unwrap();
    assert!(
        (lo + 0.114).abs() <= 0.5e-3 && (hi - 0.188_298).abs() < 1e-6,
        "{lo} {hi}"
    );
    let text_out = String::from_utf8(vps.run(&["scene", "check", &scene]).stdout).unwrap();
    assert!(
        text_out.contains("STEP: unit millimetre (from the file); 4 placed solid(s) read"),
        "{text_out}"
    );

    let report = json(&vps.run(&["run", "--scene", &scene, "--seconds", "3", "--json"]));
    let stats = &report["stats"];
    assert_eq!(stats["frames"], 3000, "{report}");
    assert!(stats["touching_frames"].as_u64().unwrap() > 0, "{report}");
    assert_eq!(stats["penetrating_frames"], 0, "{report}");

    // Three more public files in one session: a block with a through hole (an Onshape export in
    // metres) and the 100 mm cube (AP203) as static objects, the hollow cube (a solid with a void)
    // as the part, pressed onto the block's top.
    for f in [
        "cube_hole.step",
        "box_ap203.step",
        "hollow_box_ap214_is.step",
    ] {
        std::fs::copy(repo.join("assets/step").join(f), step_dir.join(f)).unwrap();
    }
    std::fs::write(
        scenes.join("three.toml"),
        include_str!("fixtures/step-three-files.toml"),
    )
    .unwrap();
    let three = vps.path("scenes/three.toml");
    let check = json(&vps.run(&["scene", "check", &three, "--json"]));
    let units: Vec<&str> = check["meshes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["step"]["unit"].as_str().unwrap())
        .collect();
    assert_eq!(units, ["metre", "millimetre", "millimetre"], "{check}");
    let report = json(&vps.run(&["run", "--scene", &three, "--seconds", "2", "--json"]));
    assert_eq!(report["stats"]["frames"], 2000, "{report}");
    assert!(
        report["stats"]["touching_frames"].as_u64().unwrap() > 0,
        "{report}"
    );
    assert_eq!(report["stats"]["penetrating_frames"], 0, "{report}");

    let mistakes = [
        (
            "solids = [\"red_cube\"]",
            "solids = [\"green_sphere\"]",
            "no solid named 'green_sphere'; the file's solids: blue_cylinder, red_cube",
        ),
        (
            "solids = [\"red_cube\"]",
            "solids = [\"red_cube\"]\nunits = \"mm\"",
            "`part.units`",
        ),
        (
            "# chord_tolerance = \"0.5mm\"",
            "chord_tolerance = \"3mm\"",
            "must be within 0.001 mm ..= the voxel size (2 mm), got 3 mm",
        ),
        (
            "source = \"../step/red_cube_blue_cylinder.step\"\nsolids = [\"red_cube\"]",
            "source = \"builtin:teapot\"\nsolids = [\"red_cube\"]",
            "applies to STEP sources (.step, .stp) only",
        ),
    ];
    for (from, to, expected) in mistakes {
        let edited = text.replace(from, to);
        assert_ne!(edited, text, "{from}");
        std::fs::write(scenes.join("bad.toml"), &edited).unwrap();
        let e = vps.fails(&["scene", "check", &vps.path("scenes/bad.toml")]);
        assert!(e.contains(expected) && e.contains("bad.toml"), "{to}: {e}");
    }
}
