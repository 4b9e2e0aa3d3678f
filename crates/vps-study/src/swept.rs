//! The swept volume: the region the part occupied along its path, as a set of voxels and as a
//! closed triangle mesh.
//!
//! How: the part's exact signed distance (negative inside, from its triangles) is tabulated once
//! on a grid of half-voxel spacing in the part's own frame. Along the path, poses no more than half
//! a voxel of motion apart are taken (frames skipped while the part moves less, poses interpolated
//! where one frame moves it more); at each, every voxel centre near the part gets the part's
//! distance there (trilinear in the table), and the swept field keeps the least over the poses: the
//! signed distance of the union of the part's placements, to within a quarter voxel between poses.
//! A voxel is inside the swept region when the field is negative at its centre. The mesh is the
//! field's zero surface by Naive Surface Nets (the `fast-surface-nets` crate); the grid's border
//! layers are outside, so the surface is closed. A part with no inside (an open sheet) is swept as
//! the sheet thickened by half a voxel each side. Lengths in metres.

use crate::clearance::motion_bound;
use crate::path::PathFrame;
use glam::{DQuat, DVec3, IVec3};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU32, Ordering};
use vps_mesh::TriMesh;
use vps_voxmap::{DenseGrid, GridSpec, Voxel};

/// Empty voxels around the swept region on every side (the surface closes in them).
const PADDING: i64 = 2;

/// Why a swept volume cannot be made.
#[derive(Clone, Debug, thiserror::Error, PartialEq)]
pub enum SweptError {
    /// The voxel size is not a positive, finite length.
    #[error("swept-volume voxel size {0} m: must be finite and > 0")]
    VoxelSize(f64),
    /// The grid over the path would hold more voxels than allowed.
    #[error(
        "the swept volume's grid at {voxel_size_m} m would hold {voxels} voxels (limit \
         {limit}): the path spans {span_m:?} m; give a coarser voxel size"
    )]
    TooLarge {
        /// The voxel size asked for (m).
        voxel_size_m: f64,
        /// Voxels the grid would hold.
        voxels: u64,
        /// The limit.
        limit: u64,
        /// The path's extent (m).
        span_m: [f64; 3],
    },
    /// The part's distance table would need more points than allowed at this voxel size.
    #[error("the part's distance table needs {points} points at {voxel_size_m} m (limit {limit}); give a coarser voxel size")]
    TableTooLarge {
        /// The voxel size asked for (m).
        voxel_size_m: f64,
        /// Points needed.
        points: u64,
        /// The limit.
        limit: u64,
    },
    /// The part's mesh cannot be measured.
    #[error("the part's mesh cannot be measured: {0}")]
    Mesh(String),
    /// The path or the part is empty.
    #[error("no path or no part triangles: nothing was swept")]
    Empty,
}

/// Limits on what a swept volume may allocate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SweptLimits {
    /// Most voxels in the grid (five bytes each).
    pub max_voxels: u64,
    /// Most points in the part's distance table (four bytes each).
    pub max_table_points: u64,
}

impl Default for SweptLimits {
    /// 256 Mi voxels (about 1.3 GiB at the peak), 64 Mi table points.
    fn default() -> Self {
        SweptLimits {
            max_voxels: 1 << 28,
            max_table_points: 1 << 26,
        }
    }
}

/// The region the part occupied along its path.
#[derive(Clone, Debug)]
pub struct SweptVolume {
    /// The grid the region is stored on.
    pub spec: GridSpec,
    /// One entry per voxel of `spec` (x fastest): inside the region.
    pub inside: Vec<bool>,
    /// Voxels inside.
    pub voxels: u64,
    /// Their volume (m³).
    pub volume_m3: f64,
    /// Poses swept (frames kept plus poses interpolated).
    pub poses: usize,
    /// Points of the part's distance table.
    pub table_points: usize,
    /// The region's surface (m, world frame), outward facing.
    pub mesh: TriMesh,
}

impl SweptVolume {
    /// The region as a voxmap grid: voxels inside with a face on the outside are Surface, the
    /// other inside voxels Interior, the rest Free. Allocates one byte per voxel.
    pub fn to_dense(&self) -> DenseGrid {
        let [nx, ny, nz] = self.spec.dims.map(|d| d as i64);
        let at = |i: i64, j: i64, k: i64| -> bool {
            (0..nx).contains(&i)
                && (0..ny).contains(&j)
                && (0..nz).contains(&k)
                && self.inside[(i + nx * (j + ny * k)) as usize]
        };
        DenseGrid::from_fn(self.spec, |v: IVec3| {
            let (i, j, k) = (v.x as i64, v.y as i64, v.z as i64);
            if !at(i, j, k) {
                return Voxel::Free;
            }
            let faces = [
                (1, 0, 0),
                (-1, 0, 0),
                (0, 1, 0),
                (0, -1, 0),
                (0, 0, 1),
                (0, 0, -1),
            ];
            if faces.iter().all(|&(a, b, c)| at(i + a, j + b, k + c)) {
                Voxel::Interior
            } else {
                Voxel::Surface
            }
        })
    }
}

/// The poses to sweep: the path's frames thinned to no less than `step` (m) of motion apart
/// (`radius`: the part's radius about its grip), with poses interpolated between two frames that
/// are more than `step` apart. The first and last frames are always kept.
fn sweep_poses(path: &[PathFrame], radius: f64, step: f64) -> Vec<(DVec3, DQuat)> {
    let pose = |f: &PathFrame| (f.part_position_m, f.part_orientation);
    let mut poses = Vec::new();
    let Some(first) = path.first() else {
        return poses;
    };
    poses.push(pose(first));
    let mut last = 0;
    for i in 1..path.len() {
        let (prev, here) = (&path[i - 1], &path[i]);
        let jump = motion_bound(prev, here, radius);
        if jump > step {
            // Interpolated poses between the two frames, the frame before kept first.
            if last != i - 1 {
                poses.push(pose(prev));
            }
            let n = (jump / step).ceil() as usize;
            for k in 1..n {
                let s = k as f64 / n as f64;
                poses.push((
                    prev.part_position_m.lerp(here.part_position_m, s),
                    prev.part_orientation.slerp(here.part_orientation, s),
                ));
            }
            poses.push(pose(here));
            last = i;
            continue;
        }
        let next_too_far = path
            .get(i + 1)
            .is_none_or(|next| motion_bound(&path[last], next, radius) > step);
        if next_too_far {
            poses.push(pose(here));
            last = i;
        }
    }
    poses
}

/// The part's signed distance tabulated on a grid in its own frame (m), for trilinear lookups.
struct PartField {
    origin: DVec3,
    spacing: f64,
    dims: [usize; 3],
    values: Vec<f32>,
}

impl PartField {
    /// The table over `part`'s bounds grown by `margin` (m), `spacing` apart, values clamped to
    /// ±`clamp`; open parts get `|d| − thicken`. Errors when it would hold more than `max` points.
    fn new(
        part: &TriMesh,
        spacing: f64,
        margin: f64,
        clamp: f64,
        thicken: f64,
        max: u64,
    ) -> Result<PartField, SweptError> {
        let bounds = part.bounds();
        let origin = bounds.min - DVec3::splat(margin);
        let extent = bounds.size() + DVec3::splat(2.0 * margin);
        let counts = (extent / spacing).ceil().as_u64vec3() + 1;
        let n = counts.x.saturating_mul(counts.y).saturating_mul(counts.z);
        if n > max {
            return Err(SweptError::TableTooLarge {
                voxel_size_m: 2.0 * spacing,
                points: n,
                limit: max,
            });
        }
        let dims = [counts.x as usize, counts.y as usize, counts.z as usize];
        let exact = vps_reference::ExactScene::new(std::slice::from_ref(part))
            .map_err(|e| SweptError::Mesh(e.to_string()))?;
        let open = exact.unsigned_components() > 0;
        let values: Vec<f32> = (0..n as usize)
            .into_par_iter()
            .map(|idx| {
                let (i, j, k) = (
                    idx % dims[0],
                    (idx / dims[0]) % dims[1],
                    idx / (dims[0] * dims[1]),
                );
                let p = origin + DVec3::new(i as f64, j as f64, k as f64) * spacing;
                let d = match exact.signed_distance_within(p, clamp + thicken) {
                    Some(sd) if open => sd.distance_m.abs() - thicken,
                    Some(sd) => sd.distance_m,
                    None => clamp,
                };
                d.clamp(-clamp, clamp) as f32
            })
            .collect();
        Ok(PartField {
            origin,
            spacing,
            dims,
            values,
        })
    }

    /// The distance at `p` (part frame, m), trilinear; `None` outside the table.
    fn at(&self, p: DVec3) -> Option<f32> {
        let g = (p - self.origin) / self.spacing;
        let [nx, ny, nz] = self.dims;
        if !(g.x >= 0.0 && g.y >= 0.0 && g.z >= 0.0) {
            return None;
        }
        let (i, j, k) = (g.x as usize, g.y as usize, g.z as usize);
        if i + 1 >= nx || j + 1 >= ny || k + 1 >= nz {
            return None;
        }
        let (fx, fy, fz) = (
            (g.x - i as f64) as f32,
            (g.y - j as f64) as f32,
            (g.z - k as f64) as f32,
        );
        let v = |a: usize, b: usize, c: usize| self.values[(i + a) + nx * ((j + b) + ny * (k + c))];
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let x00 = lerp(v(0, 0, 0), v(1, 0, 0), fx);
        let x10 = lerp(v(0, 1, 0), v(1, 1, 0), fx);
        let x01 = lerp(v(0, 0, 1), v(1, 0, 1), fx);
        let x11 = lerp(v(0, 1, 1), v(1, 1, 1), fx);
        Some(lerp(lerp(x00, x10, fy), lerp(x01, x11, fy), fz))
    }

    /// The table's box in the part's frame.
    fn corners(&self) -> [DVec3; 8] {
        let size = DVec3::new(
            (self.dims[0] - 1) as f64,
            (self.dims[1] - 1) as f64,
            (self.dims[2] - 1) as f64,
        ) * self.spacing;
        std::array::from_fn(|c| {
            self.origin
                + DVec3::new(
                    if c & 1 == 0 { 0.0 } else { size.x },
                    if c & 2 == 0 { 0.0 } else { size.y },
                    if c & 4 == 0 { 0.0 } else { size.z },
                )
        })
    }
}

/// Lowers the f32 stored (as bits) in `cell` to `value` when `value` is less.
fn store_min(cell: &AtomicU32, value: f32) {
    let mut current = cell.load(Ordering::Relaxed);
    while value < f32::from_bits(current) {
        match cell.compare_exchange_weak(
            current,
            value.to_bits(),
            Ordering::Relaxed,
            Ordering::Relaxed,
        ) {
            Ok(_) => return,
            Err(seen) => current = seen,
        }
    }
}

/// The region `part` (in its grip frame) occupied along `path`, on voxels of `voxel_size` (m).
/// Blocking, parallel (rayon), allocates the grid within `limits`.
pub fn swept_volume(
    part: &TriMesh,
    path: &[PathFrame],
    voxel_size: f64,
    limits: SweptLimits,
) -> Result<SweptVolume, SweptError> {
    if !(voxel_size.is_finite() && voxel_size > 0.0) {
        return Err(SweptError::VoxelSize(voxel_size));
    }
    if path.is_empty() || part.triangle_count() == 0 {
        return Err(SweptError::Empty);
    }
    let h = voxel_size;
    let clamp = 4.0 * h;
    let field = PartField::new(
        part,
        0.5 * h,
        2.0 * h,
        clamp,
        0.5 * h,
        limits.max_table_points,
    )?;
    let corners = field.corners();
    let radius = corners.iter().map(|c| c.length()).fold(0.0, f64::max);
    let poses = sweep_poses(path, radius, 0.5 * h);
    let (lo, hi) = poses.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), (p, _)| (lo.min(*p), hi.max(*p)),
    );
    let (lo, hi) = (lo - DVec3::splat(radius), hi + DVec3::splat(radius));
    let span = hi - lo;
    let counts = (span / h).ceil().as_i64vec3() + 1 + 2 * PADDING;
    let voxels = (counts.x as u64)
        .saturating_mul(counts.y as u64)
        .saturating_mul(counts.z as u64);
    if voxels > limits.max_voxels || counts.max_element() > i32::MAX as i64 {
        return Err(SweptError::TooLarge {
            voxel_size_m: h,
            voxels,
            limit: limits.max_voxels,
            span_m: span.to_array(),
        });
    }
    let origin = lo - DVec3::splat(PADDING as f64 * h);
    let dims = [counts.x as u32, counts.y as u32, counts.z as u32];
    let [nx, ny, nz] = dims.map(|d| d as i64);
    let swept: Vec<AtomicU32> = (0..voxels)
        .map(|_| AtomicU32::new((clamp as f32).to_bits()))
        .collect();
    poses.par_iter().for_each(|&(position, orientation)| {
        // The voxels whose centres lie in the table's box at this pose.
        let (mut blo, mut bhi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for c in &corners {
            let w = orientation * *c + position;
            blo = blo.min(w);
            bhi = bhi.max(w);
        }
        let first = ((blo - origin) / h - 0.5)
            .ceil()
            .as_i64vec3()
            .max(glam::I64Vec3::ZERO);
        let last = ((bhi - origin) / h - 0.5)
            .floor()
            .as_i64vec3()
            .min(glam::I64Vec3::new(nx - 1, ny - 1, nz - 1));
        let back = orientation.conjugate();
        for k in first.z..=last.z {
            for j in first.y..=last.y {
                for i in first.x..=last.x {
                    let centre = origin + (DVec3::new(i as f64, j as f64, k as f64) + 0.5) * h;
                    if let Some(d) = field.at(back * (centre - position)) {
                        store_min(&swept[(i + nx * (j + ny * k)) as usize], d);
                    }
                }
            }
        }
    });
    let values: Vec<f32> = swept
        .into_iter()
        .map(|a| f32::from_bits(a.into_inner()))
        .collect();
    let inside: Vec<bool> = values.iter().map(|&v| v < 0.0).collect();
    let count = inside.iter().filter(|&&x| x).count() as u64;
    let spec = GridSpec {
        origin,
        voxel_size: h,
        dims,
    };
    let mesh = surface_mesh(&values, &spec);
    Ok(SweptVolume {
        spec,
        voxels: count,
        volume_m3: count as f64 * h.powi(3),
        inside,
        poses: poses.len(),
        table_points: field.values.len(),
        mesh,
    })
}

/// The zero surface of `field` (a signed distance at each voxel centre of `spec`, negative
/// inside) by Naive Surface Nets, in world metres, facing out.
fn surface_mesh(field: &[f32], spec: &GridSpec) -> TriMesh {
    use fast_surface_nets::ndshape::{RuntimeShape, Shape};
    use fast_surface_nets::{surface_nets, SurfaceNetsBuffer};
    let [nx, ny, nz] = spec.dims;
    let shape = RuntimeShape::<u32, 3>::new([nx, ny, nz]);
    // ndshape's linear order is x fastest, as ours.
    debug_assert_eq!(field.len(), shape.usize());
    let mut buffer = SurfaceNetsBuffer::default();
    surface_nets(field, &shape, [0; 3], [nx - 1, ny - 1, nz - 1], &mut buffer);
    let vertices: Vec<DVec3> = buffer
        .positions
        .iter()
        .map(|p| {
            spec.origin
                + (DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) + 0.5) * spec.voxel_size
        })
        .collect();
    let triangles: Vec<[u32; 3]> = buffer
        .indices
        .chunks_exact(3)
        .map(|t| [t[0], t[1], t[2]])
        .collect();
    let mut mesh = TriMesh::new(vertices, triangles);
    if mesh.signed_volume() < 0.0 {
        mesh.flip_winding();
    }
    mesh
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_are_thinned_and_interpolated_to_the_step() {
        let frame = |x: f64| PathFrame::at_pose(0, 0.0, DVec3::new(x, 0.0, 0.0), DQuat::IDENTITY);
        // Slow then one jump of 1.0 with a step of 0.1.
        let path: Vec<PathFrame> = [0.0, 0.01, 0.02, 0.03, 1.03, 1.04]
            .iter()
            .map(|&x| frame(x))
            .collect();
        let poses = sweep_poses(&path, 0.0, 0.1);
        assert_eq!(poses.first().unwrap().0.x, 0.0);
        assert_eq!(poses.last().unwrap().0.x, 1.04);
        for w in poses.windows(2) {
            assert!(w[1].0.x - w[0].0.x <= 0.1 + 1e-12, "{poses:?}");
        }
        assert!(poses.len() < 16, "{poses:?}");
    }
}
