//! Internal nodes: a cube of `2^(3N)` slots, each holding either a child node index or a uniform tile
//! value. All nodes of one level live back to back in one `Vec<u32>` arena.

use crate::Voxel;
use glam::UVec3;

/// One slot of an internal node or of the root grid, packed in a `u32`.
///
/// The top bit is the tile flag (OpenVDB keeps it in a separate child mask; here it lives in the slot
/// word so a lookup reads one word per level). A tile stores its voxel code (see
/// [`crate::VoxelWidth`]; for 2-bit maps the [`Voxel`] value) in the low `W` bits and nothing else; a child stores the index of the child node in the next level's arena (`< 2^31`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Slot(pub(crate) u32);

impl Slot {
    /// The tile flag.
    pub(crate) const TILE_BIT: u32 = 1 << 31;
    /// Largest child index a slot can hold.
    pub(crate) const MAX_CHILD: u32 = Self::TILE_BIT - 1;

    /// A uniform region of voxel code `code`.
    #[inline(always)]
    pub(crate) fn tile(code: u8) -> Self {
        Slot(Self::TILE_BIT | code as u32)
    }

    /// A child node; `index <= MAX_CHILD` (callers check before building).
    #[inline(always)]
    pub(crate) fn child(index: u32) -> Self {
        Slot(index)
    }

    /// True for a tile.
    #[inline(always)]
    pub(crate) fn is_tile(self) -> bool {
        self.0 & Self::TILE_BIT != 0
    }

    /// The tile's code (meaningful only for tiles; the low 8 bits).
    #[inline(always)]
    pub(crate) fn tile_value(self) -> u8 {
        self.0 as u8
    }

    /// The child index (meaningful only for children).
    #[inline(always)]
    pub(crate) fn child_index(self) -> usize {
        self.0 as usize
    }

    /// True when the raw word is a tile with stray bits set (only the flag and `bits` value bits are
    /// allowed).
    pub(crate) fn is_malformed_tile(self, bits: u32) -> bool {
        self.is_tile() && self.0 & !(Self::TILE_BIT | ((1 << bits) - 1)) != 0
    }
}

/// The shape of one internal level: `2^log2` children per axis, each child spanning
/// `2^child_shift` voxels per axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct InternalShape {
    /// log2 of children per axis.
    pub(crate) log2: u32,
    /// log2 of a child's extent in voxels per axis.
    pub(crate) child_shift: u32,
}

impl InternalShape {
    /// Slots per node: `2^(3 log2)`.
    #[inline(always)]
    pub(crate) fn slots_per_node(self) -> usize {
        1 << (3 * self.log2)
    }

    /// The slot of node `node` that covers in-grid voxel `p` (any `p` inside the node's cube).
    #[inline(always)]
    pub(crate) fn slot_index(self, node: usize, p: UVec3) -> usize {
        let mask = (1 << self.log2) - 1;
        let local = ((p.x >> self.child_shift) & mask)
            | (((p.y >> self.child_shift) & mask) << self.log2)
            | (((p.z >> self.child_shift) & mask) << (2 * self.log2));
        (node << (3 * self.log2)) | local as usize
    }

    /// Voxel offset of slot `local` from its node's minimum corner.
    #[inline(always)]
    pub(crate) fn child_offset(self, local: usize) -> UVec3 {
        let mask = (1 << self.log2) - 1;
        let l = local as u32;
        UVec3::new(l & mask, (l >> self.log2) & mask, l >> (2 * self.log2)) << self.child_shift
    }
}

/// All nodes of one internal level, `slots_per_node` slots each, in canonical (breadth-first) order.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct InternalLevel {
    /// The level's shape.
    pub(crate) shape: InternalShape,
    /// Raw [`Slot`] words, node after node.
    pub(crate) slots: Vec<u32>,
}

impl InternalLevel {
    /// The slot covering in-grid voxel `p` in node `node`, the child index stored in the parent
    /// slot whose cube holds `p`; `shape` must equal `self.shape` (passed in so a caller can make
    /// it a constant).
    #[inline(always)]
    pub(crate) fn slot_of(&self, shape: InternalShape, node: usize, p: UVec3) -> Slot {
        debug_assert_eq!(shape, self.shape);
        let i = shape.slot_index(node, p);
        debug_assert!(i < self.slots.len());
        // SAFETY: `node` comes from a child slot of the parent level, and every stored child index
        // is below this level's node count (canonical form: children count up from 0 and the arena
        // holds one node per child; established by `from_dense`, checked by `from_parts`).
        // `slot_index` is `node * slots_per_node + local` with `local < slots_per_node`.
        Slot(unsafe { *self.slots.get_unchecked(i) })
    }

    /// Number of nodes.
    pub(crate) fn node_count(&self) -> usize {
        self.slots.len() / self.shape.slots_per_node()
    }

    /// The slots of node `node`.
    pub(crate) fn node(&self, node: usize) -> &[u32] {
        let n = self.shape.slots_per_node();
        &self.slots[node * n..(node + 1) * n]
    }
}

/// Appends a node made of `children` to `arena` unless every child inside the grid (`Some`) is the
/// same tile, in which case the node collapses to that tile. Children outside the grid (`None`) are
/// stored as Free tiles. At least one child must be inside. Returns the slot the parent stores: the
/// tile, or a child pointing at the appended node (index = nodes already in `arena`).
pub(crate) fn assemble_node(children: &[Option<Slot>], arena: &mut Vec<u32>) -> Slot {
    let mut inside = children.iter().flatten();
    if let Some(&first) = inside.next() {
        if first.is_tile() && inside.all(|&s| s == first) {
            return first;
        }
    }
    let index = arena.len() / children.len();
    arena.extend(
        children
            .iter()
            .map(|s| s.unwrap_or(Slot::tile(Voxel::Free as u8)).0),
    );
    Slot::child(index as u32)
}
