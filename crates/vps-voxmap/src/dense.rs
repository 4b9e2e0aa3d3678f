//! A dense grid of voxels, one byte each: the voxelizer's workspace, the tree's test oracle and the
//! benchmark baseline for lookup cost. Memory is `dims.x * dims.y * dims.z` bytes: never the runtime
//! representation of a large scene.

use crate::{GridSpec, Voxel};
use glam::IVec3;

/// One byte per voxel over a [`GridSpec`]; x varies fastest.
#[derive(Clone, Debug, PartialEq)]
pub struct DenseGrid {
    /// The grid's placement and size.
    pub spec: GridSpec,
    /// `spec.voxel_count()` bytes, each a [`Voxel`] value.
    pub data: Vec<u8>,
}

impl DenseGrid {
    /// An all-Free grid.
    pub fn new(spec: GridSpec) -> Self {
        Self {
            spec,
            data: vec![Voxel::Free as u8; spec.voxel_count() as usize],
        }
    }

    /// The grid whose voxel at each index `ijk` is `f(ijk)`, called once per voxel in storage
    /// order (x fastest, then y, then z).
    pub fn from_fn(spec: GridSpec, mut f: impl FnMut(IVec3) -> Voxel) -> Self {
        let [nx, ny, nz] = spec.dims.map(|d| d as i32);
        let mut data = Vec::with_capacity(spec.voxel_count() as usize);
        for z in 0..nz {
            for y in 0..ny {
                data.extend((0..nx).map(|x| f(IVec3::new(x, y, z)) as u8));
            }
        }
        Self { spec, data }
    }

    /// The voxel at `ijk`; Free outside the grid.
    #[inline]
    pub fn get(&self, ijk: IVec3) -> Voxel {
        if self.spec.contains(ijk) {
            Voxel::from_bits(self.data[self.spec.linear(ijk)])
        } else {
            Voxel::Free
        }
    }

    /// Sets an in-range voxel; out-of-range writes are ignored.
    #[inline]
    pub fn set(&mut self, ijk: IVec3, v: Voxel) {
        if self.spec.contains(ijk) {
            let i = self.spec.linear(ijk);
            self.data[i] = v as u8;
        }
    }

    /// Number of voxels of each kind, indexed by the kind's value.
    pub fn counts(&self) -> [u64; 4] {
        let mut c = [0u64; 4];
        for &b in &self.data {
            c[(b & 3) as usize] += 1;
        }
        c
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn from_fn_sets_each_voxel_at_its_own_index() {
        let kind = |p: IVec3| Voxel::from_bits(((p.x + 2 * p.y + 3 * p.z) % 4) as u8);
        let spec = GridSpec {
            origin: DVec3::new(0.5, -1.0, 2.0),
            ..GridSpec::at_origin(0.25, [5, 3, 4])
        };
        let mut calls = Vec::new();
        let grid = DenseGrid::from_fn(spec, |p| {
            calls.push(p);
            kind(p)
        });
        // Each index once, in storage order, and each voxel where `get` reads it.
        assert_eq!(calls.len(), 60);
        for (i, &p) in calls.iter().enumerate() {
            assert_eq!(spec.linear(p), i, "{p}");
            assert_eq!(grid.get(p), kind(p), "{p}");
        }
        assert_eq!(grid.counts().iter().sum::<u64>(), 60);
    }
}
