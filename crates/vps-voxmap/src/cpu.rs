//! Which instruction-set copies this CPU can run, for the crates that compile a loop twice
//! (portable and `#[target_feature]`) and pick one at run time.

/// Whether this CPU runs AVX2 code (x86-64 with AVX2; `false` on any other architecture). Cheap:
/// the standard library caches the detection.
pub fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
