//! The finished chunks as a [`CubeSource`], so the tree is built without a dense grid.

use super::chunk::{ChunkGrid, CHUNK};
use super::finish::Final;
use glam::UVec3;
use vps_voxmap::CubeSource;

/// `SPREAD[b]` has bit `i` of `b` at bit `8 i`: eight plane bits to eight code bytes.
const SPREAD: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut b = 0;
    while b < 256 {
        let mut i = 0;
        while i < 8 {
            if b >> i & 1 == 1 {
                t[b] |= 1 << (8 * i);
            }
            i += 1;
        }
        b += 1;
    }
    t
};

/// Finished chunks over a chunk grid.
pub(crate) struct ChunkSource<'a> {
    pub grid: ChunkGrid,
    pub chunks: &'a [Final],
}

impl ChunkSource<'_> {
    /// The chunk ranges (inclusive) meeting the cube `origin..origin + extent` inside the grid.
    fn range(&self, origin: UVec3, extent: u32) -> [std::ops::RangeInclusive<usize>; 3] {
        let lo = origin.to_array().map(|v| v as usize);
        let hi: [usize; 3] =
            std::array::from_fn(|a| (lo[a] + extent as usize).min(self.grid.dims[a]) - 1);
        self.grid.chunks_of(lo, hi)
    }
}

impl CubeSource for ChunkSource<'_> {
    fn cube(&self, origin: UVec3, extent: u32, out: &mut [u8]) -> Option<u8> {
        let [rx, ry, rz] = self.range(origin, extent);
        let mut codes = rz.clone().flat_map(|z| {
            let rx = rx.clone();
            ry.clone()
                .flat_map(move |y| rx.clone().map(move |x| [x, y, z]))
        });
        let first = match &self.chunks[self.grid.index(codes.next()?)] {
            Final::Uniform(c) => Some(*c),
            Final::Planes(_) => None,
        };
        if let Some(c) = first {
            if codes
                .all(|nc| matches!(self.chunks[self.grid.index(nc)], Final::Uniform(v) if v == c))
            {
                return Some(c);
            }
        }
        out.fill(0);
        let e = extent as usize;
        let o = origin.to_array().map(|v| v as usize);
        let mut row_bytes = [0u8; CHUNK];
        for nz in rz {
            for ny in ry.clone() {
                for nx in rx.clone() {
                    let nc = [nx, ny, nz];
                    let co = self.grid.origin(nc);
                    let cd = self.grid.chunk_dims(nc);
                    let r_lo: [usize; 3] = std::array::from_fn(|a| o[a].max(co[a]));
                    let r_hi: [usize; 3] = std::array::from_fn(|a| (o[a] + e).min(co[a] + cd[a]));
                    let len = r_hi[0] - r_lo[0];
                    for z in r_lo[2]..r_hi[2] {
                        for y in r_lo[1]..r_hi[1] {
                            let at = (r_lo[0] - o[0]) + e * ((y - o[1]) + e * (z - o[2]));
                            let dst = &mut out[at..at + len];
                            match &self.chunks[self.grid.index(nc)] {
                                Final::Uniform(c) => dst.fill(*c),
                                Final::Planes(planes) => {
                                    let row = (y - co[1]) + cd[1] * (z - co[2]);
                                    let mut words = [0u64; 8];
                                    for (w, p) in words.iter_mut().zip(planes) {
                                        *w = p.words[row];
                                    }
                                    decode_row(&words[..planes.len()], &mut row_bytes);
                                    let from = r_lo[0] - co[0];
                                    dst.copy_from_slice(&row_bytes[from..from + len]);
                                }
                            }
                        }
                    }
                }
            }
        }
        None
    }
}

/// The 64 codes of one chunk row from its code-bit plane words (`planes[b]`: bit `b` of each code).
fn decode_row(planes: &[u64], out: &mut [u8; CHUNK]) {
    for (g, bytes) in out.chunks_exact_mut(8).enumerate() {
        let mut v = 0u64;
        for (b, &w) in planes.iter().enumerate() {
            v |= SPREAD[(w >> (8 * g) & 0xFF) as usize] << b;
        }
        bytes.copy_from_slice(&v.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_row_assembles_codes_from_bit_planes() {
        let codes: Vec<u8> = (0..64).map(|i| (i * 37 % 256) as u8).collect();
        let planes: Vec<u64> = (0..8)
            .map(|b| {
                codes
                    .iter()
                    .enumerate()
                    .fold(0u64, |w, (i, &c)| w | ((c >> b & 1) as u64) << i)
            })
            .collect();
        let mut out = [0u8; CHUNK];
        decode_row(&planes, &mut out);
        assert_eq!(out.to_vec(), codes);
    }
}
