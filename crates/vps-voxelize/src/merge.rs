//! Combining objects and writing the result. Objects are voxelized one at a time in windows of the
//! shared grid and OR-ed into two shared planes; Interior wins over Surface, which wins over Free
//! (the precedence of [`vps_voxmap::Voxel::merge`]; Proximity does not exist yet at merge time and
//! is computed once on the merged result). The final planes are written into a [`DenseGrid`].

use crate::bitgrid::BitGrid;
use crate::offset::Layers;
use crate::scan_convert::Window;
use rayon::prelude::*;
use vps_voxmap::{DenseGrid, GridSpec, Voxel};

/// Interior and Surface planes of the whole grid, accumulated object by object.
#[derive(Debug)]
pub(crate) struct MergedPlanes {
    interior: BitGrid,
    surface: BitGrid,
}

impl MergedPlanes {
    /// Empty (all Free) planes of `dims`.
    pub fn new(dims: [usize; 3]) -> Self {
        Self {
            interior: BitGrid::zeros(dims),
            surface: BitGrid::zeros(dims),
        }
    }

    /// Adds one object's planes, which cover `window` of the grid. `window.offset[0]` must be a
    /// multiple of 64 so that rows combine word by word.
    pub fn add(&mut self, window: &Window, interior: &BitGrid, surface: &BitGrid) {
        debug_assert_eq!(window.offset[0] % 64, 0);
        for (dst, src) in [(&mut self.interior, interior), (&mut self.surface, surface)] {
            let w0 = window.offset[0] / 64;
            let (gny, grw, lrw) = (dst.dims[1], dst.row_words, src.row_words);
            for z in 0..window.dims[2] {
                for y in 0..window.dims[1] {
                    let grow = (y + window.offset[1]) + gny * (z + window.offset[2]);
                    let lrow = y + window.dims[1] * z;
                    let d = &mut dst.words[grow * grw + w0..grow * grw + w0 + lrw];
                    for (a, &b) in d.iter_mut().zip(&src.words[lrow * lrw..(lrow + 1) * lrw]) {
                        *a |= b;
                    }
                }
            }
        }
    }

    /// The merged (Interior, Surface) planes, disjoint: Surface claimed by one object inside another
    /// object's Interior is Interior.
    pub fn finish(self) -> (BitGrid, BitGrid) {
        let mut surface = self.surface;
        surface.combine(&self.interior, |s, i| s & !i);
        (self.interior, surface)
    }
}

/// Writes disjoint planes into a dense grid (one byte per voxel). Parallel over z slices; only
/// non-Free voxels are written, so all-Free pages of the fresh zeroed buffer are never touched.
pub(crate) fn to_dense(spec: GridSpec, layers: &Layers) -> DenseGrid {
    let mut grid = DenseGrid::new(spec);
    let [nx, ny, _] = layers.surface.dims;
    let rw = layers.surface.row_words;
    let sw = layers.surface.slice_words();
    if nx * ny == 0 {
        return grid;
    }
    grid.data
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, out)| {
            for y in 0..ny {
                for w in 0..rw {
                    let i = z * sw + y * rw + w;
                    let (iw, sw_, pw) = (
                        layers.interior.words[i],
                        layers.surface.words[i],
                        layers.proximity.words[i],
                    );
                    let mut any = iw | sw_ | pw;
                    while any != 0 {
                        let b = any.trailing_zeros();
                        any &= any - 1;
                        let v = if iw >> b & 1 == 1 {
                            Voxel::Interior
                        } else if sw_ >> b & 1 == 1 {
                            Voxel::Surface
                        } else {
                            Voxel::Proximity
                        };
                        out[y * nx + 64 * w + b as usize] = v.bits();
                    }
                }
            }
        });
    grid
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plane merge agrees with `Voxel::merge` for every pair of per-object kinds.
    #[test]
    fn plane_merge_matches_voxel_merge_precedence() {
        let kinds = [Voxel::Free, Voxel::Interior, Voxel::Surface];
        let dims = [64, 1, 1];
        let w = Window {
            offset: [0; 3],
            dims,
        };
        let mut merged = MergedPlanes::new(dims);
        let mut expected = Vec::new();
        for &a in &kinds {
            for &b in &kinds {
                expected.push(a.merge(b));
            }
        }
        for pick in [0usize, 1] {
            let mut interior = BitGrid::zeros(dims);
            let mut surface = BitGrid::zeros(dims);
            for (n, (a, b)) in kinds
                .iter()
                .flat_map(|a| kinds.iter().map(move |b| (*a, *b)))
                .enumerate()
            {
                let k = if pick == 0 { a } else { b };
                match k {
                    Voxel::Interior => interior.set(n, 0, 0),
                    Voxel::Surface => surface.set(n, 0, 0),
                    _ => {}
                }
            }
            merged.add(&w, &interior, &surface);
        }
        let (interior, surface) = merged.finish();
        let layers = Layers {
            proximity: BitGrid::zeros(dims),
            interior,
            surface,
        };
        let spec = GridSpec::at_origin(1.0, [64, 1, 1]);
        let dense = to_dense(spec, &layers);
        for (n, e) in expected.iter().enumerate() {
            assert_eq!(Voxel::from_bits(dense.data[n]), *e, "pair {n}");
        }
    }

    #[test]
    fn window_offsets_are_respected() {
        let dims = [130, 4, 3];
        let mut merged = MergedPlanes::new(dims);
        let w = Window {
            offset: [64, 1, 2],
            dims: [66, 2, 1],
        };
        let mut s = BitGrid::zeros(w.dims);
        s.set(0, 0, 0);
        s.set(65, 1, 0);
        merged.add(&w, &BitGrid::zeros(w.dims), &s);
        let (_, surface) = merged.finish();
        assert_eq!(surface.count(), 2);
        assert!(surface.get(64, 1, 2) && surface.get(129, 2, 2));
    }
}
