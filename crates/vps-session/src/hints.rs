//! Hints for scene files that parse and load but look like a CAD user's slip: meshes left in
//! their Y-up frame, and lengths written in millimetres where the scene file takes metres (hand
//! waypoints, the grip, a static object's `translate`), and a voxel edge no finer than the part.
//! Each hint names the field and says what to write instead; none stops a session.

use crate::file::{SceneFile, Units};
use glam::DVec3;
use vps_mesh::{Aabb, MeshHealth, TriMesh};

/// A hint when the scene looks like CAD exports left in their Y-up frame: some mesh is declared in
/// cm, mm or inches (a CAD export) and no object is rotated, while the scene's up is +Z (the hand's
/// waypoints, the standard session's floor).
pub(crate) fn y_up_hint(file: &SceneFile) -> Option<String> {
    let unrotated = |degrees: &[f64; 3]| *degrees == [0.0; 3];
    let from_cad =
        file.part.units != Units::Metres || file.objects.iter().any(|o| o.units != Units::Metres);
    let none_rotated =
        unrotated(&file.part.rotate_deg) && file.objects.iter().all(|o| unrotated(&o.rotate_deg));
    (from_cad && none_rotated).then(|| {
        "no object is rotated (`rotate_deg`) and the scene's up is +Z: if the mesh files are CAD \
         exports with Y up, as most are, set `rotate_deg = [90, 0, 0]` in [part] and in every \
         [[static]] (docs/scenes.md)"
            .to_string()
    })
}

/// A part whose enclosed volume is below this share of its bounding box diagonal cubed has no
/// inside (an open sheet, a single triangle, a panel).
pub const SHEET_VOLUME_SHARE: f64 = 1e-4;

/// Whether a mesh of `health` and bounding-box diagonal `diagonal` (m) has no inside: it encloses
/// less than [`SHEET_VOLUME_SHARE`] of `diagonal³` (an open sheet, a single triangle, a panel).
/// Such a part is rendered two-sided (`LoadedScene::part_two_sided`).
pub fn has_no_inside(health: &MeshHealth, diagonal: f64) -> bool {
    health.signed_volume_m3.abs() < SHEET_VOLUME_SHARE * diagonal.powi(3)
}

/// Hints for a mesh whose faults matter to vps ([`vps_mesh::MeshHealth`]): as a static mesh
/// (`is_static`) with boundary edges (its inside comes from the winding number), and as the part
/// (`is_part`) with no inside. `diagonal` is the mesh's bounding-box diagonal (m). Non-manifold or
/// inconsistently oriented edges alone change nothing in the voxmap (its inside is found from the
/// surface voxels), so they are reported by `vps scene check` but not hinted.
pub(crate) fn open_mesh_hints(
    source: &str,
    health: &MeshHealth,
    diagonal: f64,
    is_static: bool,
    is_part: bool,
) -> Vec<String> {
    let mut hints = Vec::new();
    if is_static && health.boundary_edges > 0 {
        hints.push(format!(
            "static mesh {source} is {}: vps finds the inside of its open parts by winding \
             number where a flood fill from outside ran in through a gap, so a leaky housing \
             keeps its inside; a gap narrower than a voxel, or a mesh whose faces disagree about \
             outside, can still misplace it: check with vps probe, or close the mesh \
             (docs/scenes.md, Mesh health)",
            health.summary()
        ));
    }
    if is_part && has_no_inside(health, diagonal) {
        hints.push(format!(
            "the part's mesh {source} has no inside (it is {}, enclosing {:.3e} m³): vps renders \
             it two-sided: its shell points have no inward normal and are pushed along the \
             scene's own surface normal (the distance force model), from either side, never \
             pulled in (docs/scenes.md, Mesh health)",
            health.summary(),
            health.signed_volume_m3.abs()
        ));
    }
    hints
}

/// A flag when the voxel edge `voxel_size` (m) is at least the part's largest extent: its shell of
/// `points` cannot resolve the part's shape (a bare number is metres: `5` is 5 m, not 5 mm).
pub fn coarse_voxel_flag(voxel_size: f64, part: &TriMesh, points: usize) -> Option<String> {
    let size = part.bounds().size().max_element();
    (voxel_size >= size).then(|| {
        format!(
            "voxels.voxel_size: {voxel_size} m is no finer than the part ({size:.4} m across), so \
             its shell has {points} points; a bare number is metres (for millimetres write \"5mm\")"
        )
    })
}

/// A hint for the first hand waypoint (or corridor end) farther from the static objects' bounds
/// than the scene and the part are across: waypoints are metres whatever the meshes' `units`, and
/// one written in millimetres (`[0, 0, 120]`) puts the hand far away, where nothing is touched.
pub(crate) fn distant_waypoint_hint(
    file: &SceneFile,
    scene: &Aabb,
    part_size: DVec3,
) -> Option<String> {
    let points: Vec<(String, [f64; 3])> = match (&file.hand, &file.corridor) {
        (Some(hand), _) => hand
            .waypoints
            .iter()
            .enumerate()
            .map(|(i, w)| (format!("hand.waypoints[{i}]"), *w))
            .collect(),
        (None, Some(c)) => vec![
            ("corridor.from".into(), c.from),
            ("corridor.to".into(), c.to),
        ],
        (None, None) => Vec::new(),
    };
    let across = scene.size().max_element() + part_size.max_element();
    points.into_iter().find_map(|(field, w)| {
        let p = DVec3::from_array(w);
        let distance = (p - p.clamp(scene.min, scene.max)).length();
        (distance > across).then(|| {
            format!(
                "{field}: [{}, {}, {}] m is {distance:.3} m from the static objects, which with the \
                 part span {across:.3} m, so the hand touches nothing there: waypoints are in \
                 metres whatever the meshes' `units` (120 mm is 0.12)",
                w[0], w[1], w[2]
            )
        })
    })
}

/// The distance (m) between two boxes; 0 when they overlap or touch.
fn box_gap(a: &Aabb, b: &Aabb) -> f64 {
    let gap = (a.min - b.max).max(b.min - a.max).max(DVec3::ZERO);
    gap.length()
}

/// A hint when `part.grip` lies farther from the part than the part is across: the grip is metres
/// in part coordinates, and one written in millimetres (`[0, 0, 43]`) holds the part metres away.
pub(crate) fn distant_grip_hint(file: &SceneFile, part: &TriMesh) -> Option<String> {
    let grip = file.part.grip?;
    let bounds = part.bounds();
    let p = DVec3::from_array(grip);
    let distance = (p - p.clamp(bounds.min, bounds.max)).length();
    let across = bounds.size().max_element();
    (distance > across).then(|| {
        format!(
            "part.grip: [{}, {}, {}] m is {distance:.3} m outside the part ({across:.3} m across): \
             the grip is in metres, in part coordinates after units and rotation (43 mm is 0.043)",
            grip[0], grip[1], grip[2]
        )
    })
}

/// Hints for every moved `[[static]]` (non-zero `translate`) that lies farther from all the other
/// static objects than they and it span: `translate` is metres, and one written in millimetres
/// puts the object metres away (and the voxmap's grid around both).
pub(crate) fn distant_static_hints(file: &SceneFile, bounds: &[Aabb]) -> Vec<String> {
    // The union of all boxes before i and of all after i: every "others" in linear time (a scene
    // may hold 10^4 objects).
    let mut before = vec![Aabb::EMPTY; bounds.len() + 1];
    let mut after = vec![Aabb::EMPTY; bounds.len() + 1];
    for (i, b) in bounds.iter().enumerate() {
        before[i + 1] = before[i].union(b);
    }
    for (i, b) in bounds.iter().enumerate().rev() {
        after[i] = after[i + 1].union(b);
    }
    let mut hints = Vec::new();
    for (i, object) in file.objects.iter().enumerate().take(bounds.len()) {
        if object.translate == [0.0; 3] || bounds.len() < 2 {
            continue;
        }
        let others = before[i].union(&after[i + 1]);
        let distance = box_gap(&bounds[i], &others);
        let across = bounds[i].size().max_element() + others.size().max_element();
        if distance > across {
            let t = object.translate;
            hints.push(format!(
                "static[{i}].translate: [{}, {}, {}] m puts it {distance:.3} m from the other \
                 static objects, which with it span {across:.3} m: `translate` is in metres \
                 whatever the mesh's `units` (150 mm is 0.15)",
                t[0], t[1], t[2]
            ));
        }
    }
    hints
}

/// Meshes larger than this after units (m) are flagged: likely a file in mm read as metres.
pub const LARGEST_PLAUSIBLE_MESH_M: f64 = 1000.0;
/// Meshes smaller than this after units (m) are flagged: likely a file in metres read as mm.
pub const SMALLEST_PLAUSIBLE_MESH_M: f64 = 0.001;

/// Flags a mesh whose size is implausible after units, with a hint.
pub(crate) fn plausible_size(bounds: &Aabb, field: &str, warnings: &mut Vec<String>) {
    let size = bounds.size().max_element();
    if size > LARGEST_PLAUSIBLE_MESH_M {
        warnings.push(format!(
            "{field}: the mesh is {size:.4e} m across (over 1 km): is the file in mm? set \
             `units = \"mm\"` in {field}"
        ));
    } else if size < SMALLEST_PLAUSIBLE_MESH_M {
        warnings.push(format!(
            "{field}: the mesh is {size:.4e} m across (under 1 mm): is the file in metres with \
             `units` set to mm, or in another unit? check `units` in {field}"
        ));
    }
}
