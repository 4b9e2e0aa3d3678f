//! A scene file resolved into what a session runs on: [`LoadedScene`] (parsed, meshes loaded and
//! placed, parameters read, geometry checked) and [`SessionAssets`] (voxmap, point shell, parameters,
//! device, hand path, and the meshes for a viewer).

use crate::cache::{cache_key, cache_path, read_cached, write_cached, CachePolicy, Expected};
use crate::device::{BridgeSettings, DeviceChoice};
use crate::error::{field_error, SceneError};
use crate::estimate::{
    estimate_triangles, mesh_bytes, part_voxmap_bytes, scene_memory, size_text,
    SceneMemoryEstimate, SceneMemoryInputs, VoxmapEstimate, MAX_GRID_VOXELS, VOXMAP_MEMORY_BUDGET,
};
use crate::file::is_step_source;
use crate::file::{rotation, ForceModelName, SceneFile};
use crate::hints::plausible_size;
use crate::hints::{
    coarse_voxel_flag, distant_grip_hint, distant_static_hints, distant_waypoint_hint,
    has_no_inside, open_mesh_hints, y_up_hint,
};
pub use crate::hints::{LARGEST_PLAUSIBLE_MESH_M, SMALLEST_PLAUSIBLE_MESH_M};
use crate::mesh_source::{load_scaled_with, resolve, Placement};
pub use crate::mesh_source::{object_names, SharedMesh};
use crate::parts::{body_radius, grip_frame_shell, LoadedPart, PartAssets};
pub use crate::script::HandPlan;
use crate::PartShell;
use anyhow::{Context, Result};
use glam::{DVec3, Vec3};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;
use vps_device::script::Script;
use vps_haptic::HapticParams;
use vps_mesh::StepSettings;
use vps_mesh::{Aabb, TriMesh};
use vps_voxelize::distance::distance_band_with_inside;
use vps_voxelize::{
    point_shell, tree_grid, voxelize_tree, voxelize_tree_keeping_inside, ShellMethod,
    VoxelizeOptions,
};
use vps_voxmap::{PointShell, TreeConfig, VoxelTree, VoxelWidth};

/// The scene `vps demo` and every session command use when no `--scene` is given.
pub const DEFAULT_SCENE: &str = "builtin:bay-teapot";

/// A scene file parsed and its meshes loaded and placed. Building it reads every mesh file.
pub struct LoadedScene {
    /// The file's path, or `builtin:NAME`.
    pub label: String,
    /// The scene's name (the file's `name`, else its stem), fit to print: control characters
    /// escaped ([`vps_files::printable`]).
    pub name: String,
    /// The file as parsed.
    pub file: SceneFile,
    /// Directory relative paths in the file are taken from.
    pub base: PathBuf,
    /// The distinct meshes the scene names (static objects and part), each read once however many
    /// objects name it: keyed by the canonical file path (or `builtin:NAME`) and the units.
    pub meshes: Vec<SharedMesh>,
    /// The static objects, in file order: each a placement of one of [`LoadedScene::meshes`]. The
    /// placed copies (scene coordinates) are made only when the voxmap is built
    /// ([`LoadedScene::placed_statics`]).
    pub statics: Vec<StaticObject>,
    /// Where each static object came from (`builtin:NAME` or the resolved file path).
    pub static_sources: Vec<String>,
    /// The part (m, part coordinates: after units and rotation).
    pub part: TriMesh,
    /// Whether the part has no inside (an open sheet, a single triangle, a panel:
    /// [`crate::hints::has_no_inside`]). Such a part is rendered two-sided: the scene uses the
    /// distance force model (switched from the tangent-plane model, with a warning) and the
    /// part's shell points carry zero normals, so each is pushed along the scene's own surface
    /// normal, from either side, and never pulled in ([`LoadedScene::build_shell`]).
    pub part_two_sided: bool,
    /// The first part's name in reports (`name` in its `[[part]]`, else its source's stem).
    pub part_name: String,
    /// The second and later moving parts (empty: a one-part scene).
    pub more_parts: Vec<LoadedPart>,
    /// The scene's force model was switched to the distance model because the part has no
    /// inside (the file said `tangent-plane`, or nothing).
    pub force_model_switched: bool,
    /// Where the part came from.
    pub part_source: String,
    /// Haptic parameters of the scene (`[haptic]`, `voxels.braking`), before the voxel size and
    /// the part's radius are set.
    pub params: HapticParams,
    /// The scene's default device (`[device] kind`, else the simulated hand).
    pub device: DeviceChoice,
    /// How the bridge is set up when it drives the session (`[device]` `mapping` and
    /// `pose_timeout_ms`).
    pub bridge: BridgeSettings,
    /// Things worth a look that do not stop the scene (implausible mesh sizes), with hints.
    pub warnings: Vec<String>,
    /// The memory budget (bytes) the whole scene's estimate is checked against before anything
    /// is built ([`LoadedScene::memory_estimate`]): `--max-memory`, else half of physical memory.
    pub max_memory_bytes: u64,
}

/// A `[[static]]` object: one of the scene's meshes and where it is placed.
#[derive(Clone, Debug)]
pub struct StaticObject {
    /// Index into [`LoadedScene::meshes`].
    pub mesh: usize,
    /// Scale, rotation and translation (m) from the file.
    pub placement: Placement,
    /// The bounds of the placed mesh (m, scene coordinates).
    pub bounds: Aabb,
    /// Triangles of the mesh.
    pub triangles: usize,
}

impl LoadedScene {
    /// Every moving part's name, the first first. Allocates.
    pub fn part_names(&self) -> Vec<String> {
        std::iter::once(self.part_name.clone())
            .chain(self.more_parts.iter().map(|p| p.name.clone()))
            .collect()
    }

    /// Loads `scene`: `builtin:NAME` (see [`BUILTIN_SCENES`](crate::file::BUILTIN_SCENES)) or a scene file path. Blocking:
    /// reads the scene and its mesh files. Errors name the file and the field.
    pub fn load(scene: &str) -> Result<LoadedScene> {
        Self::load_within(scene, vps_voxelize::default_memory_budget())
    }

    /// [`LoadedScene::load`] with the memory budget `max_memory_bytes` (bytes): the placed
    /// copies of the static objects are counted against it before the meshes' bounds are
    /// computed, and [`LoadedScene::memory_estimate`] checks the whole scene against it.
    pub fn load_within(scene: &str, max_memory_bytes: u64) -> Result<LoadedScene> {
        if let Some(name) = scene.strip_prefix("builtin:") {
            let (_, text) = crate::file::BUILTIN_SCENES
                .iter()
                .find(|(n, _)| *n == name)
                .with_context(|| {
                    format!(
                        "unknown built-in scene '{name}'; available: {}",
                        crate::file::BUILTIN_SCENES
                            .map(|(n, _)| format!("builtin:{n}"))
                            .join(", ")
                    )
                })?;
            let file = SceneFile::from_toml_str(text, scene)?;
            return Self::from_file(
                file,
                scene.to_string(),
                name.to_string(),
                PathBuf::from("."),
                max_memory_bytes,
            );
        }
        let path = Path::new(scene);
        let file = SceneFile::from_file(path)?;
        let stem = path
            .file_stem()
            .map_or_else(|| scene.to_string(), |s| s.to_string_lossy().into_owned());
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Self::from_file(file, scene.to_string(), stem, base, max_memory_bytes)
    }

    fn from_file(
        mut file: SceneFile,
        label: String,
        stem: String,
        base: PathBuf,
        max_memory_bytes: u64,
    ) -> Result<Self> {
        let mut warnings = Vec::new();
        // Each distinct mesh (canonical path or builtin, and units) is read once, however many
        // objects name it; the objects hold an index into this table.
        let mut meshes: Vec<SharedMesh> = Vec::new();
        let mut keys: Vec<(String, u64, String)> = Vec::new();
        // A STEP file is tessellated at its object's chord tolerance (default a quarter voxel).
        let voxel_size = file.voxels.voxel_size;
        let step_settings = |solids: &Option<Vec<String>>, tolerance: Option<f64>| {
            let quarter = StepSettings::quarter_voxel(voxel_size);
            StepSettings {
                chord_tolerance: tolerance.unwrap_or(quarter.chord_tolerance),
                solids: solids.clone(),
                ..quarter
            }
        };
        let mut table =
            |source: &str, units: f64, step: StepSettings, field: &str| -> Result<usize> {
                let resolved = resolve(source, &base);
                let step_key = if is_step_source(source) {
                    format!("{:?}", (step.chord_tolerance.to_bits(), &step.solids))
                } else {
                    String::new()
                };
                let key = (mesh_key(&resolved), units.to_bits(), step_key);
                if let Some(index) = keys.iter().position(|k| *k == key) {
                    return Ok(index);
                }
                let loaded = load_scaled_with(&resolved, units, &step)
                    .map_err(|e| mesh_error(&label, field, source, &base, &e))?;
                keys.push(key);
                meshes.push(SharedMesh {
                    source: resolved,
                    health: vps_mesh::mesh_health(&loaded.mesh),
                    mesh: Arc::new(loaded.mesh),
                    statics: 0,
                    part: false,
                    degenerate_dropped: loaded.degenerate_dropped,
                    open_triangles: 0,
                    step: loaded.step,
                });
                Ok(meshes.len() - 1)
            };
        let mut which = Vec::with_capacity(file.objects.len());
        for (i, o) in file.objects.iter().enumerate() {
            which.push(table(
                &o.source,
                o.units.metres(),
                step_settings(&o.solids, o.chord_tolerance),
                &format!("static[{i}].source"),
            )?);
        }
        let part_index = table(
            &file.part.source,
            file.part.units.metres(),
            step_settings(&file.part.solids, file.part.chord_tolerance),
            "part.source",
        )?;
        let mut more_indices = Vec::with_capacity(file.more_parts.len());
        for (k, m) in file.more_parts.iter().enumerate() {
            more_indices.push(table(
                &m.part.source,
                m.part.units.metres(),
                step_settings(&m.part.solids, m.part.chord_tolerance),
                &format!("part[{}].source", k + 1),
            )?);
        }
        for &k in &which {
            meshes[k].statics += 1;
        }
        // Once per distinct static mesh, for the memory estimate (`LoadedScene::memory_of`).
        for m in meshes.iter_mut().filter(|m| m.statics > 0) {
            m.open_triangles = vps_reference::components::open_triangle_count(&m.mesh);
        }
        meshes[part_index].part = true;
        for &k in &more_indices {
            meshes[k].part = true;
        }
        // Every object is a placed copy of its mesh: their memory is known before any is made
        // (and before the placed bounds are computed, O(vertices) per object).
        let copies = which
            .iter()
            .fold(0u64, |t, &k| t.saturating_add(mesh_bytes(&meshes[k].mesh)));
        if copies > max_memory_bytes {
            return Err(field_error(
                &label,
                "static",
                format!(
                    "the {} [[static]] objects are {} placed copies of {} mesh(es) holding {} in \
                     all, over the budget of {}: name fewer or smaller meshes, or raise the \
                     budget with --max-memory (e.g. --max-memory {})",
                    file.objects.len(),
                    which.len(),
                    meshes.iter().filter(|m| m.statics > 0).count(),
                    size_text(copies),
                    budget_text(max_memory_bytes),
                    raise_to(copies)
                ),
            )
            .into());
        }
        let mut statics = Vec::with_capacity(file.objects.len());
        let mut static_sources = Vec::with_capacity(file.objects.len());
        for (i, (o, &k)) in file.objects.iter().zip(&which).enumerate() {
            let placement = Placement {
                scale: DVec3::from_array(o.scale),
                rotation: rotation(o.rotate_deg),
                translate: DVec3::from_array(o.translate),
            };
            let mesh = &meshes[k].mesh;
            let bounds = placement.bounds(mesh);
            plausible_size(&bounds, &format!("static[{i}]"), &mut warnings);
            statics.push(StaticObject {
                mesh: k,
                placement,
                bounds,
                triangles: mesh.triangle_count(),
            });
            static_sources.push(meshes[k].source.clone());
        }
        let source = meshes[part_index].source.clone();
        let mut mesh = TriMesh::clone(&meshes[part_index].mesh);
        Placement {
            scale: DVec3::from_array(file.part.scale),
            rotation: rotation(file.part.rotate_deg),
            translate: DVec3::ZERO,
        }
        .apply(&mut mesh);
        plausible_size(&mesh.bounds(), "part", &mut warnings);
        warnings.extend(y_up_hint(&file));
        let part_two_sided = has_no_inside(
            &meshes[part_index].health,
            meshes[part_index].mesh.bounds().size().length(),
        );
        let force_model_switched =
            part_two_sided && file.voxels.force_model == ForceModelName::TangentPlane;
        if force_model_switched {
            // The tangent-plane force follows the part's inward normals, which a sheet lacks.
            file.voxels.force_model = ForceModelName::Distance;
            warnings.push(format!(
                "voxels.force_model: the part ({source}) has no inside, so this scene uses \
                 force_model = \"distance\" (stand-off {} unless voxels.standoff says) instead \
                 of \"tangent-plane\", whose force follows a part's inward normals \
                 (docs/scenes.md, Mesh health)",
                if file.voxels.standoff.is_some() {
                    "voxels.standoff".to_string()
                } else {
                    format!("{} voxel", vps_voxmap::distance::DEFAULT_STANDOFF_VOXELS)
                }
            ));
        }
        for m in &meshes {
            let diagonal = m.mesh.bounds().size().length();
            warnings.extend(open_mesh_hints(
                &m.source,
                &m.health,
                diagonal,
                m.statics > 0,
                m.part,
            ));
        }
        let (part, part_source) = (mesh, source);
        let scene_bounds = statics
            .iter()
            .map(|o| o.bounds)
            .reduce(|a, b| a.union(&b))
            .unwrap_or(Aabb::EMPTY);
        let (part_size, scene_size) = (part.bounds().size(), scene_bounds.size());
        check_part_fits(&label, "part", part_size, scene_size)?;
        warnings.extend(distant_waypoint_hint(&file, &scene_bounds, part_size));
        warnings.extend(distant_grip_hint(&file, &part));
        let static_bounds: Vec<Aabb> = statics.iter().map(|o| o.bounds).collect();
        warnings.extend(distant_static_hints(&file, &static_bounds));
        let mut more_parts = crate::parts::load_more_parts(
            &file,
            &label,
            &base,
            &meshes,
            &more_indices,
            &mut warnings,
        )?;
        for (k, p) in more_parts.iter().enumerate() {
            let field = format!("part[{}]", k + 1);
            check_part_fits(&label, &field, p.mesh.bounds().size(), scene_size)?;
        }
        let mut names = crate::parts::part_names(&file, &part_source, &more_parts).into_iter();
        let part_name = names.next().unwrap_or_default();
        more_parts
            .iter_mut()
            .zip(names)
            .for_each(|(m, name)| m.name = name);
        let params = scene_params(&file, &label, &base)?;
        let (device, bridge) =
            crate::parts::device_of(file.device.as_ref(), &label, "device", &base)?;
        // Printed by many commands: its control characters escaped once, here.
        let name = vps_files::printable(&file.name.clone().unwrap_or(stem)).into_owned();
        Ok(LoadedScene {
            label,
            name,
            file,
            base,
            meshes,
            statics,
            static_sources,
            part,
            part_name,
            more_parts,
            part_two_sided,
            force_model_switched,
            part_source,
            params,
            device,
            bridge,
            warnings,
            max_memory_bytes,
        })
    }

    /// Prints the scene's warnings (units, Y-up, lengths that look like millimetres) to stderr,
    /// one line each, prefixed with the scene's label.
    pub fn print_warnings(&self) {
        for w in &self.warnings {
            eprintln!(
                "{}: warning: {}",
                vps_files::printable(&self.label),
                vps_files::printable(w)
            );
        }
    }

    /// Triangles in the static objects (placed copies counted each).
    pub fn scene_triangles(&self) -> usize {
        self.statics.iter().map(|o| o.triangles).sum()
    }

    /// The bounds of all static objects placed (m, scene coordinates).
    pub fn static_bounds(&self) -> Aabb {
        self.statics
            .iter()
            .fold(Aabb::EMPTY, |b, o| b.union(&o.bounds))
    }

    /// Every static object's triangles placed (m, scene coordinates), object by object, without
    /// making the placed copies.
    pub fn static_triangles(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        self.statics.iter().flat_map(move |o| {
            let mesh = &self.meshes[o.mesh].mesh;
            (0..mesh.triangle_count()).map(move |i| mesh.triangle(i).map(|v| o.placement.point(v)))
        })
    }

    /// The static objects placed (m, scene coordinates), one copy each, in file order: what the
    /// voxelizer, the voxmap cache's key and the distance band read. Allocates
    /// [`SceneMemoryEstimate::placed_copies_bytes`]; check [`LoadedScene::memory_estimate`] first.
    pub fn placed_statics(&self) -> Vec<TriMesh> {
        self.statics
            .iter()
            .map(|o| {
                let mut mesh = TriMesh::clone(&self.meshes[o.mesh].mesh);
                o.placement.apply(&mut mesh);
                mesh
            })
            .collect()
    }

    /// The whole scene's memory at `voxel_size` (m) and `width`, with a viewer's copies when
    /// `viewer`: refused (naming the estimate, its largest parts, the budget and `--max-memory`)
    /// when over [`LoadedScene::max_memory_bytes`] or when the voxmap alone is over its limits
    /// ([`LoadedScene::plan_voxmap`]). Allocation-free; O(triangles placed).
    pub fn memory_estimate(
        &self,
        voxel_size: f64,
        width: VoxelWidth,
        viewer: bool,
    ) -> Result<SceneMemoryEstimate, SceneError> {
        let voxmap = self.plan_voxmap(voxel_size, width)?;
        let est = self.memory_of(&voxmap, voxel_size, width, viewer);
        if est.total_bytes <= self.max_memory_bytes {
            return Ok(est);
        }
        let parts = [
            ("meshes read", est.meshes_read_bytes, "static"),
            ("placed copies", est.placed_copies_bytes, "static"),
            ("voxelizer", est.voxelizer_bytes, "voxels.voxel_size"),
            ("voxmap", est.voxmap_bytes, "voxels.voxel_size"),
            ("distance band", est.distance_band_bytes, "voxels.standoff"),
            ("exact reference", est.exact_reference_bytes, "static"),
            ("winding-number trees", est.winding_trees_bytes, "static"),
            ("point shell", est.shell_bytes, "part"),
            ("parts' voxmaps", est.part_voxmaps_bytes, "part"),
            ("viewer", est.viewer_bytes, "static"),
        ];
        let field = parts.iter().max_by_key(|p| p.1).map_or("static", |p| p.2);
        let listed: Vec<String> = parts
            .iter()
            .filter(|p| p.1 > 0)
            .map(|p| format!("{} {}", p.0, size_text(p.1)))
            .collect();
        Err(field_error(
            &self.label,
            field,
            format!(
                "at {} mm the scene needs an estimated {} of memory ({}), over the budget of {}: \
                 use a larger voxel_size, a [workspace], fewer or smaller meshes, or raise the \
                 budget with --max-memory (e.g. --max-memory {})",
                voxel_size * 1e3,
                size_text(est.total_bytes),
                listed.join(", "),
                budget_text(self.max_memory_bytes),
                raise_to(est.total_bytes)
            ),
        ))
    }

    /// Triangles the voxelizer's winding-number trees hold, at most: per static object, its
    /// mesh's [`SharedMesh::open_triangles`], all of them when a `[workspace]` may cut the object.
    fn winding_triangles(&self) -> u64 {
        let cut = self.file.workspace.is_some();
        self.statics
            .iter()
            .map(|o| {
                if cut {
                    o.triangles as u64
                } else {
                    self.meshes[o.mesh].open_triangles as u64
                }
            })
            .sum()
    }

    /// What the moving parts' own voxmaps keep (bytes, summed): every part's, the first
    /// included, in a scene of several parts; 0 for one part. Allocation-free; O(triangles of the
    /// parts).
    fn part_voxmaps_bytes(&self, voxel_size: f64, width: VoxelWidth) -> u64 {
        if self.more_parts.is_empty() {
            return 0;
        }
        let opts = vps_voxelize::VoxelizeOptions {
            workspace: None,
            ..self.voxelize_options(voxel_size, width)
        };
        let standoff = self.file.voxels.standoff_at(voxel_size);
        self.more_parts
            .iter()
            .map(|p| &p.mesh)
            .chain(std::iter::once(&self.part))
            .fold(0u64, |t, mesh| {
                t.saturating_add(part_voxmap_bytes(mesh, &opts, standoff))
            })
    }

    /// [`scene_memory`] for this scene and the voxmap estimate `voxmap`.
    fn memory_of(
        &self,
        voxmap: &VoxmapEstimate,
        voxel_size: f64,
        width: VoxelWidth,
        viewer: bool,
    ) -> SceneMemoryEstimate {
        let read = self.meshes.iter().fold(mesh_bytes(&self.part), |t, m| {
            t.saturating_add(mesh_bytes(&m.mesh))
        });
        let placed = self.statics.iter().fold(0u64, |t, o| {
            t.saturating_add(mesh_bytes(&self.meshes[o.mesh].mesh))
        });
        let inputs = SceneMemoryInputs {
            meshes_read_bytes: read,
            placed_copies_bytes: placed,
            placed_triangles: self.scene_triangles() as u64,
            winding_triangles: self.winding_triangles(),
            // Every moving part's shell.
            part_area_m2: self
                .more_parts
                .iter()
                .fold(self.part.area(), |a, p| a + p.mesh.area()),
            standoff_m: self.file.voxels.standoff_at(voxel_size),
            viewer,
            part_voxmaps_bytes: self.part_voxmaps_bytes(voxel_size, width),
        };
        scene_memory(&inputs, voxmap, voxel_size, width)
    }

    /// The voxmap width the scene declares.
    pub fn width(&self) -> Result<VoxelWidth, SceneError> {
        self.file.width(&self.label)
    }

    /// The voxelizer's options at `voxel_size` (m) and `width`: the scene's offset layers and its
    /// workspace region (only that region is voxelized) when it declares one.
    pub fn voxelize_options(&self, voxel_size: f64, width: VoxelWidth) -> VoxelizeOptions {
        VoxelizeOptions {
            voxel_size,
            offset_layers: self.file.voxels.offset_layers,
            width,
            workspace: self.file.workspace.as_ref().map(|r| r.aabb()),
            max_memory_bytes: self.max_memory_bytes,
            ..VoxelizeOptions::default()
        }
    }

    /// The estimated voxmap at `voxel_size` (m) and `width`; errors (naming `voxels.voxel_size`)
    /// when it exceeds [`VOXMAP_MEMORY_BUDGET`] or the voxelizer's grid limit. Allocation-free.
    pub fn plan_voxmap(
        &self,
        voxel_size: f64,
        width: VoxelWidth,
    ) -> Result<VoxmapEstimate, SceneError> {
        let est = estimate_triangles(
            self.static_bounds(),
            self.static_triangles(),
            &self.voxelize_options(voxel_size, width),
            TreeConfig::default(),
        );
        let gib = |b: f64| b / 1024f64.powi(3);
        if est.tree_bytes > VOXMAP_MEMORY_BUDGET || est.grid_voxels > MAX_GRID_VOXELS {
            let mut hint = if self.file.workspace.is_some() {
                "use a larger voxel_size or a smaller [workspace]".to_string()
            } else {
                "use a larger voxel_size, or declare a [workspace] region (min, max in m) the part \
                 can reach so only that region is voxelized"
                    .to_string()
            };
            // A CAD file in mm read as metres is the likelier cause: name the largest object
            // left in metres.
            let largest_in_metres = self
                .file
                .objects
                .iter()
                .zip(&self.statics)
                .enumerate()
                .filter(|(_, (o, _))| {
                    o.units == crate::file::Units::Metres && !o.source.starts_with("builtin:")
                })
                .map(|(i, (_, placed))| (i, placed.bounds.size().max_element()))
                .max_by(|a, b| a.1.total_cmp(&b.1));
            if largest_in_metres.is_none() {
                if let Some(finest) = self.finest_voxel_size(voxel_size, width) {
                    hint = format!(
                        "{hint}; for this scene{} the finest voxel_size within the limits is \
                         about {}",
                        if self.file.workspace.is_some() {
                            " and workspace"
                        } else {
                            ""
                        },
                        crate::length::millimetres_rounded_up(finest)
                    );
                }
            }
            if let Some((i, size)) = largest_in_metres {
                hint = format!(
                    "static[{i}] is {size:.4} m across read as metres (its `units` is m, the \
                     default): if the file is in millimetres set `units = \"mm\"` there (cm, in \
                     likewise); else {hint}"
                );
            }
            return Err(field_error(
                &self.label,
                "voxels.voxel_size",
                format!(
                    "at {voxel_size} m the voxmap is estimated at {:.3e} grid voxels and {:.1} GiB \
                     of tree; the limits are {MAX_GRID_VOXELS:.3e} voxels and {:.0} GiB: {hint}",
                    est.grid_voxels,
                    gib(est.tree_bytes),
                    gib(VOXMAP_MEMORY_BUDGET)
                ),
            ));
        }
        Ok(est)
    }

    /// The smallest voxel size (m), to about 1 %, above `too_fine` whose estimated voxmap is within
    /// the limits of [`LoadedScene::plan_voxmap`]; `None` when none up to 10 m is. Setup-time:
    /// a few dozen estimates.
    pub fn finest_voxel_size(&self, too_fine: f64, width: VoxelWidth) -> Option<f64> {
        let fits = |s: f64| {
            let est = estimate_triangles(
                self.static_bounds(),
                self.static_triangles(),
                &self.voxelize_options(s, width),
                TreeConfig::default(),
            );
            est.tree_bytes <= VOXMAP_MEMORY_BUDGET && est.grid_voxels <= MAX_GRID_VOXELS
        };
        let (mut low, mut high) = (too_fine, too_fine);
        while !fits(high) {
            low = high;
            high *= 2.0;
            if high > 10.0 {
                return None;
            }
        }
        while high / low > 1.01 {
            let mid = (low * high).sqrt();
            if fits(mid) {
                high = mid;
            } else {
                low = mid;
            }
        }
        Some(high)
    }

    /// The static scene's voxmap at `voxel_size` (m) and `width`, from the cache when it holds
    /// one for exactly these inputs, else voxelized (and stored in the cache). Says on stderr which
    /// happened. Checks the plan against the budget first. Blocking, parallel, allocates the tree.
    pub fn build_voxmap(
        &self,
        voxel_size: f64,
        width: VoxelWidth,
        cache: &CachePolicy,
        progress: bool,
    ) -> Result<BuiltVoxmap> {
        self.memory_estimate(voxel_size, width, false)?;
        let objects = self.placed_statics();
        self.build_voxmap_of(&objects, voxel_size, width, cache, progress)
    }

    /// [`LoadedScene::build_voxmap`] of `objects`, the static objects placed, once the memory
    /// estimate has been checked.
    fn build_voxmap_of(
        &self,
        objects: &[TriMesh],
        voxel_size: f64,
        width: VoxelWidth,
        cache: &CachePolicy,
        progress: bool,
    ) -> Result<BuiltVoxmap> {
        let opts = VoxelizeOptions {
            progress,
            ..self.voxelize_options(voxel_size, width)
        };
        self.build_voxmap_with(objects, opts, cache, "voxmap")
    }

    /// A voxmap of `objects` (m) with the voxelizer's options `opts` and the scene's distance
    /// band when its force model has one, from `cache` when there. Blocking, parallel, allocates.
    pub(crate) fn build_voxmap_with(
        &self,
        objects: &[TriMesh],
        opts: VoxelizeOptions,
        cache: &CachePolicy,
        what: &str,
    ) -> Result<BuiltVoxmap> {
        let (voxel_size, width) = (opts.voxel_size, opts.width);
        let t = Instant::now();
        let standoff = self.file.voxels.standoff_at(voxel_size);
        let cached_at = match cache {
            CachePolicy::Dir(dir) => {
                let key = with_band_key(cache_key(objects, &opts, TreeConfig::default()), standoff);
                let expected = Expected {
                    spec: tree_grid(objects, &opts).with_context(|| {
                        format!("{}: the grid at {} mm", self.label, voxel_size * 1e3)
                    })?,
                    width: opts.width,
                    config: TreeConfig::default(),
                    key: key.clone(),
                    standoff_m: standoff,
                };
                Some((cache_path(dir, &key), expected))
            }
            CachePolicy::Off => None,
        };
        if let Some((path, expected)) = &cached_at {
            if let Some(tree) = read_cached(path, expected) {
                eprintln!("{what}: loaded from cache {}", path.display());
                return Ok(BuiltVoxmap {
                    tree: Arc::new(tree),
                    voxelize_ms: t.elapsed().as_secs_f64() * 1e3,
                    origin: VoxmapOrigin::Cache(path.clone()),
                });
            }
        }
        let voxelizing = || {
            format!(
                "{}: voxelizing at {} mm, {}-bit",
                self.label,
                voxel_size * 1e3,
                width.bits()
            )
        };
        let tree = match standoff {
            None => {
                voxelize_tree(objects, &opts, TreeConfig::default())
                    .with_context(voxelizing)?
                    .0
            }
            Some(standoff) => {
                // The band takes its signs from the voxelization's own inside map.
                let (tree, _, inside) =
                    voxelize_tree_keeping_inside(objects, &opts, TreeConfig::default())
                        .with_context(voxelizing)?;
                let (band, _) = distance_band_with_inside(
                    &tree,
                    &inside,
                    objects,
                    standoff,
                    opts.max_memory_bytes,
                )
                .map_err(|e| field_error(&self.label, "voxels.standoff", e.to_string()))?;
                tree.with_distance_band(band)
            }
        };
        let voxelize_ms = t.elapsed().as_secs_f64() * 1e3;
        let origin = match cached_at {
            Some((path, expected)) => match write_cached(&path, &expected.key, &tree) {
                Ok(()) => {
                    eprintln!("{what}: built, cached at {}", path.display());
                    VoxmapOrigin::Cache(path)
                }
                Err(err) => {
                    eprintln!(
                        "{what}: built; could not cache it at {}: {err}",
                        path.display()
                    );
                    VoxmapOrigin::Built
                }
            },
            None => {
                eprintln!("{what}: built (cache off)");
                VoxmapOrigin::Built
            }
        };
        Ok(BuiltVoxmap {
            tree: Arc::new(tree),
            voxelize_ms,
            origin,
        })
    }

    /// The grip (m, part coordinates): the scene's `part.grip`, else the centre of mass of
    /// `shell`'s mesh.
    pub fn grip(&self, shell: &PointShell) -> DVec3 {
        self.file
            .part
            .grip
            .map_or(shell.mass.center_of_mass, DVec3::from_array)
    }

    /// The part's point shell at `voxel_size` (m) with `method`, in the grip's frame: its origin is
    /// the grip (the centre of mass unless the scene gives `part.grip`). Blocking, allocates.
    /// A two-sided part's points ([`LoadedScene::part_two_sided`], with the distance model)
    /// carry zero normals.
    pub fn build_shell(&self, voxel_size: f64, method: ShellMethod) -> Result<PointShell> {
        let (mut shell, _) =
            crate::parts::grip_frame_shell(&self.part, self.file.part.grip, voxel_size, method)
                .with_context(|| format!("{}: building the part's point shell", self.label))?;
        if self.shell_two_sided() {
            two_sided(&mut shell);
        }
        Ok(shell)
    }

    /// Whether the part's shell is built two-sided: a part with no inside
    /// ([`LoadedScene::part_two_sided`]) under the distance force model.
    fn shell_two_sided(&self) -> bool {
        self.part_two_sided && self.file.voxels.force_model == ForceModelName::Distance
    }

    /// The part's mesh in the frame of a shell built by [`LoadedScene::build_shell`] (m).
    pub fn part_in_shell_frame(&self, shell: &PointShell) -> TriMesh {
        let grip = self.grip(shell);
        let mut mesh = self.part.clone();
        mesh.vertices.iter_mut().for_each(|v| *v -= grip);
        mesh
    }

    /// The hand's path as declared: a corridor (with detours) or a plain path.
    pub fn hand(&self) -> HandPlan {
        if let Some(h) = &self.file.hand {
            return HandPlan::Path {
                waypoints: h.waypoints.iter().map(|w| DVec3::from_array(*w)).collect(),
                speed: h.speed,
                hold: h.hold_s,
            };
        }
        let c = self.file.corridor.as_ref();
        HandPlan::Corridor {
            waypoints: self.file.corridor_waypoints(),
            reach: c.map_or(crate::file::DEFAULT_DETOUR_REACH, |c| c.reach),
            laps: c.map_or(1, |c| c.laps),
        }
    }

    /// Haptic parameters for a voxmap of `voxel_size` (m) and `shell`, validated.
    pub fn params_for(&self, voxel_size: f64, shell: &PointShell) -> Result<HapticParams> {
        Ok(self.params.with_scene(voxel_size, shell.max_radius())?)
    }

    /// Builds the session: voxmap (`options.voxel_size` or the scene's), shell, parameters, hand
    /// and meshes. Blocking, parallel, allocates.
    pub fn build(mut self, options: &BuildOptions) -> Result<SessionAssets> {
        self.max_memory_bytes = options.max_memory_bytes.unwrap_or(self.max_memory_bytes);
        let voxel_size = options.voxel_size.unwrap_or(self.file.voxels.voxel_size);
        let method = options
            .shell_method
            .unwrap_or(self.file.voxels.shell_method.method());
        let width = self.width()?;
        self.memory_estimate(voxel_size, width, options.viewer)?;
        let objects = self.placed_statics();
        let map = self.build_voxmap_of(
            &objects,
            voxel_size,
            width,
            &options.cache,
            options.progress,
        )?;
        let shell = self.build_shell(voxel_size, method)?;
        let params = self.params_for(voxel_size, &shell)?;
        let part_mesh = self.part_in_shell_frame(&shell);
        let hand = self.hand();
        let scene_triangles = self.scene_triangles();
        let static_names = object_names(&self.static_sources);
        let shell_two_sided = self.shell_two_sided();
        let more_parts = self.build_more_parts(voxel_size, method, width, &options.cache)?;
        let part_body = if more_parts.is_empty() {
            None
        } else {
            Some(self.build_body(
                &self.part_name,
                &part_mesh,
                voxel_size,
                width,
                &options.cache,
            )?)
        };
        let pair_margin = crate::parts::pair_margin(voxel_size, self.file.voxels.offset_layers);
        Ok(SessionAssets {
            name: self.name,
            label: self.label,
            voxel_size,
            tree: map.tree,
            voxelize_ms: map.voxelize_ms,
            voxmap_origin: map.origin,
            shell: PartShell::new(shell),
            params,
            device: self.device,
            bridge: self.bridge,
            hand,
            scene_triangles,
            static_meshes: objects,
            static_names,
            part_mesh,
            shell_two_sided,
            part_name: self.part_name,
            part_body,
            more_parts,
            pair_margin,
        })
    }
}

/// Gives every point of `shell` a zero normal: the points of a part with no inside have no side
/// of their own, and the distance force model then pushes each along the scene's own surface
/// normal, from either side (where it needs the point's normal, deeper than the band or where the
/// scene's gradient vanishes, a zero normal gives no push rather than a pull).
fn two_sided(shell: &mut PointShell) {
    shell.normals.iter_mut().for_each(|n| *n = Vec3::ZERO);
}

/// The error of a mesh that did not load, for `field` (`static[i].source`, `part.source`) of the
/// scene file `label`: the loader's causes, each once; when the file is missing, where a relative
/// `written` source was looked for.
fn mesh_error(
    label: &str,
    field: &str,
    written: &str,
    base: &Path,
    err: &anyhow::Error,
) -> SceneError {
    let mut text = crate::error::error_chain_text(err);
    let missing = err.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::NotFound)
    });
    if missing && !written.starts_with("builtin:") && Path::new(written).is_relative() {
        let dir = if base.as_os_str().is_empty() {
            Path::new(".")
        } else {
            base
        };
        text.push_str(&format!(
            " (`{written}` is taken relative to the scene file's directory, {})",
            dir.display()
        ));
    }
    // The source is the scene file's text: it may hold control characters or line breaks.
    field_error(label, field, vps_files::printable(&text).into_owned())
}

/// The key of a mesh source in a scene's mesh table: `builtin:NAME`, else the file's canonical
/// path (links and `./` resolved), else (a file that cannot be resolved, whose load then fails)
/// the path as resolved against the scene's directory.
fn mesh_key(resolved: &str) -> String {
    if resolved.starts_with("builtin:") {
        return resolved.to_string();
    }
    std::fs::canonicalize(resolved)
        .map_or_else(|_| resolved.to_string(), |p| p.display().to_string())
}

/// A budget for a message, saying where it came from when it is the default.
fn budget_text(budget: u64) -> String {
    if budget == vps_voxelize::default_memory_budget() {
        format!("{} (half of this machine's memory)", size_text(budget))
    } else {
        format!("{} (--max-memory)", size_text(budget))
    }
}

/// A `--max-memory` value (whole GiB) that holds `bytes`.
fn raise_to(bytes: u64) -> String {
    format!("{}GiB", bytes.div_ceil(1 << 30).max(1))
}

/// Refuses a part (`field`) larger than the whole scene: a mistake of units, and its shell and
/// voxmap would be sized by it.
fn check_part_fits(label: &str, field: &str, part_size: DVec3, scene_size: DVec3) -> Result<()> {
    if part_size.length() > scene_size.length() {
        return Err(field_error(
            label,
            field,
            format!(
                "the part ({}) is larger than the whole scene ({}); check `units` of the part \
                 and of the [[static]] objects (m, cm, mm, in)",
                fmt_size(part_size),
                fmt_size(scene_size)
            ),
        )
        .into());
    }
    Ok(())
}

fn fmt_size(v: DVec3) -> String {
    format!("{:.4} × {:.4} × {:.4} m", v.x, v.y, v.z)
}

/// The scene's haptic parameters: `[haptic]` inline keys or `file = ...`, then `voxels.braking`.
fn scene_params(file: &SceneFile, label: &str, base: &Path) -> Result<HapticParams> {
    let mut params = match &file.haptic {
        None => HapticParams::default(),
        Some(table) => match table.get("file") {
            Some(toml::Value::String(f)) if table.len() == 1 => {
                let path = base.join(f);
                HapticParams::from_file(&path)
                    .map_err(|e| field_error(label, "haptic.file", e.to_string()))?
            }
            Some(_) => {
                return Err(field_error(
                    label,
                    "haptic.file",
                    "must be a file name (a string) and the only key of [haptic]",
                )
                .into())
            }
            None => {
                let text = toml::to_string(table).context("re-encoding [haptic]")?;
                HapticParams::from_toml_str(&text, "[haptic]").map_err(|e| match e {
                    vps_haptic::ParamsError::Invalid {
                        field,
                        value,
                        reason,
                        ..
                    } => field_error(
                        label,
                        &format!("haptic.{field}"),
                        format!("{value}: {reason}"),
                    ),
                    other => field_error(label, "haptic", other.to_string()),
                })?
            }
        },
    };
    if let Some(braking) = file.voxels.braking {
        params.braking = braking;
    }
    Ok(params)
}

/// Where a session's voxmap came from.
#[derive(Clone, Debug, PartialEq)]
pub enum VoxmapOrigin {
    /// Voxelized now and not cached.
    Built,
    /// Loaded from, or voxelized and written to, this cache file.
    Cache(PathBuf),
}

/// A static scene's voxmap and what building it cost.
pub struct BuiltVoxmap {
    /// The voxmap.
    pub tree: Arc<VoxelTree>,
    /// Wall time of voxelization and tree build, or of the cache read (ms).
    pub voxelize_ms: f64,
    /// Built or cached.
    pub origin: VoxmapOrigin,
}

/// Settings of [`LoadedScene::build`] that are not in the scene file.
#[derive(Clone, Debug)]
pub struct BuildOptions {
    /// Voxel size (m) instead of the scene's `voxels.voxel_size`.
    pub voxel_size: Option<f64>,
    /// Shell method instead of the scene's `voxels.shell_method`.
    pub shell_method: Option<ShellMethod>,
    /// Where cached voxmaps live.
    pub cache: CachePolicy,
    /// Show the voxelizer's progress bar (on a terminal).
    pub progress: bool,
    /// Whether a viewer will draw the meshes (its copies count in the memory estimate).
    pub viewer: bool,
    /// The memory budget (bytes) of the whole scene's estimate and of the voxelizer
    /// (`--max-memory`); `None`: half of physical memory.
    pub max_memory_bytes: Option<u64>,
}

impl Default for BuildOptions {
    /// The scene's own settings, the cache from the environment, a progress bar.
    fn default() -> Self {
        BuildOptions {
            voxel_size: None,
            shell_method: None,
            cache: CachePolicy::from_env(),
            progress: true,
            viewer: false,
            max_memory_bytes: None,
        }
    }
}

/// Everything built once from a scene file that sessions run with: the voxmap, the part's point
/// shell, the haptic parameters, the device choice and the hand's motion (plus the meshes, for a
/// viewer). Many sessions may run on one `SessionAssets`; [`SessionAssets::plan`] plans one.
#[derive(Clone)]
pub struct SessionAssets {
    /// The scene's name.
    pub name: String,
    /// The scene file's path, or `builtin:NAME`.
    pub label: String,
    /// Voxel size of the voxmap and the shell (m).
    pub voxel_size: f64,
    /// The static scene's voxmap.
    pub tree: Arc<VoxelTree>,
    /// Voxelization (or cache read) wall time (ms).
    pub voxelize_ms: f64,
    /// Where the voxmap came from.
    pub voxmap_origin: VoxmapOrigin,
    /// The first part's point shell and its classes; its origin is the grip.
    pub shell: PartShell,
    /// Haptic parameters for this voxmap and shell, validated.
    pub params: HapticParams,
    /// The scene's default device.
    pub device: DeviceChoice,
    /// How the bridge is set up when it drives the session: the scene's `[device]` settings,
    /// which a caller may override (command-line flags) before [`SessionAssets::plan`].
    pub bridge: BridgeSettings,
    /// How the simulated hand moves.
    pub hand: HandPlan,
    /// Triangles in the static scene.
    pub scene_triangles: usize,
    /// The static meshes, placed (m, scene coordinates): for a viewer and a study.
    pub static_meshes: Vec<TriMesh>,
    /// A name per static object, in file order ([`object_names`]): for reports.
    pub static_names: Vec<String>,
    /// The part's mesh in the shell's frame (m; origin at the grip): for a viewer.
    pub part_mesh: TriMesh,
    /// Whether the shell's points carry zero normals: a part with no inside under the distance
    /// force model ([`LoadedScene::part_two_sided`]); a resampled shell keeps it.
    pub shell_two_sided: bool,
    /// The first part's name in reports.
    pub part_name: String,
    /// The first part's voxmap in its grip frame, built only when the scene has other parts.
    pub part_body: Option<Arc<VoxelTree>>,
    /// The moving parts after the first (empty: a one-part scene).
    pub more_parts: Vec<PartAssets>,
    /// The broad phase's margin between two parts' bounding spheres (m).
    pub pair_margin: f64,
}

impl SessionAssets {
    /// Loads and builds `scene` (`builtin:NAME` or a file) with `options`.
    pub fn open(scene: &str, options: &BuildOptions) -> Result<SessionAssets> {
        let budget = options
            .max_memory_bytes
            .unwrap_or_else(vps_voxelize::default_memory_budget);
        Self::from_loaded(LoadedScene::load_within(scene, budget)?, options)
    }

    /// Builds `loaded` with `options`, printing its warnings to stderr first.
    pub fn from_loaded(loaded: LoadedScene, options: &BuildOptions) -> Result<SessionAssets> {
        loaded.print_warnings();
        let assets = loaded.build(options)?;
        if let Some(w) = coarse_voxel_flag(assets.voxel_size, &assets.part_mesh, assets.shell.len())
        {
            eprintln!("{}: warning: {w}", assets.label);
        }
        Ok(assets)
    }

    /// The scene's script for the simulated hand.
    pub fn script(&self) -> Result<Script> {
        self.hand.script(&self.tree)
    }

    /// Replaces the shell with one of about `points` points (a surface's point count scales as
    /// 1/s², so the shell's voxel size is chosen from the current shell), in the same grip frame,
    /// and the parameters with ones for its bounding radius; returns the voxel size it was sampled
    /// at (m). Lets benchmarks buy point count independently of scene memory. Blocking, parallel,
    /// allocates.
    pub fn resample_shell(&mut self, points: usize, method: ShellMethod) -> Result<f64> {
        let coarse = self.shell.len().max(1) as f64;
        let shell_voxel = self.voxel_size * (coarse / points.max(1) as f64).sqrt();
        let mut shell = point_shell(&self.part_mesh, shell_voxel, method)
            .with_context(|| format!("{}: resampling the part's point shell", self.label))?;
        if self.shell_two_sided {
            two_sided(&mut shell);
        }
        // `part_mesh` has its origin at the grip: points relative to its centre of mass move to
        // the grip frame by that centre.
        let shift: Vec3 = shell.mass.center_of_mass.as_vec3();
        shell.points.iter_mut().for_each(|p| *p += shift);
        self.params = self
            .params
            .with_scene(self.voxel_size, shell.max_radius())?;
        self.shell = PartShell::new(shell);
        Ok(shell_voxel)
    }

    /// The scene's script for the simulated hand, its laps repeated to last `frames` frames.
    pub fn script_for_frames(&self, frames: u64) -> Result<Script> {
        self.hand
            .script_covering(&self.tree, frames as f64 * self.params.dt)
    }

    /// The first part's shell split into [`crate::CLASS_COUNT`] classes (built once, shared).
    pub fn classed_shell(&self) -> Arc<vps_haptic::ClassedShell> {
        self.shell.classed()
    }

    /// The first moving part: the session's own shell, mesh, parameters and hand.
    pub fn first_part(&self) -> PartView<'_> {
        PartView {
            name: &self.part_name,
            mesh: &self.part_mesh,
            shell: self.shell.points(),
            params: &self.params,
            hand: &self.hand,
        }
    }

    /// Moving part `k` (0 the first, then `more_parts` in order); `None` past the last.
    pub fn part(&self, k: usize) -> Option<PartView<'_>> {
        match k.checked_sub(1) {
            None => Some(self.first_part()),
            Some(k) => self.more_parts.get(k).map(|p| PartView {
                name: &p.name,
                mesh: &p.mesh,
                shell: p.shell.points(),
                params: &p.params,
                hand: &p.hand,
            }),
        }
    }

    /// Every moving part's name, the first first. Allocates.
    pub fn part_names(&self) -> Vec<String> {
        (0..=self.more_parts.len())
            .filter_map(|k| self.part(k))
            .map(|p| p.name.to_string())
            .collect()
    }
}

/// One moving part of a session's scene as reports, studies and the viewer see it, the first
/// ([`SessionAssets::first_part`]) like the others ([`SessionAssets::part`]).
#[derive(Clone, Copy)]
pub struct PartView<'a> {
    /// Its name in reports.
    pub name: &'a str,
    /// Its mesh in its grip frame (m).
    pub mesh: &'a TriMesh,
    /// Its point shell in its grip frame.
    pub shell: &'a PointShell,
    /// Its haptic parameters as the scene gives them.
    pub params: &'a HapticParams,
    /// Its hand's path: where it starts and, for the simulated hand, where it goes.
    pub hand: &'a HandPlan,
}

/// The cache key of a voxmap that also carries a distance band with stand-off `standoff` (m): the
/// voxmap's key hashed with the stand-off's bits; the voxmap's own key when there is no band.
fn with_band_key(key: String, standoff: Option<f64>) -> String {
    match standoff {
        None => key,
        Some(standoff) => {
            let mut h = blake3::Hasher::new();
            h.update(key.as_bytes());
            h.update(b"distance-band-1");
            h.update(&standoff.to_bits().to_le_bytes());
            h.finalize().to_hex().to_string()
        }
    }
}

impl LoadedScene {
    /// A part's voxmap in its grip frame (`mesh` already moved there) at the scene's voxel
    /// settings, with the scene's distance band when the force model has one; never cut by the
    /// workspace. Cached like the scene's voxmap; `name` (the part's) labels what is printed.
    /// Blocking, parallel, allocates.
    pub(crate) fn build_body(
        &self,
        name: &str,
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
            .build_voxmap_with(
                std::slice::from_ref(mesh),
                opts,
                cache,
                &format!("the voxmap of part '{name}'"),
            )?
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
                    format!(
                        "{}: building the point shell of part '{}'",
                        self.label, p.name
                    )
                })?;
            let mut mesh = p.mesh.clone();
            mesh.vertices.iter_mut().for_each(|v| *v -= grip);
            let body = self
                .build_body(&p.name, &mesh, voxel_size, width, cache)
                .with_context(|| format!("{}: the voxmap of part '{}'", self.label, p.name))?;
            built.push(PartAssets {
                name: p.name.clone(),
                params: self.params.with_scene(voxel_size, shell.max_radius())?,
                radius: body_radius(&mesh, &shell),
                shell: PartShell::new(shell),
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

#[cfg(test)]
mod tests {
    use super::*;
    use vps_testkit::obj::box_obj;

    /// A scene directory holding `fixture.obj` (200 × 200 × 40) and `peg.obj` (20 × 20 × 60), both
    /// in millimetres, and `scene.toml` made of `statics` then a hand path.
    fn scene_dir(statics: &str) -> (tempfile::TempDir, String) {
        let dir = tempfile::tempdir().unwrap();
        let write = |name: &str, text: &str| std::fs::write(dir.path().join(name), text).unwrap();
        write(
            "fixture.obj",
            &box_obj([-100.0, -100.0, 0.0], [100.0, 100.0, 40.0]),
        );
        write("peg.obj", &box_obj([-10.0, -10.0, 0.0], [10.0, 10.0, 60.0]));
        let scene = format!(
            "[part]\nsource = \"peg.obj\"\nunits = \"mm\"\n{statics}\
             [voxels]\nvoxel_size = \"2mm\"\n[hand]\nwaypoints = [[0.0, 0.0, 0.1]]\n"
        );
        write("scene.toml", &scene);
        let path = dir.path().join("scene.toml").display().to_string();
        (dir, path)
    }

    /// A part with no inside (one triangle) is rendered two-sided: on the distance model (the
    /// default) as it is, and a scene that asks for the tangent-plane model switches to the
    /// distance model with a warning; and its shell's normals are all
    /// zero (a resampled shell's too); the peg (a closed box) keeps the scene's model and unit
    /// normals.
    #[test]
    fn a_part_with_no_inside_gets_a_two_sided_shell_and_the_distance_model() {
        let (dir, scene) = scene_dir("[[static]]\nsource = \"fixture.obj\"\nunits = \"mm\"\n");
        std::fs::write(
            dir.path().join("sheet.obj"),
            "v -20 -20 0\nv 30 -20 0\nv -20 30 0\nf 1 2 3\n",
        )
        .unwrap();
        // With the built-in default, the distance model, the sheet needs no switch.
        let text = std::fs::read_to_string(&scene).unwrap();
        let sheet_scene = dir.path().join("sheet.toml");
        std::fs::write(&sheet_scene, text.replace("peg.obj", "sheet.obj")).unwrap();
        let sheet = LoadedScene::load(sheet_scene.to_str().unwrap()).unwrap();
        assert!(sheet.part_two_sided && !sheet.force_model_switched);
        assert_eq!(sheet.file.voxels.force_model, ForceModelName::Distance);
        assert!(sheet
            .warnings
            .iter()
            .all(|w| !w.starts_with("voxels.force_model")));

        // A scene that asks for the tangent-plane model.
        let text = text.replace(
            "voxel_size = \"2mm\"\n",
            "voxel_size = \"2mm\"\nforce_model = \"tangent-plane\"\n",
        );
        std::fs::write(&scene, &text).unwrap();
        std::fs::write(&sheet_scene, text.replace("peg.obj", "sheet.obj")).unwrap();

        let peg = LoadedScene::load(&scene).unwrap();
        assert!(!peg.part_two_sided);
        assert_eq!(peg.file.voxels.force_model, ForceModelName::TangentPlane);

        let sheet = LoadedScene::load(sheet_scene.to_str().unwrap()).unwrap();
        assert!(sheet.part_two_sided && sheet.force_model_switched);
        assert!(!peg.force_model_switched);
        assert_eq!(sheet.file.voxels.force_model, ForceModelName::Distance);
        assert!(
            sheet
                .warnings
                .iter()
                .any(|w| w.starts_with("voxels.force_model: the part") && w.contains("no inside")),
            "{:?}",
            sheet.warnings
        );
        let shell = sheet.build_shell(0.002, ShellMethod::ExactSurface).unwrap();
        assert!(shell.len() > 50, "{}", shell.len());
        assert!(shell.normals.iter().all(|n| *n == Vec3::ZERO));
        let peg_shell = peg.build_shell(0.002, ShellMethod::ExactSurface).unwrap();
        assert!(peg_shell
            .normals
            .iter()
            .all(|n| (n.length() - 1.0).abs() < 1e-3));
        // The shell file format carries zero normals (a cluster worker receives this shell).
        let mut bytes = Vec::new();
        vps_voxmap::file::write_shell(&shell, &mut bytes).unwrap();
        let back = vps_voxmap::file::read_shell(bytes.as_slice()).unwrap();
        assert_eq!(back.normals, shell.normals);
    }

    /// The memory estimate counts the moving parts' own voxmaps in a scene of several parts (the
    /// first part's and each other's, with their distance bands), and none for one part.
    #[test]
    fn the_estimate_counts_every_part_s_own_voxmap_in_a_scene_of_several() {
        let dir = tempfile::tempdir().unwrap();
        let hand = |side: f64| format!("[part.hand]\n{}\n", vps_testkit::parts::approach(side));
        let tail = "[voxels]\nvoxel_size = \"5 mm\"\n";
        let two =
            vps_testkit::parts::two_parts("source = \"builtin:sphere\"\nscale = 0.4", hand, tail);
        let path = dir.path().join("two.toml");
        std::fs::write(&path, two).unwrap();
        let scene = LoadedScene::load(&path.display().to_string()).unwrap();
        let width = scene.width().unwrap();
        let est = scene.memory_estimate(0.005, width, false).unwrap();
        let opts = vps_voxelize::VoxelizeOptions {
            workspace: None,
            ..scene.voxelize_options(0.005, width)
        };
        let standoff = scene.file.voxels.standoff_at(0.005);
        assert!(
            standoff.is_some(),
            "the distance model: each part's band counted"
        );
        let each =
            [&scene.part, &scene.more_parts[0].mesh].map(|m| part_voxmap_bytes(m, &opts, standoff));
        assert!(each.iter().all(|&b| b > 0), "{each:?}");
        assert_eq!(est.part_voxmaps_bytes, each[0] + each[1]);
        assert!(est.total_bytes >= est.part_voxmaps_bytes + est.voxmap_bytes);

        let (_dir, one) = scene_dir("[[static]]\nsource = \"fixture.obj\"\nunits = \"mm\"\n");
        let one = LoadedScene::load(&one).unwrap();
        let est = one.memory_estimate(0.002, width, false).unwrap();
        assert_eq!(est.part_voxmaps_bytes, 0);
    }

    /// The memory estimate counts the voxelizer's winding-number trees: none for the closed
    /// fixture, a tree of all ten triangles when one of its faces is left out, to the byte.
    #[test]
    fn the_estimate_counts_winding_number_trees_of_open_objects() {
        let (dir, scene) = scene_dir("[[static]]\nsource = \"fixture.obj\"\nunits = \"mm\"\n");
        let width = VoxelWidth::from_bits(2).unwrap();
        let closed = LoadedScene::load(&scene).unwrap();
        let est = closed.memory_estimate(0.002, width, false).unwrap();
        assert_eq!(est.winding_trees_bytes, 0);
        let open = box_obj([-100.0, -100.0, 0.0], [100.0, 100.0, 40.0]).replace("f 2 4 8 6\n", "");
        std::fs::write(dir.path().join("fixture.obj"), open).unwrap();
        let leaky = LoadedScene::load(&scene).unwrap();
        let est = leaky.memory_estimate(0.002, width, false).unwrap();
        assert_eq!(
            est.winding_trees_bytes,
            vps_reference::winding::WindingTree::estimated_bytes(10)
                + vps_reference::orient::estimated_bytes(10)
        );
        assert!(est.total_bytes > est.winding_trees_bytes);
    }

    /// A missing mesh says where a relative source was looked for, and the OS's reason once.
    #[test]
    fn a_missing_mesh_says_where_it_was_looked_for() {
        let (dir, scene) = scene_dir("[[static]]\nsource = \"meshes/fixture.obj\"\n");
        let err = LoadedScene::load(&scene).err().unwrap().to_string();
        let expected = format!(
            "(`meshes/fixture.obj` is taken relative to the scene file's directory, {})",
            dir.path().display()
        );
        assert!(err.contains("field `static[0].source`"), "{err}");
        assert!(err.contains(&expected), "{err}");
        assert_eq!(err.matches("os error 2").count(), 1, "{err}");
    }

    /// An absurdly fine voxel size (0.01 mm) was refused with the estimate and the limits but
    /// no figure to use instead; the error now gives the finest size within the limits for the
    /// scene, and that size (not a fifth less) is accepted.
    #[test]
    fn a_voxel_size_too_fine_names_the_finest_that_fits() {
        let (_dir, scene) = scene_dir("[[static]]\nsource = \"fixture.obj\"\nunits = \"mm\"\n");
        let loaded = LoadedScene::load(&scene).unwrap();
        let err = loaded
            .plan_voxmap(0.00001, VoxelWidth::Two)
            .unwrap_err()
            .to_string();
        let finest_mm: f64 = err
            .split("the finest voxel_size within the limits is about ")
            .nth(1)
            .and_then(|rest| rest.strip_suffix(" mm"))
            .and_then(|mm| mm.parse().ok())
            .unwrap_or_else(|| panic!("{err}"));
        assert!(loaded
            .plan_voxmap(finest_mm * 1e-3, VoxelWidth::Two)
            .is_ok());
        assert!(loaded
            .plan_voxmap(finest_mm * 0.8e-3, VoxelWidth::Two)
            .is_err());
    }

    /// CAD files in mm with `units` left out read as metres: the voxmap estimate is refused, and
    /// the error points at `units` before the voxel size or a workspace.
    #[test]
    fn a_voxmap_too_large_from_mm_read_as_metres_names_units() {
        let (_dir, scene) = scene_dir("[[static]]\nsource = \"fixture.obj\"\n");
        let loaded = LoadedScene::load(&scene).unwrap();
        let err = loaded
            .plan_voxmap(0.002, VoxelWidth::Two)
            .unwrap_err()
            .to_string();
        assert!(err.contains("field `voxels.voxel_size`"), "{err}");
        assert!(
            err.contains("static[0] is 200.0000 m across read as metres")
                && err.contains("set `units = \"mm\"` there"),
            "{err}"
        );
        // With the units declared the same scene fits, so no hint is needed.
        let (_dir, scene) = scene_dir("[[static]]\nsource = \"fixture.obj\"\nunits = \"mm\"\n");
        let loaded = LoadedScene::load(&scene).unwrap();
        assert!(loaded.plan_voxmap(0.002, VoxelWidth::Two).is_ok());
    }
}

#[cfg(test)]
mod device_settings_tests {
    use super::*;
    use vps_device::DeviceLimits;
    use vps_input::WorkspaceMapping;

    /// A scene file with every section a device test needs around it: the built-in rig (it has
    /// no `[device]` table, so a test appends one).
    const GOOD: &str = crate::file::BUILTIN_SCENES[1].1;

    fn parse(text: &str) -> Result<SceneFile, SceneError> {
        SceneFile::from_toml_str(text, "scene.toml")
    }

    #[test]
    fn the_base_scene_is_the_rig_and_has_no_device_table() {
        assert_eq!(crate::file::BUILTIN_SCENES[1].0, "rig-teapot");
        assert!(parse(GOOD).unwrap().device.is_none());
    }

    /// Two moving parts, the second on the bridge with too short a pose timeout.
    const TWO_PARTS_SHORT_TIMEOUT: &str = r#"
static = [{ source = "builtin:box" }]
[[part]]
source = "builtin:box"
hand = { waypoints = [[-0.06, 0.0, 0.0]] }
[[part]]
source = "builtin:sphere"
hand = { waypoints = [[0.06, 0.0, 0.0]] }
device = { kind = "bridge:127.0.0.1:7701", pose_timeout_ms = 1.0 }
"#;

    #[test]
    fn device_section_sets_up_the_bridge() {
        let text = format!(
            "{GOOD}\n[device]\nkind = \"bridge:127.0.0.1:7701\"\npose_timeout_ms = 200\n\
             [device.mapping]\nscale = 4.0\nrotate_deg = [0, 0, 90]\noffset = [0.1, 0.0, 0.1]\n"
        );
        let file = parse(&text).unwrap();
        let bridge = file
            .device
            .as_ref()
            .map(|d| crate::device::bridge_settings(d, "scene.toml", "device"))
            .unwrap()
            .unwrap();
        assert_eq!(bridge.pose_timeout, 0.2);
        assert_eq!(
            bridge.mapping,
            WorkspaceMapping {
                scale: 4.0,
                rotate_deg: [0.0, 0.0, 90.0],
                offset: [0.1, 0.0, 0.1],
                force_scale: 1.0,
            }
        );
        let plain = parse(&format!("{GOOD}\n[device]\nkind = \"sim\"\n")).unwrap();
        let defaults = plain
            .device
            .map(|d| crate::device::bridge_settings(&d, "scene.toml", "device"))
            .unwrap()
            .unwrap();
        assert_eq!(defaults, BridgeSettings::default());
        assert_eq!(defaults.limits, DeviceLimits::PAPER);
    }

    #[test]
    fn device_section_sets_the_wrench_limits_for_every_device() {
        let text =
            format!("{GOOD}\n[device]\nkind = \"sim\"\nmax_force = 8.0\nmax_torque = 0.05\n");
        let settings = parse(&text)
            .unwrap()
            .device
            .map(|d| crate::device::bridge_settings(&d, "scene.toml", "device"))
            .unwrap()
            .unwrap();
        assert_eq!(
            settings.limits,
            DeviceLimits {
                max_force: 8.0,
                max_torque: 0.05
            }
        );
        for (line, key) in [
            ("max_force = 0.0", "device.max_force"),
            ("max_force = 2e4", "device.max_force"),
            ("max_torque = -1.0", "device.max_torque"),
        ] {
            let text = format!("{GOOD}\n[device]\n{line}\n");
            let err = parse(&text)
                .and_then(|f| {
                    crate::device::bridge_settings(&f.device.unwrap(), "scene.toml", "device")
                })
                .unwrap_err()
                .to_string();
            assert!(err.contains(key) && err.contains("(0, "), "{line}: {err}");
        }
    }

    #[test]
    fn device_settings_out_of_range_are_refused_when_the_scene_is_loaded_naming_the_field() {
        // The schema (vps-scene-file) reads these; their ranges are the device layer's, checked
        // when the scene is loaded, before anything is built.
        let cases = [
            (
                format!("{GOOD}\n[device]\nkind = \"bridge\"\npose_timeout_ms = 0\n"),
                "`device.pose_timeout_ms`",
            ),
            (
                format!("{GOOD}\n[device]\nkind = \"bridge\"\n[device.mapping]\nscale = 0.0\n"),
                "`device.mapping.scale`",
            ),
            (
                format!("{GOOD}\n[device]\n[device.mapping]\nforce_scale = -1.0\n"),
                "`device.mapping.force_scale`",
            ),
            (
                format!("{GOOD}\n[device]\nmax_torque = -1.0\n"),
                "`device.max_torque`",
            ),
            (
                TWO_PARTS_SHORT_TIMEOUT.to_string(),
                "`part[1].device.pose_timeout_ms`",
            ),
        ];
        let dir = tempfile::tempdir().unwrap();
        for (k, (text, field)) in cases.iter().enumerate() {
            assert!(parse(text).is_ok(), "the schema refused case {k}");
            let path = dir.path().join(format!("scene{k}.toml"));
            std::fs::write(&path, text).unwrap();
            let err = LoadedScene::load(path.to_str().unwrap())
                .err()
                .unwrap_or_else(|| panic!("case {k} ({field}) was loaded"));
            let message = crate::error::error_chain_text(&err);
            assert!(
                message.contains(field) && message.contains("scene"),
                "{field} not named in: {message}"
            );
        }
    }
}
