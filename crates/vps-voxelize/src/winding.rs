//! Inside and outside where the flood fill cannot be trusted (docs/voxelize.md, "Open and leaky
//! meshes"): objects that are open or inconsistently oriented, and objects cut by the grid's
//! boundary (a workspace box).
//!
//! Each object is split by [`split_open`] into its closed, consistently oriented components (kept
//! together, flood-filled exactly as before) and the rest (open). An open part is flood-filled too;
//! then every voxel the fill reached (through a leak or from outside) becomes Interior where the
//! generalized winding number at its centre is at least 0.5
//! ([`vps_reference::winding::WindingTree`]), and stays Free otherwise. The winding number is
//! taken of the part's triangles turned to face outward
//! ([`vps_reference::orient::oriented_outward`]), so a mesh written clockwise (w = −1 inside as
//! written) or in mixed order keeps its inside. Voxels the fill did not
//! reach stay Interior: sealed by Surface, they are inside whatever the triangles' orientation (a
//! mesh with scrambled winding keeps the inside the flood fill found). A closed part whose window is cut by
//! the grid's boundary is flood-filled from the walls as before, except that a wall voxel on a cut
//! side seeds the fill only where the winding number says it is outside.
//!
//! Every decision is a function of the global voxel index alone (the voxel centre, the part's
//! triangles and its window), so the dense and the sparse pipelines agree voxel for voxel.

use crate::bitgrid::BitGrid;
use glam::{DVec3, IVec3};
use rayon::prelude::*;
use std::borrow::Cow;
use vps_mesh::TriMesh;
use vps_reference::components::components;
use vps_reference::orient::oriented_outward;
use vps_reference::winding::{WindingTree, BETA};
use vps_voxmap::GridSpec;

/// How far from 0.5 the winding numbers at both ends of a segment of reached voxels must be for the
/// whole segment to take their side without evaluating the voxels between.
pub(crate) const MARGIN: f64 = 0.25;

/// Longest piece of a segment (voxels) taken whole from its two ends: longer pieces are bisected.
/// w need not be monotone along a run that crosses no Surface (a row through a slit runs from
/// outside to inside and out again without touching a triangle), so ends are never trusted across
/// more than this.
pub(crate) const MAX_SKIP: usize = 8;

/// One part of an object to voxelize on its own.
pub(crate) struct Part<'a> {
    /// The triangles (a borrowed whole object when it needs no split).
    pub mesh: Cow<'a, TriMesh>,
    /// Some component is open or inconsistently oriented: classify by winding number.
    pub open: bool,
}

/// Splits every object into at most two parts: its closed, consistently oriented components, and
/// the others. An object that is all closed (or all open) stays one borrowed part.
pub(crate) fn split_open(objects: &[TriMesh]) -> Vec<Part<'_>> {
    let mut parts = Vec::with_capacity(objects.len());
    for mesh in objects {
        let comps = components(mesh);
        let open: Vec<u32> = comps
            .iter()
            .filter(|c| !c.closed)
            .flat_map(|c| c.triangles.iter().copied())
            .collect();
        if open.is_empty() || open.len() == mesh.triangle_count() {
            parts.push(Part {
                mesh: Cow::Borrowed(mesh),
                open: !open.is_empty(),
            });
            continue;
        }
        let closed: Vec<u32> = comps
            .iter()
            .filter(|c| c.closed)
            .flat_map(|c| c.triangles.iter().copied())
            .collect();
        for (tris, open) in [(closed, false), (open, true)] {
            parts.push(Part {
                mesh: Cow::Owned(submesh(mesh, &tris)),
                open,
            });
        }
    }
    parts
}

/// The triangles `tris` of `mesh` with only the vertices they use (so its bounds are theirs).
fn submesh(mesh: &TriMesh, tris: &[u32]) -> TriMesh {
    let mut map = vec![u32::MAX; mesh.vertices.len()];
    let mut vertices = Vec::new();
    let triangles = tris
        .iter()
        .map(|&t| {
            mesh.triangles[t as usize].map(|v| {
                if map[v as usize] == u32::MAX {
                    map[v as usize] = vertices.len() as u32;
                    vertices.push(mesh.vertices[v as usize]);
                }
                map[v as usize]
            })
        })
        .collect();
    TriMesh::new(vertices, triangles)
}

/// How one part's non-Surface voxels are classified, in global voxel indices of the grid.
pub(crate) struct PartClass {
    /// The winding tree, built only for open or cut parts.
    tree: Option<WindingTree>,
    /// Classify every non-Surface voxel by winding number (an open part).
    pub open: bool,
    /// `cut[axis][high]`: the part's window (its voxels plus two) reaches past the grid on that side.
    pub cut: [[bool; 2]; 3],
    /// First and last voxel (inclusive, clipped to the grid) of the part's window: voxels outside
    /// are Free for this part.
    pub lo: [usize; 3],
    /// See `lo`.
    pub hi: [usize; 3],
    origin: DVec3,
    voxel_size: f64,
}

impl PartClass {
    /// The class of `mesh` (checked, in world metres) on `spec`; `None` when it misses the grid.
    pub fn new(mesh: &TriMesh, open: bool, spec: &GridSpec) -> Option<PartClass> {
        let b = mesh.bounds();
        let lo = ((b.min - spec.origin) / spec.voxel_size).floor() - DVec3::splat(2.0);
        let hi = ((b.max - spec.origin) / spec.voxel_size).floor() + DVec3::splat(2.0);
        let mut cut = [[false; 2]; 3];
        let mut clo = [0; 3];
        let mut chi = [0; 3];
        for a in 0..3 {
            let n = spec.dims[a] as f64;
            if hi[a] < 0.0 || lo[a] >= n {
                return None;
            }
            cut[a] = [lo[a] < 0.0, hi[a] > n - 1.0];
            clo[a] = lo[a].max(0.0) as usize;
            chi[a] = hi[a].min(n - 1.0) as usize;
        }
        let needs_tree = open || cut.iter().flatten().any(|&c| c);
        Some(PartClass {
            tree: needs_tree.then(|| WindingTree::new(&oriented_outward(mesh), BETA)),
            open,
            cut,
            lo: clo,
            hi: chi,
            origin: spec.origin,
            voxel_size: spec.voxel_size,
        })
    }

    /// Some side of the window is cut by the grid.
    pub fn is_cut(&self) -> bool {
        self.cut.iter().flatten().any(|&c| c)
    }

    /// Winding number at the centre of global voxel `g` is at least 0.5 (false without a tree).
    pub fn inside(&self, g: [usize; 3]) -> bool {
        self.w(g) >= 0.5
    }

    /// Whether a wall voxel (global `g`) of a window whose walls lie on the cut sides `on_cut` may
    /// seed the flood fill: always on sides that are not cut, only outside (by winding number) on
    /// cut ones.
    pub fn may_seed(&self, g: [usize; 3]) -> bool {
        let on_cut = (0..3).any(|a| {
            (self.cut[a][0] && g[a] == self.lo[a]) || (self.cut[a][1] && g[a] == self.hi[a])
        });
        !on_cut || !self.inside(g)
    }

    /// Winding number at the centre of global voxel `g` (0 without a tree), computed again more
    /// exactly near ½ ([`WindingTree::refined_winding_number`]).
    fn w(&self, g: [usize; 3]) -> f64 {
        let c = self.origin
            + (IVec3::new(g[0] as i32, g[1] as i32, g[2] as i32).as_dvec3() + DVec3::splat(0.5))
                * self.voxel_size;
        self.tree
            .as_ref()
            .map_or(0.0, |t| t.refined_winding_number(c))
    }

    /// Adds to `interior` (an open part's flood-fill result over a window starting at global voxel
    /// `offset`) every voxel the fill reached, inside the part's window, whose winding number is at
    /// least 0.5. Reached voxels are taken in segments: maximal runs within one 64-voxel word of a
    /// row (words are aligned to global x, so the dense and sparse pipelines see the same
    /// segments); a piece of at most [`MAX_SKIP`] voxels whose two ends are on the same side by at
    /// least [`MARGIN`] is taken whole, otherwise it is bisected down to single voxels. Parallel
    /// over z.
    pub fn add_by_winding(&self, surface: &BitGrid, interior: &mut BitGrid, offset: [usize; 3]) {
        let dims = surface.dims;
        let rw = surface.row_words;
        let slice = surface.slice_words().max(1);
        debug_assert_eq!(offset[0] % 64, 0);
        interior
            .words
            .par_chunks_mut(slice)
            .enumerate()
            .for_each(|(z, words)| {
                let gz = z + offset[2];
                if gz < self.lo[2] || gz > self.hi[2] {
                    return;
                }
                for y in 0..dims[1] {
                    let gy = y + offset[1];
                    if gy < self.lo[1] || gy > self.hi[1] {
                        continue;
                    }
                    let row = y + dims[1] * z;
                    for w in 0..rw {
                        let g0 = offset[0] + 64 * w; // global x of bit 0
                        let lo = self.lo[0].saturating_sub(g0).min(64);
                        let hi = (self.hi[0] + 1).saturating_sub(g0).min(64);
                        if lo >= hi {
                            continue;
                        }
                        let range = (!0u64 >> (64 - (hi - lo))) << lo;
                        let word = &mut words[y * rw + w];
                        let mut todo =
                            !(surface.words[row * rw + w] | *word) & surface.valid_mask(w) & range;
                        while todo != 0 {
                            let a = todo.trailing_zeros() as usize;
                            let run = todo >> a;
                            let len = (!run).trailing_zeros() as usize;
                            let b = a + len - 1;
                            todo &= !((!0u64 >> (64 - len)) << a);
                            let at = |x: usize| [g0 + x, gy, gz];
                            let mut set = |x: usize| *word |= 1 << x;
                            self.segment(&at, a, self.w(at(a)), b, self.w(at(b)), &mut set);
                        }
                    }
                }
            });
    }

    /// Classifies bits `a..=b` of one segment whose end values are `wa`, `wb` (see
    /// [`PartClass::add_by_winding`]), calling `set` for each inside bit.
    fn segment(
        &self,
        at: &impl Fn(usize) -> [usize; 3],
        a: usize,
        wa: f64,
        b: usize,
        wb: f64,
        set: &mut impl FnMut(usize),
    ) {
        let (ia, ib) = (wa >= 0.5, wb >= 0.5);
        if b <= a + 1 {
            if ia {
                set(a);
            }
            if ib {
                set(b);
            }
            return;
        }
        let clear = b - a < MAX_SKIP && (wa - 0.5).abs() >= MARGIN && (wb - 0.5).abs() >= MARGIN;
        if ia == ib && clear {
            if ia {
                (a..=b).for_each(&mut *set);
            }
            return;
        }
        let m = (a + b) / 2;
        let wm = self.w(at(m));
        self.segment(at, a, wa, m, wm, set);
        self.segment(at, m, wm, b, wb, set);
    }
}
