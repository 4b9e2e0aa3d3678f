//! Several moving parts through the binary: two 40 mm cubes, each a `[[part]]` held by its own
//! simulated hand, pressed against each other. The two contact forces are exact negations of each
//! other; at rest under equal and opposite pushes neither drifts; the session is bit-identical on
//! one thread, three threads and two local worker processes; `vps scene check` lists the parts and
//! the pair; a part after the first with no inside is refused; a session of two parts is studied
//! part by part, live and from its two traces, to the bit.

use std::process::Output;
use vps_testkit::parts::{approach, two_parts, CUBE_40MM};
use vps_testkit::process::{failed, json, stderr, Vps};
use vps_testkit::table::csv_column;

/// Two cubes of 40 mm over a floor far below, the hands pushing each cube 5 mm past touching,
/// with the right part's source and scale lines replaced by `right` ([`CUBE_40MM`]: the second
/// cube).
fn two_cubes_with_right(right: &str) -> String {
    let hand = |side| {
        format!(
            "[part.hand]\n{}\nspeed = 0.1\nhold_s = 0.1\n",
            approach(side)
        )
    };
    let scene = two_parts(right, hand, "\n[voxels]\nvoxel_size = \"4 mm\"\n");
    format!("name = \"two cubes\"\n{scene}")
}

/// The two cubes: [`two_cubes_with_right`] of a [`CUBE_40MM`].
fn two_cubes() -> String {
    two_cubes_with_right(CUBE_40MM)
}

fn sandbox() -> (Vps, String) {
    let vps = Vps::new(env!("CARGO_BIN_EXE_vps"));
    std::fs::write(vps.dir().join("two.toml"), two_cubes()).unwrap();
    let scene = vps.path("two.toml");
    (vps, scene)
}

/// Runs `vps COMMAND --scene SCENE --seconds SECONDS --free-running MORE...` to its end.
fn free_running(vps: &Vps, command: &str, scene: &str, seconds: &str, more: &[&str]) -> Output {
    vps.session(
        command,
        scene,
        seconds,
        &[&["--free-running"], more].concat(),
    )
}

/// `vps scene check` on [`two_cubes_with_right`]`(lines)` must fail, its error holding every
/// one of `words`.
fn right_part_refused(vps: &Vps, lines: &str, words: &[&str]) {
    std::fs::write(vps.dir().join("variant.toml"), two_cubes_with_right(lines)).unwrap();
    let err = vps.fails(&["scene", "check", &vps.path("variant.toml")]);
    assert!(words.iter().all(|w| err.contains(w)), "{words:?}: {err}");
}

fn vector(v: &serde_json::Value) -> [f64; 3] {
    [0, 1, 2].map(|k| v[k].as_f64().expect("a number"))
}

/// Every component of `a` the exact negation of `b`'s (zeros: zero on both sides).
fn assert_opposite(a: [f64; 3], b: [f64; 3]) {
    for (x, y) in a.into_iter().zip(b) {
        if x == 0.0 {
            assert_eq!(y, 0.0, "{a:?} vs {b:?}");
        } else {
            assert_eq!(x.to_bits(), (-y).to_bits(), "{a:?} vs {b:?}");
        }
    }
}

#[test]
fn two_hands_press_two_parts_equal_and_opposite_and_they_rest() {
    let (vps, scene) = sandbox();
    let session = |seconds: &str, extra: &[&str]| {
        json(&free_running(
            &vps,
            "run",
            &scene,
            seconds,
            &[&["--json"], extra].concat(),
        ))
    };
    let report = session("2", &[]);
    let parts = report["parts"].as_array().expect("every part reported");
    assert_eq!(parts.len(), 2, "{report}");
    let (left, right) = (&parts[0], &parts[1]);
    assert_eq!(
        (&left["name"], &right["name"]),
        (&"left".into(), &"right".into())
    );
    let force = |p: &serde_json::Value| vector(&p["last_pair_force_n"]);
    assert!(
        force(left)[0] < -0.05,
        "the right cube pushes the left one back: {left}"
    );
    assert_opposite(force(left), force(right));
    for p in parts {
        assert!(p["pair_contact_frames"].as_u64().unwrap() > 1000, "{p}");
        assert_eq!(p["non_finite_frames"], 0, "{p}");
        assert_eq!(p["clamped_frames"], 0, "{p}");
        assert!(p["final_speed_m_per_s"].as_f64().unwrap() < 1e-4, "{p}");
    }
    // Held apart: the grips are a cube's side (40 mm) plus at most the two force layers apart,
    // short of where the hands are (30 mm apart).
    let gap = vector(&right["final_position_m"])[0] - vector(&left["final_position_m"])[0];
    assert!((0.04..0.06).contains(&gap), "grips {gap} m apart");
    let pairs = &report["pairs"];
    assert!(
        pairs["skipped"].as_u64().unwrap() > 100,
        "apart at first: {pairs}"
    );
    assert!(pairs["contact_frames"].as_u64().unwrap() > 1000, "{pairs}");

    // At rest: one more second changes neither position by a micrometre.
    let later = session("3", &[]);
    for (a, b) in parts.iter().zip(later["parts"].as_array().unwrap()) {
        let (p, q) = (
            vector(&a["final_position_m"]),
            vector(&b["final_position_m"]),
        );
        let drift = (0..3).map(|k| (p[k] - q[k]).abs()).fold(0.0, f64::max);
        assert!(
            drift < 1e-6,
            "{} drifted {drift} m from 2 s to 3 s",
            a["name"]
        );
    }

    // The same session on three threads, and over two local worker processes splitting every
    // frame, bit for bit (the JSON numbers round-trip exactly).
    let threads = session("2", &["--threads", "3"]);
    assert_eq!(threads["parts"], report["parts"]);
    let workers = [
        "--local-workers",
        "2",
        "--split",
        "always",
        "--max-stale-frames",
        "0",
    ];
    let clustered = json(&free_running(
        &vps,
        "cluster",
        &scene,
        "2",
        &[&workers, &["--json"][..]].concat(),
    ));
    assert_eq!(clustered["parts"], report["parts"]);
    for peer in clustered["cluster"]["peers"].as_array().unwrap() {
        assert_eq!(peer["merged"], 2000, "every frame split: {peer}");
    }
    // The workers took every job: both parts in the scene every frame, and both directions of
    // every pair the broad phase kept (a share is merged only when all its jobs are in).
    let sampled_pairs = clustered["pairs"]["sampled"].as_u64().unwrap();
    assert!(sampled_pairs > 1000, "{}", clustered["pairs"]);
    assert_eq!(
        clustered["cluster"]["job_samples"].as_u64(),
        Some(2 * 2000 + 2 * sampled_pairs),
        "{}",
        clustered["cluster"]
    );
}

#[test]
fn scene_check_lists_every_part_and_pair_and_refuses_a_sheet_as_a_second_part() {
    let (vps, scene) = sandbox();
    let check = json(&vps.run(&["scene", "check", &scene, "--json"]));
    let names: Vec<&str> = check["parts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap())
        .collect();
    assert_eq!(names, ["left", "right"], "{check}");
    assert_eq!(check["pairs"], serde_json::json!([["left", "right"]]));
    assert_eq!(
        check["parts"][1]["start_m"],
        serde_json::json!([0.06, 0.0, 0.0])
    );
    assert!(check["pair_margin_m"].as_f64().unwrap() > 0.0);
    let (pair, wall) = (
        check["pair_stability_index"].as_f64().unwrap(),
        check["wall_stability_index"].as_f64().unwrap(),
    );
    assert!(wall < pair && pair < 1.0, "pair {pair}, wall {wall}");

    std::fs::write(
        vps.dir().join("sheet.obj"),
        "v 0 0 0\nv 0.04 0 0\nv 0 0.04 0\nf 1 2 3\n",
    )
    .unwrap();
    right_part_refused(
        &vps,
        "source = \"sheet.obj\"",
        &["part[1].source", "has no inside"],
    );
}

/// A part after the first larger than the whole scene (a slip of units) is refused naming it, as
/// the first part is.
#[test]
fn a_second_part_larger_than_the_scene_is_refused() {
    let (vps, _) = sandbox();
    right_part_refused(
        &vps,
        "source = \"builtin:box\"\nscale = 400",
        &["part[1]", "larger than the whole scene"],
    );
}

#[test]
fn a_session_of_two_parts_is_studied_part_by_part_to_the_bit_live_and_from_its_traces() {
    let (vps, scene) = sandbox();
    let (trace, live, later) = (vps.path("s.trace"), vps.path("live"), vps.path("later"));
    let outputs = ["--record", &trace, "--study", &live, "--json"];
    let report = json(&free_running(&vps, "run", &scene, "1.5", &outputs));
    assert!(
        vps.dir().join("s.right.trace").is_file(),
        "the second part's trace is written beside the first's"
    );
    let made = json(&vps.run(&["study", &trace, "--scene", &scene, "-o", &later, "--json"]));
    let studies = made["parts"].as_array().expect("one study per part");
    let parts = report["parts"].as_array().unwrap();
    assert_eq!(studies.len(), 2, "{made}");
    let mut pair_forces = Vec::new();
    for (part, study) in parts.iter().zip(studies) {
        let name = part["name"].as_str().unwrap();
        assert_eq!(study["name"], name);
        assert_eq!(study["folder"], name);
        // Recomputed from the two traces together, each part ends where the session left it, to
        // the bit (JSON numbers round-trip exactly); the live study too.
        let s = &study["study"];
        assert_eq!(s["final_position_m"], part["final_position_m"], "{name}");
        let read = |dir: &str, file: &str| {
            std::fs::read_to_string(vps.dir().join(dir).join(name).join(file)).unwrap()
        };
        let live_json: serde_json::Value =
            serde_json::from_str(&read("live", "study.json")).unwrap();
        assert_eq!(
            live_json["final_position_m"], part["final_position_m"],
            "{name}"
        );
        assert_eq!(
            read("live", "path.csv"),
            read("later", "path.csv"),
            "{name}"
        );
        assert_eq!(s["settings"]["part"], name);
        // Pressed against each other at the end: each held back by the other part.
        assert_eq!(s["held_by_other_parts"], true, "{s}");
        assert!(
            s["verdict"]
                .as_str()
                .unwrap()
                .contains("by another moving part"),
            "{}",
            s["verdict"]
        );
        let csv = read("later", "path.csv");
        pair_forces.push(csv_column(&csv, "other_parts_force_x_n"));
    }
    // The exact clearance between the two cubes: the same live and from the traces, its least
    // over every frame no more than any of its series (docs/results/study_clearance.md checks it
    // against FCL on the two-hands scene).
    let pairs =
        |dir: &str| std::fs::read_to_string(vps.dir().join(dir).join("pairs.json")).unwrap();
    assert_eq!(pairs("live"), pairs("later"));
    let least = made["pairs"][0]["least_m"]
        .as_f64()
        .expect("a least clearance");
    let series = csv_column(
        &std::fs::read_to_string(vps.dir().join("later/pair_clearance.csv")).unwrap(),
        "left-right_m",
    );
    assert!(
        least >= 0.0 && series.iter().all(|&d| least <= d),
        "{least} {series:?}"
    );
    assert!(least < 0.02, "pressed together: {least} m");
    // The index page links each part's own report and lists the pair.
    let index = std::fs::read_to_string(vps.dir().join("later/report.html")).unwrap();
    assert!(
        index.contains("<a href=\"left/report.html\">left</a>")
            && index.contains("<a href=\"right/report.html\">right</a>")
            && index.contains("<td>left – right</td>"),
        "{index}"
    );
    // The pair's contact events: every frame in which the other part pushed on the left one
    // lies in an event, each event's peak is the largest of those pushes within it, at its
    // peak frame, and the meshes were close then (the cubes stop a few voxels apart or less).
    let left_csv = std::fs::read_to_string(vps.dir().join("later/left/path.csv")).unwrap();
    let push: Vec<f64> = {
        let axis = |a: &str| csv_column(&left_csv, &format!("other_parts_force_{a}_n"));
        let (x, y, z) = (axis("x"), axis("y"), axis("z"));
        (0..x.len())
            .map(|i| (x[i] * x[i] + y[i] * y[i] + z[i] * z[i]).sqrt())
            .collect()
    };
    let events = made["pairs"][0]["contacts"]
        .as_array()
        .expect("contact events");
    assert!(!events.is_empty(), "the cubes pressed: {}", made["pairs"]);
    let span = |e: &serde_json::Value, k: &str| e[k].as_u64().unwrap() as usize;
    for (i, &f) in push.iter().enumerate() {
        let within = events
            .iter()
            .any(|e| span(e, "start_frame") <= i && i <= span(e, "end_frame"));
        assert!(
            f == 0.0 || within,
            "a push of {f} N at frame {i} outside every event"
        );
    }
    for e in events {
        let (start, end, peak) = (
            span(e, "start_frame"),
            span(e, "end_frame"),
            span(e, "peak_frame"),
        );
        assert!(start <= peak && peak <= end, "{e}");
        let largest = push[start..=end].iter().copied().fold(0.0, f64::max);
        assert_eq!(e["peak_force_on_a_n"].as_f64().unwrap(), largest, "{e}");
        assert_eq!(push[peak], largest, "{e}");
        let gap = e["distance_at_peak_m"].as_f64().unwrap();
        assert!((0.0..0.02).contains(&gap), "{e}");
    }
    assert!(
        index.contains("<table id=\"pair-contacts\">") && index.contains(" N at "),
        "{index}"
    );
    // The pair force in the two studies' tables: equal and opposite at every frame.
    let (left, right) = (&pair_forces[0], &pair_forces[1]);
    assert_eq!(left.len(), right.len());
    assert!(left.iter().any(|&f| f < -0.05), "the cubes pressed");
    for (a, b) in left.iter().zip(right) {
        assert!(*a == -*b, "{a} vs {b}");
    }
}

#[test]
fn a_study_of_two_parts_needs_both_traces_of_one_session_and_never_overwrites_an_input() {
    let (vps, scene) = sandbox();
    let record = |scene: &str, name: &str, seconds: &str| {
        free_running(&vps, "run", scene, seconds, &["--record", &vps.path(name)])
    };
    for (name, seconds) in [("s.trace", "0.3"), ("short.trace", "0.2")] {
        let out = record(&scene, name, seconds);
        assert!(out.status.success(), "{name}: {}", stderr(&out));
    }
    let study = |out: &str| {
        vps.fails(&[
            "study",
            &vps.path("s.trace"),
            "--scene",
            &scene,
            "-o",
            &vps.path(out),
        ])
    };
    // The second part's trace from another, shorter session: refused, naming both lengths.
    std::fs::copy(
        vps.dir().join("short.right.trace"),
        vps.dir().join("s.right.trace"),
    )
    .unwrap();
    let err = study("a");
    assert!(
        err.contains("part 1's trace holds 200 frames but the first part's 300"),
        "{err}"
    );
    // Missing: refused, naming the part and the file it looked for.
    std::fs::remove_file(vps.dir().join("s.right.trace")).unwrap();
    let err = study("b");
    assert!(
        err.contains("part 'right'") && err.contains("s.right.trace") && err.contains("missing"),
        "{err}"
    );
    // A recording whose second part's trace would land on the scene file itself: refused before
    // the session, the scene left as it was.
    std::fs::copy(vps.dir().join("two.toml"), vps.dir().join("x.right.trace")).unwrap();
    let err = failed(&record(&vps.path("x.right.trace"), "x.trace", "0.1"));
    assert!(
        err.contains("--record") && err.contains("x.right.trace"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(vps.dir().join("x.right.trace")).unwrap(),
        two_cubes()
    );
    assert!(!vps.dir().join("x.trace").exists());
}
