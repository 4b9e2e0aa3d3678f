//! Scenes of several moving parts (`[[part]]` tables): each part after the first loaded
//! ([`LoadedPart`]) and built ([`PartAssets`]: its shell, parameters, hand, device and a voxmap of
//! itself in its own body frame), and the runtime's [`PartsSetup`] made from them when a session
//! is planned. The first part stays the session's own (its shell and device are
//! [`SessionAssets`]'s as in a one-part scene); it gains a body voxmap too.
//!
//! Not here yet: the viewer and studies of the other parts, pair splitting over cluster workers.

use crate::device::{BridgeSettings, DeviceChoice};
use crate::error::field_error;
use crate::file::{rotation, SceneFile};
use crate::hints::has_no_inside;
use crate::mesh_source::Placement;
use crate::scene::{object_names, HandPlan, LoadedScene, SessionAssets, SharedMesh};
use crate::CachePolicy;
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use std::path::Path;
use std::sync::Arc;
use vps_haptic::HapticParams;
use vps_mesh::TriMesh;
use vps_runtime::{ClassPool, LoopConfig, MovingPart, PartBody, PartsSetup};
use vps_voxelize::{point_shell, ShellMethod};
use vps_voxmap::{PointShell, VoxelTree, VoxelWidth};

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
        crate::scene::plausible_size(&mesh.bounds(), &field, warnings);
        let device = match &spec.device {
            Some(d) => DeviceChoice::parse(&d.kind)
                .map_err(|m| field_error(label, &format!("{field}.device.kind"), m))?
                .relative_to(base),
            None => DeviceChoice::Simulated,
        };
        let bridge = match &spec.device {
            Some(d) => d.bridge_settings(label)?,
            None => BridgeSettings::default(),
        };
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
    /// Its point shell in its grip frame.
    pub shell: PointShell,
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

impl LoadedScene {
    /// A part's voxmap in its grip frame (`mesh` already moved there) at the scene's voxel
    /// settings, with the scene's distance band when the force model has one; never cut by the
    /// workspace. Cached like the scene's voxmap. Blocking, parallel, allocates.
    pub(crate) fn build_body(
        &self,
        mesh: &TriMesh,
        voxel_size: f64,
        width: VoxelWidth,
        cache: &CachePolicy,
    ) -> Result<Arc<VoxelTree>> {
        let opts = vps_voxelize::VoxelizeOptions {
            workspace: None,
            ..self.voxelize_options(voxel_size, width)
        };
        Ok(self
            .build_voxmap_with(std::slice::from_ref(mesh), opts, cache)?
            .tree)
    }

    /// Builds the parts after the first at `voxel_size` with `method`. Blocking, allocates.
    pub(crate) fn build_more_parts(
        &self,
        voxel_size: f64,
        method: ShellMethod,
        width: VoxelWidth,
        cache: &CachePolicy,
    ) -> Result<Vec<PartAssets>> {
        let mut built = Vec::with_capacity(self.more_parts.len());
        for p in &self.more_parts {
            let (shell, grip) = grip_frame_shell(&p.mesh, p.grip, voxel_size, method)
                .with_context(|| {
                    format!("{}: building part '{}''s point shell", self.label, p.name)
                })?;
            let mut mesh = p.mesh.clone();
            mesh.vertices.iter_mut().for_each(|v| *v -= grip);
            let body = self
                .build_body(&mesh, voxel_size, width, cache)
                .with_context(|| format!("{}: part '{}''s own voxmap", self.label, p.name))?;
            built.push(PartAssets {
                name: p.name.clone(),
                params: self.params.with_scene(voxel_size, shell.max_radius())?,
                radius: body_radius(&mesh, &shell),
                shell,
                mesh,
                body,
                hand: p.hand.clone(),
                device: p.device.clone(),
                bridge: p.bridge,
            });
        }
        Ok(built)
    }
}

/// The broad phase's margin (m): two parts' bounding spheres farther apart than this are not
/// sampled. The force layer reaches at most `offset_layers` voxels beyond a surface and a
/// distance band a few voxels; four more voxels cover both with room.
pub fn pair_margin(voxel_size: f64, offset_layers: u32) -> f64 {
    f64::from(offset_layers + 4) * voxel_size
}

impl SessionAssets {
    /// The longest simulated hand's path (s): `first`'s (the first part's script) or, in a scene
    /// of several parts, another part's simulated hand's. Finds corridor detours (reads the voxmap).
    pub fn hands_duration(&self, first: &vps_device::script::Script) -> Result<f64> {
        let mut longest = first.duration();
        for p in &self.more_parts {
            if p.device == DeviceChoice::Simulated {
                longest = longest.max(p.hand.script(&self.tree)?.duration());
            }
        }
        Ok(longest)
    }

    /// The runtime's setup for the parts after the first: each part's device opened (a
    /// simulated hand on its own path), a local class pool of `config.threads` threads on the
    /// static voxmap for its shell, and every part's body. `None` in a one-part scene. Blocking
    /// (opens devices), allocates.
    pub fn parts_setup(&self, config: &LoopConfig) -> Result<Option<PartsSetup>> {
        let (Some(first_body), false) = (&self.part_body, self.more_parts.is_empty()) else {
            return Ok(None);
        };
        let mut others = Vec::with_capacity(self.more_parts.len());
        for p in &self.more_parts {
            let script = p.hand.script(&self.tree)?;
            let opened = p
                .device
                .open(script, &p.bridge)
                .with_context(|| format!("opening part '{}''s device", p.name))?;
            let shell = crate::classed(&p.shell);
            let pool = ClassPool::new(self.tree.clone(), shell.clone(), config.threads)?;
            others.push(MovingPart {
                name: p.name.clone(),
                params: p.params,
                device: opened.device,
                initial: opened.initial,
                sampler: Box::new(pool),
                body: PartBody {
                    map: p.body.clone(),
                    shell,
                    radius: p.radius,
                },
            });
        }
        Ok(Some(PartsSetup {
            first: PartBody {
                map: first_body.clone(),
                shell: self.classed_shell(),
                radius: body_radius(&self.part_mesh, &self.shell),
            },
            others,
            margin: self.pair_margin,
        }))
    }
}
