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
//! * The size: after every write the folder's entries (files named `<prefix>-<64 hex>.bin`,
//!   nothing else is touched) are pruned to at most [`max_bytes`] in all (`$MESO_CACHE_MAX_BYTES`,
//!   a size such as `500M` or `2G`; default [`DEFAULT_MAX_BYTES`], 2 GiB), least recently used
//!   first: an entry's modification time is set to now when it is read ([`read`]), so the
//!   oldest modification time is the entry used longest ago. The entry just written is kept even
//!   when it alone exceeds the cap.

use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The largest cache file read back (4 GiB).
pub const MAX_CACHE_BYTES: u64 = 4 << 30;
/// The largest source file hashed for a key (1 GiB; larger files are not cached).
pub const MAX_HASHED_BYTES: u64 = 1 << 30;

/// The default cap on the cache folder's entries (2 GiB; module docs).
pub const DEFAULT_MAX_BYTES: u64 = 2 << 30;
/// The environment variable that sets the cap (a size: `meso_core::budget::parse_size`).
pub const MAX_BYTES_VAR: &str = "MESO_CACHE_MAX_BYTES";

/// The cap on the cache folder's entries in bytes: `$MESO_CACHE_MAX_BYTES` when set to a valid
/// size, else [`DEFAULT_MAX_BYTES`] (an invalid value is ignored: the cache never fails a
/// command).
#[must_use]
pub fn max_bytes() -> u64 {
    std::env::var(MAX_BYTES_VAR)
        .ok()
        .and_then(|v| meso_core::budget::parse_size(v.trim()).ok())
        .unwrap_or(DEFAULT_MAX_BYTES)
}

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

/// The bytes of the source file `file` to hash into a key, or `None` when it cannot be read,
/// is larger than [`MAX_HASHED_BYTES`], or is not a regular file (then nothing is cached): a
/// device or FIFO can be read only once, and that read is the load's.
#[must_use]
pub fn source_bytes(file: &Path) -> Option<Vec<u8>> {
    if !crate::read::is_regular_file(file) {
        return None;
    }
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

/// What a cache lookup answered ([`crate::pyramid_cache`], [`crate::facet_cache`]): the value,
/// whether the cache had it, and the warnings that loading its source gave (a colour image
/// read as heights, 8-bit terraces dequantised, …). The warnings are kept in the entry, so a
/// hit says them as the build did, although the image is then not decoded.
#[derive(Clone, Debug)]
pub struct Cached<T> {
    /// The pyramid or facet NDF.
    pub value: T,
    /// Whether it was read from the cache (not built).
    pub hit: bool,
    /// The source's load warnings, in the order they were given.
    pub warnings: Vec<String>,
}

/// The most warnings kept with an entry ([`put_warnings`]); more are dropped.
pub const MAX_WARNINGS: usize = 64;
/// The longest warning kept with an entry, in bytes; a longer one is cut at a character.
pub const MAX_WARNING_BYTES: usize = 4096;

/// Append `warnings` to an entry's payload: their count (`u32` LE), then each one's length in
/// bytes (`u32` LE) and UTF-8 text, at most [`MAX_WARNINGS`] of at most [`MAX_WARNING_BYTES`].
pub fn put_warnings(out: &mut Vec<u8>, warnings: &[String]) {
    let kept = &warnings[..warnings.len().min(MAX_WARNINGS)];
    out.extend_from_slice(&(kept.len() as u32).to_le_bytes());
    for w in kept {
        let mut end = w.len().min(MAX_WARNING_BYTES);
        while !w.is_char_boundary(end) {
            end -= 1;
        }
        out.extend_from_slice(&(end as u32).to_le_bytes());
        out.extend_from_slice(&w.as_bytes()[..end]);
    }
}

/// Read what [`put_warnings`] wrote from the front of `bytes`, advancing it; `None` when it is
/// not well formed (a count or length over the limits, short data, text not UTF-8).
#[must_use]
pub fn take_warnings(bytes: &mut &[u8]) -> Option<Vec<String>> {
    let (n, mut b) = bytes.split_first_chunk::<4>()?;
    let n = u32::from_le_bytes(*n) as usize;
    if n > MAX_WARNINGS {
        return None;
    }
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        let (len, rest) = b.split_first_chunk::<4>()?;
        let len = u32::from_le_bytes(*len) as usize;
        if len > MAX_WARNING_BYTES || len > rest.len() {
            return None;
        }
        out.push(std::str::from_utf8(&rest[..len]).ok()?.to_string());
        b = &rest[len..];
    }
    *bytes = b;
    Some(out)
}

/// The bytes of the entry `prefix`-`key` in `dir`, if it can be read (not yet checked: see
/// [`open`]). A read entry's modification time is set to now (its last use, for [`prune`]).
#[must_use]
pub fn read(dir: &Path, prefix: &str, key: &[u8; 32]) -> Option<Vec<u8>> {
    let path = entry_path(dir, prefix, key);
    let bytes = meso_core::io::read_limited_unnoted(&path, MAX_CACHE_BYTES).ok()?;
    touch(&path);
    Some(bytes)
}

/// Set `path`'s modification time to now (failures ignored: the entry only looks older).
fn touch(path: &Path) {
    if let Ok(f) = std::fs::OpenOptions::new().append(true).open(path) {
        let _ = f.set_modified(std::time::SystemTime::now());
    }
}

/// Whether `name` is a cache entry's file name: `<prefix>-<64 hex digits>.bin`.
fn is_entry_name(name: &str) -> bool {
    let Some(stem) = name.strip_suffix(".bin") else {
        return false;
    };
    let Some((prefix, hex)) = stem.rsplit_once('-') else {
        return false;
    };
    !prefix.is_empty()
        && prefix.bytes().all(|b| b.is_ascii_lowercase())
        && hex.len() == 64
        && hex.bytes().all(|b| b.is_ascii_hexdigit())
}

/// Remove the least recently used entries of `dir` (oldest modification time first) until
/// their total is at most `max_bytes`, never removing `keep`. Only files named like entries
/// are counted or removed. Returns the number of entries removed.
pub fn prune(dir: &Path, max_bytes: u64, keep: Option<&Path>) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut entries: Vec<(std::time::SystemTime, u64, PathBuf)> = rd
        .filter_map(|e| {
            let e = e.ok()?;
            if !is_entry_name(e.file_name().to_str()?) {
                return None;
            }
            let m = e.metadata().ok()?;
            m.is_file().then(|| {
                (
                    m.modified().unwrap_or(std::time::UNIX_EPOCH),
                    m.len(),
                    e.path(),
                )
            })
        })
        .collect();
    let mut total: u64 = entries.iter().map(|e| e.1).sum();
    entries.sort();
    let mut removed = 0;
    for (_, len, path) in entries {
        if total <= max_bytes {
            break;
        }
        if Some(path.as_path()) == keep {
            continue;
        }
        if std::fs::remove_file(&path).is_ok() {
            total -= len;
            removed += 1;
        }
    }
    removed
}

/// Write the sealed entry `bytes` as `prefix`-`key` in `dir` (creating it), atomically, then
/// [`prune`] the folder to [`max_bytes`] (keeping this entry).
///
/// # Errors
/// The folder cannot be created or the file written; callers ignore this (a cache that
/// cannot be written only costs the next run the build).
pub fn write(dir: &Path, prefix: &str, key: &[u8; 32], bytes: &[u8]) -> std::io::Result<()> {
    std::fs::create_dir_all(dir)?;
    let path = entry_path(dir, prefix, key);
    meso_core::io::write_atomic(&path, bytes)?;
    prune(dir, max_bytes(), Some(&path));
    Ok(())
}
