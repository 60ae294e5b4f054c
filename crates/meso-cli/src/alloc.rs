//! The global allocator of the `meso` binary: the system allocator, except that an allocation
//! failure outside a fallible section (`meso_core::budget::fallible`, used by `try_reserve` on
//! the big buffers, which report their own error) prints one line,
//! `meso: error: out of memory: cannot allocate N bytes …`, and exits with status 1, instead of
//! the abort (SIGABRT) of Rust's default handler.

use std::alloc::{GlobalAlloc, Layout, System};

/// The system allocator with allocation failure turned into an error exit (module docs).
pub struct ExitOnOom;

/// A fixed buffer to format the message in without allocating.
struct Buf {
    bytes: [u8; 256],
    len: usize,
}

impl std::fmt::Write for Buf {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        let b = s.as_bytes();
        let n = b.len().min(self.bytes.len() - self.len);
        self.bytes[self.len..self.len + n].copy_from_slice(&b[..n]);
        self.len += n;
        Ok(())
    }
}

/// Report a failed allocation of `size` bytes and exit, unless the caller handles it.
fn failed(size: usize) {
    if meso_core::budget::in_fallible_section() {
        return;
    }
    use std::fmt::Write;
    let mut buf = Buf {
        bytes: [0; 256],
        len: 0,
    };
    let gib = size as f64 / (1u64 << 30) as f64;
    let _ = if gib >= 0.1 {
        write!(
            buf,
            "meso: error: out of memory: cannot allocate {gib:.2} GiB"
        )
    } else {
        write!(
            buf,
            "meso: error: out of memory: cannot allocate {size} bytes"
        )
    };
    let _ = writeln!(
        buf,
        " (less memory is available than the work needs: free memory, or lower \
         --memory-budget so that such work is refused before it starts)"
    );
    // SAFETY: writing a valid buffer to descriptor 2 and ending the process; no allocation.
    unsafe {
        let _ = libc::write(2, buf.bytes.as_ptr().cast(), buf.len);
        libc::_exit(1);
    }
}

// SAFETY: every method forwards to the system allocator with the same arguments.
unsafe impl GlobalAlloc for ExitOnOom {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc(layout);
        if p.is_null() {
            failed(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = System.alloc_zeroed(layout);
        if p.is_null() {
            failed(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = System.realloc(ptr, layout, new_size);
        if p.is_null() {
            failed(new_size);
        }
        p
    }
}
