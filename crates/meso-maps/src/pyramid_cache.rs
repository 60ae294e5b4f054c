//! The on-disk cache of extracted pyramids (`[ndf] kind = "heightmap"` with
//! `represent = "lobes"`, and NDF-mapped `[texture]` materials of scene files over a height map
//! or a normal map): extracting a 1024² map takes seconds, and the result is the same every
//! time the same map is loaded with the same parameters, so it is kept in a file and read back
//! by the next `meso render` or `meso brdf`.
//!
//! * The folder: that of the facet cache ([`crate::disk_cache::cache_dir`]: `$MESO_CACHE_DIR`,
//!   `off` or empty to turn it off; else `$XDG_CACHE_HOME/meso`, else `$HOME/.cache/meso`),
//!   pruned to `$MESO_CACHE_MAX_BYTES` (default 2 GiB) least recently used first
//!   ([`crate::disk_cache::prune`]).
//! * The key of a height map ([`key`]): SHA-256 of the file's bytes, the texel size, height
//!   scale and border of the map, every extraction parameter ([`ExtractParams`], lobe fit
//!   included), [`KEY_MAP_VERSION`], [`FORMAT`] and this crate's version. The key of a normal map ([`normal_key`]): the same with the green-channel
//!   convention in place of the texel size, height scale and border, in a separate domain (a
//!   file's bytes never give the same key as a height map and as a normal map).
//! * The file `pyramid-<key>.bin`: the load warnings of the source
//!   ([`crate::disk_cache::put_warnings`]: said again on a hit), then the map file's bytes
//!   (`docs/map-format.md`; written in
//!   version 4, [`crate::format::VERSION`], entries of version 3 written by earlier builds still
//!   read) sealed by [`crate::disk_cache`] (magic, format, key, SHA-256), written atomically. A
//!   damaged, truncated or foreign file is ignored and rebuilt, never an error.
//!
//! A pyramid from [`pyramid_cached`] or [`normal_pyramid_cached`] is always the one the map
//! file stores (lobes and horizon statistics quantised, format 4), built or read back: the
//! first run, the cached runs and a `.map` written by `meso extract` with the same parameters
//! give the same pyramid, bit for bit.

pub use crate::disk_cache::Cached;
use crate::heightmap::{Border, NormalConvention};
use crate::pyramid::{ExtractParams, Pyramid};
use sha2::{Digest, Sha256};
use std::path::Path;

/// The cache entry format; bumped whenever what is stored or how it is built changes. 4 since
/// 2026-12-04: EM's E-step sums over the points in lanes, so a fresh extraction differs from
/// an entry of format 3 in the last bits (a format-3 entry is then rebuilt, not read). 5 since
/// 2026-12-04 (evening): the entry keeps the source's load warnings before the map file's bytes
/// ([`crate::disk_cache::put_warnings`]), and the horizon angles are held in 16 bits
/// ([`crate::horizon::ANGLE_STEP`]), which moves the last bits of the horizon statistics. 6
/// since 2026-12-05: the cheap path of the fit tries K = `max_lobes` first (`fit` module
/// docs), which gives a few texels more lobes than a format-5 entry holds. 7 since 2026-12-05
/// (afternoon): on small footprints (≤ 4 entries per lobe) the K chain goes on past a K whose
/// k-means clusters lose to K − 1, so such texels can get more lobes than a format-6 entry holds.
/// 8 since 2026-12-07: the horizon statistics have eight azimuths (map format 5); an entry of
/// format 7 would read with its diagonals interpolated, so it is rebuilt.
pub const FORMAT: u32 = 8;
const MAGIC: &[u8; 8] = b"MESOPYC\0";
const PREFIX: &str = "pyramid";
/// The map format version hashed into every key: 3, the version the cache wrote until
/// 2026-12-04. It now writes version 4 ([`crate::format::VERSION`]), which stores the same codes
/// and reads back to the very pyramid version 3 does (`tests/map_format_v3.rs`), so the keys
/// stay and an entry of either version answers: a cache filled by an earlier build still opens.
pub const KEY_MAP_VERSION: u32 = 3;

/// The cache key of a height map file's bytes, its texel size, height scale and border, and
/// the extraction parameters.
#[must_use]
pub fn key(
    file_bytes: &[u8],
    texel_size: f64,
    height_scale: f64,
    border: Border,
    params: &ExtractParams,
) -> [u8; 32] {
    let mut fields = Vec::with_capacity(17);
    fields.extend(texel_size.to_le_bytes());
    fields.extend(height_scale.to_le_bytes());
    fields.push(u8::from(border == Border::Clamp));
    hash_key(b"meso pyramid ", &fields, params, file_bytes)
}

/// The cache key of a normal map file's bytes, its green-channel convention and the
/// extraction parameters (module docs).
#[must_use]
pub fn normal_key(
    file_bytes: &[u8],
    convention: NormalConvention,
    params: &ExtractParams,
) -> [u8; 32] {
    let fields = [u8::from(convention == NormalConvention::Dx)];
    hash_key(b"meso normal-map pyramid ", &fields, params, file_bytes)
}

/// SHA-256 of `tag`, this build's version and formats, the source's own `fields`, every field
/// of the parameters (the fit's included; floats print exactly) and the file's bytes: the one
/// layout of [`key`] and [`normal_key`].
fn hash_key(tag: &[u8], fields: &[u8], params: &ExtractParams, file_bytes: &[u8]) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(tag);
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(FORMAT.to_le_bytes());
    h.update(KEY_MAP_VERSION.to_le_bytes());
    h.update(fields);
    let p = format!("{params:?}");
    h.update((p.len() as u64).to_le_bytes());
    h.update(p.as_bytes());
    h.update((file_bytes.len() as u64).to_le_bytes());
    h.update(file_bytes);
    h.finalize().into()
}

/// The path of the entry of `key` in `dir` (whether or not it exists).
#[must_use]
pub fn entry_path(dir: &Path, key: &[u8; 32]) -> std::path::PathBuf {
    crate::disk_cache::entry_path(dir, PREFIX, key)
}

/// The pyramid stored under `key` in `dir`, if a valid entry is there.
#[must_use]
pub fn load_entry(dir: &Path, key: &[u8; 32]) -> Option<Pyramid> {
    // Over the memory budget (as `Pyramid::read` would be): a miss, and the extraction says why.
    let len = std::fs::metadata(entry_path(dir, key)).ok()?.len();
    meso_core::budget::check(
        &entry_path(dir, key),
        "reading the pyramid cache",
        crate::format::read_bytes(len),
    )
    .ok()?;
    load_with_warnings(dir, key).map(|(p, _)| p)
}

/// [`load_entry`] with the load warnings kept in the entry.
fn load_with_warnings(dir: &Path, key: &[u8; 32]) -> Option<(Pyramid, Vec<String>)> {
    let bytes = crate::disk_cache::read(dir, PREFIX, key)?;
    let mut map = crate::disk_cache::open(&bytes, MAGIC, FORMAT, key)?;
    let warnings = crate::disk_cache::take_warnings(&mut map)?;
    Some((
        Pyramid::from_bytes(&entry_path(dir, key), map).ok()?,
        warnings,
    ))
}

/// Store `pyramid` under `key` in `dir` with its source's load `warnings` (creating the
/// folder; then it is pruned).
///
/// # Errors
/// The folder cannot be created or the file written, or the pyramid holds values a map file
/// cannot (`InvalidData`).
pub fn store(
    dir: &Path,
    key: &[u8; 32],
    pyramid: &Pyramid,
    warnings: &[String],
) -> std::io::Result<()> {
    let mut entry = crate::disk_cache::header(MAGIC, FORMAT, key);
    crate::disk_cache::put_warnings(&mut entry, warnings);
    pyramid.write_to(&mut entry)?;
    crate::disk_cache::seal(&mut entry);
    crate::disk_cache::write(dir, PREFIX, key, &entry)
}

/// The pyramid of the height map in `file`, from the cache when it has it (the image is then
/// not decoded), else built by `build` (which loads and extracts, and returns the load's
/// warnings), stored and returned as the map file stores it (module docs), with whether the
/// cache answered and the load's warnings (kept in the entry: a hit returns the build's).
///
/// # Errors
/// `build`'s errors; the cache's own failures are misses, never errors.
pub fn pyramid_cached<E>(
    file: &Path,
    texel_size: f64,
    height_scale: f64,
    border: Border,
    params: &ExtractParams,
    build: impl FnOnce() -> Result<(Pyramid, Vec<String>), E>,
) -> Result<Cached<Pyramid>, E> {
    cached(
        file,
        |bytes| key(bytes, texel_size, height_scale, border, params),
        build,
    )
}

/// [`pyramid_cached`] for a tangent-space normal map read with `convention` (key:
/// [`normal_key`]).
///
/// # Errors
/// `build`'s errors; the cache's own failures are misses, never errors.
pub fn normal_pyramid_cached<E>(
    file: &Path,
    convention: NormalConvention,
    params: &ExtractParams,
    build: impl FnOnce() -> Result<(Pyramid, Vec<String>), E>,
) -> Result<Cached<Pyramid>, E> {
    cached(file, |bytes| normal_key(bytes, convention, params), build)
}

fn cached<E>(
    file: &Path,
    key_of: impl FnOnce(&[u8]) -> [u8; 32],
    build: impl FnOnce() -> Result<(Pyramid, Vec<String>), E>,
) -> Result<Cached<Pyramid>, E> {
    let dir = crate::disk_cache::cache_dir();
    let k = dir.as_ref().and_then(|_| {
        let bytes = crate::disk_cache::source_bytes(file)?;
        Some(key_of(&bytes))
    });
    if let (Some(d), Some(k)) = (dir.as_deref(), &k) {
        if let Some((value, warnings)) = load_with_warnings(d, k) {
            return Ok(Cached {
                value,
                hit: true,
                warnings,
            });
        }
    }
    let (built, warnings) = build()?;
    let as_built = |value| Cached {
        value,
        hit: false,
        warnings: warnings.clone(),
    };
    // The entry is built in place: header, warnings, the map file's bytes, then the seal. A
    // pyramid the format cannot hold (non-finite values) is used as built and not cached.
    let mut entry = crate::disk_cache::header(MAGIC, FORMAT, k.as_ref().unwrap_or(&[0; 32]));
    crate::disk_cache::put_warnings(&mut entry, &warnings);
    let map_start = entry.len();
    if built.write_to(&mut entry).is_err() {
        return Ok(as_built(built));
    }
    let Ok(pyramid) = Pyramid::from_bytes(file, &entry[map_start..]) else {
        return Ok(as_built(built));
    };
    drop(built);
    if let (Some(d), Some(k)) = (dir.as_deref(), &k) {
        crate::disk_cache::seal(&mut entry);
        // A cache that cannot be written only costs the next run the extraction.
        let _ = crate::disk_cache::write(d, PREFIX, k, &entry);
    }
    Ok(as_built(pyramid))
}
