//! The on-disk cache of height-map facet representations (`[ndf] kind = "heightmap"`,
//! `represent = "facets"`, the default): the binned facet normals and their visibility
//! ([`crate::facet_ndf::facets_with_visibility`]) take seconds to minutes to build (every
//! facet's horizon is marched in 32 azimuths) and are the same every time the same map is
//! loaded with the same parameters, so they are kept in a file and read back by the next
//! `meso brdf`, `meso render` or editor session.
//!
//! # Where and how
//! * The folder: `$MESO_CACHE_DIR` if set (empty or `off` turns the cache off), else
//!   `$XDG_CACHE_HOME/meso`, else `$HOME/.cache/meso`; none of them: no cache (shared with the
//!   pyramid cache, [`crate::pyramid_cache`]; both through [`crate::disk_cache`]).
//! * The key: SHA-256 of the height map file's bytes, the parameters that shape the result
//!   (texel size, height scale, border, normal mode), this crate's version and [`FORMAT`]. A
//!   changed file or parameter is a different key; nothing is ever looked up by path alone.
//! * The file `facets-<key>.bin`: magic, format, the key again, the height map's load warnings
//!   ([`crate::disk_cache::put_warnings`]: said again on a hit), the deltas (unit normal and
//!   weight, `f64`), the map's horizon statistics and the [`BinnedVisibility`] arrays, all
//!   little-endian, and the SHA-256 of all that. Written atomically (`meso_core::io::write_atomic`); read with a size limit
//!   and checked (every length, offset and value) before use: a damaged or foreign file is
//!   ignored and rebuilt, never trusted.
//! * Failing to create the folder or write the file only costs the next run the build; it is
//!   not an error.

pub use crate::disk_cache::Cached;
use crate::facet_ndf::FacetVisibility;
use crate::facets::NormalMode;
use crate::heightmap::{Border, HeightMap};
use crate::horizon::{HorizonStats, HORIZON_DIRECTIONS};
use crate::visibility::BinnedVisibility;
use glam::DVec3;
use meso_core::ndf::{DeltaSum, Ndf, WeightedNormal};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// The cache file format; bumped whenever what is stored or how it is built changes (3 since
/// 2026-12-04: the height map's load warnings are kept in the entry; 4: the facets' horizons
/// are marched from random points, `crate::visibility::jitter`; 5 since 2026-12-07: the map's
/// horizon statistics have eight azimuths).
pub const FORMAT: u32 = 5;
const MAGIC: &[u8; 8] = b"MESOFCT\0";
/// The largest cache file read back (4 GiB).
pub const MAX_CACHE_BYTES: u64 = crate::disk_cache::MAX_CACHE_BYTES;
const PREFIX: &str = "facets";

/// The cache folder (module docs), or `None` when the cache is off or no folder is known
/// ([`crate::disk_cache::cache_dir`]).
#[must_use]
pub fn cache_dir() -> Option<PathBuf> {
    crate::disk_cache::cache_dir()
}

/// The cache key of a height map file's bytes and the parameters that shape its facets.
#[must_use]
pub fn key(
    file_bytes: &[u8],
    texel_size: f64,
    height_scale: f64,
    border: Border,
    mode: NormalMode,
) -> [u8; 32] {
    let mut h = Sha256::new();
    h.update(b"meso facets ");
    h.update(env!("CARGO_PKG_VERSION").as_bytes());
    h.update(FORMAT.to_le_bytes());
    h.update(texel_size.to_le_bytes());
    h.update(height_scale.to_le_bytes());
    h.update([
        u8::from(border == Border::Clamp),
        u8::from(mode == NormalMode::CentralDifferences),
    ]);
    h.update((file_bytes.len() as u64).to_le_bytes());
    h.update(file_bytes);
    h.finalize().into()
}

/// The facets and visibility stored under `key` in `dir`, if a valid entry is there.
#[must_use]
pub fn load_entry(dir: &Path, key: &[u8; 32]) -> Option<(Ndf, FacetVisibility)> {
    load_with_warnings(dir, key).map(|(ndf, vis, _)| (ndf, vis))
}

/// [`load_entry`] with the load warnings kept in the entry.
fn load_with_warnings(dir: &Path, key: &[u8; 32]) -> Option<(Ndf, FacetVisibility, Vec<String>)> {
    let bytes = crate::disk_cache::read(dir, PREFIX, key)?;
    decode(&bytes, key)
}

/// Store the facets and visibility under `key` in `dir` with the height map's load
/// `warnings` (creating the folder); errors are returned for the caller to ignore or report.
///
/// # Errors
/// The folder cannot be created or the file written.
pub fn store(
    dir: &Path,
    key: &[u8; 32],
    deltas: &DeltaSum,
    vis: &FacetVisibility,
    warnings: &[String],
) -> std::io::Result<()> {
    crate::disk_cache::write(dir, PREFIX, key, &encode(key, deltas, vis, warnings))
}

fn encode(
    key: &[u8; 32],
    deltas: &DeltaSum,
    vis: &FacetVisibility,
    warnings: &[String],
) -> Vec<u8> {
    let mut out = crate::disk_cache::header(MAGIC, FORMAT, key);
    crate::disk_cache::put_warnings(&mut out, warnings);
    out.extend_from_slice(&(deltas.normals().len() as u64).to_le_bytes());
    for n in deltas.normals() {
        for v in [n.normal.x, n.normal.y, n.normal.z, n.weight] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    let h = &vis.horizon;
    for v in std::iter::once(h.weight).chain(h.mean).chain(h.var) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    vis.bins.encode(&mut out);
    crate::disk_cache::seal(&mut out);
    out
}

fn f64s<const N: usize>(bytes: &mut &[u8]) -> Option<[f64; N]> {
    let mut out = [0.0; N];
    for v in &mut out {
        let (c, rest) = bytes.split_first_chunk::<8>()?;
        *v = f64::from_le_bytes(*c);
        *bytes = rest;
        if !v.is_finite() {
            return None;
        }
    }
    Some(out)
}

fn decode(bytes: &[u8], key: &[u8; 32]) -> Option<(Ndf, FacetVisibility, Vec<String>)> {
    let mut payload = crate::disk_cache::open(bytes, MAGIC, FORMAT, key)?;
    let warnings = crate::disk_cache::take_warnings(&mut payload)?;
    let (n, mut b) = payload.split_first_chunk::<8>()?;
    let n = usize::try_from(u64::from_le_bytes(*n)).ok()?;
    if n == 0 || n > b.len() / 32 {
        return None;
    }
    let mut normals = Vec::with_capacity(n);
    for _ in 0..n {
        let [x, y, z, w] = f64s::<4>(&mut b)?;
        normals.push(WeightedNormal {
            normal: DVec3::new(x, y, z),
            weight: w,
        });
    }
    let deltas = DeltaSum::new(normals).ok()?;
    let [weight] = f64s::<1>(&mut b)?;
    let horizon = HorizonStats {
        weight,
        mean: f64s::<HORIZON_DIRECTIONS>(&mut b)?,
        var: f64s::<HORIZON_DIRECTIONS>(&mut b)?,
    };
    let exact: Vec<DVec3> = deltas.normals().iter().map(|n| n.normal).collect();
    let bins = BinnedVisibility::decode(&mut b, &exact)?;
    if !b.is_empty() {
        return None;
    }
    Some((
        Ndf::Deltas(deltas),
        FacetVisibility {
            bins: Arc::new(bins),
            horizon,
            radiosity: None,
        },
        warnings,
    ))
}

/// The largest height map file hashed for the cache (1 GiB; larger files are not cached).
pub const MAX_HASHED_BYTES: u64 = crate::disk_cache::MAX_HASHED_BYTES;

/// The facets of the height map in `file` with their visibility, from the cache when it has
/// them (the image is then not even decoded), else loaded with `load`, built with `build`
/// (e.g. [`crate::facet_ndf::facets_with_visibility`]) and stored. Returns whether the cache
/// answered and the map's load warnings ([`HeightMap::warnings`], kept in the entry: a hit
/// returns those of the load that built it).
///
/// # Errors
/// `load`'s and `build`'s errors.
pub fn facets_cached<E>(
    file: &Path,
    texel_size: f64,
    height_scale: f64,
    border: Border,
    mode: NormalMode,
    load: impl FnOnce() -> Result<HeightMap, E>,
    build: impl FnOnce(&HeightMap) -> Result<(Ndf, FacetVisibility), E>,
) -> Result<Cached<(Ndf, FacetVisibility)>, E> {
    let dir = cache_dir();
    let k = dir.as_ref().and_then(|_| {
        let bytes = crate::disk_cache::source_bytes(file)?;
        Some(key(&bytes, texel_size, height_scale, border, mode))
    });
    if let (Some(d), Some(k)) = (dir.as_deref(), &k) {
        if let Some((ndf, vis, warnings)) = load_with_warnings(d, k) {
            return Ok(Cached {
                value: (ndf, vis),
                hit: true,
                warnings,
            });
        }
    }
    let map = load()?;
    let warnings = map.warnings().to_vec();
    let (ndf, vis) = build(&map)?;
    if let (Some(d), Some(k), Ndf::Deltas(deltas)) = (dir.as_deref(), &k, &ndf) {
        // A cache that cannot be written only costs the next run the build.
        let _ = store(d, k, deltas, &vis, &warnings);
    }
    Ok(Cached {
        value: (ndf, vis),
        hit: false,
        warnings,
    })
}
