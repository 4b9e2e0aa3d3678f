//! A study as the viewer's page scrubs it ([`vps_view::StudyTrack`]): from a study just made (for
//! the 3D view of its `report.html`) or from a study's folder (`vps view --scene FILE --study
//! DIR`).

use anyhow::{bail, Context, Result};
use serde::Deserialize;
use serde_json::Value;
use std::path::Path;
use vps_mesh::TriMesh;
use vps_session::{PartView, SessionAssets};
use vps_study::files::{path_column, PATH_COLUMNS};
use vps_study::Study;
use vps_view::study::track_frames;
use vps_view::{ClosestApproach, SceneLimits, StudyTrack};

/// What a study's report carries of the scene for its 3D view: about 3.5 MB of base64 at most
/// (20,000 boxes, 5,000 shell points, 50,000 static and 20,000 part triangles, and as many of
/// the swept volume's as the part's).
pub const REPORT_VIEW_LIMITS: SceneLimits = SceneLimits {
    max_boxes: 20_000,
    max_shell_points: 5_000,
    max_static_triangles: 50_000,
    max_part_triangles: 20_000,
};

/// The report's turnable 3D view of `study` of moving part `part` made on `assets`: the viewer's page for the static scene and that part within [`REPORT_VIEW_LIMITS`]
/// ([`crate::scene_view::part_content`]), the study's track and swept volume to scrub along, its
/// data inlined (one HTML document).
pub fn report_view(assets: &SessionAssets, part: PartView<'_>, study: &Study) -> String {
    let swept = match &study.swept {
        Some(Ok(s)) => Some(&s.mesh),
        _ => None,
    };
    let content = crate::scene_view::part_content(assets, part, REPORT_VIEW_LIMITS)
        .with_study(track_of(study), swept);
    vps_view::standalone::standalone_page(&content)
}

/// Largest `study.json` read (bytes): its series hold one number per object every 10 frames.
const MAX_STUDY_JSON_BYTES: u64 = 256 * vps_files::MIB;

/// Largest `path.json` read (bytes): about 600,000 rows (10 minutes at 1 kHz, every frame). A
/// longer study is viewed from a thinned table (`vps study --every N`).
const MAX_PATH_JSON_BYTES: u64 = 256 * vps_files::MIB;

/// The track of a study just made: at most [`vps_view::study::MAX_STUDY_TRACK_FRAMES`] of its
/// frames, the closest approach's among them.
pub fn track_of(study: &Study) -> StudyTrack {
    let closest = study.verdict.minimum_clearance;
    let kept = track_frames(study.path.len(), closest.map(|(_, m)| m.frame));
    let series = &study.clearance.series_frames;
    let mut track = StudyTrack {
        verdict: study.verdict.line.clone(),
        closest: closest.map(|(o, m)| ClosestApproach {
            time_s: m.time_s,
            distance_m: m.closest.distance_m,
            object: study.object_names.get(o).cloned().unwrap_or_default(),
            on_part_m: m.closest.on_part_m.to_array(),
            on_object_m: m.closest.on_object_m.to_array(),
        }),
        ..StudyTrack::default()
    };
    for i in kept {
        let f = &study.path[i];
        track.frame.push(f.frame);
        track.time_s.push(f.time_s);
        track.position_m.push(f.part_position_m.to_array());
        track.orientation_xyzw.push(f.part_orientation.to_array());
        track.device_force_n.push(f.device_force_n.to_array());
        track.clearance_m.push(
            series
                .binary_search(&i)
                .ok()
                .and_then(|k| study.clearance.least_at(k)),
        );
    }
    track
}

/// `path.json` as written by `vps_study::files`: column names and rows of cells.
#[derive(Deserialize)]
struct PathTable {
    columns: Vec<String>,
    rows: Vec<Vec<Cell>>,
}

/// One cell of `path.json`: a number, a flag (`touching`, `penetrating`) or `null` (a value not
/// measured at that frame).
#[derive(Clone, Copy, Deserialize)]
#[serde(untagged)]
enum Cell {
    Number(f64),
    Flag(#[allow(dead_code)] bool),
    Absent(()),
}

impl Cell {
    fn number(self) -> Option<f64> {
        match self {
            Cell::Number(v) => Some(v),
            _ => None,
        }
    }
}

/// A study read back from its folder ([`track_from_folder`]).
pub struct StudyFolder {
    /// Its track to scrub.
    pub track: StudyTrack,
    /// Its swept volume, when the folder has one.
    pub swept: Option<TriMesh>,
    /// The scene it was made on (study.json's `settings.scene`; empty when absent).
    pub scene: String,
    /// The moving part it studied, in a scene of several (`settings.part`).
    pub part: Option<String>,
}

/// The track and swept volume of the study in `dir` (its `study.json`, `path.json` and, when
/// present, `swept.stl`), the scene it was made on and, in a scene of several moving parts, the
/// part. Errors name the file and what is wrong with it.
pub fn track_from_folder(dir: &Path) -> Result<StudyFolder> {
    let summary_path = dir.join("study.json");
    if !summary_path.exists() && dir.join("pairs.json").exists() {
        bail!(
            "{} is the study of several moving parts: give one part's folder in it ({}/<part>)",
            dir.display(),
            dir.display()
        );
    }
    let text = vps_files::read_regular_to_string(&summary_path, MAX_STUDY_JSON_BYTES)
        .with_context(|| format!("reading {}", summary_path.display()))?;
    let summary: Value = serde_json::from_str(&text)
        .with_context(|| format!("{}: not JSON", summary_path.display()))?;
    if summary["format"] != vps_study::files::STUDY_FORMAT {
        bail!(
            "{}: not a vps study (its \"format\" is {}, expected \"{}\")",
            summary_path.display(),
            summary["format"],
            vps_study::files::STUDY_FORMAT
        );
    }
    let version = summary["version"].as_u64();
    if version != Some(u64::from(vps_study::files::STUDY_VERSION)) {
        bail!(
            "{}: study format version {}, this vps reads version {}",
            summary_path.display(),
            summary["version"],
            vps_study::files::STUDY_VERSION
        );
    }
    let point = |v: &Value, field: &str| -> Result<[f64; 3]> {
        serde_json::from_value(v[field].clone()).with_context(|| {
            format!(
                "{}: minimum_clearance.{field} is not three numbers",
                summary_path.display()
            )
        })
    };
    let m = &summary["minimum_clearance"];
    let closest = if m.is_null() {
        None
    } else {
        Some(ClosestApproach {
            time_s: m["time_s"].as_f64().unwrap_or(f64::NAN),
            distance_m: m["distance_m"].as_f64().unwrap_or(f64::NAN),
            object: m["object"].as_str().unwrap_or("?").to_string(),
            on_part_m: point(m, "on_part_m")?,
            on_object_m: point(m, "on_object_m")?,
        })
    };
    let scene = summary["settings"]["scene"]
        .as_str()
        .unwrap_or_default()
        .to_string();
    let part = summary["settings"]["part"].as_str().map(str::to_string);

    let path_file = dir.join("path.json");
    let text =
        vps_files::read_regular_to_string(&path_file, MAX_PATH_JSON_BYTES).with_context(|| {
            format!(
                "reading {} (a larger table: make the study with --every N)",
                path_file.display()
            )
        })?;
    let table: PathTable = serde_json::from_str(&text)
        .with_context(|| format!("{}: not a study's path table", path_file.display()))?;
    drop(text);
    // Found by name: a table from another version may have columns added or moved.
    let column = |place: usize| -> Result<usize> {
        let name = PATH_COLUMNS[place];
        table
            .columns
            .iter()
            .position(|c| c == name)
            .with_context(|| format!("{}: no column {name:?}", path_file.display()))
    };
    let frame = column(path_column::FRAME)?;
    let time = column(path_column::TIME)?;
    let clearance = column(path_column::CLEARANCE)?;
    let [x, y, z] = path_column::PART_POSITION.map(column);
    let position = [x?, y?, z?];
    let [qx, qy, qz, qw] = path_column::PART_ORIENTATION.map(column);
    let orientation = [qx?, qy?, qz?, qw?];
    let [fx, fy, fz] = path_column::DEVICE_FORCE.map(column);
    let force = [fx?, fy?, fz?];
    let closest_row = closest.as_ref().and_then(|c| {
        table
            .rows
            .iter()
            .position(|r| r.get(time).and_then(|v| v.number()) == Some(c.time_s))
    });
    let mut track = StudyTrack {
        verdict: summary["verdict"].as_str().unwrap_or_default().to_string(),
        closest,
        ..StudyTrack::default()
    };
    for i in track_frames(table.rows.len(), closest_row) {
        let row = &table.rows[i];
        let number = |c: usize| -> Result<f64> {
            row.get(c)
                .and_then(|v| v.number())
                .filter(|v| v.is_finite())
                .with_context(|| {
                    format!(
                        "{}: row {} has no number in column {:?}",
                        path_file.display(),
                        i + 1,
                        table.columns[c]
                    )
                })
        };
        track.frame.push(number(frame)? as u64);
        track.time_s.push(number(time)?);
        let [x, y, z] = position.map(number);
        track.position_m.push([x?, y?, z?]);
        let [qx, qy, qz, qw] = orientation.map(number);
        track.orientation_xyzw.push([qx?, qy?, qz?, qw?]);
        let [fx, fy, fz] = force.map(number);
        track.device_force_n.push([fx?, fy?, fz?]);
        track
            .clearance_m
            .push(row.get(clearance).and_then(|v| v.number()));
    }
    let swept_path = dir.join("swept.stl");
    let swept = if swept_path.is_file() {
        Some(
            vps_mesh::load_mesh(&swept_path)
                .with_context(|| format!("reading {}", swept_path.display()))?
                .mesh,
        )
    } else {
        None
    };
    Ok(StudyFolder {
        track,
        swept,
        scene,
        part,
    })
}
