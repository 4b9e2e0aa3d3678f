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
