//! What the page draws of the static scene and the part, built once when the viewer starts.
//!
//! The static scene is drawn as boxes at the Surface voxels of its voxmap. A large scene has
//! millions of them (the aircraft bay at 5 mm: see `docs/viewer.md`), so they are decimated: the
//! grid is coarsened by the smallest integer factor `k` for which the coarse cells holding at least
//! one Surface voxel number at most [`SceneLimits::max_boxes`], and one box of edge `k · s` is drawn
//! per such cell. The part's shell is thinned by a stride to at most
//! [`SceneLimits::max_shell_points`] for drawing; the full shell is kept for contact sampling.

use glam::{DVec3, UVec3, Vec3};
use serde::Serialize;
use std::sync::Arc;
use vps_voxmap::{DenseGrid, PointShell, Voxel, VoxelTree};

/// Bounds on what is sent to the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneLimits {
    /// Most boxes drawn for the static scene. Default 200,000.
    pub max_boxes: usize,
    /// Most shell points drawn for the part and its ghost. Default 50,000.
    pub max_shell_points: usize,
}

impl Default for SceneLimits {
    fn default() -> Self {
        Self {
            max_boxes: 200_000,
            max_shell_points: 50_000,
        }
    }
}

/// Largest coarsening factor tried; past it the coarse cells are thinned by a stride.
const MAX_COARSENING: u32 = 64;

/// The scene's description as `/scene` serves it (JSON). Lengths in m.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SceneMeta {
    /// What the scene is (e.g. "aircraft bay", a file name).
    pub label: String,
    /// Voxel edge of the voxmap (m).
    pub voxel_size_m: f64,
    /// Edge of one drawn box (m): `voxel_size_m` times the coarsening factor.
    pub box_size_m: f64,
    /// The coarsening factor `k` (1: every Surface voxel is a box).
    pub coarsening: u32,
    /// Surface voxels in the voxmap, before decimation.
    pub surface_voxels: u64,
    /// Boxes drawn (the length of `/scene/boxes` is 12 bytes per box).
    pub boxes: usize,
    /// Minimum corner of the voxmap's grid (m).
    pub bounds_min_m: [f64; 3],
    /// Maximum corner of the voxmap's grid (m).
    pub bounds_max_m: [f64; 3],
    /// Shell points drawn (the length of `/scene/shell` is 12 bytes per point); 0 without a part.
    pub shell_points: usize,
    /// Points in the full shell.
    pub shell_points_total: usize,
    /// Voxel size the shell was sampled at (m); 0 without a part.
    pub shell_voxel_size_m: f64,
}

/// The part as the contact sampler needs it: the static scene's voxmap and the full shell.
#[derive(Clone, Debug)]
pub struct ContactModel {
    /// The static scene's voxmap.
    pub tree: Arc<VoxelTree>,
    /// The part's full point shell (body frame).
    pub shell: Arc<PointShell>,
}

/// Everything the viewer serves about the scene. Built once; immutable.
#[derive(Clone, Debug)]
pub struct ViewerScene {
    /// The description served at `/scene`.
    pub meta: SceneMeta,
    /// Centres of the drawn boxes (m, world frame).
    pub boxes: Vec<Vec3>,
    /// Drawn shell points (m, body frame).
    pub shell: Vec<Vec3>,
    /// What contact sampling needs; `None` without a part.
    pub contact: Option<ContactModel>,
}

impl ViewerScene {
    /// Builds the drawn scene from a voxmap and, optionally, the part's shell. Expands the tree to
    /// a dense byte grid once (one byte per voxel, freed on return) to find the Surface voxels;
    /// cost is linear in the grid's voxel count (tens of ms per 10⁷ voxels).
    pub fn new(
        label: impl Into<String>,
        tree: Arc<VoxelTree>,
        shell: Option<Arc<PointShell>>,
        limits: SceneLimits,
    ) -> ViewerScene {
        let dense = tree.to_dense();
        let surface = surface_voxels(&dense);
        drop(dense);
        let spec = *tree.spec();
        let (cells, coarsening) = decimate(&surface, limits.max_boxes);
        let box_size = spec.voxel_size * coarsening as f64;
        let boxes: Vec<Vec3> = cells
            .iter()
            .map(|c| (spec.origin + (c.as_dvec3() + DVec3::splat(0.5)) * box_size).as_vec3())
            .collect();
        let drawn_shell: Vec<Vec3> = shell
            .as_deref()
            .map(|s| thin(&s.points, limits.max_shell_points))
            .unwrap_or_default();
        let meta = SceneMeta {
            label: label.into(),
            voxel_size_m: spec.voxel_size,
            box_size_m: box_size,
            coarsening,
            surface_voxels: surface.len() as u64,
            boxes: boxes.len(),
            bounds_min_m: spec.origin.to_array(),
            bounds_max_m: spec.max_corner().to_array(),
            shell_points: drawn_shell.len(),
            shell_points_total: shell.as_deref().map_or(0, PointShell::len),
            shell_voxel_size_m: shell.as_deref().map_or(0.0, |s| s.voxel_size),
        };
        ViewerScene {
            meta,
            boxes,
            shell: drawn_shell,
            contact: shell.map(|shell| ContactModel { tree, shell }),
        }
    }
}

/// Indices of every Surface voxel of `grid`, x fastest.
fn surface_voxels(grid: &DenseGrid) -> Vec<UVec3> {
    let [nx, ny, _] = grid.spec.dims.map(|d| d as usize);
    let mut out = Vec::new();
    if nx == 0 || ny == 0 {
        return out;
    }
    for (row_index, row) in grid.data.chunks_exact(nx).enumerate() {
        let (y, z) = ((row_index % ny) as u32, (row_index / ny) as u32);
        for (x, &v) in row.iter().enumerate() {
            if Voxel::from_bits(v) == Voxel::Surface {
                out.push(UVec3::new(x as u32, y, z));
            }
        }
    }
    out
}

/// The distinct coarse cells (indices in units of `k` voxels) holding the `voxels`, with the
/// smallest `k` ≥ 1 giving at most `max_cells` of them. Surface counts fall about as `1/k²`, so the
/// search starts near `sqrt(n / max_cells)`. Past [`MAX_COARSENING`] the cells are thinned by a
/// stride. Returns the cells (sorted, z slowest) and `k`.
fn decimate(voxels: &[UVec3], max_cells: usize) -> (Vec<UVec3>, u32) {
    let max_cells = max_cells.max(1);
    let estimate = (voxels.len() as f64 / max_cells as f64).sqrt().floor() as u32;
    let mut k = estimate.clamp(1, MAX_COARSENING);
    loop {
        let cells = coarse_cells(voxels, k);
        if cells.len() <= max_cells {
            return (cells, k);
        }
        if k == MAX_COARSENING {
            return (thin(&cells, max_cells), k);
        }
        k += 1;
    }
}

/// The distinct cells `v / k` of `voxels`, sorted with z slowest.
fn coarse_cells(voxels: &[UVec3], k: u32) -> Vec<UVec3> {
    let mut cells: Vec<UVec3> = voxels.iter().map(|v| *v / k).collect();
    cells.sort_unstable_by_key(|c| (c.z, c.y, c.x));
    cells.dedup();
    cells
}

/// At most `max` items of `items`, every `ceil(len / max)`-th.
fn thin<T: Copy>(items: &[T], max: usize) -> Vec<T> {
    if items.len() <= max {
        return items.to_vec();
    }
    let stride = items.len().div_ceil(max.max(1));
    items.iter().step_by(stride).copied().collect()
}

/// Little-endian f32 `x, y, z` triples, 12 bytes per point: the body of `/scene/boxes` and
/// `/scene/shell`.
pub fn encode_points(points: &[Vec3]) -> Vec<u8> {
    points
        .iter()
        .flat_map(|p| p.to_array())
        .flat_map(f32::to_le_bytes)
        .collect()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::IVec3;
    use vps_voxmap::{GridSpec, MassProperties, TreeConfig};

    /// A 40³ grid of 1 cm voxels at the origin with a Surface slab at z = 10 (Interior below).
    pub(crate) fn slab() -> Arc<VoxelTree> {
        let spec = GridSpec {
            origin: DVec3::ZERO,
            voxel_size: 0.01,
            dims: [40, 40, 40],
        };
        let mut grid = DenseGrid::new(spec);
        for z in 0..=10 {
            for y in 0..40 {
                for x in 0..40 {
                    let kind = if z == 10 {
                        Voxel::Surface
                    } else {
                        Voxel::Interior
                    };
                    grid.set(IVec3::new(x, y, z), kind);
                }
            }
        }
        Arc::new(VoxelTree::from_dense(&grid, TreeConfig::default()).unwrap())
    }

    /// A flat 5 × 5 shell of points 1 cm apart in the body's z = 0 plane, normals pointing +z
    /// (into the part, which lies above its lowest face).
    pub(crate) fn square_shell() -> Arc<PointShell> {
        let points: Vec<Vec3> = (0..25)
            .map(|i| {
                Vec3::new(
                    (i % 5) as f32 * 0.01 - 0.02,
                    (i / 5) as f32 * 0.01 - 0.02,
                    0.0,
                )
            })
            .collect();
        Arc::new(PointShell {
            normals: vec![Vec3::Z; points.len()],
            points,
            voxel_size: 0.01,
            method: vps_voxmap::shell::ShellMethod::VoxelCentres,
            mass: MassProperties {
                volume: 1e-6,
                center_of_mass: DVec3::ZERO,
                bounding_radius: 0.03,
            },
        })
    }

    #[test]
    fn a_small_scene_is_drawn_voxel_for_voxel() {
        let scene = ViewerScene::new("slab", slab(), Some(square_shell()), SceneLimits::default());
        assert_eq!(scene.meta.surface_voxels, 1600);
        assert_eq!((scene.meta.coarsening, scene.boxes.len()), (1, 1600));
        assert!(scene
            .boxes
            .iter()
            .all(|b| (b.z - 0.105).abs() < 1e-6 && b.x > 0.0 && b.x < 0.4));
        assert_eq!(scene.meta.shell_points, 25);
        assert!(scene.contact.is_some());
    }

    #[test]
    fn a_large_scene_is_coarsened_under_the_cap() {
        let limits = SceneLimits {
            max_boxes: 500,
            max_shell_points: 10,
        };
        let scene = ViewerScene::new("slab", slab(), Some(square_shell()), limits);
        // 40 × 40 Surface voxels: k = 2 gives 400 cells of 2 cm.
        assert_eq!(scene.meta.coarsening, 2);
        assert_eq!(scene.boxes.len(), 400);
        assert!((scene.meta.box_size_m - 0.02).abs() < 1e-12);
        assert!(scene.meta.shell_points <= 10 && scene.meta.shell_points_total == 25);
    }

    #[test]
    fn past_the_largest_coarsening_the_cells_are_thinned() {
        let voxels: Vec<UVec3> = (0..1000).map(|i| UVec3::new(i * 64, 0, 0)).collect();
        let (cells, k) = decimate(&voxels, 10);
        assert_eq!(k, MAX_COARSENING);
        assert!(cells.len() <= 10 && !cells.is_empty());
    }

    #[test]
    fn points_encode_as_little_endian_triples() {
        let bytes = encode_points(&[Vec3::new(1.0, -2.0, 0.5)]);
        assert_eq!(bytes.len(), 12);
        assert_eq!(f32::from_le_bytes(bytes[4..8].try_into().unwrap()), -2.0);
    }
}
