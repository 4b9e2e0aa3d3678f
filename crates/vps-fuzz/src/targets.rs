//! The fuzz targets: every parser and decoder of untrusted bytes, with its seeds and the name its
//! errors must carry.

use crate::seeds;
use std::path::Path;
use vps_mesh::MeshFormat;

/// One parser or decoder under test.
#[derive(Clone, Copy)]
pub struct Target {
    /// Short name (`--target` on the command line).
    pub name: &'static str,
    /// Builds the seed corpus.
    pub seeds: fn() -> Vec<Vec<u8>>,
    /// Parses one input: `Ok` when accepted, `Err(message)` when rejected. A disagreement between
    /// two entry points of the same format panics (and is reported as a finding).
    pub run: fn(&[u8]) -> Result<(), String>,
    /// A text every rejection's message must contain (the file name, or `": "` for errors that
    /// must open with the field at fault), or `None` where the message need only be non-empty.
    pub must_name: Option<&'static str>,
    /// Cap on a mutated input's length (bytes).
    pub max_len: usize,
    /// Whether the entry point catches panics of the third-party crates it drives on purpose and
    /// turns them into errors (the STEP reader does for the geometry kernel, which panics on much
    /// malformed geometry): such a panic is counted apart
    /// ([`crate::TargetReport::caught_dependency_panics`]), not as a finding. A panic in vps's own
    /// code, or one that escapes the entry point, still is.
    pub catches_dependency_panics: bool,
}

/// The file name mesh, haptic and trace inputs are parsed under (their errors must name it).
pub const MESH_OBJ: &str = "fuzz-input.obj";
/// See [`MESH_OBJ`].
pub const MESH_STL: &str = "fuzz-input.stl";
/// See [`MESH_OBJ`].
pub const MESH_PLY: &str = "fuzz-input.ply";
/// See [`MESH_OBJ`].
pub const HAPTIC_TOML: &str = "fuzz-haptic.toml";
/// See [`MESH_OBJ`].
pub const TRACE: &str = "fuzz-input.trace";
/// See [`MESH_OBJ`].
pub const SCENE_TOML: &str = "fuzz-scene.toml";
/// See [`MESH_OBJ`].
pub const SWEEP_TOML: &str = "fuzz-sweep.toml";

fn mesh(bytes: &[u8], format: MeshFormat, file: &str) -> Result<(), String> {
    let mesh = vps_mesh::parse_mesh(bytes, format, file).map_err(|e| e.to_string())?;
    vps_mesh::validate(mesh, file)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The two readers of one file format (`name`) on the same bytes: both accept what they read
/// alike (`same`), or both reject (with the sized reader's message); anything else panics.
fn readers_agree<T, E: std::fmt::Display>(
    name: &str,
    sized: Result<T, E>,
    stream: Result<T, E>,
    same: impl FnOnce(&T, &T) -> bool,
) -> Result<(), String> {
    match (sized, stream) {
        (Ok(a), Ok(b)) => {
            assert!(same(&a, &b), "{name}: readers differ");
            Ok(())
        }
        (Err(e), Err(_)) => Err(e.to_string()),
        (a, b) => panic!(
            "{name}: sized reader {:?} but stream reader {:?}",
            a.err().map(|e| e.to_string()),
            b.err().map(|e| e.to_string())
        ),
    }
}

/// A `.vmap` through both readers; an accepted map that carries a distance band (version 3) is
/// then read where the kernel reads it: its band's interpolated value on a lattice over the grid
/// and one voxel beyond, each finite and within the band's depth (a decoded band whose directory
/// or codes point outside its storage would panic here).
fn vmap(bytes: &[u8]) -> Result<(), String> {
    readers_agree(
        "vmap",
        vps_voxmap::file::read_voxmap_sized(bytes, bytes.len() as u64),
        vps_voxmap::file::read_voxmap(bytes),
        |a, b| {
            if let Some(band) = a.distance_band() {
                probe_band(band, a.spec());
            }
            a.content_hash() == b.content_hash()
        },
    )
}

/// [`vmap`]'s read of an accepted band: 9³ points from one voxel below the grid to one above.
fn probe_band(band: &vps_voxmap::distance::DistanceBand, spec: &vps_voxmap::GridSpec) {
    const STEPS: u32 = 8;
    let size = spec.voxel_size;
    let low = spec.origin - glam::DVec3::splat(size);
    let span =
        glam::UVec3::from_array(spec.dims).as_dvec3() * size + glam::DVec3::splat(2.0 * size);
    let limit = band.max_contact_depth(size) + band.standoff_m() + size;
    for i in 0..=STEPS {
        for j in 0..=STEPS {
            for k in 0..=STEPS {
                let f =
                    glam::DVec3::new(f64::from(i), f64::from(j), f64::from(k)) / f64::from(STEPS);
                if let Some(e) = band.standoff_distance_at(spec, low + f * span) {
                    assert!(
                        e.is_finite() && e.abs() <= limit,
                        "vmap: the band reads {e} m at {:?} (limit {limit} m)",
                        low + f * span
                    );
                }
            }
        }
    }
}

fn vshell(bytes: &[u8]) -> Result<(), String> {
    readers_agree(
        "vshell",
        vps_voxmap::file::read_shell_sized(bytes, bytes.len() as u64),
        vps_voxmap::file::read_shell(bytes),
        |a, b| a == b,
    )
}

fn haptic_toml(bytes: &[u8]) -> Result<(), String> {
    let text = String::from_utf8_lossy(bytes);
    vps_haptic::HapticParams::from_toml_str(&text, HAPTIC_TOML)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// A scene file as `vps_session::SceneFile::from_toml_str` reads it, then what a session derives
/// from an accepted file before loading any mesh: the corridor's waypoints (asserted within
/// `MAX_WAYPOINTS`, so a corridor cannot size an allocation), the voxel width, the bridge
/// settings, and inline `[haptic]` keys through `HapticParams::from_toml_str` as the scene loader
/// passes them (its errors are named `[haptic]` inside the scene file).
fn scene_toml(bytes: &[u8]) -> Result<(), String> {
    use vps_session::file::MAX_WAYPOINTS;
    let text = String::from_utf8_lossy(bytes);
    let file =
        vps_session::SceneFile::from_toml_str(&text, SCENE_TOML).map_err(|e| e.to_string())?;
    let waypoints = file.corridor_waypoints();
    let laps = file.corridor.as_ref().map_or(1, |c| c.laps);
    assert!(
        waypoints.len() * laps <= MAX_WAYPOINTS,
        "scene: {} corridor waypoints × {laps} laps accepted",
        waypoints.len()
    );
    assert!(
        waypoints.iter().all(|w| w.is_finite()),
        "scene: a waypoint is not finite"
    );
    file.width(SCENE_TOML).map_err(|e| e.to_string())?;
    if let Some(device) = &file.device {
        vps_session::device::bridge_settings(device, SCENE_TOML, "device")
            .map_err(|e| e.to_string())?;
    }
    // Every part after the first was checked: a hand of finite waypoints, a device that parses
    // (its settings' ranges are checked where a session's devices are made: above).
    assert!(
        file.more_parts.len() < vps_session::file::MAX_PARTS,
        "scene: {} parts accepted",
        file.more_parts.len() + 1
    );
    for part in &file.more_parts {
        let hand = part
            .hand
            .as_ref()
            .expect("scene: a part after the first without a hand");
        assert!(
            hand.waypoints.iter().flatten().all(|c| c.is_finite()),
            "scene: a part's waypoint is not finite"
        );
        if let Some(device) = &part.device {
            vps_session::DeviceChoice::parse(&device.kind)
                .expect("scene: a part's device kind was accepted unparsed");
            vps_session::device::bridge_settings(device, SCENE_TOML, "part[k].device")
                .map_err(|e| e.to_string())?;
        }
    }
    if let Some(table) = file.haptic.as_ref().filter(|t| !t.contains_key("file")) {
        let inline = toml::to_string(table).map_err(|e| format!("{SCENE_TOML}: [haptic]: {e}"))?;
        vps_haptic::HapticParams::from_toml_str(&inline, "[haptic]")
            .map_err(|e| format!("{SCENE_TOML}: {e}"))?;
    }
    Ok(())
}

/// A sweep file as `vps_session::sweep_file::SweepFile::from_toml_str` reads it; an accepted
/// file must hold what `vps sweep` relies on without checking again: every run has at least one
/// voxel size (finite, > 0) and one method, a width list (when any) is not empty, and a run's
/// length is in `(0, MAX_SESSION_SECONDS]`.
fn sweep_toml(bytes: &[u8]) -> Result<(), String> {
    use vps_session::sweep_file::{SweepFile, MAX_SESSION_SECONDS};
    let text = String::from_utf8_lossy(bytes);
    let file = SweepFile::from_toml_str(&text, SWEEP_TOML).map_err(|e| e.to_string())?;
    assert!(!file.run.is_empty(), "sweep: no run accepted");
    for run in &file.run {
        let sizes = file.sizes_mm(run);
        assert!(
            !sizes.is_empty() && sizes.iter().all(|s| s.is_finite() && *s > 0.0),
            "sweep: voxel sizes {sizes:?} accepted"
        );
        assert!(
            !file.methods_of(run).is_empty(),
            "sweep: no method accepted"
        );
        assert!(
            file.widths_of(run).is_none_or(|w| !w.is_empty()),
            "sweep: an empty width list accepted"
        );
        assert!(
            run.seconds
                .is_none_or(|s| s > 0.0 && s <= MAX_SESSION_SECONDS),
            "sweep: run length {:?} s accepted",
            run.seconds
        );
    }
    Ok(())
}

/// A voxmap cache entry as `vps_session::cache::check_entry` checks it: the input is the `.vmap`
/// file's bytes, [`seeds::CACHE_RECORD_MARKER`], then the record's text (no marker: no record). The
/// entry asked for is the seeds' (`seeds::cache_expected`): an accepted map must have exactly its
/// grid, width and tree shape.
fn cache_entry(bytes: &[u8]) -> Result<(), String> {
    let split = bytes
        .windows(seeds::CACHE_RECORD_MARKER.len())
        .rposition(|w| w == seeds::CACHE_RECORD_MARKER);
    let (map, record) = match split {
        Some(at) => (
            &bytes[..at],
            &bytes[at + seeds::CACHE_RECORD_MARKER.len()..],
        ),
        None => (bytes, &b""[..]),
    };
    let expected = seeds::cache_expected();
    let tree = vps_session::cache::check_entry(map, &String::from_utf8_lossy(record), expected)?;
    assert!(
        *tree.spec() == expected.spec
            && tree.width() == expected.width
            && tree.config() == expected.config,
        "cache entry: a map of another grid accepted: {:?}",
        tree.spec()
    );
    Ok(())
}

/// The memory budget (bytes) a `scene-mesh` input's scene is loaded and estimated within, as
/// `vps scene check --max-memory 16MiB` would (under the runner's 64 MiB per input).
pub const SCENE_MESH_BUDGET: u64 = 16 << 20;

/// A scene file with its mesh files, loaded as `vps scene check` loads it: the input is split at
/// [`seeds::SCENE_FILE_MARKER`] lines into the scene's text ([`SCENE_TOML`]) and mesh files (each
/// marker line names its file; names other than `[A-Za-z0-9._-]`, up to 32 bytes, not starting
/// with a dot, are dropped), written to a fresh directory, then
/// `LoadedScene::load_within(.., SCENE_MESH_BUDGET)` (every mesh read once, the placed copies'
/// memory checked) and `LoadedScene::memory_estimate` (the voxmap's limits and the whole scene
/// against the budget). An accepted scene must have one table entry per distinct source, every
/// object's bounds finite, and an estimate within the budget. (Scene check then builds the part's
/// shell and times the kernel: not done here.)
fn scene_mesh(bytes: &[u8]) -> Result<(), String> {
    let dir =
        tempfile::tempdir().map_err(|e| format!("{SCENE_TOML}: a temporary directory: {e}"))?;
    let mut parts = split_at(bytes, seeds::SCENE_FILE_MARKER).into_iter();
    let scene = parts.next().unwrap_or_default();
    for part in parts {
        let (name, body) = match part.iter().position(|&b| b == b'\n') {
            Some(at) => (&part[..at], &part[at + 1..]),
            None => (part, &b""[..]),
        };
        let ok = !name.is_empty()
            && name.len() <= 32
            && name[0] != b'.'
            && name
                .iter()
                .all(|b| b.is_ascii_alphanumeric() || matches!(b, b'.' | b'_' | b'-'));
        if ok {
            let name = String::from_utf8_lossy(name).into_owned();
            std::fs::write(dir.path().join(name), body)
                .map_err(|e| format!("{SCENE_TOML}: writing a mesh file: {e}"))?;
        }
    }
    let path = dir.path().join(SCENE_TOML);
    std::fs::write(&path, scene).map_err(|e| format!("{SCENE_TOML}: writing: {e}"))?;
    let loaded =
        vps_session::LoadedScene::load_within(&path.display().to_string(), SCENE_MESH_BUDGET)
            .map_err(|e| format!("{e:#}"))?;
    let width = loaded.width().map_err(|e| e.to_string())?;
    let est = loaded
        .memory_estimate(loaded.file.voxels.voxel_size, width, false)
        .map_err(|e| e.to_string())?;
    assert!(
        est.total_bytes <= SCENE_MESH_BUDGET,
        "scene-mesh: an estimate of {} bytes accepted",
        est.total_bytes
    );
    let mut sources: Vec<&str> = loaded.meshes.iter().map(|m| m.source.as_str()).collect();
    let distinct = sources.len();
    sources.sort_unstable();
    sources.dedup();
    assert_eq!(sources.len(), distinct, "scene-mesh: one source read twice");
    let objects: usize = loaded.meshes.iter().map(|m| m.statics).sum();
    assert_eq!(
        objects,
        loaded.statics.len(),
        "scene-mesh: objects miscounted"
    );
    assert!(
        loaded
            .statics
            .iter()
            .all(|o| o.bounds.min.is_finite() && o.bounds.max.is_finite()),
        "scene-mesh: an object with non-finite bounds accepted"
    );
    Ok(())
}

/// `bytes` split at every `marker` (the markers dropped).
fn split_at<'a>(bytes: &'a [u8], marker: &[u8]) -> Vec<&'a [u8]> {
    let mut out = Vec::new();
    let mut rest = bytes;
    while let Some(at) = rest.windows(marker.len()).position(|w| w == marker) {
        out.push(&rest[..at]);
        rest = &rest[at + marker.len()..];
    }
    out.push(rest);
    out
}

fn trace(bytes: &[u8]) -> Result<(), String> {
    vps_device::trace::read_trace(bytes, Path::new(TRACE))
        .map(|_| ())
        .map_err(|e| e.to_string())
}

fn bridge_datagram(bytes: &[u8]) -> Result<(), String> {
    vps_input::bridge::protocol::Datagram::decode(bytes)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// Every cluster decoder on the same bytes: accepted when any accepts; rejected (with the frame
/// request decoder's message) when all reject.
fn cluster_datagram(bytes: &[u8]) -> Result<(), String> {
    use vps_cluster::protocol::{FrameReply, FrameRequest, JoinMessage};
    let request = FrameRequest::decode(bytes).map(|_| ());
    let reply = FrameReply::decode(bytes).map(|_| ());
    let join = JoinMessage::decode(bytes).map(|_| ());
    let mut messages = Vec::new();
    for r in [request, reply, join] {
        match r {
            Ok(()) => return Ok(()),
            Err(e) => messages.push(e.to_string()),
        }
    }
    // Empty when any decoder's message is empty, so the runner flags it.
    if messages.iter().any(String::is_empty) {
        return Err(String::new());
    }
    Err(messages.join("; "))
}

/// A STEP file's structure as vps reads it before tessellating: the exchange structure, the
/// grammar, the length unit, the solids, names and assembly placements (`vps_step::read_structure`).
/// The whole read, tessellation included, is the `step` target.
fn step_structure(bytes: &[u8]) -> Result<(), String> {
    let s = vps_step::read_structure(bytes, None).map_err(|e| e.to_string())?;
    for (_, solid) in &s.selected {
        assert!(
            !solid.placements.is_empty(),
            "step-structure: a solid with no placement accepted"
        );
    }
    Ok(())
}

/// Triangles a solid may need in the `step` target: the seeds need under 1,000 at its tolerance;
/// a small limit keeps the tessellation's grid bounds (`vps_step::guard`) small, so a malformed
/// surface fails in milliseconds.
const STEP_MAX_TRIANGLES: usize = 20_000;

/// A STEP file read whole (`vps_step::read_step` at a 0.5 mm chord tolerance): structure, truck's
/// tessellation under vps's grid and evaluation bounds, the closed-solid checks. A read that runs
/// into its deadline (60 s; every input so far took under a second) is a finding, as a panic is:
/// the bounds must stop malformed geometry, not the deadline.
fn step_read(bytes: &[u8]) -> Result<(), String> {
    let mut options = vps_step::StepOptions::new(0.0005);
    options.max_triangles = STEP_MAX_TRIANGLES;
    options.deadline = std::time::Duration::from_secs(60);
    match vps_step::read_step(bytes, &options) {
        Ok(model) => {
            for solid in &model.solids {
                assert!(
                    solid.triangles.len() <= STEP_MAX_TRIANGLES,
                    "step: a solid over the triangle limit accepted"
                );
            }
            Ok(())
        }
        Err(e @ vps_step::StepError::Deadline { .. }) => {
            panic!("step: the tessellation ran into its deadline: {e}")
        }
        Err(e) => Err(e.to_string()),
    }
}

/// Every target, in a fixed order (the index is what [`crate::CountingAlloc`]'s refusal line names).
pub fn all_targets() -> Vec<Target> {
    const TEXT: usize = 64 * 1024;
    vec![
        Target {
            name: "mesh-obj",
            seeds: seeds::obj,
            run: |b| mesh(b, MeshFormat::Obj, MESH_OBJ),
            must_name: Some(MESH_OBJ),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "mesh-stl",
            seeds: seeds::stl,
            run: |b| mesh(b, MeshFormat::Stl, MESH_STL),
            must_name: Some(MESH_STL),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "mesh-ply",
            seeds: seeds::ply,
            run: |b| mesh(b, MeshFormat::Ply, MESH_PLY),
            must_name: Some(MESH_PLY),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "step-structure",
            seeds: seeds::step,
            run: step_structure,
            must_name: None,
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "step",
            seeds: seeds::step,
            run: step_read,
            must_name: None,
            max_len: TEXT,
            catches_dependency_panics: true,
        },
        Target {
            name: "vmap",
            seeds: seeds::vmap,
            run: vmap,
            must_name: Some(": "),
            max_len: 256 * 1024,
            catches_dependency_panics: false,
        },
        Target {
            name: "vshell",
            seeds: seeds::vshell,
            run: vshell,
            must_name: Some(": "),
            max_len: 256 * 1024,
            catches_dependency_panics: false,
        },
        Target {
            name: "haptic-toml",
            seeds: seeds::haptic_toml,
            run: haptic_toml,
            must_name: Some(HAPTIC_TOML),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "scene-toml",
            seeds: seeds::scene_toml,
            run: scene_toml,
            must_name: Some(SCENE_TOML),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "trace",
            seeds: seeds::trace,
            run: trace,
            must_name: Some(TRACE),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "bridge-datagram",
            seeds: seeds::bridge_datagram,
            run: bridge_datagram,
            must_name: None,
            max_len: 2048,
            catches_dependency_panics: false,
        },
        Target {
            name: "cluster-datagram",
            seeds: seeds::cluster_datagram,
            run: cluster_datagram,
            must_name: None,
            max_len: 2048,
            catches_dependency_panics: false,
        },
        Target {
            name: "cache-entry",
            seeds: seeds::cache_entry,
            run: cache_entry,
            must_name: Some("the cache entry"),
            max_len: 256 * 1024,
            catches_dependency_panics: false,
        },
        Target {
            name: "scene-mesh",
            seeds: seeds::scene_mesh,
            run: scene_mesh,
            must_name: Some(SCENE_TOML),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
        Target {
            name: "sweep-toml",
            seeds: seeds::sweep_toml,
            run: sweep_toml,
            must_name: Some(SWEEP_TOML),
            max_len: TEXT,
            catches_dependency_panics: false,
        },
    ]
}
