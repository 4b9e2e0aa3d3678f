//! A counting global allocator: live and peak bytes, and a hard cap on single requests.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Write;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// Wraps the system allocator, counting live bytes and their peak. Install it in a test or binary:
///
/// ```ignore
/// #[global_allocator]
/// static ALLOC: vps_fuzz::CountingAlloc = vps_fuzz::CountingAlloc::new();
/// ```
///
/// With a cap set ([`CountingAlloc::set_request_cap`]), a single request larger than the cap is
/// refused (null), after a line on stderr naming the request and the input being run: a decoder
/// that asks for an absurd size then fails with Rust's allocation-error abort instead of taking the
/// machine's memory, and the line says which input did it. Counting is process-wide: run one
/// input at a time when reading per-input peaks.
pub struct CountingAlloc {
    live: AtomicUsize,
    peak: AtomicUsize,
    cap: AtomicUsize,
    /// The target and input index being run, for the refusal message.
    target: AtomicUsize,
    input: AtomicUsize,
}

impl CountingAlloc {
    /// A counter with no cap.
    pub const fn new() -> Self {
        Self {
            live: AtomicUsize::new(0),
            peak: AtomicUsize::new(0),
            cap: AtomicUsize::new(usize::MAX),
            target: AtomicUsize::new(usize::MAX),
            input: AtomicUsize::new(0),
        }
    }

    /// Bytes currently allocated.
    pub fn live(&self) -> usize {
        self.live.load(Relaxed)
    }

    /// Starts a new peak measurement at the current live bytes; returns them (the baseline).
    pub fn reset_peak(&self) -> usize {
        let live = self.live();
        self.peak.store(live, Relaxed);
        live
    }

    /// The highest live byte count since the last [`CountingAlloc::reset_peak`].
    pub fn peak(&self) -> usize {
        self.peak.load(Relaxed)
    }

    /// Refuse single requests above `bytes` (`usize::MAX`: no cap).
    pub fn set_request_cap(&self, bytes: usize) {
        self.cap.store(bytes, Relaxed);
    }

    /// Records which target (by index in [`crate::all_targets`]) and input are running.
    pub fn set_current(&self, target: usize, input: u64) {
        self.target.store(target, Relaxed);
        self.input.store(input as usize, Relaxed);
    }

    fn admit(&self, size: usize) -> bool {
        if size <= self.cap.load(Relaxed) {
            return true;
        }
        // No allocation here: format into a stack buffer.
        let mut buf = [0u8; 160];
        let mut w = &mut buf[..];
        let _ = writeln!(
            w,
            "vps-fuzz: refused a request of {size} bytes (cap {}) at target #{} input {}",
            self.cap.load(Relaxed),
            self.target.load(Relaxed),
            self.input.load(Relaxed)
        );
        let left = w.len();
        let _ = std::io::stderr().write_all(&buf[..buf.len() - left]);
        false
    }

    fn added(&self, size: usize) {
        let live = self.live.fetch_add(size, Relaxed) + size;
        self.peak.fetch_max(live, Relaxed);
    }
}

impl Default for CountingAlloc {
    fn default() -> Self {
        Self::new()
    }
}

impl CountingAlloc {
    /// A new block of `size` bytes from `make` (`System`'s alloc or alloc_zeroed): null when the
    /// request is refused or `make` fails; counted as live when made. Never allocates itself.
    fn counted(&self, size: usize, make: impl FnOnce() -> *mut u8) -> *mut u8 {
        if !self.admit(size) {
            return std::ptr::null_mut();
        }
        let p = make();
        if !p.is_null() {
            self.added(size);
        }
        p
    }
}

// SAFETY: every call is forwarded to `System` with the caller's layout; the counters are atomics
// and never allocate.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        self.counted(layout.size(), || System.alloc(layout))
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        self.counted(layout.size(), || System.alloc_zeroed(layout))
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
        self.live.fetch_sub(layout.size(), Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if !self.admit(new_size) {
            return std::ptr::null_mut();
        }
        let p = System.realloc(ptr, layout, new_size);
        if !p.is_null() {
            self.live.fetch_sub(layout.size(), Relaxed);
            self.added(new_size);
        }
        p
    }
}
