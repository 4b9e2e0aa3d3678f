//! The study's files, written into one folder:
//! - `study.json`: the verdict, the settings it was made with, each object's minimum clearance
//!   (time, distance, the two nearest points), the contact events and the clearance series;
//! - `path.csv` and `path.json`: the part's and the handle's poses, the wrench sent to the device
//!   and the scene's force on the part, every `every`-th frame and the last;
//! - `clearance.csv`: the exact clearance to each object at the series frames;
//! - `contacts.csv`: one row per contact event;
//! - `part.obj`: the part's mesh in its own frame (m, origin at the grip): posed by a path row
//!   (`x = R(q) v + p`) it is the part where the study measured it;
//! - `swept.stl` (binary STL, m) and `swept.vmap` (a voxmap: the region Interior, its boundary
//!   layer Surface): the swept volume, when made;
//! - `report.html`: the study on one page that opens offline ([`crate::report`]).
//!
//! Each file is written whole to a temporary file and renamed into place, so a failed write never
//! leaves a half-written file; only regular files are ever replaced.
//!
//! A session of several moving parts is studied part by part, each part's files in a folder of
//! its own named after it ([`part_file_names`]), and the clearance between each pair of parts
//! beside those folders ([`write_pairs`]: `pairs.json`, `pair_clearance.csv`).

use crate::Study;
use serde_json::{json, Value};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use vps_mesh::TriMesh;

/// The format name in `study.json`.
pub const STUDY_FORMAT: &str = "vps-study";
/// The version of `study.json`'s layout.
pub const STUDY_VERSION: u32 = 1;

/// The names of the files a study writes, in the order written.
pub const STUDY_FILES: [&str; 9] = [
    "path.csv",
    "path.json",
    "clearance.csv",
    "contacts.csv",
    "part.obj",
    "swept.stl",
    "swept.vmap",
    "study.json",
    "report.html",
];

/// A file name for each of `names` (the parts of one session, in order): each name with every
/// character but ASCII letters, digits, `-` and `_` made `_` (at most 64 characters; `part` when
/// none is left), then `-k` (its index, or the next free number) added to any that another part's already took, so the
/// names are distinct and name no other folder (`..`, `/`). Used for each part's study folder
/// and its trace file.
pub fn part_file_names(names: &[String]) -> Vec<String> {
    let mut taken: Vec<String> = Vec::with_capacity(names.len());
    for (k, name) in names.iter().enumerate() {
        let mut safe: String = name
            .chars()
            .take(64)
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect();
        if safe.chars().all(|c| c == '_') {
            safe = "part".into();
        }
        let mut candidate = safe.clone();
        let mut n = k;
        while taken.contains(&candidate) {
            candidate = format!("{safe}-{n}");
            n += 1;
        }
        taken.push(candidate);
    }
    taken
}

/// The files [`write_pairs`] writes beside the parts' folders, in the order written
/// (`report.html` the index of the parts' studies, [`crate::report::parts_index_html`]).
pub const PAIR_FILES: [&str; 3] = ["pair_clearance.csv", "pairs.json", "report.html"];

/// The paths of the files [`write_pairs`] writes into `dir`.
pub fn pair_paths(dir: &Path) -> Vec<PathBuf> {
    PAIR_FILES.iter().map(|name| dir.join(name)).collect()
}

/// The pairs' clearance as JSON: per pair the two parts' names, the least exact clearance over
/// every frame (m), its time and frame, and the two nearest points in the world (m).
pub fn pairs_json(names: &[String], pairs: &[crate::pairs::PairClearance], every: usize) -> Value {
    let rows: Vec<Value> = pairs
        .iter()
        .map(|p| {
            let m = p.minimum.as_ref();
            json!({
                "a": names.get(p.a),
                "b": names.get(p.b),
                "least_m": m.map(|m| m.closest.distance_m),
                "time_s": m.map(|m| m.time_s),
                "frame": m.map(|m| m.frame),
                "on_a_m": m.map(|m| m.closest.on_object_m.to_array()),
                "on_b_m": m.map(|m| m.closest.on_part_m.to_array()),
                "contacts": p.contacts,
            })
        })
        .collect();
    json!({
        "format": "vps-study-pairs",
        "version": 1,
        "parts": names,
        "series_every_frames": every,
        "pairs": rows,
    })
}

/// Writes the clearance between each pair of moving parts into `dir`: `pairs.json`
/// ([`pairs_json`]), `pair_clearance.csv` (frame, time and one column per pair, `A-B_m`, at the
/// series frames; `times_s` the session's frame times) and `index_html` as `report.html` (the
/// index of the parts' studies). Returns the paths written. Blocking.
pub fn write_pairs(
    dir: &Path,
    names: &[String],
    pairs: &[crate::pairs::PairClearance],
    times_s: &[f64],
    every: usize,
    index_html: &str,
) -> io::Result<Vec<PathBuf>> {
    let paths = pair_paths(dir);
    let mut header = vec!["frame".to_string(), "time_s".to_string()];
    let name = |k: usize| names.get(k).map_or("?", String::as_str);
    header.extend(
        pairs
            .iter()
            .map(|p| format!("{}-{}_m", name(p.a), name(p.b))),
    );
    let frames = pairs.first().map_or(&[][..], |p| &p.series_frames[..]);
    let rows: Vec<Vec<Value>> = frames
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            let mut row = vec![json!(i), json!(times_s.get(i))];
            row.extend(pairs.iter().map(|p| json!(p.series_m[k])));
            row
        })
        .collect();
    write_file(&paths[0], |out| write_csv(out, &header, &rows))?;
    write_file(&paths[1], |out| {
        serde_json::to_writer_pretty(&mut *out, &pairs_json(names, pairs, every))?;
        writeln!(out)
    })?;
    write_file(&paths[2], |out| out.write_all(index_html.as_bytes()))?;
    Ok(paths)
}

/// The paths of the files a study writes into `dir`.
pub fn study_paths(dir: &Path) -> Vec<PathBuf> {
    STUDY_FILES.iter().map(|name| dir.join(name)).collect()
}

/// The columns of `path.csv` and `path.json`, in order (SI units in each name). A reader finds a
/// column by name, not by place ([`path_column`] names the ones the viewer reads), so a table
/// written by another version with columns added still reads.
pub const PATH_COLUMNS: [&str; 33] = [
    "frame",
    "time_s",
    "part_x_m",
    "part_y_m",
    "part_z_m",
    "part_qx",
    "part_qy",
    "part_qz",
    "part_qw",
    "hand_x_m",
    "hand_y_m",
    "hand_z_m",
    "hand_qx",
    "hand_qy",
    "hand_qz",
    "hand_qw",
    "device_force_x_n",
    "device_force_y_n",
    "device_force_z_n",
    "device_torque_x_nm",
    "device_torque_y_nm",
    "device_torque_z_nm",
    "contact_force_x_n",
    "contact_force_y_n",
    "contact_force_z_n",
    "other_parts_force_x_n",
    "other_parts_force_y_n",
    "other_parts_force_z_n",
    "contacts",
    "touching",
    "penetrating",
    "clearance_m",
    "speed_m_per_s",
];

/// Places in [`PATH_COLUMNS`] of the columns a study's reader needs (the viewer's track).
pub mod path_column {
    /// `frame`: the frame number.
    pub const FRAME: usize = 0;
    /// `time_s`: seconds since the session started.
    pub const TIME: usize = 1;
    /// `part_x_m`, `part_y_m`, `part_z_m`: the part's position (m).
    pub const PART_POSITION: [usize; 3] = [2, 3, 4];
    /// `part_qx` .. `part_qw`: the part's orientation (unit quaternion).
    pub const PART_ORIENTATION: [usize; 4] = [5, 6, 7, 8];
    /// `device_force_x_n` .. `_z_n`: the force sent to the device (N).
    pub const DEVICE_FORCE: [usize; 3] = [16, 17, 18];
    /// `clearance_m`: the exact clearance (m).
    pub const CLEARANCE: usize = 31;
}

/// One CSV field: quoted when it holds a comma, quote or line break.
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// The rows of the path table: every `every`-th frame and the last.
fn path_rows(study: &Study, every: usize) -> Vec<Vec<Value>> {
    let frames = crate::clearance::series_frames(study.path.len(), every);
    // The least clearance over the objects at each series frame, where the series has it.
    let series = &study.clearance.series_frames;
    frames
        .iter()
        .map(|&i| {
            let f = &study.path[i];
            let clearance = series
                .binary_search(&i)
                .ok()
                .and_then(|k| study.clearance.least_at(k));
            let speed = crate::path::grip_speed(&study.path, i);
            let mut row: Vec<Value> = vec![json!(f.frame), json!(f.time_s)];
            row.extend(f.part_position_m.to_array().map(|v| json!(v)));
            row.extend(f.part_orientation.to_array().map(|v| json!(v)));
            row.extend(f.handle_position_m.to_array().map(|v| json!(v)));
            row.extend(f.handle_orientation.to_array().map(|v| json!(v)));
            row.extend(f.device_force_n.to_array().map(|v| json!(v)));
            row.extend(f.device_torque_nm.to_array().map(|v| json!(v)));
            row.extend(f.contact_force_n.to_array().map(|v| json!(v)));
            row.extend(f.other_parts_force_n.to_array().map(|v| json!(v)));
            row.push(json!(f.contacts));
            row.push(json!(f.touching));
            row.push(json!(f.penetrating));
            row.push(clearance.map_or(Value::Null, |d| json!(d)));
            row.push(speed.map_or(Value::Null, |v| json!(v)));
            row
        })
        .collect()
}

/// A JSON value as a CSV cell: numbers and booleans as written, null as empty.
fn cell(v: &Value) -> String {
    match v {
        Value::Null => String::new(),
        Value::String(s) => csv_field(s),
        other => other.to_string(),
    }
}

fn write_csv(out: &mut dyn Write, header: &[String], rows: &[Vec<Value>]) -> io::Result<()> {
    let header: Vec<String> = header.iter().map(|h| csv_field(h)).collect();
    writeln!(out, "{}", header.join(","))?;
    for row in rows {
        let cells: Vec<String> = row.iter().map(cell).collect();
        writeln!(out, "{}", cells.join(","))?;
    }
    Ok(())
}

fn write_file(path: &Path, write: impl FnOnce(&mut dyn Write) -> io::Result<()>) -> io::Result<()> {
    vps_files::atomic::write_atomically(
        path,
        |out| write(out),
        |stage, e| {
            io::Error::new(
                e.kind(),
                format!("{}: {}: {e}", path.display(), stage.name()),
            )
        },
    )
    .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))
}

/// The content of `study.json`: the verdict, `settings` (what the caller ran the session with:
/// scene, voxel size, model, command), each object's minimum, the contact events and the series.
pub fn study_json(study: &Study, settings: &Value, every: usize) -> Value {
    let names = &study.object_names;
    let name = |o: Option<usize>| o.and_then(|o| names.get(o)).cloned();
    let objects: Vec<Value> = study
        .clearance
        .objects
        .iter()
        .enumerate()
        .map(|(o, c)| {
            json!({
                "name": names.get(o),
                "minimum_clearance": c.minimum.map(|m| json!({
                    "distance_m": m.closest.distance_m,
                    "time_s": m.time_s,
                    "frame": m.frame,
                    "on_part_m": m.closest.on_part_m.to_array(),
                    "on_part_local_m": m.closest.on_part_local_m.to_array(),
                    "on_object_m": m.closest.on_object_m.to_array(),
                })),
                "frames_searched_for_the_minimum": c.searched_frames,
                "series_m": c.series_m.iter().map(|d| d.is_finite().then_some(*d)).collect::<Vec<_>>(),
            })
        })
        .collect();
    let contacts: Vec<Value> = study
        .contacts
        .iter()
        .map(|c| {
            json!({
                "start_s": c.start_s,
                "end_s": c.end_s,
                "start_frame": c.start_frame,
                "end_frame": c.end_frame,
                "object": name(c.object),
                "peak_force_n": c.peak_force_n,
                "peak_s": study.path[c.peak_frame].time_s,
                "distance_at_peak_m": c.distance_at_peak_m,
                "on_part_local_m": c.on_part_local_m.map(|p| p.to_array()),
                "on_part_m": c.on_part_m.map(|p| p.to_array()),
            })
        })
        .collect();
    let v = &study.verdict;
    json!({
        "format": STUDY_FORMAT,
        "version": STUDY_VERSION,
        "verdict": v.line,
        "reached": v.reached,
        "target": {
            "what": v.target.what,
            "position_m": v.target.position_m.to_array(),
            "path_end_s": v.target.path_end_s,
        },
        "final_position_m": v.final_position_m.to_array(),
        "short_m": v.short_m,
        "reach_tolerance_m": v.tolerance_m,
        "held_by": name(v.held_by),
        "held_by_other_parts": v.held_by_other_parts,
        "session_end_s": v.session_end_s,
        "path_completed": v.path_completed,
        "minimum_clearance": v.minimum_clearance.map(|(o, m)| json!({
            "object": names.get(o),
            "distance_m": m.closest.distance_m,
            "time_s": m.time_s,
            "frame": m.frame,
            "on_part_m": m.closest.on_part_m.to_array(),
            "on_object_m": m.closest.on_object_m.to_array(),
        })),
        "frames": study.path.len(),
        "settings": settings,
        "objects": objects,
        "contacts": contacts,
        "clearance_series": {
            "frames": study.clearance.series_frames,
            "time_s": study.clearance.series_frames.iter().map(|&i| study.path[i].time_s).collect::<Vec<_>>(),
        },
        "swept_volume": swept_json(study),
        "path_rows_every": every.max(1),
        "files": STUDY_FILES,
        "timings_ms": study.timings,
    })
}

/// `mesh` as a Wavefront OBJ (m; shortest round-trip decimals, so it reads back bit for bit).
fn write_obj(out: &mut dyn Write, mesh: &TriMesh) -> io::Result<()> {
    writeln!(
        out,
        "# the part in its own frame (m), origin at the grip; written by vps study"
    )?;
    for v in &mesh.vertices {
        writeln!(out, "v {} {} {}", v.x, v.y, v.z)?;
    }
    for [a, b, c] in &mesh.triangles {
        writeln!(out, "f {} {} {}", a + 1, b + 1, c + 1)?;
    }
    Ok(())
}

/// `mesh` as a binary STL (f32 metres, facet normals from the winding).
fn write_stl(out: &mut dyn Write, mesh: &TriMesh) -> io::Result<()> {
    let mut header = [0u8; 80];
    let text = b"vps study: swept volume (m)";
    header[..text.len()].copy_from_slice(text);
    out.write_all(&header)?;
    let count = u32::try_from(mesh.triangle_count())
        .map_err(|_| io::Error::new(io::ErrorKind::InvalidInput, "too many triangles for STL"))?;
    out.write_all(&count.to_le_bytes())?;
    for t in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.triangle(t);
        let n = (b - a).cross(c - a).normalize_or_zero();
        for v in [n, a, b, c] {
            for x in v.to_array() {
                out.write_all(&(x as f32).to_le_bytes())?;
            }
        }
        out.write_all(&[0, 0])?;
    }
    Ok(())
}

/// The swept volume's figures for `study.json`, or why there is none.
fn swept_json(study: &Study) -> Value {
    match &study.swept {
        None => Value::Null,
        Some(Err(e)) => json!({ "error": e.to_string() }),
        Some(Ok(s)) => {
            let health = vps_mesh::mesh_health(&s.mesh);
            json!({
                "voxel_size_m": s.spec.voxel_size,
                "voxels": s.voxels,
                "volume_m3": s.volume_m3,
                "mesh_volume_m3": s.mesh.signed_volume(),
                "mesh_triangles": s.mesh.triangle_count(),
                "mesh_closed": health.boundary_edges == 0,
                "poses_swept": s.poses,
                "bounds_m": {
                    "min": s.spec.origin.to_array(),
                    "max": (s.spec.origin + glam::DVec3::new(
                        s.spec.dims[0] as f64,
                        s.spec.dims[1] as f64,
                        s.spec.dims[2] as f64,
                    ) * s.spec.voxel_size).to_array(),
                },
                "files": ["swept.stl", "swept.vmap"],
            })
        }
    }
}

/// Writes the study's files into `dir` (created when missing), the path table every `every`-th
/// frame, `part_mesh` (the part in its grip frame) as `part.obj`, `report.html` with `view_page`
/// as its 3D view (see [`crate::report::report_html`]). Returns the paths written. Blocking file
/// I/O.
pub fn write_study(
    dir: &Path,
    study: &Study,
    part_mesh: &TriMesh,
    settings: &Value,
    every: usize,
    view_page: Option<&str>,
) -> io::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", dir.display())))?;
    let paths = study_paths(dir);
    let rows = path_rows(study, every);
    let header: Vec<String> = PATH_COLUMNS.iter().map(|c| c.to_string()).collect();
    write_file(&paths[0], |out| write_csv(out, &header, &rows))?;
    write_file(&paths[1], |out| {
        serde_json::to_writer(
            &mut *out,
            &json!({"columns": &PATH_COLUMNS[..], "rows": rows}),
        )?;
        writeln!(out)
    })?;
    let mut header = vec!["frame".to_string(), "time_s".to_string()];
    header.extend(study.object_names.iter().map(|n| format!("{n}_m")));
    let series: Vec<Vec<Value>> = study
        .clearance
        .series_frames
        .iter()
        .enumerate()
        .map(|(k, &i)| {
            let mut row = vec![json!(i), json!(study.path[i].time_s)];
            row.extend(study.clearance.objects.iter().map(|o| {
                let d = o.series_m[k];
                if d.is_finite() {
                    json!(d)
                } else {
                    Value::Null
                }
            }));
            row
        })
        .collect();
    write_file(&paths[2], |out| write_csv(out, &header, &series))?;
    let header: Vec<String> = [
        "start_s",
        "end_s",
        "object",
        "peak_force_n",
        "peak_s",
        "distance_at_peak_m",
        "part_point_x_m",
        "part_point_y_m",
        "part_point_z_m",
    ]
    .iter()
    .map(|c| c.to_string())
    .collect();
    let events: Vec<Vec<Value>> = study
        .contacts
        .iter()
        .map(|c| {
            let local = c.on_part_local_m.map(|p| p.to_array());
            vec![
                json!(c.start_s),
                json!(c.end_s),
                json!(c.object.and_then(|o| study.object_names.get(o))),
                json!(c.peak_force_n),
                json!(study.path[c.peak_frame].time_s),
                json!(c.distance_at_peak_m),
                json!(local.map(|p| p[0])),
                json!(local.map(|p| p[1])),
                json!(local.map(|p| p[2])),
            ]
        })
        .collect();
    write_file(&paths[3], |out| write_csv(out, &header, &events))?;
    write_file(&paths[4], |out| write_obj(out, part_mesh))?;
    let mut written: Vec<PathBuf> = paths[..5].to_vec();
    if let Some(Ok(swept)) = &study.swept {
        write_file(&paths[5], |out| write_stl(out, &swept.mesh))?;
        let tree = vps_voxmap::VoxelTree::from_dense(&swept.to_dense(), Default::default())
            .map_err(|e| io::Error::other(format!("the swept volume's voxmap: {e}")))?;
        vps_voxmap::file::save_voxmap(&tree, &paths[6])
            .map_err(|e| io::Error::other(format!("{}: {e}", paths[6].display())))?;
        written.extend_from_slice(&paths[5..7]);
    } else {
        // No swept volume this time: an earlier study's must not pass for this one's.
        for stale in &paths[5..7] {
            if std::fs::symlink_metadata(stale).is_ok_and(|m| m.is_file()) {
                std::fs::remove_file(stale)
                    .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", stale.display())))?;
            }
        }
    }
    let summary = study_json(study, settings, every);
    write_file(&paths[7], |out| {
        serde_json::to_writer_pretty(&mut *out, &summary)?;
        writeln!(out)
    })?;
    written.push(paths[7].clone());
    let page = crate::report::report_html(study, settings, view_page);
    write_file(&paths[8], |out| out.write_all(page.as_bytes()))?;
    written.push(paths[8].clone());
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::{part_file_names, path_column, PATH_COLUMNS};

    #[test]
    fn the_named_path_columns_are_the_columns_written() {
        let name = |i: usize| PATH_COLUMNS[i];
        assert_eq!(name(path_column::FRAME), "frame");
        assert_eq!(name(path_column::TIME), "time_s");
        assert_eq!(
            path_column::PART_POSITION.map(name),
            ["part_x_m", "part_y_m", "part_z_m"]
        );
        assert_eq!(
            path_column::PART_ORIENTATION.map(name),
            ["part_qx", "part_qy", "part_qz", "part_qw"]
        );
        assert_eq!(
            path_column::DEVICE_FORCE.map(name),
            ["device_force_x_n", "device_force_y_n", "device_force_z_n"]
        );
        assert_eq!(name(path_column::CLEARANCE), "clearance_m");
    }

    #[test]
    fn part_file_names_are_distinct_and_stay_in_the_folder() {
        let names: Vec<String> = ["wrench", "../etc", "a b", "a_b", "", "a_b-3", "ключ"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let files = part_file_names(&names);
        assert_eq!(
            files,
            ["wrench", "___etc", "a_b", "a_b-3", "part", "a_b-3-5", "part-6"]
        );
        let long = vec!["x".repeat(500)];
        assert_eq!(part_file_names(&long)[0].len(), 64);
    }
}
