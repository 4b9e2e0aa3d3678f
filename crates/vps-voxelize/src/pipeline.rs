//! The whole voxelization of a static scene (docs/architecture.md#voxmaps-and-point-shells): per object scan conversion and flood fill
//! in a window of the shared grid, merge by precedence, then Proximity and the force-layer offset
//! once on the merged result, written to a [`DenseGrid`].

use crate::bitgrid::BitGrid;
use crate::error::{VoxelizeError, MAX_SPARSE_VOXELS, MAX_VOXELS};
use crate::flood_fill::{flood_fill, flood_fill_filtered};
use crate::merge::{to_dense, MergedPlanes};
use crate::offset::{offset, Layers};
use crate::scan_convert::{scan_convert, Window};
use crate::sparse::InsideMap;
use crate::stats::VoxelizeStats;
use crate::winding::{split_open, Part, PartClass};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rayon::prelude::*;
use std::sync::{Mutex, PoisonError};
use std::time::Instant;
use vps_mesh::{Aabb, TriMesh};
use vps_voxmap::{DenseGrid, GridSpec, TreeConfig, VoxelTree, VoxelWidth};

/// Inputs of at least this many triangles or voxels get a progress bar when asked for.
const PROGRESS_MIN_TRIANGLES: usize = 100_000;
const PROGRESS_MIN_VOXELS: u64 = 10_000_000;

/// Workspace bytes per voxel, for the error message of an oversized grid: the one-byte dense grid
/// plus about seven bit planes alive at the peak.
const BYTES_PER_VOXEL_NUM: u64 = 15;
const BYTES_PER_VOXEL_DEN: u64 = 8;

/// Settings of [`voxelize`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VoxelizeOptions {
    /// Edge length of one voxel (m); positive and finite. Default 5 mm.
    pub voxel_size: f64,
    /// Force-layer offset `k` in voxel layers (docs/architecture.md#voxmaps-and-point-shells step 4); 0 keeps the scan-converted layer.
    /// Default 2.
    pub offset_layers: u32,
    /// Free voxels added around the scene's bounds by [`grid_for`]. The grid always gets at least
    /// `offset_layers + 2` (room for the grown layers, Proximity and a Free wall for the flood fill),
    /// so 0 means "automatic". Default 4.
    pub padding_voxels: u32,
    /// Show an indicatif progress bar on stderr for large inputs (hidden when stderr is not a
    /// terminal). Default false.
    pub progress: bool,
    /// Bits per voxel of the voxmap [`voxelize_tree`] builds: 2 (kinds only, the paper's format) or
    /// 4 / 8 (kinds plus distance layers, see [`vps_voxmap::LayeredVoxel`]). The dense functions
    /// ([`voxelize`] and friends) always return 2-bit kinds. Default 2.
    pub width: VoxelWidth,
    /// The region the dynamic part can reach (m). When set, only voxels overlapping it are
    /// voxelized: the grid is the scene's padded grid clipped to the voxels that overlap the
    /// workspace, voxels outside read Free, and triangles outside are never scan-converted.
    /// An object cut by the workspace boundary keeps its inside: on a cut side the flood fill is
    /// seeded only from wall voxels whose generalized winding number is below 0.5 (docs/voxelize.md,
    /// "Open and leaky meshes").
    /// Default `None` (the whole scene).
    pub workspace: Option<Aabb>,
    /// Working-memory budget (bytes). The voxelizer estimates its peak from the plan (grid,
    /// surface area, chunk counts; [`crate::memory`]) before computing anything and refuses a plan
    /// over the budget with [`VoxelizeError::OverMemoryBudget`]. Default
    /// [`crate::memory::default_memory_budget`]: half of physical memory.
    pub max_memory_bytes: u64,
}

impl Default for VoxelizeOptions {
    fn default() -> Self {
        Self {
            voxel_size: 0.005,
            offset_layers: 2,
            padding_voxels: 4,
            progress: false,
            width: VoxelWidth::Two,
            workspace: None,
            max_memory_bytes: crate::memory::default_memory_budget(),
        }
    }
}

impl VoxelizeOptions {
    /// The padding [`grid_for`] actually applies (voxels): `max(padding_voxels, offset_layers + 2)`.
    pub fn effective_padding(&self) -> u32 {
        self.padding_voxels
            .max(self.offset_layers.saturating_add(2))
    }
}

/// Checks a voxel size (m).
pub(crate) fn check_voxel_size(s: f64) -> Result<(), VoxelizeError> {
    if s.is_finite() && s > 0.0 {
        Ok(())
    } else {
        Err(VoxelizeError::InvalidVoxelSize { value: s })
    }
}

/// Checks grid dimensions against `limit` voxels and `i32` indexing.
fn check_dims(dims: [u64; 3], limit: u64) -> Result<(), VoxelizeError> {
    let voxels = dims.iter().fold(1u64, |a, &d| a.saturating_mul(d));
    if voxels > limit || dims.iter().any(|&d| d > i32::MAX as u64) {
        return Err(VoxelizeError::GridTooLarge {
            dims,
            voxels,
            bytes: voxels.saturating_mul(BYTES_PER_VOXEL_NUM) / BYTES_PER_VOXEL_DEN,
            limit,
        });
    }
    if dims.contains(&0) {
        return Err(VoxelizeError::InvalidGrid {
            reason: format!("dimension of zero voxels in {dims:?}"),
        });
    }
    Ok(())
}

/// The padded grid for a scene with world-space `bounds` (m): voxels of `opts.voxel_size`, origin on
/// a multiple of the voxel size (so grids built for different bounds share one lattice), and
/// [`VoxelizeOptions::effective_padding`] Free voxels beyond the bounds on every side.
///
/// Errors: invalid voxel size, empty or non-finite bounds, or a grid over [`MAX_VOXELS`].
pub fn grid_for(bounds: &Aabb, opts: &VoxelizeOptions) -> Result<GridSpec, VoxelizeError> {
    grid_for_limit(bounds, opts, MAX_VOXELS)
}

/// [`grid_for`] with a voxel-count limit.
fn grid_for_limit(
    bounds: &Aabb,
    opts: &VoxelizeOptions,
    limit: u64,
) -> Result<GridSpec, VoxelizeError> {
    let s = opts.voxel_size;
    check_voxel_size(s)?;
    if bounds.is_empty() || !bounds.min.is_finite() || !bounds.max.is_finite() {
        return Err(VoxelizeError::InvalidGrid {
            reason: format!("scene bounds {bounds:?} are empty or not finite"),
        });
    }
    let pad = opts.effective_padding() as f64;
    let lo = (bounds.min / s).floor() - DVec3::splat(pad);
    let hi = (bounds.max / s).floor() + DVec3::splat(pad);
    let span = hi - lo + DVec3::ONE;
    // Saturating float-to-int casts; absurd sizes are caught by check_dims.
    let dims = [span.x as u64, span.y as u64, span.z as u64];
    if opts.workspace.is_none() {
        check_dims(dims, limit)?;
    }
    Ok(GridSpec {
        origin: lo * s,
        voxel_size: s,
        dims: dims.map(|d| d as u32),
    })
}

/// Checks a grid given to [`voxelize_in`] against `limit` voxels.
fn check_spec(spec: &GridSpec, limit: u64) -> Result<(), VoxelizeError> {
    check_voxel_size(spec.voxel_size)?;
    if !spec.origin.is_finite() {
        return Err(VoxelizeError::InvalidGrid {
            reason: format!("origin {} is not finite", spec.origin),
        });
    }
    check_dims(spec.dims.map(|d| d as u64), limit)
}

/// `spec` clipped to the voxels that overlap `workspace` (m). Errors when they do not meet or the
/// workspace is empty or not finite.
pub fn clip_to_workspace(spec: &GridSpec, workspace: &Aabb) -> Result<GridSpec, VoxelizeError> {
    if workspace.is_empty() || !workspace.min.is_finite() || !workspace.max.is_finite() {
        return Err(VoxelizeError::InvalidOptions {
            reason: format!("workspace {workspace:?} is empty or not finite"),
        });
    }
    let s = spec.voxel_size;
    let lo = ((workspace.min - spec.origin) / s).floor();
    let hi = ((workspace.max - spec.origin) / s).floor();
    let mut first = [0u32; 3];
    let mut dims = [0u32; 3];
    for a in 0..3 {
        let n = spec.dims[a] as f64;
        let (l, h) = (lo[a].max(0.0), hi[a].min(n - 1.0));
        if l > h {
            return Err(VoxelizeError::InvalidOptions {
                reason: format!(
                    "workspace {workspace:?} does not overlap the scene's grid ({} .. {} m)",
                    spec.origin,
                    spec.max_corner()
                ),
            });
        }
        first[a] = l as u32;
        dims[a] = (h - l) as u32 + 1;
    }
    Ok(GridSpec {
        origin: spec.origin + glam::UVec3::from_array(first).as_dvec3() * s,
        voxel_size: s,
        dims,
    })
}

/// The grid [`voxelize_tree`] builds for `objects` and `opts` (the padded bounds of every object,
/// clipped to `opts.workspace`), computed without voxelizing: what a stored map of these inputs
/// must have (the voxmap cache checks it on load). Errors as [`voxelize_tree`]'s grid checks.
pub fn tree_grid(objects: &[TriMesh], opts: &VoxelizeOptions) -> Result<GridSpec, VoxelizeError> {
    check_voxel_size(opts.voxel_size)?;
    check_objects(objects)?;
    scene_grid(objects, opts, MAX_SPARSE_VOXELS)
}

/// The grid of a whole scene: [`grid_for`] its joint bounds, clipped to `opts.workspace`; at most
/// `limit` voxels after clipping.
fn scene_grid(
    objects: &[TriMesh],
    opts: &VoxelizeOptions,
    limit: u64,
) -> Result<GridSpec, VoxelizeError> {
    let bounds = objects
        .iter()
        .fold(Aabb::EMPTY, |b, m| b.union(&m.bounds()));
    let spec = grid_for_limit(&bounds, opts, limit)?;
    match &opts.workspace {
        None => Ok(spec),
        Some(ws) => {
            let clipped = clip_to_workspace(&spec, ws)?;
            check_spec(&clipped, limit)?;
            Ok(clipped)
        }
    }
}

/// Checks that every triangle of every object indexes existing, finite vertices.
pub(crate) fn check_objects(objects: &[TriMesh]) -> Result<(), VoxelizeError> {
    if objects.is_empty() {
        return Err(VoxelizeError::NoObjects);
    }
    for (object, mesh) in objects.iter().enumerate() {
        if mesh.triangles.is_empty() {
            return Err(VoxelizeError::EmptyObject { object });
        }
        for (triangle, tri) in mesh.triangles.iter().enumerate() {
            for &v in tri {
                let reason = match mesh.vertices.get(v as usize) {
                    None => format!(
                        "vertex index {v} out of range ({} vertices)",
                        mesh.vertices.len()
                    ),
                    Some(p) if !p.is_finite() => format!("vertex {v} = {p} is not finite"),
                    Some(_) => continue,
                };
                return Err(VoxelizeError::InvalidMesh {
                    object,
                    triangle,
                    reason,
                });
            }
        }
    }
    Ok(())
}

/// The window of `spec` an object with `bounds` needs: its voxels plus two on every side (one for
/// touching triangles, one Free wall for the flood fill), clipped to the grid, with the x start
/// rounded down to a multiple of 64 for word-wise merging. `None` when it misses the grid.
fn object_window(bounds: &Aabb, spec: &GridSpec) -> Option<Window> {
    let lo = ((bounds.min - spec.origin) / spec.voxel_size).floor() - DVec3::splat(2.0);
    let hi = ((bounds.max - spec.origin) / spec.voxel_size).floor() + DVec3::splat(2.0);
    let mut offset = [0usize; 3];
    let mut dims = [0usize; 3];
    for a in 0..3 {
        let n = spec.dims[a] as f64;
        if hi[a] < 0.0 || lo[a] >= n {
            return None;
        }
        let first = lo[a].max(0.0) as usize;
        let last = hi[a].min(n - 1.0) as usize;
        offset[a] = if a == 0 { first / 64 * 64 } else { first };
        dims[a] = last + 1 - offset[a];
    }
    Some(Window { offset, dims })
}

/// Progress bar over the pipeline's phases, or a hidden one.
fn progress_bar(show: bool, phases: usize) -> ProgressBar {
    if !show {
        return ProgressBar::hidden();
    }
    let bar = ProgressBar::with_draw_target(Some(phases as u64), ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("voxelize {bar:30} {pos}/{len} {msg} [{elapsed}]")
    {
        bar.set_style(style);
    }
    bar
}

/// Locks a mutex, ignoring poisoning (a panicking worker already aborts the whole call).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

fn ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// The Interior plane of one part over `window` given its Surface plane: the flood fill from the
/// window's walls for a closed part (walls cut by the grid seed only outside when `cut_aware`), the
/// winding number for an `open` part (see [`crate::winding`]).
fn interior_of(
    mesh: &TriMesh,
    open: bool,
    cut_aware: bool,
    spec: &GridSpec,
    window: &Window,
    surface: &BitGrid,
) -> BitGrid {
    let class = match cut_aware
        .then(|| PartClass::new(mesh, open, spec))
        .flatten()
    {
        Some(c) if c.open || c.is_cut() => c,
        _ => return flood_fill(surface),
    };
    let o = window.offset;
    let mut interior = if class.is_cut() {
        flood_fill_filtered(surface, |x, y, z| {
            class.may_seed([x + o[0], y + o[1], z + o[2]])
        })
    } else {
        flood_fill(surface)
    };
    if class.open {
        class.add_by_winding(surface, &mut interior, o);
    }
    interior
}

/// Voxelizes `objects` into disjoint planes over `spec` with `offset_layers` of offset. Inputs must
/// be checked. Shared by [`voxelize_in`] (`winding` true: open parts and cut windows use the
/// winding number, [`crate::winding`]) and the point shell (`winding` false: the plain flood fill).
pub(crate) fn voxelize_planes(
    objects: &[TriMesh],
    spec: &GridSpec,
    offset_layers: u32,
    progress: bool,
    winding: bool,
    stats: &mut VoxelizeStats,
) -> Layers {
    let dims = spec.dims.map(|d| d as usize);
    let triangles: usize = objects.iter().map(TriMesh::triangle_count).sum();
    let big = triangles >= PROGRESS_MIN_TRIANGLES || spec.voxel_count() >= PROGRESS_MIN_VOXELS;
    let bar = progress_bar(progress && big, objects.len() + 2);
    stats.objects = objects.len();
    stats.triangles = triangles;
    stats.dims = spec.dims;

    // Objects run in parallel (each also parallel inside its scan); at most one window per worker
    // thread is alive at a time. Phase times are summed over objects (CPU-like, may exceed wall).
    let merged = Mutex::new(MergedPlanes::new(dims));
    let phase_ms = Mutex::new([0.0f64; 3]);
    bar.set_message("objects: scan + fill");
    let parts = if winding {
        split_open(objects)
    } else {
        objects
            .iter()
            .map(|m| Part {
                mesh: std::borrow::Cow::Borrowed(m),
                open: false,
            })
            .collect()
    };
    parts.par_iter().for_each(|part| {
        let mesh: &TriMesh = &part.mesh;
        if let Some(window) = object_window(&mesh.bounds(), spec) {
            let t = Instant::now();
            let surface = scan_convert(mesh, spec, &window);
            let scan = ms(t);
            let t = Instant::now();
            let interior =
                interior_of(mesh, part.open && winding, winding, spec, &window, &surface);
            let fill = ms(t);
            let t = Instant::now();
            lock(&merged).add(&window, &interior, &surface);
            let merge = ms(t);
            let mut p = lock(&phase_ms);
            p[0] += scan;
            p[1] += fill;
            p[2] += merge;
        }
        bar.inc(1);
    });
    drop(parts);
    let [scan_ms, fill_ms, merge_ms] = *lock(&phase_ms);
    stats.scan_ms += scan_ms;
    stats.fill_ms += fill_ms;
    stats.merge_ms += merge_ms;
    let merged = merged.into_inner().unwrap_or_else(PoisonError::into_inner);
    bar.set_message("proximity + offset");
    let t = Instant::now();
    let (interior, surface) = merged.finish();
    let layers = offset(interior, surface, offset_layers);
    stats.offset_ms += ms(t);
    bar.inc(1);
    stats.interior_voxels = layers.interior.count();
    stats.surface_voxels = layers.surface.count();
    stats.proximity_voxels = layers.proximity.count();
    stats.free_voxels =
        spec.voxel_count() - stats.interior_voxels - stats.surface_voxels - stats.proximity_voxels;
    bar.finish_and_clear();
    layers
}

/// Voxelizes static `objects` into one voxmap on the padded grid [`grid_for`] their joint bounds.
///
/// Every mesh must already be in its final world pose (metres): the voxelizer does not transform,
/// and a rotated object voxelizes to a different shape. Meshes may be open or inconsistently
/// oriented: closed, consistently oriented components are flood-filled; the voxels the flood fill
/// reaches in the other components (through holes wider than a voxel) are Interior where their
/// generalized winding number is at least 0.5 (docs/voxelize.md, "Open and leaky meshes"). Each
/// object is scan-converted and flood-filled on its own, the objects are combined with the precedence of
/// [`vps_voxmap::Voxel::merge`], then Proximity and the `opts.offset_layers` force-layer offset are
/// computed once on the merged result. Blocking, parallel (rayon), allocates about 1.9 bytes per
/// voxel at the peak.
pub fn voxelize(objects: &[TriMesh], opts: &VoxelizeOptions) -> Result<DenseGrid, VoxelizeError> {
    voxelize_with_stats(objects, opts).map(|(grid, _)| grid)
}

/// [`voxelize`], also returning timings and voxel counts.
pub fn voxelize_with_stats(
    objects: &[TriMesh],
    opts: &VoxelizeOptions,
) -> Result<(DenseGrid, VoxelizeStats), VoxelizeError> {
    check_voxel_size(opts.voxel_size)?;
    check_objects(objects)?;
    let spec = scene_grid(objects, opts, MAX_VOXELS)?;
    voxelize_in_with_stats(objects, spec, opts)
}

/// Voxelizes static `objects` straight into a [`VoxelTree`] of `config` and `opts.width`, with the
/// sparse (chunked) pipeline: the same voxels as [`voxelize`] (equal trees for 2-bit), but working
/// memory and the tree follow the scene's surface, not its bounding volume, so the grid may hold up
/// to [`MAX_SPARSE_VOXELS`]. Honours `opts.workspace`. Wider voxels add distance layers (up to
/// [`crate::sparse::MAX_COMPUTED_LAYERS`] per side in 8-bit maps). Blocking, parallel (rayon).
///
/// Errors: as [`voxelize`], plus [`VoxelizeError::InvalidOptions`] for a workspace that misses the
/// scene or an offset too deep for the chunk halo (`offset_layers + layers > 64`).
pub fn voxelize_tree(
    objects: &[TriMesh],
    opts: &VoxelizeOptions,
    config: TreeConfig,
) -> Result<(VoxelTree, VoxelizeStats), VoxelizeError> {
    scene_tree(objects, opts, config, false).map(|(tree, stats, _)| (tree, stats))
}

/// [`voxelize_tree`] on a given grid `spec` (see [`voxelize_in`]; `opts.workspace` is not applied:
/// clip the spec with [`clip_to_workspace`] first).
pub fn voxelize_tree_in(
    objects: &[TriMesh],
    spec: GridSpec,
    opts: &VoxelizeOptions,
    config: TreeConfig,
) -> Result<(VoxelTree, VoxelizeStats), VoxelizeError> {
    sparse_tree_in(objects, spec, opts, config, false).map(|(tree, stats, _)| (tree, stats))
}

/// [`voxelize_tree`], also keeping the scene's [`InsideMap`] (its classification before
/// proximity and the force-layer offset), from which
/// [`crate::distance::distance_band_with_inside`] takes the band's signs without voxelizing the
/// scene a second time. The map holds [`InsideMap::memory_bytes`] beside the tree until dropped
/// (counted in the stats' peak working bytes).
pub fn voxelize_tree_keeping_inside(
    objects: &[TriMesh],
    opts: &VoxelizeOptions,
    config: TreeConfig,
) -> Result<(VoxelTree, VoxelizeStats, InsideMap), VoxelizeError> {
    let (tree, stats, inside) = scene_tree(objects, opts, config, true)?;
    let inside = inside.ok_or_else(|| VoxelizeError::InvalidGrid {
        reason: "the sparse voxelizer kept no inside map (a bug)".into(),
    })?;
    Ok((tree, stats, inside))
}

/// The [`InsideMap`] of `objects` on `spec` alone (scan, flood fill and merge of the sparse
/// pipeline; no layers, no tree), within `max_memory_bytes`. Blocking, parallel (rayon).
pub fn inside_map_in(
    objects: &[TriMesh],
    spec: GridSpec,
    max_memory_bytes: u64,
) -> Result<InsideMap, VoxelizeError> {
    check_spec(&spec, MAX_SPARSE_VOXELS)?;
    check_objects(objects)?;
    crate::memory::check_budget(
        crate::memory::estimate_sparse(objects, &spec, VoxelWidth::Two),
        &spec,
        max_memory_bytes,
    )?;
    let mut stats = VoxelizeStats::default();
    Ok(crate::sparse::inside_map(objects, &spec, &mut stats))
}

/// [`voxelize_tree`], with the inside map when `keep_inside`.
fn scene_tree(
    objects: &[TriMesh],
    opts: &VoxelizeOptions,
    config: TreeConfig,
    keep_inside: bool,
) -> Result<(VoxelTree, VoxelizeStats, Option<InsideMap>), VoxelizeError> {
    check_voxel_size(opts.voxel_size)?;
    check_objects(objects)?;
    let spec = scene_grid(objects, opts, MAX_SPARSE_VOXELS)?;
    sparse_tree_in(objects, spec, opts, config, keep_inside)
}

/// [`voxelize_tree_in`], with the inside map when `keep_inside`.
fn sparse_tree_in(
    objects: &[TriMesh],
    spec: GridSpec,
    opts: &VoxelizeOptions,
    config: TreeConfig,
    keep_inside: bool,
) -> Result<(VoxelTree, VoxelizeStats, Option<InsideMap>), VoxelizeError> {
    let start = Instant::now();
    check_spec(&spec, MAX_SPARSE_VOXELS)?;
    check_objects(objects)?;
    crate::memory::check_budget(
        crate::memory::estimate_sparse(objects, &spec, opts.width),
        &spec,
        opts.max_memory_bytes,
    )?;
    config
        .validate()
        .map_err(|e| VoxelizeError::InvalidOptions {
            reason: e.to_string(),
        })?;
    let plan = crate::sparse::plan_for(opts.width, opts.offset_layers)?;
    let mut stats = VoxelizeStats {
        objects: objects.len(),
        triangles: objects.iter().map(TriMesh::triangle_count).sum(),
        dims: spec.dims,
        ..VoxelizeStats::default()
    };
    let (tree, inside) =
        crate::sparse::voxelize_sparse(objects, &spec, &plan, config, &mut stats, keep_inside)?;
    let [free, interior, surface, proximity] = tree.counts();
    stats.free_voxels = free;
    stats.interior_voxels = interior;
    stats.surface_voxels = surface;
    stats.proximity_voxels = proximity;
    stats.total_ms = ms(start);
    Ok((tree, stats, inside))
}

/// [`voxelize`] on a given grid: `spec` (its own voxel size wins over `opts.voxel_size`, and
/// `opts.padding_voxels` is unused). Parts of objects outside the grid are clipped; an object cut by
/// the grid's boundary keeps its inside (wall voxels there seed the flood fill only where the
/// winding number says they are outside).
pub fn voxelize_in(
    objects: &[TriMesh],
    spec: GridSpec,
    opts: &VoxelizeOptions,
) -> Result<DenseGrid, VoxelizeError> {
    voxelize_in_with_stats(objects, spec, opts).map(|(grid, _)| grid)
}

/// [`voxelize_in`], also returning timings and voxel counts.
pub fn voxelize_in_with_stats(
    objects: &[TriMesh],
    spec: GridSpec,
    opts: &VoxelizeOptions,
) -> Result<(DenseGrid, VoxelizeStats), VoxelizeError> {
    let start = Instant::now();
    check_spec(&spec, MAX_VOXELS)?;
    check_objects(objects)?;
    crate::memory::check_budget(
        crate::memory::estimate_dense(&spec),
        &spec,
        opts.max_memory_bytes,
    )?;
    let mut stats = VoxelizeStats {
        peak_work_bytes: spec.voxel_count() * BYTES_PER_VOXEL_NUM / BYTES_PER_VOXEL_DEN,
        ..VoxelizeStats::default()
    };
    let layers = voxelize_planes(
        objects,
        &spec,
        opts.offset_layers,
        opts.progress,
        true,
        &mut stats,
    );
    let t = Instant::now();
    let grid = to_dense(spec, &layers);
    stats.output_ms = ms(t);
    stats.total_ms = ms(start);
    Ok((grid, stats))
}

/// Looks up a plane at a signed grid index (false outside).
pub(crate) fn plane_at(plane: &BitGrid, ijk: glam::IVec3) -> bool {
    plane.get_signed(ijk.x as i64, ijk.y as i64, ijk.z as i64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_for_pads_and_aligns() {
        let b = Aabb {
            min: DVec3::new(0.012, -0.003, 1.0),
            max: DVec3::new(0.031, 0.0, 1.0),
        };
        let opts = VoxelizeOptions::default();
        let g = grid_for(&b, &opts).unwrap();
        assert_eq!(g.voxel_size, 0.005);
        // x: floor(2.4)=2 .. floor(6.2)=6, padded by 4: -2 .. 10 → 13 voxels.
        assert_eq!(g.dims[0], 13);
        assert!((g.origin.x - (-0.010)).abs() < 1e-12);
        // A flat box still gets 1 + 2*4 voxels.
        assert_eq!(g.dims[2], 9);
        let zero_pad = VoxelizeOptions {
            padding_voxels: 0,
            offset_layers: 0,
            ..opts
        };
        assert_eq!(grid_for(&b, &zero_pad).unwrap().dims[2], 5);
    }

    #[test]
    fn errors_are_reported() {
        let b = Aabb {
            min: DVec3::ZERO,
            max: DVec3::ONE,
        };
        for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let o = VoxelizeOptions {
                voxel_size: s,
                ..Default::default()
            };
            assert!(matches!(
                grid_for(&b, &o),
                Err(VoxelizeError::InvalidVoxelSize { .. })
            ));
        }
        let o = VoxelizeOptions {
            voxel_size: 1e-4,
            ..Default::default()
        };
        match grid_for(&b, &o) {
            Err(VoxelizeError::GridTooLarge { voxels, .. }) => assert!(voxels > 1_000_000_000_000),
            other => panic!("{other:?}"),
        }
        assert!(grid_for(&Aabb::EMPTY, &VoxelizeOptions::default()).is_err());
        assert_eq!(
            voxelize(&[], &VoxelizeOptions::default()),
            Err(VoxelizeError::NoObjects)
        );
        assert_eq!(
            voxelize(&[TriMesh::default()], &VoxelizeOptions::default()),
            Err(VoxelizeError::EmptyObject { object: 0 })
        );
        let bad = TriMesh::new(
            vec![DVec3::ZERO, DVec3::X, DVec3::Y],
            vec![[0, 1, 2], [0, 1, 3]],
        );
        assert!(matches!(
            voxelize(&[bad], &VoxelizeOptions::default()),
            Err(VoxelizeError::InvalidMesh {
                object: 0,
                triangle: 1,
                ..
            })
        ));
        let nan = TriMesh::new(vec![DVec3::ZERO, DVec3::X, DVec3::NAN], vec![[0, 1, 2]]);
        assert!(matches!(
            voxelize(&[nan], &VoxelizeOptions::default()),
            Err(VoxelizeError::InvalidMesh { triangle: 0, .. })
        ));
    }

    #[test]
    fn object_window_is_aligned_and_clipped() {
        let spec = GridSpec::at_origin(1.0, [200, 10, 10]);
        let b = Aabb {
            min: DVec3::new(100.5, 3.5, -5.0),
            max: DVec3::new(110.5, 4.5, 4.0),
        };
        let w = object_window(&b, &spec).unwrap();
        assert_eq!(w.offset, [64, 1, 0]);
        assert_eq!(w.dims, [112 + 1 - 64, 6, 7]);
        let far = Aabb {
            min: DVec3::splat(300.0),
            max: DVec3::splat(301.0),
        };
        assert_eq!(object_window(&far, &spec), None);
    }
}
