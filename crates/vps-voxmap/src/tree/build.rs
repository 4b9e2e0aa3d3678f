//! Bottom-up construction from a dense grid or a [`CubeSource`].
//!
//! The work items are the lower-node cubes in canonical order (root cell, then upper slot). Chunks of
//! them are built in parallel, each into its own lower-slot and leaf arenas with local indices; the
//! chunks are then concatenated in order with their child indices shifted, and the upper nodes and
//! root are assembled from the per-cube slots. The result is the same for any thread count.

use super::internal::{assemble_node, Slot};
use super::leaf::ByteBox;
use super::{Arenas, TreeConfig, TreeError, VoxelTree};
use crate::{DenseGrid, GridSpec, VoxelWidth};
use glam::UVec3;
use rayon::prelude::*;
use std::ops::Range;

/// Voxel codes of a scene, handed to [`VoxelTree::from_source`] one lower-node cube at a time (the
/// voxelizer's sparse output implements it, so no dense grid of the whole scene is needed).
pub trait CubeSource: Sync {
    /// The codes of the cube of `extent`³ voxels whose minimum corner is voxel `origin` (inside the
    /// grid): `Some(code)` when every in-grid voxel of the cube holds `code` (`out` may be left
    /// untouched), else `None` after writing all `extent³` codes into `out` (x fastest; voxels outside
    /// the grid dims must be 0). Called concurrently from several threads.
    fn cube(&self, origin: UVec3, extent: u32, out: &mut [u8]) -> Option<u8>;
}

/// Where the builder reads voxel codes from.
#[derive(Clone, Copy)]
enum Input<'a> {
    /// A dense grid of 2-bit kinds.
    Dense(&'a DenseGrid),
    /// A cube source of codes of the tree's width (validated while building).
    Source(&'a dyn CubeSource),
}

/// Lower-node cubes built by one parallel task.
struct LowerChunk {
    /// One slot per cube (`None` outside the grid): a tile, or a child indexing `lower_slots` (local
    /// index).
    cube_slots: Vec<Option<Slot>>,
    /// Lower nodes; child slots index `leaf_words` (local leaf index).
    lower_slots: Vec<u32>,
    /// Leaves, `words_per_leaf` words each.
    leaf_words: Vec<u64>,
}

/// See [`VoxelTree::from_dense`].
pub(super) fn from_dense(grid: &DenseGrid, config: TreeConfig) -> Result<VoxelTree, TreeError> {
    let expected = grid.spec.voxel_count();
    if grid.data.len() as u64 != expected {
        return Err(TreeError::DataLength {
            expected,
            found: grid.data.len() as u64,
        });
    }
    build(grid.spec, VoxelWidth::Two, config, Input::Dense(grid))
}

/// See [`VoxelTree::from_source`].
pub(super) fn from_source(
    spec: GridSpec,
    width: VoxelWidth,
    config: TreeConfig,
    source: &dyn CubeSource,
) -> Result<VoxelTree, TreeError> {
    build(spec, width, config, Input::Source(source))
}

fn build(
    spec: GridSpec,
    width: VoxelWidth,
    config: TreeConfig,
    input: Input<'_>,
) -> Result<VoxelTree, TreeError> {
    let mut tree = VoxelTree::assemble(spec, config, width, Arenas::default())?;
    let root_cells = super::root::RootGrid::cell_count(tree.root.dims) as usize;
    let cubes = root_cells * tree.upper.shape.slots_per_node();
    let chunk_len = cubes.div_ceil(32 * rayon::current_num_threads()).max(1);
    let chunks: Vec<LowerChunk> = (0..cubes.div_ceil(chunk_len))
        .into_par_iter()
        .map(|c| {
            build_chunk(
                &tree,
                input,
                c * chunk_len..((c + 1) * chunk_len).min(cubes),
            )
        })
        .collect::<Result<_, _>>()?;

    let wpl = tree.leaf_shape.words_per_leaf();
    let spn_lower = tree.lower.shape.slots_per_node();
    let total_leaf_words: usize = chunks.iter().map(|c| c.leaf_words.len()).sum();
    let total_lower_slots: usize = chunks.iter().map(|c| c.lower_slots.len()).sum();
    check_node_count(total_leaf_words / wpl, "leaf words")?;
    check_node_count(total_lower_slots / spn_lower, "lower slots")?;

    let mut cube_slots = Vec::with_capacity(cubes);
    tree.lower.slots.reserve_exact(total_lower_slots);
    tree.leaf_words.reserve_exact(total_leaf_words);
    for chunk in chunks {
        let lower_base = (tree.lower.slots.len() / spn_lower) as u32;
        let leaf_base = (tree.leaf_words.len() / wpl) as u32;
        cube_slots.extend(
            chunk
                .cube_slots
                .iter()
                .map(|s| s.map(|s| relocate(s, lower_base))),
        );
        tree.lower.slots.extend(
            chunk
                .lower_slots
                .iter()
                .map(|&w| relocate(Slot(w), leaf_base).0),
        );
        tree.leaf_words.extend_from_slice(&chunk.leaf_words);
    }

    tree.root.slots.reserve_exact(root_cells);
    for children in cube_slots.chunks_exact(tree.upper.shape.slots_per_node()) {
        let slot = assemble_node(children, &mut tree.upper.slots);
        tree.root.slots.push(slot.0);
    }
    tree.upper.slots.shrink_to_fit();
    Ok(tree.with_directory())
}

/// The codes of one lower-node cube: uniform, or a byte box and the cube's origin inside it.
enum CubeCodes<'a> {
    Uniform(u8),
    Bytes(ByteBox<'a>, UVec3),
}

/// Fetches the cube at `origin` from `input` (a source writes into `buf`), validating source codes.
fn fetch<'a>(
    input: Input<'a>,
    width: VoxelWidth,
    origin: UVec3,
    extent: u32,
    buf: &'a mut Vec<u8>,
) -> Result<CubeCodes<'a>, TreeError> {
    let invalid = |index: usize, code: u8| TreeError::InvalidCode {
        arena: "source",
        index,
        code,
        bits: width.bits(),
    };
    match input {
        Input::Dense(grid) => Ok(CubeCodes::Bytes(
            ByteBox {
                data: &grid.data,
                dims: grid.spec.dims,
            },
            origin,
        )),
        Input::Source(source) => {
            buf.resize((extent as usize).pow(3), 0);
            if let Some(code) = source.cube(origin, extent, buf) {
                return match width.is_valid_code(code) {
                    true => Ok(CubeCodes::Uniform(code)),
                    false => Err(invalid(0, code)),
                };
            }
            if let Some(i) = buf.iter().position(|&c| !width.is_valid_code(c)) {
                return Err(invalid(i, buf[i]));
            }
            Ok(CubeCodes::Bytes(
                ByteBox {
                    data: buf,
                    dims: [extent; 3],
                },
                UVec3::ZERO,
            ))
        }
    }
}

/// Builds the lower-node cubes `range` (canonical cube indices).
fn build_chunk(
    tree: &VoxelTree,
    input: Input<'_>,
    range: Range<usize>,
) -> Result<LowerChunk, TreeError> {
    let leaf_shape = tree.leaf_shape;
    let lower_shape = tree.lower.shape;
    let dims = tree.spec.dims;
    let extent = tree.config.extent(1);
    let outside = |o: UVec3| o.x >= dims[0] || o.y >= dims[1] || o.z >= dims[2];
    let mut chunk = LowerChunk {
        cube_slots: Vec::with_capacity(range.len()),
        lower_slots: Vec::new(),
        leaf_words: Vec::new(),
    };
    let mut children = Vec::with_capacity(lower_shape.slots_per_node());
    let mut leaf = vec![0u64; leaf_shape.words_per_leaf()];
    let mut buf = Vec::new();
    for cube in range {
        let origin = cube_origin(tree, cube);
        if outside(origin) {
            chunk.cube_slots.push(None);
            continue;
        }
        let (src, at) = match fetch(input, tree.width, origin, extent, &mut buf)? {
            CubeCodes::Uniform(code) => {
                chunk.cube_slots.push(Some(Slot::tile(code)));
                continue;
            }
            CubeCodes::Bytes(src, at) => (src, at),
        };
        children.clear();
        for local in 0..lower_shape.slots_per_node() {
            let offset = lower_shape.child_offset(local);
            let leaf_origin = origin + offset;
            if outside(leaf_origin) {
                children.push(None);
                continue;
            }
            let inside = leaf_shape.inside(leaf_origin, dims);
            leaf_shape.pack(src, at + offset, inside, &mut leaf);
            let slot = match leaf_shape.uniform_value(&leaf, leaf_origin, dims) {
                Some(code) => Slot::tile(code),
                None => {
                    let index = chunk.leaf_words.len() / leaf.len();
                    chunk.leaf_words.extend_from_slice(&leaf);
                    Slot::child(index as u32)
                }
            };
            children.push(Some(slot));
        }
        let slot = assemble_node(&children, &mut chunk.lower_slots);
        chunk.cube_slots.push(Some(slot));
    }
    Ok(chunk)
}

/// Voxel origin of lower-node cube `cube`: root cell `cube / spn`, upper slot `cube % spn`.
fn cube_origin(tree: &VoxelTree, cube: usize) -> UVec3 {
    let spn = tree.upper.shape.slots_per_node();
    tree.root.cell_origin(cube / spn) + tree.upper.shape.child_offset(cube % spn)
}

/// Shifts a child slot's index by `base` (tiles unchanged). Totals were checked to fit.
fn relocate(slot: Slot, base: u32) -> Slot {
    if slot.is_tile() {
        slot
    } else {
        Slot::child(slot.0 + base)
    }
}

fn check_node_count(nodes: usize, arena: &'static str) -> Result<(), TreeError> {
    if nodes > Slot::MAX_CHILD as usize + 1 {
        return Err(TreeError::TooManyNodes { arena });
    }
    Ok(())
}
