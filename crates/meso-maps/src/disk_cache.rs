//! The on-disk cache shared by [`crate::facet_cache`] (facet NDFs and their visibility) and
//! [`crate::pyramid_cache`] (extracted pyramids): where it lives, how entries are named, sealed
//! and written.
//!
//! * The folder: `$MESO_CACHE_DIR` if set (empty or `off` turns the cache off), else
//!   `$XDG_CACHE_HOME/meso`, else `$HOME/.cache/meso`; none of them: no cache.
//! * An entry `<prefix>-<key in hex>.bin` is `magic (8 bytes) · format (u32 LE) · key (32 bytes)
//!   · payload · SHA-256 of all that`, written atomically (`meso_core::io::write_atomic`) and
//!   read with a size limit; [`open`] answers the payload only when the magic, format, key and
//!   checksum all match, so a damaged, truncated or foreign file is a miss (rebuilt), never an
//!   error.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The largest cache file read back (4 GiB).
pub const MAX_CACHE_BYTES: u64 = 4 << 30;
/// The largest source file hashed for a key (1 GiB; larger files are not cached).
pub const MAX_HASHED_BYTES: u64 = 1 << 30;

/// The cache folder (module docs), or `None` when the cache is off or no folder is known.
#[must_use]
pub fn cache_dir() -> Option<PathBuf> {
    match std::env::var_os("MESO_CACHE_DIR") {
        Some(v) if v.is_empty() || v == "off" => None,
        Some(v) => Some(PathBuf::from(v)),
        None => std::env::var_os("XDG_CACHE_HOME")
            .filter(|v| !v.is_empty())
            .map(|v| PathBuf::from(v).join("meso"))
            .or_else(|| {
                std::env::var_os("HOME")
                    .filter(|v| !v.is_empty())
                    .map(|h| PathBuf::from(h).join(".cache").join("meso"))
            }),
    }
}

/// The bytes of the source file `file` to hash into a key, or `None` when it cannot be read
/// or is larger than [`MAX_HASHED_BYTES`] (then nothing is cached).
#[must_use]
pub fn source_bytes(file: &Path) -> Option<Vec<u8>> {
    meso_core::io::read_limited(file, MAX_HASHED_BYTES).ok()
}

/// The path of the entry `prefix`-`key` in `dir`.
#[must_use]
pub fn entry_path(dir: &Path, prefix: &str, key: &[u8; 32]) -> PathBuf {
    let hex: String = key.iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!("{prefix}-{hex}.bin"))
}

/// The opening of an entry: `magic`, `format` and `key`; append the payload, then [`seal`].
#[must_use]
pub fn header(magic: &[u8; 8], format: u32, key: &[u8; 32]) -> Vec<u8> {
    let mut out = Vec::with_capacity(44);
    out.extend_from_slice(magic);
    out.extend_from_slice(&format.to_le_bytes());
    out.extend_from_slice(key);
    out
}

/// Append the SHA-256 of everything in `out` (header and payload).
pub fn seal(out: &mut Vec<u8>) {
    let sum: [u8; 32] = Sha256::digest(&out[..]).into();
    out.extend_from_slice(&sum);
}

/// The payload of an entry's `bytes` when its checksum, `magic`, `format` and `key` match.
#[must_use]
pub fn open<'a>(bytes: &'a [u8], magic: &[u8; 8], format: u32, key: &[u8; 32]) -> Option<&'a [u8]> {
    let (payload, sum) = bytes.split_last_chunk::<32>()?;
    if <[u8; 32]>::from(Sha256::digest(payload)) != *sum {
        return None;
    }
    let b = payload.strip_prefix(magic.as_slice())?;
    let (f, rest) = b.split_first_chunk::<4>()?;
    if u32::from_le_bytes(*f) != format {
        return None;
    }
    let (stored_key, rest) = rest.split_first_chunk::<32>()?;
    (stored_key == key).then_some(rest)
}

/// The bytes of the entry `prefix`-`key` in `dir`, if it can be read (not yet checked: see
/// [`open`]).
#[must_use]
pub fn read(dir: &Path, prefix: &str, key: &[u8; 32]) -> Option<Vec<u8>> {
    meso_core::io::read_limited(&entry_path(dir, prefix, key), MAX_CACHE_BYTES).ok()
}

/// Write the sealed entry `bytes` as `prefix`-`key` in `dir` (creating it), atomically.
///
/// # Errors
/// The folder cannot be created or the file written; callers ignore this (a cache that
/// cannot be written only costs the next run the build).
pub fn write(dir: &Path, prefix: &str, key: &[u8; 32], bytes: &[u8]) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    meso_core::io::write_atomic(&entry_path(dir, prefix, key), bytes)
}
