//! `vps scene check FILE`: validates a scene without running it and prints what it will build:
//! triangles and bounds (m) of every object and the part, the voxmap's estimated voxels and
//! memory, the shell's point count, and whether a frame fits the budget on this machine (from the
//! current sampling kernel's cost per point, measured briefly: [`crate::kernel_timing`]); and the
//! effective voxel settings, where each came from (the scene file or the built-in default) and
//! why.

use crate::output::{metres_4, print_json};
use anyhow::Result;
use serde::Serialize;
use vps_files::printable;
use vps_mesh::Aabb;
use vps_session::estimate::{size_text, SceneMemoryEstimate, VoxmapEstimate};
use vps_session::file::{ShellMethodName, BUILTIN_VOXELS_REASON};
use vps_session::LoadedScene;

/// Where a setting the scene file does not give comes from.
const BUILT_IN: &str = "built-in default";

/// Share of the 1 ms period a frame's compute may take (as `vps tune`'s default budget).
const FRAME_BUDGET_FRACTION: f64 = 0.6;
/// Seconds per timing batch of the kernel measurement.
const KERNEL_BATCH_SECONDS: f64 = 0.02;

/// A mesh as a scene places it: where it came from, its triangles and its bounds (m).
#[derive(Serialize)]
struct PlacedMesh {
    source: String,
    triangles: usize,
    bounds_min_m: [f64; 3],
    bounds_max_m: [f64; 3],
}

impl PlacedMesh {
    fn new(source: &str, triangles: usize, b: Aabb) -> Self {
        PlacedMesh {
            source: source.to_string(),
            triangles,
            bounds_min_m: b.min.to_array(),
            bounds_max_m: b.max.to_array(),
        }
    }
}

/// A static object or the part, by the scene file's field (`static[0]`, `part`).
#[derive(Serialize)]
struct ObjectReport {
    field: String,
    #[serde(flatten)]
    mesh: PlacedMesh,
}

/// A mesh read once for the objects naming it.
#[derive(Serialize)]
struct MeshReport {
    source: String,
    /// Static objects naming it (each a placed copy of it).
    static_objects: usize,
    /// Whether the part names it.
    part: bool,
    triangles: usize,
    /// Bytes of the one copy held (m, after units; vertices and triangles).
    bytes: u64,
    /// Every edge has two triangles running it opposite ways: the mesh bounds a solid.
    closed: bool,
    /// Shells, boundary, non-manifold and inconsistent edges, signed volume.
    health: vps_mesh::MeshHealth,
    /// Degenerate triangles the loader dropped.
    degenerate_dropped: usize,
    /// For a STEP file: its unit, the solids read (name, triangles), every solid's name, the
    /// chord tolerance (m) and the time to tessellate (s).
    step: Option<vps_mesh::StepSummary>,
}

/// One effective voxel setting and where it came from: `"scene file"` or `"built-in default"`
/// (the force model: also `"the part has no inside"`).
#[derive(Serialize)]
struct Setting<T> {
    value: T,
    from: &'static str,
}

fn setting<T>(value: T, in_file: bool) -> Setting<T> {
    Setting {
        value,
        from: if in_file { "scene file" } else { BUILT_IN },
    }
}

/// The voxel settings a session on the scene runs with.
#[derive(Serialize)]
struct VoxelsReport {
    voxel_size_m: Setting<f64>,
    voxel_width_bits: Setting<u8>,
    shell_method: Setting<ShellMethodName>,
    offset_layers: Setting<u32>,
    /// `tangent-plane` or `distance`.
    force_model: Setting<&'static str>,
    /// The `distance` model's stand-off (m); `None` for the tangent-plane model.
    standoff_m: Option<f64>,
    /// The scene file's `voxels.reason`.
    reason: Option<String>,
    /// Why the built-in defaults are what they are, when any setting is one.
    builtin_reason: Option<&'static str>,
}

/// One moving part of a scene of several.
#[derive(Serialize)]
struct PartCheck {
    name: String,
    #[serde(flatten)]
    mesh: PlacedMesh,
    /// `sim`, `bridge:ADDR`, … as its `[part.device]` (or the scene's `[device]` for the first).
    device: String,
    /// Where its hand starts (m), the grip's position at frame 0 for the simulated hand.
    start_m: Option<[f64; 3]>,
    shell_points: usize,
    /// Its shell's bounding radius about its grip (m).
    shell_radius_m: f64,
}

#[derive(Serialize)]
struct CheckReport {
    scene: String,
    name: String,
    objects: Vec<ObjectReport>,
    part: ObjectReport,
    grip_m: [f64; 3],
    /// Every moving part, the first first, in a scene of several (empty for one part).
    parts: Vec<PartCheck>,
    /// Every pair of parts, sampled both ways whenever their bounding spheres come within
    /// `pair_margin_m` of each other.
    pairs: Vec<[String; 2]>,
    /// The broad phase's margin (m).
    pair_margin_m: Option<f64>,
    /// The first part's own linearised stability index against a wall (for comparison).
    wall_stability_index: f64,
    /// The worst linearised stability index of any pair pressed together (< 1: stable by the
    /// bound; `vps_haptic::pair::pair_stability`); absent for one part.
    pair_stability_index: Option<f64>,
    voxel_size_m: f64,
    voxel_width_bits: u32,
    voxels: VoxelsReport,
    workspace: bool,
    /// The distinct mesh files and built-ins read, each once however many objects name it.
    meshes: Vec<MeshReport>,
    voxmap_estimate: VoxmapEstimate,
    /// The whole scene's memory without a viewer (checked against `memory_budget_bytes`).
    memory_estimate: SceneMemoryEstimate,
    /// What a viewer (`--view`) adds to `memory_estimate` (bytes).
    viewer_memory_bytes: u64,
    /// The budget (bytes): `--max-memory`, else half of physical memory.
    memory_budget_bytes: u64,
    shell_points: usize,
    kernel_contact_ns_per_point: f64,
    frame_compute_estimate_us: f64,
    frame_budget_us: f64,
    fits_frame_budget: bool,
    /// Whether this binary was built with debug assertions, i.e. without `--release` (its kernel
    /// timing is then no guide to a release build's).
    debug_build: bool,
    flags: Vec<String>,
}

fn object(field: String, source: &str, triangles: usize, b: Aabb) -> ObjectReport {
    ObjectReport {
        field,
        mesh: PlacedMesh::new(source, triangles, b),
    }
}

/// The `voxels` keys of `v` that the scene file left to the built-in defaults.
fn defaults_used(v: &VoxelsReport) -> Vec<&'static str> {
    [
        ("voxel_size", v.voxel_size_m.from),
        ("voxel_width", v.voxel_width_bits.from),
        ("shell_method", v.shell_method.from),
        ("offset_layers", v.offset_layers.from),
        ("force_model", v.force_model.from),
    ]
    .into_iter()
    .filter(|(_, from)| *from == BUILT_IN)
    .map(|(key, _)| key)
    .collect()
}

/// An estimated count as a whole number to 3 significant digits (`2`, `204000`), or in exponent
/// form above a million (`5.995e6`): an estimate has no fractions of a voxel, nor six exact digits.
fn approximate_count(estimate: f64) -> String {
    if estimate >= 1e6 {
        return format!("{estimate:.3e}");
    }
    if estimate < 1000.0 {
        return format!("{}", estimate.round());
    }
    let unit = 10f64.powi(estimate.log10().floor() as i32 - 2);
    format!("{}", (estimate / unit).round() * unit)
}

/// An estimated size in bytes: MiB to one decimal, or KiB below 0.1 MiB.
fn approximate_size(bytes: f64) -> String {
    if bytes < 0.1 * 1048576.0 {
        format!("{:.0} KiB", bytes / 1024.0)
    } else {
        format!("{:.1} MiB", bytes / 1048576.0)
    }
}

/// A length in m as millimetres to the micrometre, without trailing zeros (`0.007` → `7`).
fn millimetres(metres: f64) -> String {
    let text = format!("{:.3}", metres * 1e3);
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Every moving part of a scene of several, the first first (`first_points`: its shell's
/// points); empty for a one-part scene. Builds the other parts' shells.
fn part_checks(
    loaded: &LoadedScene,
    (first_points, first_radius): (usize, f64),
    voxel_size: f64,
) -> Result<Vec<PartCheck>> {
    if loaded.more_parts.is_empty() {
        return Ok(Vec::new());
    }
    let method = loaded.file.voxels.shell_method.method();
    let mut parts = vec![PartCheck {
        name: loaded.part_name.clone(),
        mesh: PlacedMesh::new(
            &loaded.part_source,
            loaded.part.triangle_count(),
            loaded.part.bounds(),
        ),
        device: loaded
            .file
            .device
            .as_ref()
            .map_or("sim".into(), |d| d.kind.clone()),
        start_m: loaded.hand().first_waypoint().map(|w| w.to_array()),
        shell_points: first_points,
        shell_radius_m: first_radius,
    }];
    for (k, p) in loaded.more_parts.iter().enumerate() {
        let (shell, _) = vps_session::parts::grip_frame_shell(&p.mesh, p.grip, voxel_size, method)?;
        parts.push(PartCheck {
            name: p.name.clone(),
            mesh: PlacedMesh::new(&p.source, p.mesh.triangle_count(), p.mesh.bounds()),
            device: loaded.file.more_parts[k]
                .device
                .as_ref()
                .map_or("sim".into(), |d| d.kind.clone()),
            start_m: p.hand.first_waypoint().map(|w| w.to_array()),
            shell_points: shell.len(),
            shell_radius_m: shell.max_radius(),
        });
    }
    Ok(parts)
}

/// The worst [`vps_haptic::pair::pair_stability`] index over every pair of `parts` with the
/// scene's parameters at `voxel_size`; `None` for one part.
fn pair_stability_index(
    loaded: &LoadedScene,
    parts: &[PartCheck],
    voxel_size: f64,
) -> Result<Option<f64>> {
    let params = |p: &PartCheck| loaded.params.with_scene(voxel_size, p.shell_radius_m);
    let mut worst: Option<f64> = None;
    for (i, a) in parts.iter().enumerate() {
        for b in &parts[i + 1..] {
            let index = vps_haptic::pair::pair_stability(
                &params(a)?,
                &params(b)?,
                vps_haptic::pair::PAIR_SHARE,
            )
            .worst();
            worst = Some(worst.map_or(index, |w| w.max(index)));
        }
    }
    Ok(worst)
}

/// Runs `vps scene check`; `max_memory` (bytes) is the budget instead of half of physical memory.
pub fn run(scene: &str, json: bool, max_memory: Option<u64>) -> Result<()> {
    let budget = max_memory.unwrap_or_else(vps_voxelize::default_memory_budget);
    let loaded = LoadedScene::load_within(scene, budget)?;
    let voxels = &loaded.file.voxels;
    let width = loaded.width()?;
    let estimate = loaded.plan_voxmap(voxels.voxel_size, width)?;
    let memory = loaded.memory_estimate(voxels.voxel_size, width, false)?;
    let with_viewer = loaded.memory_estimate(voxels.voxel_size, width, true);
    let viewer_memory_bytes = with_viewer
        .map_or(memory.placed_copies_bytes.saturating_mul(2), |m| {
            m.viewer_bytes
        });
    let shell = loaded.build_shell(voxels.voxel_size, voxels.shell_method.method())?;
    let ns_per_point = crate::kernel_timing::contact_ns_per_point(
        shell.len().max(1),
        KERNEL_BATCH_SECONDS,
        voxels.standoff_at(voxels.voxel_size).is_some(),
    )?;
    let set = voxels.set_in_file;
    let voxels_report = VoxelsReport {
        voxel_size_m: setting(voxels.voxel_size, set.voxel_size),
        voxel_width_bits: setting(voxels.voxel_width, set.voxel_width),
        shell_method: setting(voxels.shell_method, set.shell_method),
        offset_layers: setting(voxels.offset_layers, set.offset_layers),
        force_model: if loaded.force_model_switched {
            Setting {
                value: voxels.force_model.name(),
                from: "the part has no inside",
            }
        } else {
            setting(voxels.force_model.name(), set.force_model)
        },
        standoff_m: voxels.standoff_at(voxels.voxel_size),
        reason: voxels.reason.clone(),
        builtin_reason: (!(set.voxel_size
            && set.voxel_width
            && set.shell_method
            && set.offset_layers
            && set.force_model))
            .then_some(BUILTIN_VOXELS_REASON),
    };
    let parts = part_checks(
        &loaded,
        (shell.len(), shell.max_radius()),
        voxels.voxel_size,
    )?;
    let pairs: Vec<[String; 2]> = parts
        .iter()
        .enumerate()
        .flat_map(|(i, a)| {
            parts[i + 1..]
                .iter()
                .map(|b| [a.name.clone(), b.name.clone()])
        })
        .collect();
    // Every part's shell in the static scene, and every pair both ways (all in contact at once).
    let points: usize = parts
        .iter()
        .map(|p| p.shell_points)
        .sum::<usize>()
        .max(shell.len())
        + parts
            .iter()
            .enumerate()
            .flat_map(|(i, a)| {
                parts[i + 1..]
                    .iter()
                    .map(move |b| a.shell_points + b.shell_points)
            })
            .sum::<usize>();
    let frame_us = ns_per_point * points as f64 / 1e3;
    let budget_us = 1000.0 * FRAME_BUDGET_FRACTION;
    let report = CheckReport {
        scene: loaded.label.clone(),
        name: loaded.name.clone(),
        objects: loaded
            .statics
            .iter()
            .zip(&loaded.static_sources)
            .enumerate()
            .map(|(i, (o, source))| object(format!("static[{i}]"), source, o.triangles, o.bounds))
            .collect(),
        part: object(
            "part".into(),
            &loaded.part_source,
            loaded.part.triangle_count(),
            loaded.part.bounds(),
        ),
        grip_m: loaded.grip(&shell).to_array(),
        pair_stability_index: pair_stability_index(&loaded, &parts, voxels.voxel_size)?,
        wall_stability_index: loaded
            .params_for(voxels.voxel_size, &shell)?
            .stability()
            .worst(),
        pair_margin_m: (!parts.is_empty())
            .then(|| vps_session::parts::pair_margin(voxels.voxel_size, voxels.offset_layers)),
        parts,
        pairs,
        voxel_size_m: voxels.voxel_size,
        voxel_width_bits: width.bits(),
        voxels: voxels_report,
        workspace: loaded.file.workspace.is_some(),
        meshes: loaded
            .meshes
            .iter()
            .map(|m| MeshReport {
                source: m.source.clone(),
                static_objects: m.statics,
                part: m.part,
                triangles: m.mesh.triangle_count(),
                bytes: vps_session::estimate::mesh_bytes(&m.mesh),
                closed: m.health.closed(),
                health: m.health,
                degenerate_dropped: m.degenerate_dropped,
                step: m.step.clone(),
            })
            .collect(),
        voxmap_estimate: estimate,
        memory_estimate: memory,
        viewer_memory_bytes,
        memory_budget_bytes: budget,
        shell_points: points,
        kernel_contact_ns_per_point: ns_per_point,
        frame_compute_estimate_us: frame_us,
        frame_budget_us: budget_us,
        fits_frame_budget: frame_us <= budget_us,
        debug_build: cfg!(debug_assertions),
        flags: loaded
            .warnings
            .iter()
            .cloned()
            .chain(vps_session::hints::coarse_voxel_flag(
                voxels.voxel_size,
                &loaded.part,
                shell.len(),
            ))
            .collect(),
    };
    if json {
        return print_json(&report);
    }
    println!("scene {} ({}): ok", report.name, printable(&report.scene));
    let line = |o: &ObjectReport| {
        println!(
            "  {:<10} {:>9} triangles  bounds (m) [{}] .. [{}]  {}",
            o.field,
            o.mesh.triangles,
            o.mesh.bounds_min_m.map(metres_4).join(", "),
            o.mesh.bounds_max_m.map(metres_4).join(", "),
            printable(&o.mesh.source)
        )
    };
    report.objects.iter().for_each(line);
    line(&report.part);
    println!(
        "  grip (part coordinates, m): [{}]",
        report.grip_m.map(metres_4).join(", ")
    );
    if !report.parts.is_empty() {
        println!(
            "moving parts: {}, each with its own hand or device",
            report.parts.len()
        );
        for p in &report.parts {
            println!(
                "  part '{}': {} triangles, {} shell points, device {}, starts at [{}] m  {}",
                printable(&p.name),
                p.mesh.triangles,
                p.shell_points,
                printable(&p.device),
                p.start_m.map_or("?".into(), |s| s.map(metres_4).join(", ")),
                printable(&p.mesh.source)
            );
        }
        if let Some(index) = report.pair_stability_index {
            println!(
                "  pair stability index {index:.3} (the linear bound for two parts pressed \
                 together; < 1 is stable; the first part on a wall: {:.3})",
                report.wall_stability_index
            );
        }
        for [a, b] in &report.pairs {
            println!(
                "  pair '{}' – '{}': each part's shell sampled in the other's own voxmap, both \
                 ways, when their bounding spheres come within {} mm",
                printable(a),
                printable(b),
                millimetres(report.pair_margin_m.unwrap_or(0.0))
            );
        }
    }
    let v = &report.voxels;
    println!(
        "voxels: size {} mm ({}), width {} bits ({}), shell {} ({}), offset {} layers ({})",
        v.voxel_size_m.value * 1e3,
        v.voxel_size_m.from,
        v.voxel_width_bits.value,
        v.voxel_width_bits.from,
        match v.shell_method.value {
            ShellMethodName::Centres => "centres",
            ShellMethodName::Exact => "exact",
        },
        v.shell_method.from,
        v.offset_layers.value,
        v.offset_layers.from
    );
    if let Some(reason) = &v.reason {
        println!("  why (scene file): {}", printable(reason));
    }
    if let Some(reason) = v.builtin_reason {
        println!(
            "  why (built-in defaults, used here for {}): {reason}",
            defaults_used(v).join(", ")
        );
    }
    if let Some(standoff) = v.standoff_m {
        println!(
            "  force model: distance ({}): contact starts {} mm from the exact surface (the \
             stand-off), distances resolved to {} mm (1/128 voxel): a clearance of more than \
             about {} mm a side reads as open",
            v.force_model.from,
            millimetres(standoff),
            millimetres(v.voxel_size_m.value / 128.0),
            millimetres(standoff)
        );
    } else if v.offset_layers.value > 0 {
        println!(
            "  force model: tangent-plane ({}), the paper's; force_model = \"distance\" \
             resolves sub-voxel gaps (docs/scenes.md, Force models)",
            v.force_model.from
        );
        let standoff_mm = millimetres(f64::from(v.offset_layers.value) * v.voxel_size_m.value);
        println!(
            "  clearance: the force layer stands {} voxel(s), {standoff_mm} mm, off every static \
             surface and the part stops at least that far out: a gap under about {standoff_mm} mm \
             a side reads as closed (docs/scenes.md, Clearances)",
            v.offset_layers.value
        );
    }
    println!(
        "voxmap: {} m, {}-bit{}: about {} voxels in the grid, {} in the surface band, \
         {} of tree (estimate)",
        report.voxel_size_m,
        report.voxel_width_bits,
        if report.workspace {
            ", workspace region only"
        } else {
            ""
        },
        approximate_count(estimate.grid_voxels),
        approximate_count(estimate.band_voxels),
        approximate_size(estimate.tree_bytes)
    );
    println!(
        "meshes: {} read for {} objects, each once (the placed copies are made when the voxmap \
         is built)",
        report.meshes.len(),
        report.objects.len() + 1
    );
    for m in &report.meshes {
        let users = match (m.static_objects, m.part) {
            (n, true) if n > 0 => format!("{n} static object(s) and the part"),
            (_, true) => "the part".to_string(),
            (n, false) => format!("{n} static object(s)"),
        };
        let dropped = match m.degenerate_dropped {
            0 => String::new(),
            n => format!(", {n} degenerate triangles dropped"),
        };
        println!(
            "  {}: {users}; {} triangles, {} held once; {}{dropped}",
            printable(&m.source),
            m.triangles,
            size_text(m.bytes),
            m.health.summary()
        );
        if let Some(step) = &m.step {
            let listed: Vec<String> = step
                .solids
                .iter()
                .map(|(name, triangles)| format!("{} ({triangles} triangles)", printable(name)))
                .collect();
            println!(
                "    STEP: unit {} (from the file); {} placed solid(s) read of the file's {}: {}; \
                 chord tolerance {} mm; tessellated in {:.0} ms",
                step.unit,
                step.solids.len(),
                step.available.len(),
                listed.join(", "),
                step.chord_tolerance * 1e3,
                step.seconds * 1e3
            );
        }
    }
    let m = &report.memory_estimate;
    println!(
        "memory: about {} in all (estimate, within the budget of {}): meshes read {}, placed \
         copies {}, voxelizer {}, voxmap {}, distance band {}, exact reference {}, winding-number \
         trees {}, shell {}, parts' voxmaps {}; a viewer (--view) adds {}",
        size_text(m.total_bytes),
        size_text(report.memory_budget_bytes),
        size_text(m.meshes_read_bytes),
        size_text(m.placed_copies_bytes),
        size_text(m.voxelizer_bytes),
        size_text(m.voxmap_bytes),
        size_text(m.distance_band_bytes),
        size_text(m.exact_reference_bytes),
        size_text(m.winding_trees_bytes),
        size_text(m.shell_bytes),
        size_text(m.part_voxmaps_bytes),
        size_text(report.viewer_memory_bytes)
    );
    println!(
        "shell: {} points; kernel {:.1} ns/point in full contact on this machine: a frame about \
         {:.0} µs of the {:.0} µs budget: {}",
        report.shell_points,
        ns_per_point,
        frame_us,
        budget_us,
        if report.fits_frame_budget {
            "fits"
        } else {
            "does NOT fit (use a larger voxel_size, or workers: vps cluster)"
        }
    );
    if report.debug_build {
        println!(
            "  (this vps was built without --release (debug assertions on): its kernel figure is no \
             guide to a release build's; check the budget with target/release/vps)"
        );
    }
    for flag in &report.flags {
        println!("flag: {}", printable(flag));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimates_print_as_whole_counts() {
        assert_eq!(approximate_count(2.268), "2");
        assert_eq!(approximate_count(204_128.4), "204000");
        assert_eq!(approximate_count(599_500.0), "600000");
        assert_eq!(approximate_count(5.995e6), "5.995e6");
    }

    #[test]
    fn small_trees_print_in_kib() {
        assert_eq!(approximate_size(2048.0), "2 KiB");
        assert_eq!(approximate_size(0.3 * 1048576.0), "0.3 MiB");
    }

    #[test]
    fn millimetres_carry_no_float_noise() {
        // 7 × 0.001 m is 0.007000000000000001 m in f64.
        assert_eq!(millimetres(7.0 * 0.001), "7");
        assert_eq!(millimetres(0.0025), "2.5");
        assert_eq!(millimetres(0.0100), "10");
    }
}
