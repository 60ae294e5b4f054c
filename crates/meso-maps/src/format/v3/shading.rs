//! The optional shading-error trailer of format 3 (`docs/map-format.md`): after the streams,
//! [`SHADING_TAG`] and per level the mean and largest shading error (read; format 4 records
//! them in each level's end record).

use crate::error::Result;
use crate::format::Reader;

/// The tag of the optional shading-error trailer of a format-3 file (`docs/map-format.md`).
pub const SHADING_TAG: [u8; 4] = *b"SHE1";

/// The shading-error trailer of a format-3 file of `nlev` levels, if the bytes after the
/// streams start with [`SHADING_TAG`] (files written before it existed end after the streams:
/// `None`); a truncated trailer is refused, other trailing bytes are left for the caller to
/// refuse. Values must be finite and ≥ 0.
pub(in crate::format) fn read_shading(
    r: &mut Reader<'_>,
    nlev: usize,
) -> Result<Option<Vec<(f64, f64)>>> {
    let left = r.b.len() - r.pos;
    if left < 4 || r.b[r.pos..r.pos + 4] != SHADING_TAG {
        return Ok(None);
    }
    r.pos += 4;
    let mut out = Vec::with_capacity(nlev);
    for k in 0..nlev {
        let m = r.f64("shading error")?;
        let x = r.f64("shading error")?;
        if !(m.is_finite() && x.is_finite() && m >= 0.0 && x >= 0.0) {
            return Err(r.err(format!("level {k}: bad shading error {m}/{x}")));
        }
        out.push((m, x));
    }
    Ok(Some(out))
}
