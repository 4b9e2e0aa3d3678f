//! Helpers shared by the integration tests: voxel iteration and structural invariants of a voxmap.
#![allow(dead_code)]

use glam::{DVec3, IVec3};
use vps_voxmap::{DenseGrid, Voxel};

/// Every voxel index of the grid with its kind.
pub fn voxels(grid: &DenseGrid) -> impl Iterator<Item = (IVec3, Voxel)> + '_ {
    let [nx, ny, _] = grid.spec.dims.map(|d| d as usize);
    grid.data.iter().enumerate().map(move |(i, &b)| {
        let ijk = IVec3::new(
            (i % nx) as i32,
            (i / nx % ny) as i32,
            (i / (nx * ny)) as i32,
        );
        (ijk, Voxel::from_bits(b))
    })
}

/// The 26 neighbour offsets.
pub fn neighbours26() -> Vec<IVec3> {
    let mut v = Vec::new();
    for z in -1..=1 {
        for y in -1..=1 {
            for x in -1..=1 {
                if (x, y, z) != (0, 0, 0) {
                    v.push(IVec3::new(x, y, z));
                }
            }
        }
    }
    v
}

/// Checks the invariants every voxmap must meet: Proximity voxels touch Surface, Free voxels do not
/// (Proximity is complete), and, when the force layer was offset (`offset_layers >= 1`), no Free or
/// Proximity voxel shares a face, edge or corner with an Interior voxel (the Surface layer is closed
/// in the 26-connected sense). Returns the number of voxels of each kind.
pub fn check_invariants(grid: &DenseGrid, offset_layers: u32) -> [u64; 4] {
    let n26 = neighbours26();
    for (ijk, v) in voxels(grid) {
        if v == Voxel::Interior || v == Voxel::Surface {
            continue;
        }
        let kinds: Vec<Voxel> = n26.iter().map(|d| grid.get(ijk + *d)).collect();
        let touches_surface = kinds.contains(&Voxel::Surface);
        match v {
            Voxel::Proximity => {
                assert!(touches_surface, "Proximity {ijk} has no Surface neighbour")
            }
            _ => assert!(!touches_surface, "Free {ijk} touches Surface"),
        }
        if offset_layers >= 1 {
            assert!(
                !kinds.contains(&Voxel::Interior),
                "{v:?} voxel {ijk} is a 26-neighbour of an Interior voxel"
            );
        }
    }
    grid.counts()
}

/// Centre of voxel `ijk` (m).
pub fn centre(grid: &DenseGrid, ijk: IVec3) -> DVec3 {
    grid.spec.center_of(ijk)
}
