//! Grid generators shared by the voxmap integration tests.
#![allow(dead_code)]

use glam::{DVec3, IVec3, UVec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use vps_voxmap::{CubeSource, DenseGrid, GridSpec, Voxel};

/// A seeded generator.
pub fn rng(seed: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(seed)
}

/// An all-Free grid with an off-zero origin.
pub fn empty(dims: [u32; 3]) -> DenseGrid {
    DenseGrid::new(GridSpec {
        origin: DVec3::new(-0.25, 0.5, 1.0),
        voxel_size: 0.005,
        dims,
    })
}

/// Independent random voxels: each non-Free with probability `density`.
pub fn sparse(dims: [u32; 3], density: f64, seed: u64) -> DenseGrid {
    let mut g = empty(dims);
    let mut r = rng(seed);
    for b in g.data.iter_mut() {
        if r.gen_bool(density) {
            *b = r.gen_range(1..4);
        }
    }
    g
}

/// Large uniform regions: random solid Interior boxes wrapped in Surface and Proximity shells, so
/// whole leaves and nodes are uniform Free or Interior.
pub fn boxes(dims: [u32; 3], count: usize, seed: u64) -> DenseGrid {
    let mut g = empty(dims);
    let mut r = rng(seed);
    let d = IVec3::new(dims[0] as i32, dims[1] as i32, dims[2] as i32);
    for _ in 0..count {
        let lo = IVec3::new(
            r.gen_range(-4..d.x),
            r.gen_range(-4..d.y),
            r.gen_range(-4..d.z),
        );
        let size = IVec3::new(
            r.gen_range(1..d.x),
            r.gen_range(1..d.y),
            r.gen_range(1..d.z),
        );
        fill_box(&mut g, lo - 2, lo + size + 2, Voxel::Proximity);
        fill_box(&mut g, lo - 1, lo + size + 1, Voxel::Surface);
        fill_box(&mut g, lo, lo + size, Voxel::Interior);
    }
    g
}

/// Sets every voxel in `[lo, hi)` (clipped to the grid) to `v`.
pub fn fill_box(g: &mut DenseGrid, lo: IVec3, hi: IVec3, v: Voxel) {
    for z in lo.z..hi.z {
        for y in lo.y..hi.y {
            for x in lo.x..hi.x {
                g.set(IVec3::new(x, y, z), v);
            }
        }
    }
}

/// Codes from a function of the voxel index (0 outside the grid).
pub struct FnSource<F: Fn(UVec3) -> u8 + Sync> {
    pub dims: [u32; 3],
    pub code: F,
}

impl<F: Fn(UVec3) -> u8 + Sync> CubeSource for FnSource<F> {
    fn cube(&self, origin: UVec3, extent: u32, out: &mut [u8]) -> Option<u8> {
        let e = extent as usize;
        for (i, o) in out.iter_mut().enumerate() {
            let p = origin + UVec3::new((i % e) as u32, (i / e % e) as u32, (i / (e * e)) as u32);
            let inside = (0..3).all(|a| p[a] < self.dims[a]);
            *o = if inside { (self.code)(p) } else { 0 };
        }
        None
    }
}

/// Asserts that `read` rejects every copy of `bytes` with one byte flipped by 0x01, 0x80 or 0xFF.
pub fn assert_every_flipped_byte_rejected<T, E>(
    bytes: &[u8],
    read: impl Fn(&[u8]) -> Result<T, E>,
) {
    for i in 0..bytes.len() {
        for flip in [0x01u8, 0x80, 0xFF] {
            let mut damaged = bytes.to_vec();
            damaged[i] ^= flip;
            assert!(read(&damaged).is_err(), "byte {i} ^ {flip:#x} accepted");
        }
    }
}
