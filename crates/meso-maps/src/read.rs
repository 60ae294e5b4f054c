//! Reading an input file whole, with a limit when the file has no size to budget from.
//!
//! A regular file's size is known before it is read, and the callers check the memory of
//! loading it against the budget ([`meso_core::budget`]) from that size or from its header. A
//! character or block device, FIFO or `/proc` file reports no useful size (`/dev/zero` never
//! ends): [`read_whole`] reads such a file once, into memory, with a limit derived from the
//! budget, and refuses it, naming the file, when it gives more.

use crate::error::{MapError, Result};
use std::path::Path;

/// Whether `path` is a regular file (following symlinks). A path whose metadata cannot be read
/// is not.
#[must_use]
pub fn is_regular_file(path: &Path) -> bool {
    std::fs::metadata(path).is_ok_and(|m| m.is_file())
}

/// The most bytes [`read_whole`] reads from a non-regular file whose loading needs `factor`
/// bytes of memory for each byte of the file: the memory budget divided by `factor`.
#[must_use]
pub fn stream_limit(factor: u64) -> u64 {
    meso_core::budget::budget().bytes / factor.max(1)
}

/// Read the file `path` whole. A regular file is read as it is (its caller has checked its
/// memory against the budget from its size or header); any other file (device, FIFO) is read
/// once with the limit [`stream_limit`]`(factor)`, since loading it needs about `factor` bytes of
/// memory for each byte read.
///
/// # Errors
/// [`MapError::Io`] naming `path`: it cannot be read, or it is not a regular file and gives more
/// bytes than the budget allows (the message says so and how to raise the budget).
pub fn read_whole(path: &Path, factor: u64) -> Result<Vec<u8>> {
    meso_core::io::note_input(path);
    let io = |e: std::io::Error| MapError::Io {
        path: path.to_path_buf(),
        source: e,
    };
    if is_regular_file(path) {
        return std::fs::read(path).map_err(io);
    }
    let limit = stream_limit(factor);
    meso_core::io::read_limited(path, limit).map_err(|e| {
        if e.kind() != std::io::ErrorKind::FileTooLarge {
            return io(e);
        }
        let b = meso_core::budget::budget();
        io(std::io::Error::new(
            std::io::ErrorKind::FileTooLarge,
            format!(
                "it is not a regular file and gives more than {} bytes ({}), more than the \
                 memory budget of {} allows for reading it (raise the budget with \
                 --memory-budget SIZE or {}=SIZE, or give a regular file)",
                limit,
                meso_core::budget::human(limit),
                meso_core::budget::human(b.bytes),
                meso_core::budget::ENV_VAR
            ),
        ))
    })
}
