//! A counting global allocator for memory tests: every heap byte a test binary allocates is
//! counted, with the peak. A test binary installs it with
//!
//! ```ignore
//! #[global_allocator]
//! static A: meso_testkit::alloc::Counting = meso_testkit::alloc::Counting;
//! ```
//!
//! and reads [`peak_since`] around the work it measures. The counters are global: keep one test
//! per binary so that the counts are that test's.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};

/// The system allocator, counting the bytes it hands out (bytes now, and the peak).
pub struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call forwards to `System` unchanged; the counters only observe sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(l) };
        if !p.is_null() {
            let now = NOW.fetch_add(l.size(), Relaxed) + l.size();
            PEAK.fetch_max(now, Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) };
        NOW.fetch_sub(l.size(), Relaxed);
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, new: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, l, new) };
        if !q.is_null() {
            if new >= l.size() {
                let now = NOW.fetch_add(new - l.size(), Relaxed) + new - l.size();
                PEAK.fetch_max(now, Relaxed);
            } else {
                NOW.fetch_sub(l.size() - new, Relaxed);
            }
        }
        q
    }
}

/// Bytes allocated at the peak since the last call (the allocation then, `*reset`, as the
/// floor), above what was allocated then; resets the peak to what is allocated now.
pub fn peak_since(reset: &mut usize) -> usize {
    let p = PEAK.load(Relaxed).saturating_sub(*reset);
    *reset = NOW.load(Relaxed);
    PEAK.store(*reset, Relaxed);
    p
}
