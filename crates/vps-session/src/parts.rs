//! Scenes of several moving parts (`[[part]]` tables): each part after the first loaded
//! ([`LoadedPart`]) and built ([`PartAssets`]: its shell, parameters, hand, device and a voxmap of
//! itself in its own body frame), and the runtime's `PartsSetup` made from them when a session
//! is planned (`SessionAssets::parts_setup`). The first part stays the session's own (its shell
//! and device are `SessionAssets`'s as in a one-part scene); it gains a body voxmap too.

use crate::device::{BridgeSettings, DeviceChoice};
use crate::error::{field_error, SceneError};
use crate::file::{rotation, DeviceSection, SceneFile};
use crate::hints::{has_no_inside, plausible_size};
use crate::mesh_source::{object_names, Placement, SharedMesh};
use crate::script::HandPlan;
use crate::PartShell;
use anyhow::Result;
use glam::{DVec3, Vec3};
use std::path::Path;
use std::sync::Arc;
use vps_haptic::HapticParams;
use vps_mesh::TriMesh;
use vps_voxelize::{point_shell, ShellMethod};
use vps_voxmap::{PointShell, VoxelTree};

/// A moving part after the first, loaded and placed in its own frame.
#[derive(Clone, Debug)]
pub struct LoadedPart {
    /// Its name in reports (unique in the scene).
    pub name: String,
    /// Its source, resolved.
    pub source: String,
    /// Its mesh after units, scale and rotation (m, part coordinates).
    pub mesh: TriMesh,
    /// Where its handle holds it (m, part coordinates); `None`: its centre of mass.
    pub grip: Option<[f64; 3]>,
    /// Its hand's path: where it starts and, for the simulated hand, where it goes.
    pub hand: HandPlan,
    /// Its device.
    pub device: DeviceChoice,
    /// Its bridge settings and device limits.
    pub bridge: BridgeSettings,
}

/// Loads the second and later parts of `file` (their meshes already in `meshes` at `indices`).
/// A part with no inside is refused (two-sided parts are rendered against the static scene only).
pub(crate) fn load_more_parts(
    file: &SceneFile,
    label: &str,
    base: &Path,
    meshes: &[SharedMesh],
    indices: &[usize],
    warnings: &mut Vec<String>,
) -> Result<Vec<LoadedPart>> {
    let mut parts = Vec::with_capacity(indices.len());
    for (k, (spec, &index)) in file.more_parts.iter().zip(indices).enumerate() {
        let field = format!("part[{}]", k + 1);
        let shared = &meshes[index];
        if has_no_inside(&shared.health, shared.mesh.bounds().size().length()) {
            return Err(field_error(
                label,
                &format!("{field}.source"),
                format!(
                    "{} has no inside (an open sheet): a part after the first must enclose a \
                     volume, its own voxmap is what the other parts feel",
                    shared.source
                ),
            )
            .into());
        }
        let mut mesh = TriMesh::clone(&shared.mesh);
        Placement {
            scale: DVec3::from_array(spec.part.scale),
            rotation: rotation(spec.part.rotate_deg),
            translate: DVec3::ZERO,
        }
        .apply(&mut mesh);
        plausible_size(&mesh.bounds(), &field, warnings);
        let (device, bridge) = device_of(
            spec.device.as_ref(),
            label,
            &format!("{field}.device"),
            base,
        )?;
        // Validated: every part after the first has a hand.
        let hand = spec.hand.as_ref().map_or(
            HandPlan::Path {
                waypoints: vec![DVec3::ZERO],
                speed: 0.1,
                hold: 0.0,
            },
            |h| HandPlan::Path {
                waypoints: h.waypoints.iter().map(|w| DVec3::from_array(*w)).collect(),
                speed: h.speed,
                hold: h.hold_s,
            },
        );
        parts.push(LoadedPart {
            name: String::new(),
            source: shared.source.clone(),
            mesh,
            grip: spec.part.grip,
            hand,
            device,
            bridge,
        });
    }
    Ok(parts)
}

/// The device a `[device]` section (`table`: where it sits, `device` or `part[k].device`) names,
/// a replay file taken relative to `base`, and its bridge settings; the simulated hand with the
/// default settings when there is none. Errors name the scene file `label` and the field.
pub(crate) fn device_of(
    section: Option<&DeviceSection>,
    label: &str,
    table: &str,
    base: &Path,
) -> Result<(DeviceChoice, BridgeSettings), SceneError> {
    let Some(d) = section else {
        return Ok((DeviceChoice::Simulated, BridgeSettings::default()));
    };
    let choice = DeviceChoice::parse(&d.kind)
        .map_err(|m| field_error(label, &format!("{table}.kind"), m))?
        .relative_to(base);
    Ok((choice, crate::device::bridge_settings(d, label, table)?))
}

/// Every part's name, the first's first: the name its `[[part]]` gives, else its source's file
/// stem; a name another part already has gets ` #k` (its index) added.
pub(crate) fn part_names(file: &SceneFile, first_source: &str, more: &[LoadedPart]) -> Vec<String> {
    let sources: Vec<String> = std::iter::once(first_source.to_string())
        .chain(more.iter().map(|m| m.source.clone()))
        .collect();
    let given = std::iter::once(&file.part_name).chain(file.more_parts.iter().map(|m| &m.name));
    let mut names: Vec<String> = Vec::with_capacity(sources.len());
    for (k, (given, stem)) in given.zip(object_names(&sources)).enumerate() {
        let name = given
            .as_deref()
            .map_or(stem, |n| vps_files::printable(n).into_owned());
        if names.contains(&name) {
            names.push(format!("{name} #{k}"));
        } else {
            names.push(name);
        }
    }
    names
}

/// A moving part after the first, built: what its session needs.
#[derive(Clone)]
pub struct PartAssets {
    /// Its name in reports.
    pub name: String,
    /// Its point shell in its grip frame and its classes.
    pub shell: PartShell,
    /// Its haptic parameters (the scene's, with its own bounding radius).
    pub params: HapticParams,
    /// Its mesh in its grip frame (m).
    pub mesh: TriMesh,
    /// Its voxmap in its grip frame.
    pub body: Arc<VoxelTree>,
    /// Radius about its grip holding its mesh and shell (m).
    pub radius: f64,
    /// Its hand's path: where it starts and, for the simulated hand, where it goes.
    pub hand: HandPlan,
    /// Its device.
    pub device: DeviceChoice,
    /// Its bridge settings and device limits.
    pub bridge: BridgeSettings,
}

/// `mesh`'s point shell at `voxel_size` with `method`, moved into the frame whose origin is the
/// grip (`grip`, else the centre of mass); returns the shell and the grip (m, mesh coordinates).
/// Blocking, allocates.
pub fn grip_frame_shell(
    mesh: &TriMesh,
    grip: Option<[f64; 3]>,
    voxel_size: f64,
    method: ShellMethod,
) -> Result<(PointShell, DVec3)> {
    let mut shell = point_shell(mesh, voxel_size, method)?;
    let grip = grip.map_or(shell.mass.center_of_mass, DVec3::from_array);
    if grip != shell.mass.center_of_mass {
        let shift: Vec3 = (shell.mass.center_of_mass - grip).as_vec3();
        shell.points.iter_mut().for_each(|p| *p += shift);
    }
    Ok((shell, grip))
}

/// The radius about the origin (m) holding `mesh`'s vertices and `shell`'s points.
pub fn body_radius(mesh: &TriMesh, shell: &PointShell) -> f64 {
    mesh.vertices
        .iter()
        .map(|v| v.length())
        .fold(shell.max_radius(), f64::max)
}

/// The broad phase's margin (m): two parts' bounding spheres farther apart than this are not
/// sampled. The force layer reaches at most `offset_layers` voxels beyond a surface and a
/// distance band a few voxels; four more voxels cover both with room.
pub fn pair_margin(voxel_size: f64, offset_layers: u32) -> f64 {
    f64::from(offset_layers + 4) * voxel_size
}
