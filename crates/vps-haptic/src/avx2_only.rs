//! The sampling kernel on at most AVX2 (the kernel before its AVX-512 copy), kept only so that
//! `vps bench kernel` and the `kernel_ir` example can measure the full kernel ([`crate::kernel`])
//! against it in the same run. Not for the frame path.
//!
//! It is the kernel without its AVX-512 copy of the block loop: full blocks with AVX2
//! intrinsics where the CPU has AVX2 (each sum's lanes rounded through two f32 → f64 conversions
//! and the `1.5 · 2^52` addition), the portable lane loops elsewhere. Everything else is the
//! current kernel's own code, and the sums are the same bits.

use crate::classed::ClassedShell;
use crate::kernel::{sample_all_on, Widest};
use crate::state::KernelPose;
use crate::sums::PartialSums;
use vps_voxmap::VoxelLookup;

/// The merged sums of every class of `shell` on at most AVX2: the same bits as
/// [`crate::sample_all`]. Does not allocate or block.
pub fn sample_all<L: VoxelLookup>(map: &L, shell: &ClassedShell, pose: &KernelPose) -> PartialSums {
    sample_all_on(map, shell, pose, Widest::Avx2)
}
