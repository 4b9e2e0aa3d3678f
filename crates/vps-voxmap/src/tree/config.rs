//! The tree's shape: how many children each level has per axis, and the shifts derived from it.

use super::TreeError;

/// Per-axis log2 child counts of the three node levels: `log2_dims[0]` for the leaf (voxels per leaf
/// edge = `2^log2_dims[0]`), `[1]` for the lower internal node (leaves per edge), `[2]` for the upper
/// internal node (lower nodes per edge). Each node is a cube of `2^(3N)` children.
///
/// Invariant (checked by [`TreeConfig::validate`]): every entry is in `1..=5`, so one upper node spans
/// at most `2^15` voxels per axis and every index computation fits in `u32`/`i32`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TreeConfig {
    /// log2 of the children per axis at the leaf, lower and upper level (index 0 = leaf).
    pub log2_dims: [u8; 3],
}

impl Default for TreeConfig {
    /// The paper's 512-tree: `N = 3` at every level (8³ voxels per leaf, 8³ children per node).
    fn default() -> Self {
        Self::uniform(3)
    }
}

impl TreeConfig {
    /// Smallest allowed log2 child count per axis.
    pub const MIN_LOG2: u8 = 1;
    /// Largest allowed log2 child count per axis.
    pub const MAX_LOG2: u8 = 5;

    /// The same `N` at every level: `N = 1` is an octree, `N = 3` the paper's 512-tree (Figure 6 sweeps
    /// `N = 1..=5`). Not validated until used.
    pub fn uniform(n: u8) -> Self {
        Self { log2_dims: [n; 3] }
    }

    /// Checks every level's log2 child count is in `MIN_LOG2..=MAX_LOG2`.
    pub fn validate(&self) -> Result<(), TreeError> {
        for (level, &log2) in self.log2_dims.iter().enumerate() {
            if !(Self::MIN_LOG2..=Self::MAX_LOG2).contains(&log2) {
                return Err(TreeError::InvalidConfig { level, log2 });
            }
        }
        Ok(())
    }

    /// Voxels per axis covered by one node of `level` (0 = leaf, 1 = lower, 2 = upper).
    pub fn extent(&self, level: usize) -> u32 {
        1 << self.shift(level)
    }

    /// log2 of [`TreeConfig::extent`]: the sum of the log2 child counts up to and including `level`.
    pub(crate) fn shift(&self, level: usize) -> u32 {
        self.log2_dims[..=level].iter().map(|&n| n as u32).sum()
    }
}
