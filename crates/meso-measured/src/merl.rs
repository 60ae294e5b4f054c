//! The MERL BRDF binary format (Matusik, Pfister, Brand, McMillan 2003).
//!
//! # Layout
//! * Header: three little-endian `i32` dimensions, `90, 90, 180` (θh, θd, φd bins).
//! * Then three blocks — red, green, blue — of `90·90·180 = 1 458 000` little-endian `f64` each,
//!   the cell `(ih, id, ip)` at index `(ih·90 + id)·180 + ip`. A file is exactly
//!   [`MERL_FILE_BYTES`] = 34 992 012 bytes.
//! * A stored value times the channel scale ([`MERL_SCALES`]: 1/1500, 1.15/1500, 1.66/1500) is the
//!   BRDF in 1/sr. A negative stored value means "not measured".
//!
//! # Cells
//! The axes are the [Rusinkiewicz angles](crate::rusinkiewicz) with φh dropped (isotropy):
//! * θh ∈ [0, π/2] is binned non-linearly: `ih = floor(sqrt(θh/(π/2))·90)`; cell `ih` starts at
//!   `θh = (ih/90)²·π/2`;
//! * θd ∈ [0, π/2] linearly: `id = floor(θd/(π/2)·90)`;
//! * φd ∈ [0, π) linearly: `ip = floor(φd/π·180)`, after `φd < 0 ↦ φd + π` (reciprocity).
//!
//! Lookups ([`MerlTable::lookup`]) take the nearest cell in that sense, as MERL's reference
//! reader `BRDFRead.cpp` does. The direction pair that *represents* a cell (for writing a table
//! from a function, and for iterating over the cells when fitting) is chosen by [`CellPosition`]:
//! the lower bin edge (the default; the nodes of MERL's own interpolating readers, and exactly
//! invertible by the floor lookup) or the bin centre.

use crate::rusinkiewicz::{dirs_from_half_diff, half_diff_from_dirs, HalfDiff};
use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, PI};
use std::io::Read;
use std::path::Path;

/// Number of θh bins.
pub const N_THETA_H: usize = 90;
/// Number of θd bins.
pub const N_THETA_D: usize = 90;
/// Number of φd bins (over `[0, π)`).
pub const N_PHI_D: usize = 180;
/// Cells per channel: 1 458 000.
pub const N_CELLS: usize = N_THETA_H * N_THETA_D * N_PHI_D;
/// Size in bytes of a valid MERL file: 12 + 3·8·1 458 000.
pub const MERL_FILE_BYTES: u64 = 12 + 3 * 8 * N_CELLS as u64;
/// Bytes of a table in memory ([`MerlTable`]: `3·N_CELLS` values, f64): 34 992 000.
pub const MERL_TABLE_BYTES: u64 = 3 * 8 * N_CELLS as u64;
/// Peak memory of [`MerlTable::read`]: the file's body and the decoded table, 69 984 000 bytes.
pub const MERL_READ_BYTES: u64 = 2 * MERL_TABLE_BYTES;
/// Channel scales: stored value × scale = BRDF in 1/sr (red, green, blue).
pub const MERL_SCALES: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

/// Errors reading or writing a MERL binary.
#[derive(Debug, thiserror::Error)]
pub enum MerlError {
    /// The file could not be opened or read.
    #[error("cannot read MERL file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
    /// The file is shorter than the 12-byte header.
    #[error("MERL file {path} is {size} bytes: too short for the 12-byte header")]
    NoHeader {
        /// The file.
        path: String,
        /// Its size in bytes.
        size: u64,
    },
    /// The header dimensions are not `90, 90, 180`.
    #[error("MERL file {path}: header dimensions {dims:?}, expected [90, 90, 180]")]
    BadHeader {
        /// The file.
        path: String,
        /// The three dimensions found.
        dims: [i32; 3],
    },
    /// The file size does not match the header (truncated or with trailing data).
    #[error("MERL file {path} is {size} bytes, expected {expected} (truncated or trailing data)")]
    BadSize {
        /// The file.
        path: String,
        /// Actual size in bytes.
        size: u64,
        /// Expected size in bytes.
        expected: u64,
    },
    /// A sample is NaN or infinite.
    #[error("MERL file {path}: non-finite value {value} in channel {channel} at cell (θh {ih}, θd {id}, φd {ip})")]
    NonFinite {
        /// The file.
        path: String,
        /// Channel 0 (red), 1 (green) or 2 (blue).
        channel: usize,
        /// θh bin.
        ih: usize,
        /// θd bin.
        id: usize,
        /// φd bin.
        ip: usize,
        /// The value.
        value: f64,
    },
    /// A function given to [`MerlTable::from_fn`] returned a NaN, infinite or negative value.
    #[error("BRDF value {value} at cell (θh {ih}, θd {id}, φd {ip}) is not a finite non-negative number")]
    BadValue {
        /// θh bin.
        ih: usize,
        /// θd bin.
        id: usize,
        /// φd bin.
        ip: usize,
        /// The value.
        value: f64,
    },
    /// Reading refused because its memory ([`MERL_READ_BYTES`]) is above the budget
    /// (`meso_core::budget`); the message names the file, the estimate and the budget.
    #[error(transparent)]
    Budget(#[from] meso_core::budget::BudgetError),
    /// A big allocation failed (the memory was not there after all).
    #[error("{path}: {source}")]
    OutOfMemory {
        /// The file.
        path: String,
        /// The failed allocation.
        source: meso_core::budget::AllocError,
    },
    /// Writing failed (nothing was left behind).
    #[error("cannot write MERL file {path}: {source}")]
    Write {
        /// The file.
        path: String,
        /// The underlying error.
        source: std::io::Error,
    },
}

/// Which direction pair represents a cell.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum CellPosition {
    /// The lower bin edge: `θh = (ih/90)²·π/2`, `θd = id/90·π/2`, `φd = ip/180·π` (default).
    #[default]
    Edge,
    /// The bin centre: `((ih+½)/90)²·π/2`, `(id+½)/90·π/2`, `(ip+½)/180·π`.
    Centre,
}

/// A MERL table: three channels of 1 458 000 cells, stored as BRDF values in 1/sr (already
/// multiplied by the channel scales); a negative value is a missing measurement.
#[derive(Clone, Debug)]
pub struct MerlTable {
    data: Vec<f64>,
}

/// One cell of a table, as produced by [`MerlTable::cells`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MerlCell {
    /// Flat index `(ih·90 + id)·180 + ip`.
    pub index: usize,
    /// θh, θd, φd bins.
    pub bins: [usize; 3],
    /// Light direction (towards the light), local frame, φh = 0.
    pub wi: DVec3,
    /// View direction, local frame.
    pub wo: DVec3,
    /// BRDF in 1/sr per channel (negative = not measured).
    pub rgb: [f64; 3],
    /// The solid-angle measure of the cell in the four-dimensional space of direction pairs,
    /// `∫∫ dω_i dω_o` over the cell with φh integrated over `[0, 2π)` and φd over both halves:
    /// `4 · 2π · 2 · (cos θh₀ − cos θh₁) · ½(sin² θd₁ − sin² θd₀) · Δφd` (sr²).
    pub measure: f64,
}

/// Bin index of θh (radians): `floor(sqrt(θh/(π/2))·90)` clamped to `[0, 89]`.
#[inline]
#[must_use]
pub fn theta_h_bin(theta_h: f64) -> usize {
    if theta_h <= 0.0 || theta_h.is_nan() {
        return 0;
    }
    let x = (theta_h / FRAC_PI_2).sqrt() * N_THETA_H as f64;
    (x as usize).min(N_THETA_H - 1)
}

/// Bin index of θd (radians): `floor(θd/(π/2)·90)` clamped to `[0, 89]`.
#[inline]
#[must_use]
pub fn theta_d_bin(theta_d: f64) -> usize {
    if theta_d <= 0.0 || theta_d.is_nan() {
        return 0;
    }
    ((theta_d / FRAC_PI_2 * N_THETA_D as f64) as usize).min(N_THETA_D - 1)
}

/// Bin index of φd (radians, any range in `(−π, π]`): negative φd is shifted by π (reciprocity),
/// then `floor(φd/π·180)` clamped to `[0, 179]`.
#[inline]
#[must_use]
pub fn phi_d_bin(phi_d: f64) -> usize {
    let mut p = phi_d;
    if p < 0.0 {
        p += PI;
    }
    if p <= 0.0 || p.is_nan() {
        return 0;
    }
    ((p / PI * N_PHI_D as f64) as usize).min(N_PHI_D - 1)
}

/// The half/difference angles (φh = 0) representing the cell `(ih, id, ip)`.
#[must_use]
pub fn cell_angles(ih: usize, id: usize, ip: usize, pos: CellPosition) -> HalfDiff {
    let off = match pos {
        CellPosition::Edge => 0.0,
        CellPosition::Centre => 0.5,
    };
    let u = (ih as f64 + off) / N_THETA_H as f64;
    HalfDiff {
        theta_h: u * u * FRAC_PI_2,
        phi_h: 0.0,
        theta_d: (id as f64 + off) / N_THETA_D as f64 * FRAC_PI_2,
        phi_d: (ip as f64 + off) / N_PHI_D as f64 * PI,
    }
}

/// The solid-angle measure (sr²) of the cell `(ih, id, ·)`; see [`MerlCell::measure`].
#[must_use]
pub fn cell_measure(ih: usize, id: usize) -> f64 {
    let th = |i: usize| {
        let u = i as f64 / N_THETA_H as f64;
        u * u * FRAC_PI_2
    };
    let td = |i: usize| i as f64 / N_THETA_D as f64 * FRAC_PI_2;
    let dh = th(ih).cos() - th(ih + 1).cos();
    let s0 = td(id).sin();
    let s1 = td(id + 1).sin();
    let dd = 0.5 * (s1 * s1 - s0 * s0);
    4.0 * 2.0 * PI * 2.0 * dh * dd * (PI / N_PHI_D as f64)
}

#[inline]
fn flat(ih: usize, id: usize, ip: usize) -> usize {
    (ih * N_THETA_D + id) * N_PHI_D + ip
}

/// Decode stored MERL values (little-endian `f64`, 8 bytes each, a trailing partial value is
/// ignored) whose first one has the flat index `first` in the body (channel-major, `channel ·
/// N_CELLS + (ih·90 + id)·180 + ip`), appending BRDF values in 1/sr (scaled by the channel's
/// scale; negative stored values become −1, "not measured") to `out`. The body of a table is
/// `first = 0` and `3·N_CELLS` values. Indices past the body are errors.
///
/// # Errors
/// [`MerlError::NonFinite`] (with an empty path) naming the channel and cell of the first NaN or
/// infinite value; [`MerlError::BadSize`] if the values run past the body.
pub fn decode_values(bytes: &[u8], first: usize, out: &mut Vec<f64>) -> Result<(), MerlError> {
    let n = bytes.len() / 8;
    if first.checked_add(n).is_none_or(|end| end > 3 * N_CELLS) {
        return Err(MerlError::BadSize {
            path: String::new(),
            size: 12 + 8 * (first as u64).saturating_add(n as u64),
            expected: MERL_FILE_BYTES,
        });
    }
    out.reserve(n);
    for (j, chunk) in bytes.chunks_exact(8).enumerate() {
        let k = first + j;
        let mut b = [0u8; 8];
        b.copy_from_slice(chunk);
        let v = f64::from_le_bytes(b);
        let channel = k / N_CELLS;
        if !v.is_finite() {
            let c = k % N_CELLS;
            return Err(MerlError::NonFinite {
                path: String::new(),
                channel,
                ih: c / (N_THETA_D * N_PHI_D),
                id: (c / N_PHI_D) % N_THETA_D,
                ip: c % N_PHI_D,
                value: v,
            });
        }
        out.push(if v < 0.0 {
            -1.0
        } else {
            v * MERL_SCALES[channel]
        });
    }
    Ok(())
}

/// The checks of a MERL file's 12-byte header `head` and its `size` (both ways of reading):
/// the dimensions 90, 90, 180 ([`MerlError::BadHeader`]), then the size they imply
/// ([`MerlError::BadSize`]); errors name the file `path`.
fn check_header(head: &[u8], size: u64, path: &str) -> Result<(), MerlError> {
    let dims = [0, 1, 2].map(|k| {
        i32::from_le_bytes([
            head[4 * k],
            head[4 * k + 1],
            head[4 * k + 2],
            head[4 * k + 3],
        ])
    });
    if dims != [N_THETA_H as i32, N_THETA_D as i32, N_PHI_D as i32] {
        return Err(MerlError::BadHeader {
            path: path.to_string(),
            dims,
        });
    }
    if size != MERL_FILE_BYTES {
        return Err(MerlError::BadSize {
            path: path.to_string(),
            size,
            expected: MERL_FILE_BYTES,
        });
    }
    Ok(())
}

impl MerlError {
    /// A [`MerlError::NonFinite`] of the decoder (no file) names the file `path`; other errors
    /// are returned as they are.
    fn in_file(self, path: &str) -> MerlError {
        match self {
            MerlError::NonFinite {
                channel,
                ih,
                id,
                ip,
                value,
                ..
            } => MerlError::NonFinite {
                path: path.to_string(),
                channel,
                ih,
                id,
                ip,
                value,
            },
            other => other,
        }
    }
}

impl MerlTable {
    /// Read a MERL binary. The header, the file size and the memory budget
    /// ([`MERL_READ_BYTES`] against `meso_core::budget`) are checked before any allocation, and
    /// the two big buffers are reserved fallibly (an allocation failure is
    /// [`MerlError::OutOfMemory`], not an abort); NaN or infinite samples are errors; negative
    /// samples are kept as "not measured".
    pub fn read(path: &Path) -> Result<MerlTable, MerlError> {
        let p = path.display().to_string();
        let io = |source| MerlError::Io {
            path: p.clone(),
            source,
        };
        meso_core::io::note_input(path);
        let mut f = std::fs::File::open(path).map_err(io)?;
        let size = f.metadata().map_err(io)?.len();
        if size < 12 {
            return Err(MerlError::NoHeader { path: p, size });
        }
        let mut head = [0u8; 12];
        f.read_exact(&mut head).map_err(io)?;
        check_header(&head, size, &p)?;
        meso_core::budget::check(path, "reading the MERL table", MERL_READ_BYTES)?;
        let oom = |source| MerlError::OutOfMemory {
            path: p.clone(),
            source,
        };
        let mut bytes = meso_core::budget::try_with_capacity::<u8>(3 * N_CELLS * 8).map_err(oom)?;
        let mut data = meso_core::budget::try_with_capacity::<f64>(3 * N_CELLS).map_err(oom)?;
        f.take(3 * N_CELLS as u64 * 8)
            .read_to_end(&mut bytes)
            .map_err(io)?;
        if bytes.len() != 3 * N_CELLS * 8 {
            // The file shrank between the size check and the read.
            return Err(MerlError::BadSize {
                path: p,
                size: 12 + bytes.len() as u64,
                expected: MERL_FILE_BYTES,
            });
        }
        decode_values(&bytes, 0, &mut data)
            .map(|()| MerlTable { data })
            .map_err(|e| e.in_file(&p))
    }

    /// Decode a whole MERL file held in memory (header and body), with the checks of
    /// [`MerlTable::read`]; errors name the file as `(memory)`.
    pub fn from_bytes(bytes: &[u8]) -> Result<MerlTable, MerlError> {
        let p = "(memory)";
        let size = bytes.len() as u64;
        if bytes.len() < 12 {
            return Err(MerlError::NoHeader {
                path: p.to_string(),
                size,
            });
        }
        check_header(&bytes[..12], size, p)?;
        Self::from_le_bytes(&bytes[12..]).map_err(|e| e.in_file(p))
    }

    /// Whether `bytes` (the start of a file, at least 12 bytes) begin with the MERL header
    /// `90, 90, 180` — a cheap format detection.
    #[must_use]
    pub fn has_header(bytes: &[u8]) -> bool {
        bytes.len() >= 12
            && bytes[..12]
                .chunks_exact(4)
                .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .eq([N_THETA_H as i32, N_THETA_D as i32, N_PHI_D as i32])
    }

    /// Decode the three channel blocks (without header) from little-endian `f64` bytes; the
    /// slice must be exactly `3·8·N_CELLS` bytes long (checked by [`MerlTable::read`]).
    fn from_le_bytes(bytes: &[u8]) -> Result<MerlTable, MerlError> {
        debug_assert_eq!(bytes.len(), 3 * N_CELLS * 8);
        let mut data = Vec::with_capacity(3 * N_CELLS);
        decode_values(bytes, 0, &mut data)?;
        Ok(MerlTable { data })
    }

    /// Tabulate a BRDF `f(wi, wo) → [r, g, b]` (1/sr, local frame) at the representative direction
    /// pair of every cell (`pos`, with φh = 0). Cells whose `wi` or `wo` lies below the horizon
    /// (z ≤ 0) are stored as "not measured", as in MERL's files. Returns an error if `f`
    /// returns a negative, NaN or infinite value for an above-horizon cell.
    pub fn from_fn<F>(pos: CellPosition, f: F) -> Result<MerlTable, MerlError>
    where
        F: Fn(DVec3, DVec3) -> [f64; 3] + Sync,
    {
        use rayon::prelude::*;
        let mut data = vec![0.0; 3 * N_CELLS];
        let (r, rest) = data.split_at_mut(N_CELLS);
        let (g, b) = rest.split_at_mut(N_CELLS);
        r.par_chunks_mut(N_PHI_D)
            .zip(g.par_chunks_mut(N_PHI_D))
            .zip(b.par_chunks_mut(N_PHI_D))
            .enumerate()
            .try_for_each(|(row, ((r, g), b))| {
                let ih = row / N_THETA_D;
                let id = row % N_THETA_D;
                for ip in 0..N_PHI_D {
                    let (wi, wo) = dirs_from_half_diff(cell_angles(ih, id, ip, pos));
                    let v = if wi.z <= 0.0 || wo.z <= 0.0 {
                        [-1.0; 3]
                    } else {
                        let v = f(wi, wo);
                        for x in v {
                            if !(x.is_finite() && x >= 0.0) {
                                return Err(MerlError::BadValue {
                                    ih,
                                    id,
                                    ip,
                                    value: x,
                                });
                            }
                        }
                        v
                    };
                    r[ip] = v[0];
                    g[ip] = v[1];
                    b[ip] = v[2];
                }
                Ok(())
            })?;
        Ok(MerlTable { data })
    }

    /// A table whose red value in every above-horizon cell is the cell's flat index (as `f64`,
    /// green and blue 0), and "not measured" where `wi` or `wo` is below the horizon, as
    /// [`MerlTable::from_fn`] marks them: what [`crate::samples::SampleSet::from_merl_fn`]
    /// samples to learn which cells a sampling keeps before evaluating any.
    pub(crate) fn cell_index_table(pos: CellPosition) -> MerlTable {
        let mut data = vec![0.0; 3 * N_CELLS];
        for k in 0..N_CELLS {
            let (ih, id, ip) = (
                k / (N_THETA_D * N_PHI_D),
                (k / N_PHI_D) % N_THETA_D,
                k % N_PHI_D,
            );
            let (wi, wo) = dirs_from_half_diff(cell_angles(ih, id, ip, pos));
            if wi.z <= 0.0 || wo.z <= 0.0 {
                for c in 0..3 {
                    data[c * N_CELLS + k] = -1.0;
                }
            } else {
                data[k] = k as f64;
            }
        }
        MerlTable { data }
    }

    /// Write the table as a MERL binary (atomically: nothing is left behind on error). Values are
    /// divided by the channel scales; missing cells are written as −1.
    pub fn write(&self, path: &Path) -> Result<(), MerlError> {
        meso_core::io::write_atomic_with(path, |w| {
            for d in [N_THETA_H as i32, N_THETA_D as i32, N_PHI_D as i32] {
                w.write_all(&d.to_le_bytes())?;
            }
            let mut buf = Vec::with_capacity(8 * N_PHI_D * N_THETA_D);
            for (c, block) in self.data.chunks_exact(N_CELLS).enumerate() {
                for row in block.chunks(N_PHI_D * N_THETA_D) {
                    buf.clear();
                    for &v in row {
                        let s = if v < 0.0 { -1.0 } else { v / MERL_SCALES[c] };
                        buf.extend_from_slice(&s.to_le_bytes());
                    }
                    w.write_all(&buf)?;
                }
            }
            Ok(())
        })
        .map_err(|source| MerlError::Write {
            path: path.display().to_string(),
            source,
        })
    }

    /// The stored value (1/sr, negative = missing) of channel `c` at bins `(ih, id, ip)`.
    #[inline]
    #[must_use]
    pub fn value(&self, c: usize, ih: usize, id: usize, ip: usize) -> f64 {
        self.data[c * N_CELLS + flat(ih, id, ip)]
    }

    /// The nearest cell's RGB value (1/sr) for the directions `wi`, `wo` (local frame), as
    /// `BRDFRead.cpp` looks it up; `None` if any channel of that cell is not measured.
    #[must_use]
    pub fn lookup(&self, wi: DVec3, wo: DVec3) -> Option<[f64; 3]> {
        let hd = half_diff_from_dirs(wi, wo);
        let k = flat(
            theta_h_bin(hd.theta_h),
            theta_d_bin(hd.theta_d),
            phi_d_bin(hd.phi_d),
        );
        let v = [0, 1, 2].map(|c| self.data[c * N_CELLS + k]);
        if v.iter().any(|&x| x < 0.0) {
            None
        } else {
            Some(v)
        }
    }

    /// [`MerlTable::lookup`] from spherical angles `(θi, φi, θo, φo)` in radians.
    #[must_use]
    pub fn lookup_angles(
        &self,
        theta_i: f64,
        phi_i: f64,
        theta_o: f64,
        phi_o: f64,
    ) -> Option<[f64; 3]> {
        self.lookup(
            meso_core::frame::spherical_direction(theta_i, phi_i),
            meso_core::frame::spherical_direction(theta_o, phi_o),
        )
    }

    /// Number of cells (out of 1 458 000) with at least one channel not measured.
    #[must_use]
    pub fn missing_count(&self) -> usize {
        (0..N_CELLS)
            .filter(|&k| (0..3).any(|c| self.data[c * N_CELLS + k] < 0.0))
            .count()
    }

    /// Iterate over all 1 458 000 cells in file order with their representative direction pair
    /// (`pos`, φh = 0), values and measure; missing cells included (negative values).
    pub fn cells(&self, pos: CellPosition) -> impl Iterator<Item = MerlCell> + '_ {
        (0..N_CELLS).map(move |k| {
            let ih = k / (N_THETA_D * N_PHI_D);
            let id = (k / N_PHI_D) % N_THETA_D;
            let ip = k % N_PHI_D;
            let (wi, wo) = dirs_from_half_diff(cell_angles(ih, id, ip, pos));
            MerlCell {
                index: k,
                bins: [ih, id, ip],
                wi,
                wo,
                rgb: [0, 1, 2].map(|c| self.data[c * N_CELLS + k]),
                measure: cell_measure(ih, id),
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_invert_cell_edges() {
        for i in 0..N_THETA_H {
            let hd = cell_angles(i, i, 2 * i, CellPosition::Edge);
            assert_eq!(theta_h_bin(hd.theta_h + 1e-12), i);
            assert_eq!(theta_d_bin(hd.theta_d + 1e-12), i);
            assert_eq!(phi_d_bin(hd.phi_d + 1e-12), 2 * i);
            let hc = cell_angles(i, i, 2 * i, CellPosition::Centre);
            assert_eq!(theta_h_bin(hc.theta_h), i);
            assert_eq!(theta_d_bin(hc.theta_d), i);
            assert_eq!(phi_d_bin(hc.phi_d), 2 * i);
            // Reciprocity: φd − π falls in the same bin.
            assert_eq!(phi_d_bin(hc.phi_d - PI), 2 * i);
        }
        assert_eq!(theta_h_bin(10.0), N_THETA_H - 1);
        assert_eq!(phi_d_bin(PI), N_PHI_D - 1);
    }

    #[test]
    fn cell_measures_sum_to_the_full_measure() {
        // ∫∫ dω_i dω_o over all (i, o) pairs covered by θh, θd ∈ [0, π/2]: the table's domain
        // covers each unordered-in-φd pair twice; the total must be 4·2π·2·1·½·π = 8π².
        let total: f64 = (0..N_THETA_H)
            .flat_map(|ih| (0..N_THETA_D).map(move |id| cell_measure(ih, id) * N_PHI_D as f64))
            .sum();
        assert!((total - 8.0 * PI * PI).abs() < 1e-9 * total, "{total}");
    }
}
