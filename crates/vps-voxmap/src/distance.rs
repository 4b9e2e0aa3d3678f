//! The signed-distance band: sub-voxel distances to the scene's exact surface in a narrow band
//! around it, for the `distance` force model (docs/architecture.md#voxmaps-and-point-shells).
//!
//! **What is stored.** A sample sits at every voxel centre of the grid the band shares with its
//! tree. Each sample holds `e = d − standoff` quantised to an `i8` in steps of `s / 64` (`s` the
//! voxel size), where `d` is the signed distance (m, positive outside) from the voxel centre to the
//! exact meshes and `standoff` the stand-off distance the force starts at. Codes saturate at ±127
//! (±1.98 voxels): [`CODE_FAR`] means "at least that far outside the stand-off", [`CODE_DEEP`] "at
//! least that deep". The stand-off is baked in, so the frame path needs no parameter for it.
//!
//! **Layout.** The grid is cut into cubes of 8³ voxels (the tree's leaf cube). A cube whose samples
//! are all saturated the same way needs no storage: its directory slot says [`SLOT_FAR`] or
//! [`SLOT_DEEP`]. Every other cube has a brick of 9³ codes: its 8³ samples plus the first sample
//! of the next cube on each axis (an apron), so that the trilinear cell of any point whose lower
//! corner lies in the cube reads one brick. Bricks are numbered in directory order (x fastest), so
//! equal content gives equal bytes.
//!
//! **Query** ([`DistanceBand::cell`]): the trilinear cell whose lower corner sample is `base`;
//! [`BandCell::value_and_gradient`] interpolates `e` (in voxels) and its gradient (the direction of
//! steepest increase: the scene's outward normal at the surface). f32 basic operations in a fixed
//! order, no fused multiply-add: the same bits on every machine.
//!
//! Memory: 4 bytes per 8³ cube (the directory) plus 729 bytes per brick.
//!
//! **In memory** the bricks follow two constant bricks, one all [`CODE_FAR`] at slot
//! [`SLOT_FAR`] and one all [`CODE_DEEP`] at slot [`SLOT_DEEP`], and end in [`CODES_PADDING`]
//! bytes: every directory slot `v` then names the brick at `v · 729` ([`DistanceBand::slot_codes`]),
//! so a SIMD kernel reads the cell of any lane, far and deep ones included, with the same four
//! 4-byte gathers and no branch. The file holds only the stored bricks ([`DistanceBand::codes`]).

use crate::GridSpec;

/// Voxels per cube edge (the tree's leaf cube).
pub const CUBE_EDGE: u32 = 8;
/// Samples per brick edge: the cube's 8 plus one of the next cube (the apron).
pub const BRICK_EDGE: usize = 9;
/// Codes per brick: `9³`.
pub const BRICK_CODES: usize = BRICK_EDGE * BRICK_EDGE * BRICK_EDGE;
/// Quantisation: codes per voxel of distance (a code is `s / 64`).
pub const CODES_PER_VOXEL: f32 = 64.0;
/// A sample at least [`BAND_VOXELS`] outside the stand-off.
pub const CODE_FAR: i8 = 127;
/// A sample at least [`BAND_VOXELS`] inside the stand-off (deep).
pub const CODE_DEEP: i8 = -127;
/// The band's half width in voxels: `127 / 64`.
pub const BAND_VOXELS: f32 = 127.0 / CODES_PER_VOXEL;
/// The largest stand-off a band holds, in voxels: the surface itself (`d = 0`, `e = −standoff`)
/// must lie almost a voxel inside the band (127/64 − 1 = 0.98 voxel), so that points just inside
/// it are still resolved.
pub const MAX_STANDOFF_VOXELS: f64 = 1.0;

/// The stand-off a scene gets when it states none, in voxels: half a voxel. Measured on the
/// standard session (the teapot through the aircraft bay at 5 mm, `vps sweep`): the smallest
/// exact separation of any shell point was −1.27 mm at 1/8 voxel, −0.79 mm at 1/4, −0.15 mm at
/// 3/8 and +0.62 mm at 1/2. Two effects add up: a single contact point under the coupling's
/// largest force sits `k_T s / 2 / K_ff = s / 4` into the stand-off (no averaging below ten
/// contacts), and trilinear interpolation reads the distance near the scene's convex edges up to
/// about 0.2 voxel high. A smaller stand-off (`voxels.standoff`) resolves tighter clearances but no
/// longer keeps every point outside the exact surface at sharp edges.
pub const DEFAULT_STANDOFF_VOXELS: f64 = 0.5;

/// Directory slot value of a cube whose samples are all [`CODE_FAR`] (and of any cell outside the
/// grid, [`DistanceBand::slot_of_cell`]).
pub const SLOT_FAR: u32 = 0;
/// Directory slot value of a cube whose samples are all [`CODE_DEEP`].
pub const SLOT_DEEP: u32 = 1;
/// Brick `k` is stored in slots as `k + BRICK_SLOT_BASE`.
const BRICK_SLOT_BASE: u32 = 2;
/// Bytes after the last brick in memory, so that a 4-byte read at any cell corner of any brick
/// stays inside the allocation (the farthest corner row starts 2 bytes before a brick's end).
pub const CODES_PADDING: usize = 4;
/// Codes before the first stored brick in memory: the constant far and deep bricks.
const CONSTANT_CODES: usize = BRICK_SLOT_BASE as usize * BRICK_CODES;

/// The signed-distance band of a voxmap (see the module docs). Immutable once built; `Sync`.
///
/// Invariants (checked by [`DistanceBand::from_parts`]): the directory has one slot per cube of the
/// grid; brick slots number the bricks 0, 1, 2, … in directory order; exactly 729 codes per
/// brick, none equal to −128; the stand-off is finite, in `[0, 1]` voxel. In memory
/// (`slot_codes`): the far brick, the deep brick, the stored bricks, [`CODES_PADDING`] zeros.
#[derive(Clone, Debug, PartialEq)]
pub struct DistanceBand {
    standoff_m: f64,
    cube_dims: [u32; 3],
    directory: Vec<u32>,
    slot_codes: Vec<i8>,
}

/// Why band parts are not a valid [`DistanceBand`]; each names the field at fault.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BandError {
    /// The stand-off is not finite or outside `[0, 1]` voxel.
    #[error("distance band standoff: {standoff_m} m is not within 0..={max_m} m (one voxel)")]
    Standoff {
        /// The stand-off given (m).
        standoff_m: f64,
        /// The largest allowed (m).
        max_m: f64,
    },
    /// The cube dims do not match the grid.
    #[error("distance band cube dims {found:?}: the grid's dims imply {expected:?}")]
    CubeDims {
        /// As given.
        found: [u32; 3],
        /// `ceil(grid dims / 8)`.
        expected: [u32; 3],
    },
    /// The directory has the wrong length.
    #[error("distance band directory: {found} slots, the cube dims imply {expected}")]
    DirectoryLength {
        /// As given.
        found: usize,
        /// One per cube.
        expected: u64,
    },
    /// A brick slot is out of order (bricks must be numbered in directory order).
    #[error("distance band directory slot {slot}: brick {found}, expected brick {expected} (bricks are numbered in directory order)")]
    BrickOrder {
        /// Slot index.
        slot: usize,
        /// Brick named.
        found: u32,
        /// The next brick number.
        expected: u32,
    },
    /// The codes do not hold 729 per brick.
    #[error("distance band codes: {found} codes for {bricks} bricks (729 each)")]
    CodesLength {
        /// As given.
        found: usize,
        /// Bricks in the directory.
        bricks: u64,
    },
    /// A code is −128 (reserved).
    #[error("distance band code {index}: -128 is reserved (codes are -127..=127)")]
    ReservedCode {
        /// Index of the first such code.
        index: usize,
    },
}

/// The cubes per axis of a grid of `dims` voxels: `ceil(dims / 8)`.
pub fn cube_dims(spec: &GridSpec) -> [u32; 3] {
    spec.dims.map(|d| d.div_ceil(CUBE_EDGE))
}

/// The eight codes of one trilinear cell, `corners[z][y][x]`, as f32.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BandCell {
    /// Codes of the cell's corners (`s / 64` each), `[z][y][x]`.
    pub corners: [[[f32; 2]; 2]; 2],
}

/// What the band holds at one trilinear cell.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CellLookup {
    /// Free space beyond the band (outside the grid included).
    Far,
    /// Inside the scene beyond the band.
    Deep,
    /// A cell of stored samples.
    Near(BandCell),
}

impl BandCell {
    /// `e` (voxels, `d − standoff`) at fractional position `f` (each in `[0, 1]`) in the cell, and
    /// its gradient (per voxel, dimensionless: the outward direction, not normalised). The f32
    /// operations and their order are fixed (no fused multiply-add), so the bits are the same on
    /// every machine. Does not allocate.
    #[inline(always)]
    pub fn value_and_gradient(&self, f: [f32; 3]) -> (f32, [f32; 3]) {
        let c = &self.corners;
        let [fx, fy, fz] = f;
        let (gx, gy, gz) = (1.0 - fx, 1.0 - fy, 1.0 - fz);
        // Edges along x, then their interpolation.
        let x00 = c[0][0][0] * gx + c[0][0][1] * fx;
        let x10 = c[0][1][0] * gx + c[0][1][1] * fx;
        let x01 = c[1][0][0] * gx + c[1][0][1] * fx;
        let x11 = c[1][1][0] * gx + c[1][1][1] * fx;
        let y0 = x00 * gy + x10 * fy;
        let y1 = x01 * gy + x11 * fy;
        let value = y0 * gz + y1 * fz;
        // d/dx: the x differences interpolated in y and z.
        let d00 = c[0][0][1] - c[0][0][0];
        let d10 = c[0][1][1] - c[0][1][0];
        let d01 = c[1][0][1] - c[1][0][0];
        let d11 = c[1][1][1] - c[1][1][0];
        let dx = (d00 * gy + d10 * fy) * gz + (d01 * gy + d11 * fy) * fz;
        // d/dy from the x-interpolated edges; d/dz from the y-interpolated faces.
        let dy = (x10 - x00) * gz + (x11 - x01) * fz;
        let dz = y1 - y0;
        let q = 1.0 / CODES_PER_VOXEL;
        (value * q, [dx * q, dy * q, dz * q])
    }
}

impl DistanceBand {
    /// A band from its parts (see the type's invariants); the error names the part at fault.
    /// `spec` is the grid of the tree the band belongs to.
    pub fn from_parts(
        spec: &GridSpec,
        standoff_m: f64,
        cube_dims_given: [u32; 3],
        directory: Vec<u32>,
        codes: Vec<i8>,
    ) -> Result<DistanceBand, BandError> {
        let max_m = MAX_STANDOFF_VOXELS * spec.voxel_size;
        if !(standoff_m.is_finite() && (0.0..=max_m).contains(&standoff_m)) {
            return Err(BandError::Standoff { standoff_m, max_m });
        }
        let expected = cube_dims(spec);
        if cube_dims_given != expected {
            return Err(BandError::CubeDims {
                found: cube_dims_given,
                expected,
            });
        }
        let slots: u64 = expected.iter().map(|&d| u64::from(d)).product();
        if directory.len() as u64 != slots {
            return Err(BandError::DirectoryLength {
                found: directory.len(),
                expected: slots,
            });
        }
        let mut next = 0u32;
        for (slot, &v) in directory.iter().enumerate() {
            if v >= BRICK_SLOT_BASE {
                let found = v - BRICK_SLOT_BASE;
                if found != next {
                    return Err(BandError::BrickOrder {
                        slot,
                        found,
                        expected: next,
                    });
                }
                next += 1;
            }
        }
        if codes.len() as u64 != u64::from(next) * BRICK_CODES as u64 {
            return Err(BandError::CodesLength {
                found: codes.len(),
                bricks: u64::from(next),
            });
        }
        if let Some(index) = codes.iter().position(|&c| c == i8::MIN) {
            return Err(BandError::ReservedCode { index });
        }
        let mut slot_codes = Vec::with_capacity(CONSTANT_CODES + codes.len() + CODES_PADDING);
        slot_codes.extend_from_slice(&[CODE_FAR; BRICK_CODES]);
        slot_codes.extend_from_slice(&[CODE_DEEP; BRICK_CODES]);
        slot_codes.extend_from_slice(&codes);
        slot_codes.extend_from_slice(&[0; CODES_PADDING]);
        Ok(DistanceBand {
            standoff_m,
            cube_dims: expected,
            directory,
            slot_codes,
        })
    }

    /// The stand-off baked into the codes (m): contact begins where the exact distance falls
    /// below it.
    pub fn standoff_m(&self) -> f64 {
        self.standoff_m
    }

    /// Cubes per axis.
    pub fn cube_dims(&self) -> [u32; 3] {
        self.cube_dims
    }

    /// Raw directory slots (file encoding).
    pub fn directory(&self) -> &[u32] {
        &self.directory
    }

    /// The stored bricks' codes, brick after brick (file encoding).
    pub fn codes(&self) -> &[i8] {
        &self.slot_codes[CONSTANT_CODES..self.slot_codes.len() - CODES_PADDING]
    }

    /// The in-memory codes: directory slot `v` names the 729 codes at `v · 729` (slot
    /// [`SLOT_FAR`] a brick of [`CODE_FAR`], [`SLOT_DEEP`] one of [`CODE_DEEP`]), followed by
    /// [`CODES_PADDING`] zeros. For kernels that gather codes by slot; the length is not bounded
    /// by `i32::MAX` (check it before using 32-bit offsets).
    pub fn slot_codes(&self) -> &[i8] {
        &self.slot_codes
    }

    /// Number of bricks stored.
    pub fn brick_count(&self) -> usize {
        self.codes().len() / BRICK_CODES
    }

    /// Heap bytes held: the directory and the bricks (the two constant bricks included).
    pub fn memory_bytes(&self) -> usize {
        4 * self.directory.capacity() + self.slot_codes.capacity()
    }

    /// The deepest contact depth a point can report (m): a point deeper than the band pushes with
    /// the band's depth, [`BAND_VOXELS`] voxels.
    pub fn max_contact_depth(&self, voxel_size: f64) -> f64 {
        f64::from(BAND_VOXELS) * voxel_size
    }

    /// The raw directory slot of the cube holding the trilinear cell whose lower corner is the
    /// sample of voxel `base`: [`SLOT_FAR`] (also outside the grid), [`SLOT_DEEP`], or a brick's
    /// slot for [`DistanceBand::cell_codes`]. One load; does not allocate or block.
    #[inline(always)]
    pub fn slot_of_cell(&self, base: [i32; 3]) -> u32 {
        let [nx, ny, nz] = self.cube_dims;
        let c = base.map(|b| b >> 3);
        if c[0] < 0
            || c[1] < 0
            || c[2] < 0
            || c[0] as u32 >= nx
            || c[1] as u32 >= ny
            || c[2] as u32 >= nz
        {
            return SLOT_FAR;
        }
        self.directory[(c[2] as usize * ny as usize + c[1] as usize) * nx as usize + c[0] as usize]
    }

    /// The eight codes (`[z][y][x]`) of the trilinear cell whose lower corner is the sample of
    /// voxel `base`, in the brick of directory slot `slot` (the slot that
    /// [`DistanceBand::slot_of_cell`] returned for the same `base`; [`SLOT_FAR`] and [`SLOT_DEEP`]
    /// read their constant bricks). Eight loads; does not allocate or block.
    #[inline(always)]
    pub fn cell_codes(&self, slot: u32, base: [i32; 3]) -> [[[i8; 2]; 2]; 2] {
        let brick = slot as usize * BRICK_CODES;
        let l = base.map(|b| (b & (CUBE_EDGE as i32 - 1)) as usize);
        let at = brick + (l[2] * BRICK_EDGE + l[1]) * BRICK_EDGE + l[0];
        let codes = &self.slot_codes[at..at + BRICK_EDGE * BRICK_EDGE + BRICK_EDGE + 2];
        let get = |x: usize, y: usize, z: usize| codes[(z * BRICK_EDGE + y) * BRICK_EDGE + x];
        [
            [[get(0, 0, 0), get(1, 0, 0)], [get(0, 1, 0), get(1, 1, 0)]],
            [[get(0, 0, 1), get(1, 0, 1)], [get(0, 1, 1), get(1, 1, 1)]],
        ]
    }

    /// The trilinear cell whose lower corner is the sample of voxel `base` (samples sit at voxel
    /// centres, so the cell spans voxel centres `base ..= base + 1` on each axis). Reads one
    /// directory slot and eight codes of one brick. Does not allocate or block.
    #[inline(always)]
    pub fn cell(&self, base: [i32; 3]) -> CellLookup {
        match self.slot_of_cell(base) {
            SLOT_FAR => CellLookup::Far,
            SLOT_DEEP => CellLookup::Deep,
            slot => CellLookup::Near(BandCell {
                corners: self
                    .cell_codes(slot, base)
                    .map(|plane| plane.map(|row| row.map(f32::from))),
            }),
        }
    }

    /// `e` (m, `d − standoff`) at world point `p` (m) of the grid `spec`, interpolated; `None`
    /// beyond the band (far outside or deep inside). For inspection and tests, not the frame path.
    pub fn standoff_distance_at(&self, spec: &GridSpec, p: glam::DVec3) -> Option<f64> {
        let t = (p - spec.origin) / spec.voxel_size - glam::DVec3::splat(0.5);
        let base = t.floor();
        let f = (t - base).as_vec3().to_array();
        match self.cell(base.as_ivec3().to_array()) {
            CellLookup::Near(cell) => {
                let (e, _) = cell.value_and_gradient(f);
                Some(f64::from(e) * spec.voxel_size)
            }
            _ => None,
        }
    }
}

/// Assembles a band from a per-cube sampler: `sample(cube)` returns the cube's 729 codes (its 8³
/// samples and the apron, `[z][y][x]` with x fastest), or `None` when none of them lies within the
/// band, in which case `deep(cube)` says whether the cube is inside the scene. Cubes are visited in
/// directory order. The builder of the voxelizer supplies the sampler; this keeps the numbering
/// canonical.
pub fn assemble(
    spec: &GridSpec,
    standoff_m: f64,
    mut cubes: impl FnMut([u32; 3]) -> CubeCodes,
) -> Result<DistanceBand, BandError> {
    let dims = cube_dims(spec);
    let mut directory = Vec::with_capacity(dims.iter().map(|&d| d as usize).product());
    let mut codes = Vec::new();
    let mut bricks = 0u32;
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                match cubes([x, y, z]) {
                    CubeCodes::Far => directory.push(SLOT_FAR),
                    CubeCodes::Deep => directory.push(SLOT_DEEP),
                    CubeCodes::Brick(b) => {
                        directory.push(bricks + BRICK_SLOT_BASE);
                        codes.extend_from_slice(&b[..]);
                        bricks += 1;
                    }
                }
            }
        }
    }
    DistanceBand::from_parts(spec, standoff_m, dims, directory, codes)
}

/// One cube's content for [`assemble`].
#[derive(Clone, Debug, PartialEq)]
pub enum CubeCodes {
    /// All samples far outside.
    Far,
    /// All samples deep inside.
    Deep,
    /// The 729 codes.
    Brick(Box<[i8; BRICK_CODES]>),
}

impl CubeCodes {
    /// A cube of `codes` (its 729 samples, `[z][y][x]` with x fastest): [`CubeCodes::Far`] or
    /// [`CubeCodes::Deep`] when every code is saturated that way (nothing to store), else the
    /// brick.
    pub fn from_codes(codes: Box<[i8; BRICK_CODES]>) -> CubeCodes {
        if codes.iter().all(|&c| c == CODE_FAR) {
            CubeCodes::Far
        } else if codes.iter().all(|&c| c == CODE_DEEP) {
            CubeCodes::Deep
        } else {
            CubeCodes::Brick(codes)
        }
    }
}

/// The code of a stand-off distance `e` (m) at voxel size `s` (m): `round(e · 64 / s)` clamped to
/// ±127.
pub fn code_of(e_m: f64, voxel_size: f64) -> i8 {
    let q = (e_m / voxel_size * f64::from(CODES_PER_VOXEL)).round();
    q.clamp(f64::from(CODE_DEEP), f64::from(CODE_FAR)) as i8
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn spec() -> GridSpec {
        GridSpec {
            origin: DVec3::ZERO,
            voxel_size: 0.01,
            dims: [20, 10, 9],
        }
    }

    /// A plane `z = 0.045` m (outside above): every cube sampled analytically.
    fn plane_band(standoff: f64) -> DistanceBand {
        let s = spec();
        assemble(&s, standoff, |c| {
            let mut b = Box::new([0i8; BRICK_CODES]);
            for (z, plane) in b.chunks_mut(BRICK_EDGE * BRICK_EDGE).enumerate() {
                let zc = (f64::from(c[2] * 8) + z as f64 + 0.5) * s.voxel_size;
                plane.fill(code_of(zc - 0.045 - standoff, s.voxel_size));
            }
            CubeCodes::from_codes(b)
        })
        .unwrap()
    }

    #[test]
    fn a_plane_is_interpolated_exactly_with_its_normal() {
        let band = plane_band(0.002);
        let s = spec();
        for &(x, y, z) in &[
            (0.031, 0.052, 0.047),
            (0.1234, 0.02, 0.04),
            (0.07, 0.07, 0.0501),
        ] {
            let e = band.standoff_distance_at(&s, DVec3::new(x, y, z)).unwrap();
            // Quantisation: half a code, s / 128.
            assert!(
                (e - (z - 0.045 - 0.002)).abs() <= s.voxel_size / 128.0 + 1e-9,
                "{e}"
            );
        }
        let t = DVec3::new(3.3, 4.1, 3.9);
        let base = t.floor();
        let CellLookup::Near(cell) = band.cell(base.as_ivec3().to_array()) else {
            panic!("near the plane")
        };
        let (_, g) = cell.value_and_gradient((t - base).as_vec3().to_array());
        assert_eq!(g[0], 0.0);
        assert_eq!(g[1], 0.0);
        assert!((g[2] - 1.0).abs() < 1.0 / 64.0, "{g:?}");
    }

    #[test]
    fn far_and_deep_cubes_are_not_stored_and_outside_reads_far() {
        let band = plane_band(0.0);
        assert_eq!(band.cell([-3, 0, 0]), CellLookup::Far);
        assert_eq!(band.cell([0, 0, 900]), CellLookup::Far);
        assert!(band.brick_count() > 0);
        assert!(band.brick_count() < band.directory().len());
    }

    #[test]
    fn every_slot_names_its_brick_in_memory_and_the_file_holds_the_stored_bricks_only() {
        let band = plane_band(0.0);
        let codes = band.slot_codes();
        assert_eq!(
            codes.len(),
            (band.brick_count() + 2) * BRICK_CODES + CODES_PADDING
        );
        assert!(codes[..BRICK_CODES].iter().all(|&c| c == CODE_FAR));
        assert!(codes[BRICK_CODES..2 * BRICK_CODES]
            .iter()
            .all(|&c| c == CODE_DEEP));
        assert_eq!(
            band.codes(),
            &codes[2 * BRICK_CODES..codes.len() - CODES_PADDING]
        );
        assert_eq!(
            band.cell_codes(SLOT_FAR, [5, 6, 7]),
            [[[CODE_FAR; 2]; 2]; 2]
        );
        assert_eq!(
            band.cell_codes(SLOT_DEEP, [7, 7, 7]),
            [[[CODE_DEEP; 2]; 2]; 2]
        );
        let again = DistanceBand::from_parts(
            &spec(),
            band.standoff_m(),
            band.cube_dims(),
            band.directory().to_vec(),
            band.codes().to_vec(),
        )
        .unwrap();
        assert_eq!(again, band);
    }

    #[test]
    fn parts_that_break_an_invariant_are_refused_naming_it() {
        let s = spec();
        let dims = cube_dims(&s);
        let n = dims.iter().product::<u32>() as usize;
        let too_far = DistanceBand::from_parts(&s, 0.011, dims, vec![0; n], vec![]);
        assert!(matches!(too_far, Err(BandError::Standoff { .. })));
        let short = DistanceBand::from_parts(&s, 0.0, dims, vec![0; n - 1], vec![]);
        assert!(matches!(short, Err(BandError::DirectoryLength { .. })));
        let mut dir = vec![0; n];
        dir[3] = 3; // brick 1 before brick 0
        let order = DistanceBand::from_parts(&s, 0.0, dims, dir, vec![0; 729]);
        assert!(matches!(order, Err(BandError::BrickOrder { slot: 3, .. })));
        let mut dir = vec![0; n];
        dir[3] = 2;
        let codes = DistanceBand::from_parts(&s, 0.0, dims, dir.clone(), vec![0; 728]);
        assert!(matches!(codes, Err(BandError::CodesLength { .. })));
        let mut bad = vec![0i8; 729];
        bad[5] = i8::MIN;
        let reserved = DistanceBand::from_parts(&s, 0.0, dims, dir, bad);
        assert_eq!(reserved, Err(BandError::ReservedCode { index: 5 }));
    }

    #[test]
    fn codes_round_and_saturate() {
        assert_eq!(code_of(0.0, 0.01), 0);
        assert_eq!(code_of(0.01 / 64.0 * 3.4, 0.01), 3);
        assert_eq!(code_of(1.0, 0.01), CODE_FAR);
        assert_eq!(code_of(-1.0, 0.01), CODE_DEEP);
    }
}
