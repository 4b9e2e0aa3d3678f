//! Step 4 of docs/architecture.md#voxmaps-and-point-shells: offset the force layer outward by `k` layers. Each step promotes Proximity to
//! Surface and demotes the old Surface to Interior; Proximity is then recomputed. After `k` steps
//! every point of the exact static surface lies behind `k` layers of Interior, and thin wires and
//! spikes have grown into closed 26-connected layers.

use crate::bitgrid::BitGrid;
use crate::proximity::proximity;

/// The three non-Free kinds of a voxelized box as disjoint bit planes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Layers {
    /// Interior voxels.
    pub interior: BitGrid,
    /// Surface (force-layer) voxels.
    pub surface: BitGrid,
    /// Proximity voxels (Free 26-neighbours of Surface).
    pub proximity: BitGrid,
}

/// Computes Proximity and offsets the force layer by `layers` steps (0 = Proximity only), starting
/// from disjoint `interior` and `surface` planes. Allocates a few planes per step.
pub(crate) fn offset(mut interior: BitGrid, mut surface: BitGrid, layers: u32) -> Layers {
    let mut free = BitGrid::neither(&interior, &surface);
    let mut prox = proximity(&surface, &free);
    for _ in 0..layers {
        interior.combine(&surface, |i, s| i | s);
        surface = prox;
        free.combine(&surface, |f, s| f & !s);
        prox = proximity(&surface, &free);
    }
    Layers {
        interior,
        surface,
        proximity: prox,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn single_voxel_grows_shells() {
        let dims = [11, 11, 11];
        let mut s = BitGrid::zeros(dims);
        s.set(5, 5, 5);
        let l = offset(BitGrid::zeros(dims), s.clone(), 0);
        assert_eq!(
            (l.interior.count(), l.surface.count(), l.proximity.count()),
            (0, 1, 26)
        );
        let l = offset(BitGrid::zeros(dims), s, 2);
        // Interior: the 3x3x3 cube; Surface: the 5x5x5 shell; Proximity: the 7x7x7 shell.
        assert_eq!(l.interior.count(), 27);
        assert_eq!(l.surface.count(), 125 - 27);
        assert_eq!(l.proximity.count(), 343 - 125);
        assert!(l.interior.get(4, 4, 4) && l.surface.get(3, 5, 5) && l.proximity.get(2, 2, 2));
    }

    #[test]
    fn offset_does_not_grow_into_interior() {
        let dims = [9, 9, 9];
        let mut interior = BitGrid::zeros(dims);
        let mut surface = BitGrid::zeros(dims);
        for z in 2..7 {
            for y in 2..7 {
                for x in 2..7 {
                    if [x, y, z].iter().any(|&c| c == 2 || c == 6) {
                        surface.set(x, y, z);
                    } else {
                        interior.set(x, y, z);
                    }
                }
            }
        }
        let l = offset(interior, surface, 1);
        assert_eq!(l.interior.count(), 125);
        assert_eq!(l.surface.count(), 343 - 125);
        assert_eq!(l.proximity.count(), 729 - 343);
    }
}
