//! What a session on a scene will cost, estimated before anything is built: the voxmap (the
//! padded grid's voxel count and the sparse tree's memory, from the scene's bounds and surface
//! area) and the whole scene's memory ([`SceneMemoryEstimate`]: meshes, placed copies, the
//! voxelizer's working memory, tree, distance band, exact reference, point shell, viewer). Plans
//! over a budget are refused before anything is allocated.

use glam::DVec3;
use serde::Serialize;
use vps_mesh::{Aabb, TriMesh};
use vps_voxelize::VoxelizeOptions;
use vps_voxmap::distance::{BAND_VOXELS, BRICK_CODES, CUBE_EDGE};
use vps_voxmap::{TreeConfig, VoxelWidth};

/// The largest voxmap a scene may plan (bytes of tree, estimated): 8 GiB.
pub const VOXMAP_MEMORY_BUDGET: f64 = 8.0 * 1024.0 * 1024.0 * 1024.0;

/// The voxelizer's hard limit on the padded grid (voxels), `vps_voxelize`'s sparse cap (2^40).
pub const MAX_GRID_VOXELS: f64 = (1u64 << 40) as f64;

/// Bytes per triangle of the exact reference (`vps_reference::ExactScene`: its triangle records
/// and bounding-volume hierarchy, about 250 bytes per triangle), built with the distance band.
pub const EXACT_REFERENCE_BYTES_PER_TRIANGLE: u64 = 250;

/// Bytes per point of a point shell: a position and an inward normal, three f32 each.
pub const SHELL_BYTES_PER_POINT: u64 = 24;

/// Bytes of one triangle of a mesh held in memory: its three `u32` vertex indices.
pub const MESH_BYTES_PER_TRIANGLE: u64 = 12;

/// Bytes of one vertex of a mesh held in memory: three f64 coordinates.
pub const MESH_BYTES_PER_VERTEX: u64 = 24;

/// The bytes `mesh` holds: its vertices and triangles.
pub fn mesh_bytes(mesh: &TriMesh) -> u64 {
    (mesh.vertices.len() as u64)
        .saturating_mul(MESH_BYTES_PER_VERTEX)
        .saturating_add((mesh.triangles.len() as u64).saturating_mul(MESH_BYTES_PER_TRIANGLE))
}

/// An estimate of one voxmap.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct VoxmapEstimate {
    /// Voxels in the padded grid (clipped to the workspace when one is given).
    pub grid_voxels: f64,
    /// Voxels per axis of the padded grid (clipped to the workspace when one is given).
    pub grid_dims: [f64; 3],
    /// Voxels in the band around the surfaces (Surface, force layers, Proximity).
    pub band_voxels: f64,
    /// Surface area of the static objects (m², within the workspace when one is given).
    pub surface_area_m2: f64,
    /// Tree memory (bytes): leaves the band touches × leaf size. Within a factor of about three
    /// (over, for cluttered scenes: the built-in bay at 5 mm is estimated at 20 MB, built 7.4 MB).
    pub tree_bytes: f64,
}

/// Estimates the voxmap of `objects` voxelized with `opts` into a tree of shape `tree`.
/// Allocation-free; O(triangles).
pub fn estimate(objects: &[TriMesh], opts: &VoxelizeOptions, tree: TreeConfig) -> VoxmapEstimate {
    let bounds = objects
        .iter()
        .fold(Aabb::EMPTY, |b, mesh| b.union(&mesh.bounds()));
    let triangles = objects
        .iter()
        .flat_map(|mesh| (0..mesh.triangle_count()).map(|i| mesh.triangle(i)));
    estimate_triangles(bounds, triangles, opts, tree)
}

/// [`estimate`] for static objects given as their `bounds` (m, all objects together) and their
/// `triangles` (m, scene coordinates), e.g. placed one at a time from a mesh shared by many
/// objects, without making the placed copies. Allocation-free; O(triangles).
pub fn estimate_triangles(
    bounds: Aabb,
    triangles: impl IntoIterator<Item = [DVec3; 3]>,
    opts: &VoxelizeOptions,
    tree: TreeConfig,
) -> VoxmapEstimate {
    let s = opts.voxel_size;
    let mut bounds = bounds;
    let mut area = 0.0;
    for [a, b, c] in triangles {
        if let Some(w) = &opts.workspace {
            let lo = a.min(b).min(c);
            let hi = a.max(b).max(c);
            if (lo - w.max).max_element() > 0.0 || (w.min - hi).max_element() > 0.0 {
                continue;
            }
        }
        area += 0.5 * (b - a).cross(c - a).length();
    }
    if let Some(w) = &opts.workspace {
        bounds = Aabb {
            min: bounds.min.max(w.min),
            max: bounds.max.min(w.max),
        };
    }
    let pad = f64::from(opts.effective_padding());
    let size = (bounds.max - bounds.min).max(DVec3::ZERO);
    let dims = (size / s).ceil() + DVec3::splat(2.0 * pad + 1.0);
    let grid_voxels = dims.x * dims.y * dims.z;
    let band = 2.0 * (f64::from(opts.offset_layers) + 2.0);
    let band_voxels = (area / (s * s) * band).min(grid_voxels);
    let leaf = f64::from(1u32 << tree.log2_dims[0]);
    // A surface crosses about 1.5 leaves per leaf-sized patch of its area (the mean of
    // |nx| + |ny| + |nz| over orientations), widened by the band's thickness.
    let leaves =
        (area / (leaf * s).powi(2) * 1.5 * (1.0 + band / leaf)).min(grid_voxels / leaf.powi(3));
    let leaf_bytes = leaf.powi(3) * f64::from(opts.width.bits()) / 8.0 + 16.0;
    VoxmapEstimate {
        grid_voxels,
        grid_dims: dims.to_array(),
        band_voxels,
        surface_area_m2: area,
        tree_bytes: leaves * leaf_bytes,
    }
}

/// What a session on a scene holds, estimated before any of it is built (bytes). The parts are
/// not all alive at once (the voxelizer's working memory is freed before the distance band is
/// built), so their sum, [`SceneMemoryEstimate::total_bytes`], is an upper bound of the peak.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct SceneMemoryEstimate {
    /// The distinct meshes read (each once, however many objects name it) and the placed part.
    pub meshes_read_bytes: u64,
    /// The static objects' placed copies in scene coordinates: made when the voxmap is built
    /// (the voxelizer, the cache key and the distance band read them), kept for a viewer.
    pub placed_copies_bytes: u64,
    /// The sparse voxelizer's working memory at its peak (the area bound of
    /// `vps_voxelize::memory::estimate_sparse_by_area`).
    pub voxelizer_bytes: u64,
    /// The voxmap's tree ([`VoxmapEstimate::tree_bytes`]).
    pub voxmap_bytes: u64,
    /// The distance band (distance force model only; 0 otherwise): the cube directory, the
    /// bricks near the surface, the builder's triangle table and its inside map (a 2-bit tree of
    /// the grid, whose voxelization's working memory is at most the voxelizer's, freed before).
    pub distance_band_bytes: u64,
    /// The exact reference the distance band is measured with (distance force model only).
    pub exact_reference_bytes: u64,
    /// The voxelizer's winding-number trees (`vps_reference::winding::WindingTree`) for static
    /// objects that are not closed, or for every object when a workspace may cut them; 0
    /// otherwise, with the copy of the triangles turned outward each is built from
    /// (`vps_reference::orient`). An upper bound: a tree holds only an object's open part.
    pub winding_trees_bytes: u64,
    /// The part's point shell (about 1.5 points per voxel of its surface area).
    pub shell_bytes: u64,
    /// The moving parts' own voxmaps, what the other parts feel (a scene of several parts only;
    /// 0 for one part): each part's tree ([`VoxmapEstimate::tree_bytes`] of its mesh alone) and,
    /// with the distance model, its band's stored directory and bricks. They are built one after
    /// another, each builder's working memory freed before the next and no larger than the
    /// scene's (a part larger than the scene is refused), so only what is kept is counted.
    pub part_voxmaps_bytes: u64,
    /// A viewer's copies of the meshes (0 without one): the copy handed over and the decimation's
    /// working copy.
    pub viewer_bytes: u64,
    /// The sum of the above.
    pub total_bytes: u64,
}

/// What [`scene_memory`] needs to know of a scene.
#[derive(Clone, Copy, Debug)]
pub struct SceneMemoryInputs {
    /// Bytes of the distinct meshes read plus the placed part ([`mesh_bytes`]).
    pub meshes_read_bytes: u64,
    /// Bytes of the static objects placed, summed over objects ([`mesh_bytes`] of each one's mesh).
    pub placed_copies_bytes: u64,
    /// Triangles of the static objects placed, summed over objects.
    pub placed_triangles: u64,
    /// Triangles of the static objects whose inside the voxelizer finds by winding number
    /// (objects that are not closed, or all of them under a workspace), summed over objects.
    pub winding_triangles: u64,
    /// The moving parts' surface area, summed over every part (m²).
    pub part_area_m2: f64,
    /// The distance model's stand-off (m), `None` for the tangent-plane model.
    pub standoff_m: Option<f64>,
    /// Whether a viewer will draw the meshes.
    pub viewer: bool,
    /// The moving parts' own voxmaps, summed over parts (bytes; 0 for one part): [`part_voxmap_bytes`].
    pub part_voxmaps_bytes: u64,
}

/// The stored part of a distance band on the grid of `voxmap` at `voxel_size` (m): the cube
/// directory (4 bytes a cube) and the bricks of the cubes within the band's reach of the surface.
fn band_stored(voxmap: &VoxmapEstimate, voxel_size: f64) -> (f64, f64) {
    let edge = f64::from(CUBE_EDGE);
    let cubes: f64 = voxmap.grid_dims.iter().map(|d| (d / edge).ceil()).product();
    // Cubes within the band's reach of the surface: as the tree's leaves, widened by the band on
    // both sides.
    let reach = 2.0 * (f64::from(BAND_VOXELS) + 1.0);
    let stored =
        (voxmap.surface_area_m2 / (edge * voxel_size).powi(2) * 1.5 * (1.0 + reach / edge))
            .min(cubes);
    (cubes, stored)
}

/// What a distance band keeps (bytes) with `cubes` cubes in its directory (4 bytes each) and
/// `stored` of them holding a brick of codes ([`band_stored`]).
fn band_kept_bytes(cubes: f64, stored: f64) -> f64 {
    4.0 * cubes + stored * BRICK_CODES as f64
}

/// What a moving part's own voxmap keeps (bytes): its tree, voxelized from `mesh` (m, its grip
/// frame) alone with `opts` (no workspace), and with a distance band (`standoff_m` given) the
/// band's directory and bricks. Allocation-free; O(triangles of `mesh`).
pub fn part_voxmap_bytes(mesh: &TriMesh, opts: &VoxelizeOptions, standoff_m: Option<f64>) -> u64 {
    let voxmap = estimate(std::slice::from_ref(mesh), opts, TreeConfig::default());
    let band = match standoff_m {
        None => 0.0,
        Some(_) => {
            let (cubes, stored) = band_stored(&voxmap, opts.voxel_size);
            band_kept_bytes(cubes, stored)
        }
    };
    saturating_bytes(voxmap.tree_bytes + band)
}

/// `x` bytes as a whole count: saturated at `u64::MAX` (NaN too), 0 below 0.
fn saturating_bytes(x: f64) -> u64 {
    if x.is_nan() || x >= u64::MAX as f64 {
        u64::MAX
    } else {
        x.max(0.0) as u64
    }
}

/// The whole scene's memory for the voxmap `voxmap` (from [`estimate_triangles`]) at
/// `voxel_size` (m) and `width`. Allocation-free, O(1); saturates instead of overflowing.
pub fn scene_memory(
    inputs: &SceneMemoryInputs,
    voxmap: &VoxmapEstimate,
    voxel_size: f64,
    width: VoxelWidth,
) -> SceneMemoryEstimate {
    let voxelizer = vps_voxelize::memory::estimate_sparse_by_area(
        voxmap.grid_dims,
        voxel_size,
        voxmap.surface_area_m2,
        width,
    )
    .bytes;
    let (band, exact) = match inputs.standoff_m {
        None => (0, 0),
        Some(_) => {
            let (cubes, stored) = band_stored(voxmap, voxel_size);
            // The builder's table: about eight (triangle, cube) pairs per triangle or stored cube
            // (a triangle's box grown by the reach meets about 2³ cubes), 4 bytes each, and 8
            // bytes of offsets per cube.
            let pairs = 8.0 * (inputs.placed_triangles as f64).max(stored);
            // The inside map the band takes its signs from: a 2-bit tree of the same grid.
            let inside_map = voxmap.tree_bytes * 2.0 / f64::from(width.bits());
            let band = band_kept_bytes(cubes, stored) + 4.0 * pairs + 8.0 * cubes + inside_map;
            (
                saturating_bytes(band),
                inputs
                    .placed_triangles
                    .saturating_mul(EXACT_REFERENCE_BYTES_PER_TRIANGLE),
            )
        }
    };
    // The tree, and the triangles turned outward that it is built from.
    let winding_triangles = usize::try_from(inputs.winding_triangles).unwrap_or(usize::MAX);
    let winding = vps_reference::winding::WindingTree::estimated_bytes(winding_triangles)
        .saturating_add(vps_reference::orient::estimated_bytes(winding_triangles));
    let shell_points = 1.5 * inputs.part_area_m2 / (voxel_size * voxel_size);
    let shell = saturating_bytes(shell_points * SHELL_BYTES_PER_POINT as f64);
    let viewer = if inputs.viewer {
        inputs.placed_copies_bytes.saturating_mul(2)
    } else {
        0
    };
    let voxmap_bytes = saturating_bytes(voxmap.tree_bytes);
    let total = [
        inputs.meshes_read_bytes,
        inputs.placed_copies_bytes,
        voxelizer,
        voxmap_bytes,
        band,
        exact,
        winding,
        shell,
        viewer,
        inputs.part_voxmaps_bytes,
    ]
    .iter()
    .fold(0u64, |t, &b| t.saturating_add(b));
    SceneMemoryEstimate {
        meshes_read_bytes: inputs.meshes_read_bytes,
        placed_copies_bytes: inputs.placed_copies_bytes,
        voxelizer_bytes: voxelizer,
        voxmap_bytes,
        distance_band_bytes: band,
        exact_reference_bytes: exact,
        winding_trees_bytes: winding,
        shell_bytes: shell,
        part_voxmaps_bytes: inputs.part_voxmaps_bytes,
        viewer_bytes: viewer,
        total_bytes: total,
    }
}

/// A size in bytes for a message: GiB to two decimals, MiB to one below 1 GiB, whole KiB
/// below 1 MiB.
pub fn size_text(bytes: u64) -> String {
    let b = bytes as f64;
    if b >= 1024.0 * 1024.0 * 1024.0 {
        format!("{:.2} GiB", b / (1024.0 * 1024.0 * 1024.0))
    } else if b >= 1024.0 * 1024.0 {
        format!("{:.1} MiB", b / (1024.0 * 1024.0))
    } else {
        format!("{:.0} KiB", b / 1024.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A moving part's own voxmap as estimated is within a factor of three of what is built for
    /// it (the sphere at 2 mm: its tree, and with a 1 mm stand-off its tree and distance band).
    #[test]
    fn a_part_s_own_voxmap_is_near_its_estimate() {
        let mesh = vps_mesh::builtin::by_name("sphere").unwrap();
        let opts = VoxelizeOptions {
            voxel_size: 0.002,
            workspace: None,
            ..VoxelizeOptions::default()
        };
        let objects = std::slice::from_ref(&mesh);
        let (tree, _) = vps_voxelize::voxelize_tree(objects, &opts, TreeConfig::default()).unwrap();
        let band = vps_voxelize::distance::distance_band(&tree, objects, 0.001, 1 << 30).unwrap();
        for (standoff, built) in [
            (None, tree.memory_bytes()),
            (Some(0.001), tree.memory_bytes() + band.memory_bytes()),
        ] {
            let est = part_voxmap_bytes(&mesh, &opts, standoff) as f64;
            let built = built as f64;
            assert!(
                est > built / 3.0 && est < built * 3.0,
                "stand-off {standoff:?}: estimate {est} built {built}"
            );
        }
    }

    /// The estimate is within a factor of three of the tree the voxelizer builds for a sphere, and
    /// the grid count is near the padded bounds'.
    #[test]
    fn the_estimate_is_near_the_built_tree() {
        let mesh = vps_mesh::builtin::by_name("sphere").unwrap();
        let opts = VoxelizeOptions {
            voxel_size: 0.002,
            ..VoxelizeOptions::default()
        };
        let est = estimate(std::slice::from_ref(&mesh), &opts, TreeConfig::default());
        let (tree, _) = vps_voxelize::voxelize_tree(&[mesh], &opts, TreeConfig::default()).unwrap();
        let built = tree.memory_bytes() as f64;
        assert!(
            est.tree_bytes > built / 3.0 && est.tree_bytes < built * 3.0,
            "estimate {} built {built}",
            est.tree_bytes
        );
        let dims = tree.spec().dims.map(f64::from);
        let grid = dims[0] * dims[1] * dims[2];
        assert!(
            (est.grid_voxels / grid - 1.0).abs() < 0.2,
            "{} {grid}",
            est.grid_voxels
        );
    }
}
