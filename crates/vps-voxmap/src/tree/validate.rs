//! Checks that stored parts form a tree in canonical form, so a tree read from a file is exactly the
//! tree [`VoxelTree::from_dense`] would build from the same content (and lookups cannot index out of
//! range).

use super::internal::{assemble_node, InternalLevel, Slot};
use super::root::RootGrid;
use super::{TreeError, VoxelTree};
use crate::{GridSpec, VoxelWidth};
use glam::UVec3;

/// Checks the [`GridSpec`] invariants, with dims also at most `i32::MAX` (voxel indices are `i32`).
pub(super) fn check_spec(spec: &GridSpec) -> Result<(), TreeError> {
    let bad = |field, reason| Err(TreeError::InvalidSpec { field, reason });
    if !(spec.voxel_size.is_finite() && spec.voxel_size > 0.0) {
        return bad("voxel_size", "must be finite and > 0");
    }
    if !spec.origin.is_finite() {
        return bad("origin", "must be finite");
    }
    for (axis, &d) in spec.dims.iter().enumerate() {
        let field = ["dims[0]", "dims[1]", "dims[2]"][axis];
        if d == 0 || d > i32::MAX as u32 {
            return bad(field, "must be in 1..=i32::MAX");
        }
    }
    Ok(())
}

/// Checks every structural invariant of `tree` (spec and config were checked on assembly).
pub(super) fn check_canonical(tree: &VoxelTree) -> Result<(), TreeError> {
    let dims = tree.spec.dims;
    let root_cells = RootGrid::cell_count(tree.root.dims);
    expect_len("root slots", tree.root.slots.len(), root_cells)?;
    let width = tree.width;
    let upper_origins = check_slots("root slots", &tree.root.slots, dims, width, |i| {
        tree.root.cell_origin(i)
    })?;
    let lower_origins = check_internal("upper slots", &tree.upper, &upper_origins, dims, width)?;
    let leaf_origins = check_internal("lower slots", &tree.lower, &lower_origins, dims, width)?;

    let wpl = tree.leaf_shape.words_per_leaf();
    expect_len(
        "leaf words",
        tree.leaf_words.len(),
        leaf_origins.len() as u64 * wpl as u64,
    )?;
    for (index, (leaf, &origin)) in tree
        .leaf_words
        .chunks_exact(wpl)
        .zip(&leaf_origins)
        .enumerate()
    {
        check_leaf_codes(leaf, width, index * wpl)?;
        let reason = if tree.leaf_shape.uniform_value(leaf, origin, dims).is_some() {
            "leaf is uniform inside the grid (must be a tile)"
        } else if !tree.leaf_shape.padding_is_clear(leaf, origin, dims) {
            "leaf has non-Free bits outside the grid"
        } else {
            continue;
        };
        return Err(TreeError::NotCanonical {
            arena: "leaf words",
            index: index * wpl,
            reason,
        });
    }
    Ok(())
}

/// Checks the nodes of one internal level, whose origins (in order) are `origins`; returns the
/// origins of their children.
fn check_internal(
    arena: &'static str,
    level: &InternalLevel,
    origins: &[UVec3],
    dims: [u32; 3],
    width: VoxelWidth,
) -> Result<Vec<UVec3>, TreeError> {
    let spn = level.shape.slots_per_node();
    expect_len(arena, level.slots.len(), origins.len() as u64 * spn as u64)?;
    let origin_of = |i: usize| origins[i / spn] + level.shape.child_offset(i % spn);
    for (node, slots) in level.slots.chunks_exact(spn).enumerate() {
        let inside: Vec<Option<Slot>> = (0..spn)
            .map(|local| {
                (!is_outside(origin_of(node * spn + local), dims)).then_some(Slot(slots[local]))
            })
            .collect();
        if assemble_node(&inside, &mut Vec::new()).is_tile() {
            return Err(TreeError::NotCanonical {
                arena,
                index: node * spn,
                reason: "node is uniform inside the grid (must be a tile)",
            });
        }
    }
    check_slots(arena, &level.slots, dims, width, origin_of)
}

/// Checks that every voxel code of a leaf is valid for `width` (`first_word`: the leaf's first
/// word in the arena, for the error).
fn check_leaf_codes(leaf: &[u64], width: VoxelWidth, first_word: usize) -> Result<(), TreeError> {
    if width == VoxelWidth::Two {
        return Ok(()); // every 2-bit code is valid
    }
    let bits = width.bits();
    for (w, &word) in leaf.iter().enumerate() {
        for f in 0..64 / bits {
            let code = ((word >> (f * bits)) & ((1 << bits) - 1)) as u8;
            if !width.is_valid_code(code) {
                return Err(TreeError::InvalidCode {
                    arena: "leaf words",
                    index: first_word + w,
                    code,
                    bits,
                });
            }
        }
    }
    Ok(())
}

fn is_outside(origin: UVec3, dims: [u32; 3]) -> bool {
    origin.x >= dims[0] || origin.y >= dims[1] || origin.z >= dims[2]
}

/// Checks each slot: tiles carry only a value, slots wholly outside the grid are Free tiles, and
/// child indices count up from 0 in slot order. Returns the children's origins (`origin_of` gives a
/// slot's cube origin).
fn check_slots(
    arena: &'static str,
    slots: &[u32],
    dims: [u32; 3],
    width: VoxelWidth,
    origin_of: impl Fn(usize) -> UVec3,
) -> Result<Vec<UVec3>, TreeError> {
    let mut child_origins = Vec::new();
    for (index, &raw) in slots.iter().enumerate() {
        let slot = Slot(raw);
        let origin = origin_of(index);
        let reason = if slot.is_malformed_tile(width.bits()) {
            "tile has bits besides its value"
        } else if slot.is_tile() && !width.is_valid_code(slot.tile_value()) {
            return Err(TreeError::InvalidCode {
                arena,
                index,
                code: slot.tile_value(),
                bits: width.bits(),
            });
        } else if is_outside(origin, dims) && slot != Slot::tile(0) {
            "slot outside the grid must be a Free tile"
        } else if !slot.is_tile() && slot.child_index() != child_origins.len() {
            "child index out of canonical order"
        } else {
            if !slot.is_tile() {
                child_origins.push(origin);
            }
            continue;
        };
        return Err(TreeError::NotCanonical {
            arena,
            index,
            reason,
        });
    }
    Ok(child_origins)
}

fn expect_len(arena: &'static str, found: usize, expected: u64) -> Result<(), TreeError> {
    if found as u64 != expected {
        return Err(TreeError::ArenaLength {
            arena,
            expected,
            found: found as u64,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tree::TreeConfig;
    use crate::{DenseGrid, Voxel};
    use glam::IVec3;

    /// A tree with stored nodes at every level, tiles of several kinds, and clipped boundary cubes.
    fn sample(config: TreeConfig) -> VoxelTree {
        let mut grid = DenseGrid::new(GridSpec::at_origin(0.01, [45, 30, 21]));
        for i in 0..grid.data.len() {
            let ijk = IVec3::new((i % 45) as i32, (i / 45 % 30) as i32, (i / 1350) as i32);
            let v = if ijk.x < 20 {
                Voxel::Interior
            } else if (i * 7919) % 13 == 0 {
                Voxel::Surface
            } else {
                Voxel::Free
            };
            grid.set(ijk, v);
        }
        VoxelTree::from_dense(&grid, config).unwrap()
    }

    #[test]
    fn built_trees_are_canonical() {
        for n in 1..=5 {
            check_canonical(&sample(TreeConfig::uniform(n))).unwrap();
        }
        check_canonical(&sample(TreeConfig {
            log2_dims: [2, 1, 3],
        }))
        .unwrap();
    }

    #[test]
    fn broken_slots_and_leaves_are_rejected() {
        let tree = sample(TreeConfig::uniform(2));
        assert!(tree.node_counts().leaves > 1 && tree.node_counts().lower > 1);
        let first_child = |slots: &[u32]| slots.iter().position(|&s| !Slot(s).is_tile()).unwrap();
        let first_tile = |slots: &[u32]| slots.iter().position(|&s| Slot(s).is_tile()).unwrap();

        let mut t = tree.clone();
        let i = first_child(&t.lower.slots);
        t.lower.slots[i] += 1;
        let err = check_canonical(&t).unwrap_err();
        assert!(err.to_string().contains("canonical order"), "{err}");

        let mut t = tree.clone();
        let i = first_tile(&t.upper.slots);
        t.upper.slots[i] |= 4;
        let err = check_canonical(&t).unwrap_err();
        assert!(err.to_string().contains("bits besides"), "{err}");

        let mut t = tree.clone();
        t.leaf_words.pop();
        assert!(matches!(
            check_canonical(&t),
            Err(TreeError::ArenaLength { .. })
        ));

        let mut t = tree.clone();
        t.leaf_words[..1].fill(0);
        t.leaf_words[1] = 0;
        let err = check_canonical(&t).unwrap_err();
        assert!(err.to_string().contains("uniform"), "{err}");
    }
}
