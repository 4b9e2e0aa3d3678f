//! [`ViewerContent`]: what the page draws of the static scene and the part, built once when the viewer starts.
//!
//! The static scene is drawn as boxes at the Surface voxels of its voxmap. A large scene has
//! millions of them (the aircraft bay at 5 mm: see `docs/viewer.md`), so they are decimated: the
//! grid is coarsened by the smallest integer factor `k` for which the coarse cells holding at least
//! one Surface voxel number at most [`SceneLimits::max_boxes`], and one box of edge `k · s` is drawn
//! per such cell. The cells are found from the tree's leaves and tiles, never from a dense grid:
//! memory is bounded by `max_boxes` cells whatever the grid's volume (a 2¹⁴-per-axis grid costs no
//! more than its Surface voxels' leaves). The part's shell is thinned by a stride to at most
//! [`SceneLimits::max_shell_points`] for drawing; the full shell is kept for contact sampling.
//!
//! With meshes ([`ViewerContent::with_meshes`]) the page draws the static meshes and the part's mesh
//! shaded, decimated to [`SceneLimits::max_static_triangles`] and
//! [`SceneLimits::max_part_triangles`] (see [`crate::mesh`]), and the boxes become an overlay.

use crate::mesh::{decimate, decimate_all};
use crate::study::StudyTrack;
use glam::{DVec3, UVec3, Vec3};
use serde::Serialize;
use std::collections::HashSet;
use std::sync::Arc;
use vps_mesh::TriMesh;
use vps_voxmap::{PointShell, Voxel, VoxelTree};

/// Bounds on what is sent to the page.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneLimits {
    /// Most boxes drawn for the static scene. Default 200,000.
    pub max_boxes: usize,
    /// Most shell points drawn for the part and its ghost. Default 50,000.
    pub max_shell_points: usize,
    /// Most triangles drawn for all static meshes together (36 bytes each on the wire).
    /// Default 300,000 (10.8 MB).
    pub max_static_triangles: usize,
    /// Most triangles drawn for the part's mesh. Default 100,000.
    pub max_part_triangles: usize,
}

impl Default for SceneLimits {
    fn default() -> Self {
        Self {
            max_boxes: 200_000,
            max_shell_points: 50_000,
            max_static_triangles: 300_000,
            max_part_triangles: 100_000,
        }
    }
}

/// Largest coarsening factor tried; past it the coarse cells are thinned by a stride.
const MAX_COARSENING: u32 = 64;

/// What the viewer draws, as `/scene` serves it (JSON): the static scene and, when there is one,
/// the part (its shell and mesh; the `/scene/*` routes serve both). Lengths in m.
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
    /// Static mesh triangles drawn (the length of `/scene/mesh` is 36 bytes per triangle); 0
    /// without meshes (the page then shows the Surface voxel boxes).
    pub mesh_triangles: usize,
    /// Triangles of the static meshes before decimation.
    pub mesh_triangles_total: usize,
    /// Vertex-clustering cell of the static meshes (m); 0 when they were not decimated.
    pub mesh_cell_m: f64,
    /// Part mesh triangles drawn (the length of `/scene/part_mesh` is 36 bytes per triangle, in
    /// the shell's body frame); 0 without a part mesh.
    pub part_mesh_triangles: usize,
    /// Triangles of the part's mesh before decimation.
    pub part_mesh_triangles_total: usize,
    /// Vertex-clustering cell of the part's mesh (m); 0 when it was not decimated.
    pub part_mesh_cell_m: f64,
    /// The simulated hand's path (m, world frame, in time order, at most [`MAX_HAND_PATH_POINTS`]
    /// points): drawn as a line; empty when there is none.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub hand_path_m: Vec<[f64; 3]>,
    /// Where the part starts: drawn until a session's first frame arrives (an offline view shows
    /// it for good); absent when unknown.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub part_start: Option<StartPose>,
    /// An assembly study's path to scrub along ([`ViewerContent::with_study`]); absent without.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub study: Option<StudyTrack>,
    /// The study's swept-volume mesh triangles drawn (the length of `/scene/swept_mesh` is 36
    /// bytes per triangle, world frame); 0 without.
    pub swept_mesh_triangles: usize,
    /// The other moving parts of a scene of several, in order (empty for one part): their
    /// meshes follow each other in `/scene/other_part_meshes` (36 bytes per triangle, each in its
    /// own grip frame), and each frame's `others` gives their poses, hands and device wrenches in
    /// the same order.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub other_parts: Vec<OtherPartMeta>,
}

/// One of the other moving parts as the page draws it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct OtherPartMeta {
    /// Its name.
    pub name: String,
    /// Its mesh's triangles drawn (after the previous parts' in `/scene/other_part_meshes`).
    pub mesh_triangles: usize,
    /// Where it starts (drawn until a session's first frame).
    pub start: StartPose,
}

/// Most points of [`SceneMeta::hand_path_m`].
pub const MAX_HAND_PATH_POINTS: usize = 2000;

/// A pose as the page reads it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StartPose {
    /// Position (m).
    pub position_m: [f64; 3],
    /// Orientation, quaternion `[x, y, z, w]`.
    pub orientation_xyzw: [f64; 4],
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
pub struct ViewerContent {
    /// The description served at `/scene`.
    pub meta: SceneMeta,
    /// Centres of the drawn boxes (m, world frame).
    pub boxes: Vec<Vec3>,
    /// Drawn shell points (m, body frame).
    pub shell: Vec<Vec3>,
    /// Drawn static mesh triangles (m, world frame); empty without meshes.
    pub mesh: Vec<[Vec3; 3]>,
    /// Drawn part mesh triangles (m, the shell's body frame); empty without a part mesh.
    pub part_mesh: Vec<[Vec3; 3]>,
    /// Drawn swept-volume triangles of a study (m, world frame); empty without.
    pub swept_mesh: Vec<[Vec3; 3]>,
    /// Drawn triangles of the other moving parts, one part after another (m, each in its own
    /// grip frame; [`SceneMeta::other_parts`] says how many each).
    pub other_part_meshes: Vec<[Vec3; 3]>,
    /// What contact sampling needs; `None` without a part.
    pub contact: Option<ContactModel>,
    /// The bounds it was built with (the mesh budgets apply in [`ViewerContent::with_meshes`]).
    limits: SceneLimits,
}

impl ViewerContent {
    /// Builds the drawn scene from a voxmap and, optionally, the part's shell. Reads the tree's
    /// leaves and tiles (never a dense grid): memory is bounded by [`SceneLimits::max_boxes`]
    /// coarse cells, whatever the grid's volume; time is linear in the stored leaves and tiles per
    /// coarsening factor tried (usually one or two).
    pub fn new(
        label: impl Into<String>,
        tree: Arc<VoxelTree>,
        shell: Option<Arc<PointShell>>,
        limits: SceneLimits,
    ) -> ViewerContent {
        let spec = *tree.spec();
        let surface_voxels = tree.counts()[Voxel::Surface as usize];
        let (cells, coarsening) = decimate_boxes(&tree, surface_voxels, limits.max_boxes);
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
            surface_voxels,
            boxes: boxes.len(),
            bounds_min_m: spec.origin.to_array(),
            bounds_max_m: spec.max_corner().to_array(),
            shell_points: drawn_shell.len(),
            shell_points_total: shell.as_deref().map_or(0, PointShell::len),
            shell_voxel_size_m: shell.as_deref().map_or(0.0, |s| s.voxel_size),
            mesh_triangles: 0,
            mesh_triangles_total: 0,
            mesh_cell_m: 0.0,
            part_mesh_triangles: 0,
            part_mesh_triangles_total: 0,
            part_mesh_cell_m: 0.0,
            hand_path_m: Vec::new(),
            part_start: None,
            study: None,
            swept_mesh_triangles: 0,
            other_parts: Vec::new(),
        };
        ViewerContent {
            meta,
            boxes,
            shell: drawn_shell,
            mesh: Vec::new(),
            part_mesh: Vec::new(),
            swept_mesh: Vec::new(),
            other_part_meshes: Vec::new(),
            contact: shell.map(|shell| ContactModel { tree, shell }),
            limits,
        }
    }

    /// Adds the simulated hand's path (`path`, m, in time order; evenly thinned to at most
    /// [`MAX_HAND_PATH_POINTS`], the last point kept) and the part's start pose, for the page to
    /// draw.
    pub fn with_hand(mut self, path: &[DVec3], start: (DVec3, glam::DQuat)) -> ViewerContent {
        // One point in `stride`, room left for the last.
        let stride = path.len().div_ceil(MAX_HAND_PATH_POINTS - 1).max(1);
        let mut points: Vec<[f64; 3]> = path.iter().step_by(stride).map(|p| p.to_array()).collect();
        if let Some(last) = path.last() {
            if points.last() != Some(&last.to_array()) {
                points.push(last.to_array());
            }
        }
        self.meta.hand_path_m = points;
        self.meta.part_start = Some(StartPose {
            position_m: start.0.to_array(),
            orientation_xyzw: start.1.to_array(),
        });
        self
    }

    /// Adds the other moving parts of a scene of several: each `(name, mesh in its grip frame (m),
    /// start pose)`, its mesh decimated to [`SceneLimits::max_part_triangles`]. Replaces parts
    /// given before. Allocates about the meshes' size.
    pub fn with_other_parts(
        mut self,
        parts: Vec<(String, TriMesh, (DVec3, glam::DQuat))>,
    ) -> ViewerContent {
        self.meta.other_parts.clear();
        self.other_part_meshes.clear();
        for (name, mesh, (position, orientation)) in parts {
            let drawn = decimate(&mesh, self.limits.max_part_triangles);
            self.meta.other_parts.push(OtherPartMeta {
                name,
                mesh_triangles: drawn.triangles.len(),
                start: StartPose {
                    position_m: position.to_array(),
                    orientation_xyzw: orientation.to_array(),
                },
            });
            self.other_part_meshes.extend(drawn.triangles);
        }
        self
    }

    /// Adds an assembly study to scrub along: its `track` (see [`crate::study`]) and its swept
    /// volume's closed mesh (world frame, m; decimated to [`SceneLimits::max_part_triangles`]),
    /// drawn translucent. Replaces a study given before.
    pub fn with_study(mut self, track: StudyTrack, swept: Option<&TriMesh>) -> ViewerContent {
        let drawn = swept
            .map(|m| decimate(m, self.limits.max_part_triangles))
            .unwrap_or_default();
        self.meta.swept_mesh_triangles = drawn.triangles.len();
        self.swept_mesh = drawn.triangles;
        self.meta.study = Some(track);
        self
    }

    /// The same scene with meshes to draw: `statics` in scene (world) coordinates in metres,
    /// merged and decimated to [`SceneLimits::max_static_triangles`] in total, and the part's mesh
    /// in the frame of its point shell (the body frame the live pose places; decimated to
    /// [`SceneLimits::max_part_triangles`]). The page then draws the meshes shaded and shows the
    /// Surface voxel boxes only as an overlay the user turns on. Replaces meshes given before.
    /// Allocates about the meshes' size again while decimating (see [`crate::mesh`]); a mesh over
    /// its budget costs a dozen clustering passes (about a second for the 593k-triangle aircraft
    /// bay in a release build).
    pub fn with_meshes(mut self, statics: Vec<TriMesh>, part: Option<TriMesh>) -> ViewerContent {
        let drawn = decimate_all(&statics, self.limits.max_static_triangles);
        drop(statics);
        self.meta.mesh_triangles = drawn.triangles.len();
        self.meta.mesh_triangles_total = drawn.source_triangles;
        self.meta.mesh_cell_m = drawn.cell_m;
        self.mesh = drawn.triangles;
        let drawn = part
            .map(|p| decimate(&p, self.limits.max_part_triangles))
            .unwrap_or_default();
        self.meta.part_mesh_triangles = drawn.triangles.len();
        self.meta.part_mesh_triangles_total = drawn.source_triangles;
        self.meta.part_mesh_cell_m = drawn.cell_m;
        self.part_mesh = drawn.triangles;
        self
    }
}

/// The distinct coarse cells (indices in units of `k` voxels) holding a Surface voxel of `tree`,
/// with the smallest `k` ≥ 1 giving at most `max_cells` of them. Surface counts fall about as
/// `1/k²`, so the search starts near `sqrt(surface_voxels / max_cells)`. Past [`MAX_COARSENING`]
/// the cells are thinned to at most `max_cells` by a spatial hash. Returns the cells (sorted, z
/// slowest) and `k`. Never holds more than `max_cells + 1` cells.
fn decimate_boxes(tree: &VoxelTree, surface_voxels: u64, max_cells: usize) -> (Vec<UVec3>, u32) {
    let max_cells = max_cells.max(1);
    let estimate = (surface_voxels as f64 / max_cells as f64).sqrt().floor();
    let mut k = (estimate.min(MAX_COARSENING as f64) as u32).max(1);
    loop {
        if let Some(cells) = coarse_cells(tree, k, max_cells, 0) {
            return (sorted(cells), k);
        }
        if k == MAX_COARSENING {
            break;
        }
        k += 1;
    }
    // Still too many at the largest k: keep the cells whose hash falls in a shrinking share.
    let mut keep_log2 = 1;
    loop {
        if let Some(cells) = coarse_cells(tree, k, max_cells, keep_log2) {
            return (sorted(cells), k);
        }
        keep_log2 += 1;
    }
}

/// The distinct cells `v / k` of the Surface voxels `v` of `tree` whose [`cell_hash`] has its low
/// `keep_log2` bits clear (all cells when 0), or `None` as soon as there are more than `max_cells`.
fn coarse_cells(
    tree: &VoxelTree,
    k: u32,
    max_cells: usize,
    keep_log2: u32,
) -> Option<HashSet<UVec3>> {
    let keep_mask = (1u64 << keep_log2.min(63)) - 1;
    let mut cells = HashSet::new();
    let mut overflow = false;
    // Leaves are visited voxel by voxel in order, so consecutive voxels often share a cell.
    let mut last = None;
    tree.for_each_region_of(Voxel::Surface, |lo, hi| {
        if overflow {
            return;
        }
        let (a, b) = (lo / k, (hi - UVec3::ONE) / k);
        if a == b && last == Some(a) {
            return;
        }
        last = Some(a);
        let span = (b - a + UVec3::ONE).as_u64vec3();
        if keep_log2 == 0 && span.x * span.y * span.z > max_cells as u64 {
            overflow = true;
            return;
        }
        for z in a.z..=b.z {
            for y in a.y..=b.y {
                for x in a.x..=b.x {
                    let c = UVec3::new(x, y, z);
                    if cell_hash(c) & keep_mask == 0 && cells.insert(c) && cells.len() > max_cells {
                        overflow = true;
                        return;
                    }
                }
            }
        }
    });
    (!overflow).then_some(cells)
}

/// A well-mixed hash of a cell index (splitmix64 of its packed coordinates): thinning by its low
/// bits keeps an even spread of cells.
fn cell_hash(c: UVec3) -> u64 {
    let mut h = (c.x as u64) ^ ((c.y as u64) << 21) ^ ((c.z as u64) << 42) ^ ((c.z as u64) >> 22);
    h = h.wrapping_add(0x9E37_79B9_7F4A_7C15);
    h = (h ^ (h >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h = (h ^ (h >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    h ^ (h >> 31)
}

/// The cells sorted with z slowest.
fn sorted(cells: HashSet<UVec3>) -> Vec<UVec3> {
    let mut cells: Vec<UVec3> = cells.into_iter().collect();
    cells.sort_unstable_by_key(|c| (c.z, c.y, c.x));
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
    use vps_voxmap::{DenseGrid, GridSpec, MassProperties, TreeConfig};

    /// A 40³ grid of 1 cm voxels at the origin with a Surface slab at z = 10 (Interior below).
    pub(crate) fn slab() -> Arc<VoxelTree> {
        let spec = GridSpec::at_origin(0.01, [40, 40, 40]);
        let grid = DenseGrid::from_fn(spec, |p| match p.z {
            10 => Voxel::Surface,
            z if z < 10 => Voxel::Interior,
            _ => Voxel::Free,
        });
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
        let scene =
            ViewerContent::new("slab", slab(), Some(square_shell()), SceneLimits::default());
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
            ..SceneLimits::default()
        };
        let scene = ViewerContent::new("slab", slab(), Some(square_shell()), limits);
        // 40 × 40 Surface voxels: k = 2 gives 400 cells of 2 cm.
        assert_eq!(scene.meta.coarsening, 2);
        assert_eq!(scene.boxes.len(), 400);
        assert!((scene.meta.box_size_m - 0.02).abs() < 1e-12);
        assert!(scene.meta.shell_points <= 10 && scene.meta.shell_points_total == 25);
    }

    /// The dense computation the viewer used before it read the tree: every Surface voxel of the
    /// expanded grid, then the same search for `k`. The oracle for small trees.
    fn dense_oracle(tree: &VoxelTree, max_cells: usize) -> (Vec<UVec3>, u32) {
        let grid = tree.to_dense();
        let [nx, ny, _] = grid.spec.dims.map(|d| d as usize);
        let mut voxels = Vec::new();
        for (row_index, row) in grid.data.chunks_exact(nx).enumerate() {
            let (y, z) = ((row_index % ny) as u32, (row_index / ny) as u32);
            for (x, &v) in row.iter().enumerate() {
                if Voxel::from_bits(v) == Voxel::Surface {
                    voxels.push(UVec3::new(x as u32, y, z));
                }
            }
        }
        let estimate = (voxels.len() as f64 / max_cells as f64).sqrt().floor() as u32;
        let mut k = estimate.clamp(1, MAX_COARSENING);
        loop {
            let mut cells: Vec<UVec3> = voxels.iter().map(|v| *v / k).collect();
            cells.sort_unstable_by_key(|c| (c.z, c.y, c.x));
            cells.dedup();
            if cells.len() <= max_cells {
                return (cells, k);
            }
            assert!(
                k < MAX_COARSENING,
                "the oracle only covers k up to the largest"
            );
            k += 1;
        }
    }

    /// A 70 × 45 × 33 grid with a solid Surface block (whole leaves and nodes: tiles) and scattered
    /// Surface and Interior voxels (leaves).
    fn mixed(config: TreeConfig) -> VoxelTree {
        let spec = GridSpec {
            origin: DVec3::new(-0.3, 0.1, 2.0),
            voxel_size: 0.005,
            dims: [70, 45, 33],
        };
        let grid = DenseGrid::from_fn(spec, |IVec3 { x, y, z }| {
            let h = (x * 73 + y * 151 + z * 29) % 17;
            let block = (8..24).contains(&x) && (16..32).contains(&y) && z < 16;
            if block || h == 0 || h == 5 {
                Voxel::Surface
            } else if h == 3 {
                Voxel::Interior
            } else {
                Voxel::Free
            }
        });
        VoxelTree::from_dense(&grid, config).unwrap()
    }

    #[test]
    fn boxes_from_the_tree_equal_the_dense_computation() {
        for tree in [
            mixed(TreeConfig::default()),
            mixed(TreeConfig::uniform(2)),
            mixed(TreeConfig::uniform(1)),
            Arc::try_unwrap(slab()).unwrap(),
        ] {
            let surface = tree.counts()[Voxel::Surface as usize];
            for max_cells in [1_000_000, 5000, 1000, 300, 40, 3] {
                let expected = dense_oracle(&tree, max_cells);
                let got = decimate_boxes(&tree, surface, max_cells);
                assert_eq!(got, expected, "max_cells {max_cells}, {:?}", tree.config());
            }
        }
    }

    #[test]
    fn past_the_largest_coarsening_the_cells_are_thinned() {
        // Surface voxels 64 apart along x in a long thin grid: 1000 cells at every k ≤ 64.
        let spec = GridSpec::at_origin(0.01, [64_000, 1, 1]);
        let grid = DenseGrid::from_fn(spec, |p| match p.x % 64 {
            0 => Voxel::Surface,
            _ => Voxel::Free,
        });
        let tree = VoxelTree::from_dense(&grid, TreeConfig::default()).unwrap();
        let (cells, k) = decimate_boxes(&tree, 1000, 10);
        assert_eq!(k, MAX_COARSENING);
        assert!(cells.len() <= 10 && !cells.is_empty(), "{}", cells.len());
    }

    #[test]
    fn points_encode_as_little_endian_triples() {
        let bytes = encode_points(&[Vec3::new(1.0, -2.0, 0.5)]);
        assert_eq!(bytes.len(), 12);
        assert_eq!(f32::from_le_bytes(bytes[4..8].try_into().unwrap()), -2.0);
    }
}
