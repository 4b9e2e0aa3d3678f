//! Why a tree could not be built or accepted.

/// A tree build or validation failure; every variant names the offending field, level or element.
#[derive(Debug, thiserror::Error, Clone, PartialEq, Eq)]
pub enum TreeError {
    /// A level's log2 child count is outside `1..=5`.
    #[error("tree config: log2_dims[{level}] = {log2} is outside 1..=5")]
    InvalidConfig {
        /// 0 = leaf, 1 = lower, 2 = upper.
        level: usize,
        /// The rejected value.
        log2: u8,
    },
    /// The grid spec breaks its invariants.
    #[error("grid spec: {field} {reason}")]
    InvalidSpec {
        /// `voxel_size`, `origin` or `dims[i]`.
        field: &'static str,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The dense grid's data length does not match its spec.
    #[error("dense grid: data has {found} bytes, spec needs {expected}")]
    DataLength {
        /// `spec.voxel_count()`.
        expected: u64,
        /// `data.len()`.
        found: u64,
    },
    /// An arena's length is not what the header and the parent level imply.
    #[error("{arena}: length {found}, expected {expected}")]
    ArenaLength {
        /// `root slots`, `upper slots`, `lower slots` or `leaf words`.
        arena: &'static str,
        /// The implied length.
        expected: u64,
        /// The stored length.
        found: u64,
    },
    /// A level would hold more nodes than a slot can index (`2^31`).
    #[error("{arena}: more than 2^31 nodes")]
    TooManyNodes {
        /// The level's arena.
        arena: &'static str,
    },
    /// A leaf row of `2^log2` voxels of `bits` bits does not fit one 64-bit word.
    #[error("tree config: {bits}-bit voxels need log2_dims[0] <= {}, got {log2}", (64 / bits).trailing_zeros())]
    LeafTooWide {
        /// Bits per voxel.
        bits: u32,
        /// The leaf's log2 edge.
        log2: u8,
    },
    /// A voxel code is reserved (invalid) for the tree's width.
    #[error("{arena}[{index}]: code {code} is not a valid {bits}-bit voxel code")]
    InvalidCode {
        /// Where the code was found (`leaf words`, a slot arena, or `source`).
        arena: &'static str,
        /// Element index in that arena (voxel index for a source cube).
        index: usize,
        /// The rejected code.
        code: u8,
        /// Bits per voxel.
        bits: u32,
    },
    /// A slot or node breaks the canonical form.
    #[error("{arena}[{index}]: {reason}")]
    NotCanonical {
        /// The arena holding the element.
        arena: &'static str,
        /// Slot index (or leaf/node index for whole-node problems).
        index: usize,
        /// What is wrong.
        reason: &'static str,
    },
}
