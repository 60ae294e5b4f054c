//! Map format version 3 (`docs/map-format.md`): the pyramid's values quantised and stored as
//! deflate-compressed streams of byte planes (structure of arrays).
//!
//! * Lobe axis: octahedral coordinates, 2 × 20 bits (the best of the four nearest codes;
//!   angular error ≤ 2.9·10⁻⁶ rad).
//! * Lobe weight: u16 share of the texel's total, the codes of a texel adding to exactly
//!   65 535 (largest remainders); read back as `q / Σq` (the texel's weights sum to 1; error
//!   < 1/65 535).
//! * Lobe exponent η: u16 of `log2(1 + η) / log2(1 + ETA_MAX)` (relative error
//!   ≤ 1.06·10⁻⁴·(1 + 1/η)).
//! * Horizon statistics: the weight as f32, the four mean angles as 12 bits over [0, π/2] and
//!   the four standard deviations as 12 bits over [0, π/4] (errors ≤ 1.92·10⁻⁴ and
//!   9.6·10⁻⁵ rad).
//!
//! Each stream is one column after another, each column predicted (or not, whichever
//! compresses smaller) from the same slot of the previous texel of its level, split into byte
//! planes and deflated. Reading bounds every stream's inflated size by the level table (and by
//! deflate's 1032:1 limit) before inflating anything, and the whole pyramid's memory by the
//! budget.

use super::{Reader, LEVEL_HEADER_BYTES};
use crate::compact::{Horizons, Lobes, COMPACT_TEXELS};
use crate::error::{MapError, Result};
use crate::horizon::HorizonStats;
use crate::limits::ETA_MAX;
use crate::pyramid::{Level, Pyramid, Residual};
use glam::DVec3;
use meso_core::ndf::PhongLobe;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};
use std::io::{Read, Write};

/// The format version of this module.
pub const VERSION_3: u32 = 3;
/// deflate's largest expansion: a stream may not claim more than this many bytes per
/// compressed byte (plus 1024 bytes of slack).
pub const MAX_DEFLATE_RATIO: u64 = 1032;
const RATIO_SLACK: u64 = 1024;
/// Bytes of a stream header: id, filter, 2 reserved, raw length (u64), compressed length (u64).
const STREAM_HEADER: usize = 20;
/// Bytes in memory of one `f64` lobe (`PhongLobe`) and of one texel's `f64` horizon statistics
/// (half on the levels kept in `f32`, `crate::compact`).
const LOBE_MEM: u64 = 40;
const HORIZON_MEM: u64 = 72;
const Q: f64 = 65535.0;
/// Full scale of an octahedral axis coordinate (20 bits, stored in 3 bytes).
const QA: f64 = 1_048_575.0;
/// Full scale of a horizon angle (12 bits, stored in 2 bytes).
const QH: f64 = 4095.0;
/// The ranges of the horizon mean and standard deviation codes (radians): horizon angles lie in
/// [0, π/2), so their means do and their standard deviations are at most π/4.
const MEAN_SPAN: f64 = FRAC_PI_2;
const SD_SPAN: f64 = FRAC_PI_4;

/// The streams, in file order: name, per-lobe (else per-texel), columns, bytes per value,
/// bits per value (a stored value or prediction residual above them is refused).
const STREAMS: [(&str, bool, usize, usize, u32); 6] = [
    ("lobe counts", false, 1, 1, 8),
    ("lobe axes", true, 2, 3, 20),
    ("lobe weights", true, 1, 2, 16),
    ("lobe exponents", true, 1, 2, 16),
    ("horizon weights", false, 1, 4, 32),
    ("horizon angles", false, 8, 2, 12),
];

fn mask(bits: u32) -> u32 {
    if bits >= 32 {
        u32::MAX
    } else {
        (1u32 << bits) - 1
    }
}

/// Where each level's texels and lobes start in the whole-pyramid arrays.
struct Layout {
    /// Per level: (first texel, texels).
    levels: Vec<(usize, usize)>,
    /// Lobe counts of every texel, all levels, finest first.
    counts: Vec<u8>,
    /// First lobe of every texel (global), plus the end.
    start: Vec<usize>,
}

impl Layout {
    fn new(levels: Vec<(usize, usize)>, counts: Vec<u8>) -> Layout {
        let mut start = Vec::with_capacity(counts.len() + 1);
        let mut s = 0usize;
        start.push(0);
        for &c in &counts {
            s += c as usize;
            start.push(s);
        }
        Layout {
            levels,
            counts,
            start,
        }
    }
    fn texels(&self) -> usize {
        self.counts.len()
    }
    fn lobes(&self) -> usize {
        *self.start.last().unwrap_or(&0)
    }
    /// The predictor index of each value of a column (per lobe or per texel): the same slot
    /// of the previous texel in the level, or `None`.
    fn for_each_pred(&self, per_lobe: bool, mut f: impl FnMut(usize, Option<usize>)) {
        for &(t0, n) in &self.levels {
            for t in t0..t0 + n {
                if !per_lobe {
                    f(t, (t > t0).then(|| t - 1));
                    continue;
                }
                for j in 0..self.counts[t] as usize {
                    let pred =
                        (t > t0 && j < self.counts[t - 1] as usize).then(|| self.start[t - 1] + j);
                    f(self.start[t] + j, pred);
                }
            }
        }
    }
}

/// Filter and split the `columns` (values of `bits` bits in `bytes` bytes each) into byte
/// planes; with `delta` each value is stored as its difference from its predictor modulo
/// 2^`bits`.
fn planes(
    layout: &Layout,
    per_lobe: bool,
    columns: &[Vec<u32>],
    (bytes, bits): (usize, u32),
    delta: bool,
) -> Vec<u8> {
    let n = columns.first().map_or(0, Vec::len);
    let mut out = vec![0u8; n * bytes * columns.len()];
    let mask = mask(bits);
    for (c, col) in columns.iter().enumerate() {
        let base = c * n * bytes;
        layout.for_each_pred(per_lobe, |i, pred| {
            let p = match (delta, pred) {
                (true, Some(p)) => col[p],
                _ => 0,
            };
            let v = col[i].wrapping_sub(p) & mask;
            for b in 0..bytes {
                out[base + b * n + i] = (v >> (8 * b)) as u8;
            }
        });
    }
    out
}

/// Undo [`planes`] for stream `s`: its columns' values, or the first stored value wider than
/// the stream's bits.
fn unplanes(
    layout: &Layout,
    s: usize,
    raw: &[u8],
    delta: bool,
) -> std::result::Result<Vec<Vec<u32>>, u32> {
    let (_, per_lobe, cols, bytes, bits) = STREAMS[s];
    let n = if per_lobe {
        layout.lobes()
    } else {
        layout.texels()
    };
    let mask = mask(bits);
    let mut bad = None;
    let out = (0..cols)
        .map(|c| {
            let base = c * n * bytes;
            let mut col = vec![0u32; n];
            layout.for_each_pred(per_lobe, |i, pred| {
                let mut v = 0u32;
                for b in 0..bytes {
                    v |= u32::from(raw[base + b * n + i]) << (8 * b);
                }
                if v & !mask != 0 {
                    bad.get_or_insert(v);
                }
                let p = match (delta, pred) {
                    (true, Some(p)) => col[p],
                    _ => 0,
                };
                col[i] = v.wrapping_add(p) & mask;
            });
            col
        })
        .collect();
    match bad {
        Some(v) => Err(v),
        None => Ok(out),
    }
}

fn deflate(raw: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::DeflateEncoder::new(
        Vec::with_capacity(raw.len() / 2),
        flate2::Compression::default(),
    );
    e.write_all(raw).expect("writing to memory cannot fail");
    e.finish().expect("writing to memory cannot fail")
}

/// Octahedral code of a unit vector (2 × 20 bits): the best of the four nearest codes.
fn oct_encode(a: DVec3) -> (u32, u32) {
    let l1 = a.x.abs() + a.y.abs() + a.z.abs();
    let (mut u, mut v) = (a.x / l1, a.y / l1);
    if a.z < 0.0 {
        (u, v) = ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum());
    }
    let (fu, fv) = ((u * 0.5 + 0.5) * QA, (v * 0.5 + 0.5) * QA);
    let mut best = (0u32, 0u32);
    let mut best_dot = f64::NEG_INFINITY;
    for qu in [fu.floor(), fu.ceil()] {
        for qv in [fv.floor(), fv.ceil()] {
            let c = (qu.clamp(0.0, QA) as u32, qv.clamp(0.0, QA) as u32);
            let d = oct_decode(c.0, c.1).dot(a);
            if d > best_dot {
                best_dot = d;
                best = c;
            }
        }
    }
    best
}

/// The unit vector of an octahedral code.
fn oct_decode(qu: u32, qv: u32) -> DVec3 {
    let u = f64::from(qu) / QA * 2.0 - 1.0;
    let v = f64::from(qv) / QA * 2.0 - 1.0;
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = if z < 0.0 {
        ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum())
    } else {
        (u, v)
    };
    DVec3::new(x, y, z).normalize()
}

/// log2(1 + ETA_MAX): the exponent code's full scale.
fn eta_scale() -> f64 {
    (1.0 + ETA_MAX).log2()
}

fn eta_encode(eta: f64) -> u16 {
    ((1.0 + eta.clamp(0.0, ETA_MAX)).log2() / eta_scale() * Q).round() as u16
}

fn eta_decode(q: u16) -> f64 {
    if q == u16::MAX {
        return ETA_MAX;
    }
    ((f64::from(q) / Q * eta_scale()).exp2() - 1.0).clamp(0.0, ETA_MAX)
}

fn angle_encode(x: f64, span: f64) -> u16 {
    (x / span * QH).round().clamp(0.0, QH) as u16
}

fn angle_decode(q: u16, span: f64) -> f64 {
    f64::from(q.min(QH as u16)) / QH * span
}

/// The weight codes of one texel's lobes: `w / Σw · Q16` rounded, then the codes farthest
/// above (below) their exact value lowered (raised) by one until they add to exactly Q16, so a
/// code is within 1 of its exact value and decoding (`q / Σq`) then encoding gives the same
/// codes back.
fn weight_codes(w: &[f64]) -> Vec<u32> {
    let sum: f64 = w.iter().sum();
    let exact: Vec<f64> = w.iter().map(|x| x / sum * Q).collect();
    let mut q: Vec<i64> = exact.iter().map(|x| x.round() as i64).collect();
    let mut total: i64 = q.iter().sum();
    while !q.is_empty() && total != Q as i64 {
        let up = total < Q as i64;
        // The code whose rounding went most the wrong way for the correction.
        let i = (0..q.len())
            .filter(|&i| if up { q[i] < Q as i64 } else { q[i] > 0 })
            .max_by(|&a, &b| {
                let (da, db) = (exact[a] - q[a] as f64, exact[b] - q[b] as f64);
                if up {
                    da.total_cmp(&db)
                } else {
                    db.total_cmp(&da)
                }
            })
            .expect("a code can move");
        q[i] += if up { 1 } else { -1 };
        total += if up { 1 } else { -1 };
    }
    q.into_iter().map(|x| x as u32).collect()
}

/// Why `pyramid` cannot be stored (a value a map file cannot hold), or `None`.
pub(super) fn unstorable(p: &Pyramid) -> Option<String> {
    for (k, l) in p.levels.iter().enumerate() {
        for t in 0..l.texels() {
            let (a, b) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
            let mut sum = 0.0;
            for lobe in l.lobes.range(a, b) {
                let a = lobe.axis;
                if !a.is_finite() || (a.length() - 1.0).abs() > 1e-3 {
                    return Some(format!("level {k}: lobe axis {a} is not a unit vector"));
                }
                if !(lobe.weight.is_finite() && lobe.weight >= 0.0) {
                    return Some(format!("level {k}: lobe weight {}", lobe.weight));
                }
                if !(lobe.exponent.is_finite() && (0.0..=ETA_MAX * 1.0001).contains(&lobe.exponent))
                {
                    return Some(format!("level {k}: lobe exponent {}", lobe.exponent));
                }
                sum += lobe.weight;
            }
            if b > a && (sum.is_nan() || sum <= 0.0) {
                return Some(format!("level {k}: a texel's lobe weights sum to {sum}"));
            }
        }
        for s in l.horizon.iter().flat_map(Horizons::iter) {
            if !(s.weight.is_finite()
                && s.weight >= 0.0
                && s.mean.iter().chain(&s.var).all(|v| v.is_finite()))
            {
                return Some(format!("level {k}: bad horizon statistics"));
            }
            if s.var.iter().any(|v| *v < 0.0) {
                return Some(format!("level {k}: negative horizon variance {:?}", s.var));
            }
            // Horizon angles lie in [0, π/2): their means in it, their variances ≤ (π/4)².
            let eps = 1e-9;
            if s.mean.iter().any(|m| !(-eps..=MEAN_SPAN + eps).contains(m))
                || s.var.iter().any(|v| v.sqrt() > SD_SPAN + eps)
            {
                return Some(format!(
                    "level {k}: horizon statistics outside the range of horizon angles \
                     (means {:?} not in [0, π/2] or variances {:?} above (π/4)²)",
                    s.mean, s.var
                ));
            }
        }
    }
    None
}

/// The raw (unfiltered) columns of stream `s` of `p`.
fn columns(p: &Pyramid, s: usize) -> Vec<Vec<u32>> {
    let lobes = || p.levels.iter().flat_map(|l| l.lobes.iter());
    let horizon = || {
        p.levels
            .iter()
            .flat_map(|l| l.horizon.iter().flat_map(Horizons::iter))
    };
    match s {
        0 => vec![p
            .levels
            .iter()
            .flat_map(|l| l.lobe_start.windows(2).map(|w| w[1] - w[0]))
            .collect()],
        1 => {
            let codes: Vec<(u32, u32)> = lobes().map(|l| oct_encode(l.axis)).collect();
            vec![
                codes.iter().map(|c| c.0).collect(),
                codes.iter().map(|c| c.1).collect(),
            ]
        }
        2 => {
            let mut col = Vec::new();
            for l in &p.levels {
                for w in l.lobe_start.windows(2) {
                    let t = l.lobes.range(w[0] as usize, w[1] as usize);
                    col.extend(weight_codes(&t.map(|x| x.weight).collect::<Vec<_>>()));
                }
            }
            vec![col]
        }
        3 => vec![lobes().map(|l| u32::from(eta_encode(l.exponent))).collect()],
        4 => vec![horizon().map(|h| (h.weight as f32).to_bits()).collect()],
        _ => {
            let mut cols = Vec::with_capacity(8);
            for d in 0..4 {
                cols.push(
                    horizon()
                        .map(|h| u32::from(angle_encode(h.mean[d], MEAN_SPAN)))
                        .collect(),
                );
            }
            for d in 0..4 {
                cols.push(
                    horizon()
                        .map(|h| u32::from(angle_encode(h.var[d].sqrt(), SD_SPAN)))
                        .collect(),
                );
            }
            cols
        }
    }
}

/// Write the levels of `p` (after the common header) in format 3: the level table, then the
/// streams. The caller has checked [`unstorable`].
pub(super) fn write_levels(p: &Pyramid, w: &mut dyn Write) -> std::io::Result<()> {
    let has_h = p.levels[0].horizon.is_some();
    let mut levels = Vec::with_capacity(p.levels.len());
    let mut t0 = 0;
    for l in &p.levels {
        w.write_all(&(l.cols as u32).to_le_bytes())?;
        w.write_all(&(l.rows as u32).to_le_bytes())?;
        w.write_all(&(l.span as u32).to_le_bytes())?;
        w.write_all(&(l.lobes.len() as u32).to_le_bytes())?;
        w.write_all(&l.residual.mean.to_le_bytes())?;
        w.write_all(&l.residual.max.to_le_bytes())?;
        w.write_all(&l.residual.texels.to_le_bytes())?;
        levels.push((t0, l.texels()));
        t0 += l.texels();
    }
    let counts: Vec<u8> = columns(p, 0)[0].iter().map(|&c| c as u8).collect();
    let layout = Layout::new(levels, counts);
    let n = if has_h { STREAMS.len() } else { 4 };
    // One stream at a time (its columns, both byte-plane layouts and their deflated bytes are
    // all that is held beside the pyramid), compressed with and without prediction in
    // parallel; the smaller is kept.
    for (s, &(_, per_lobe, _, bytes, bits)) in STREAMS.iter().enumerate().take(n) {
        let cols = columns(p, s);
        let encode = |delta: bool| {
            let raw = planes(&layout, per_lobe, &cols, (bytes, bits), delta);
            (u8::from(delta), raw.len(), deflate(&raw))
        };
        let (plain, pred) = rayon::join(|| encode(false), || encode(true));
        drop(cols);
        let (filter, raw_len, comp) = if pred.2.len() < plain.2.len() {
            pred
        } else {
            plain
        };
        w.write_all(&[s as u8, filter, 0, 0])?;
        w.write_all(&(raw_len as u64).to_le_bytes())?;
        w.write_all(&(comp.len() as u64).to_le_bytes())?;
        w.write_all(&comp)?;
    }
    Ok(())
}

/// The tag of the optional shading-error trailer of a format-3 file (`docs/map-format.md`).
pub const SHADING_TAG: [u8; 4] = *b"SHE1";

/// Write the shading-error trailer (after the streams): [`SHADING_TAG`], then per level the
/// mean and largest shading error (`f64`, fractions of the peak). Nothing when a level has
/// none recorded.
pub(super) fn write_shading(p: &Pyramid, w: &mut dyn Write) -> std::io::Result<()> {
    let vals: Option<Vec<(f64, f64)>> = p
        .levels
        .iter()
        .map(|l| Some((l.residual.shading_mean?, l.residual.shading_max?)))
        .collect();
    let Some(vals) = vals else {
        return Ok(());
    };
    w.write_all(&SHADING_TAG)?;
    for (m, x) in vals {
        w.write_all(&m.to_le_bytes())?;
        w.write_all(&x.to_le_bytes())?;
    }
    Ok(())
}

/// The shading-error trailer of a format-3 file of `nlev` levels, if the bytes after the
/// streams start with [`SHADING_TAG`] (files written before it existed end after the streams:
/// `None`); a truncated trailer is refused, other trailing bytes are left for the caller to
/// refuse. Values must be finite and ≥ 0.
pub(super) fn read_shading(r: &mut Reader<'_>, nlev: usize) -> Result<Option<Vec<(f64, f64)>>> {
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

/// One entry of a format-3 level table, with where the level starts among all texels.
#[derive(Clone, Copy)]
struct TableEntry {
    cols: usize,
    rows: usize,
    span: usize,
    lobes: usize,
    residual: Residual,
    /// Index of the level's first texel among the pyramid's texels.
    t0: usize,
}

impl TableEntry {
    fn texels(&self) -> usize {
        self.cols * self.rows
    }
    /// Whether the level is kept in `f32` in memory ([`COMPACT_TEXELS`]).
    fn compact(&self) -> bool {
        self.texels() >= COMPACT_TEXELS
    }
}

/// The decoded columns of streams 1–5: octahedral axis codes (u, v), weight codes, exponent
/// codes, horizon weights (`f32` bits) and the 8 horizon angle codes.
struct Columns {
    axes: Vec<Vec<u32>>,
    weights: Vec<u32>,
    etas: Vec<u32>,
    hw: Vec<u32>,
    ha: Vec<Vec<u32>>,
}

/// Read the levels of a format-3 file after the common header (`docs/map-format.md`): the
/// level table, the memory budget, the streams inflated, the lobe counts checked, the columns
/// decoded, the levels built.
pub(super) fn read_levels(
    r: &mut Reader<'_>,
    cols: usize,
    rows: usize,
    nlev: usize,
    max_lobes: usize,
    has_h: bool,
) -> Result<Vec<Level>> {
    let (table, texels, lobes) = read_table(r, cols, rows, nlev, max_lobes)?;
    let n_streams = if has_h { STREAMS.len() } else { 4 };
    let expect = |s: usize| {
        (if STREAMS[s].1 { lobes } else { texels }) * (STREAMS[s].2 * STREAMS[s].3) as u64
    };
    // The memory of reading, before allocating any: the file, the pyramid, every inflated
    // stream and every decoded column (4 bytes a value) with the lobe layout (9 bytes a
    // texel), as if all were held at once (an upper bound: the streams are freed as they are
    // decoded).
    let raw: u64 = (0..n_streams).map(expect).sum();
    let decoded: u64 = (1..n_streams)
        .map(|s| (if STREAMS[s].1 { lobes } else { texels }) * 4 * STREAMS[s].2 as u64)
        .sum::<u64>()
        + 9 * texels;
    let need = r.b.len() as u64 + pyramid_bytes(&table, has_h) + raw + decoded;
    meso_core::budget::check(&r.path, "reading the map file", need)?;

    let mut raws = Vec::with_capacity(n_streams);
    for s in 0..n_streams {
        raws.push(read_stream(r, s, expect(s))?);
    }
    let levels_at: Vec<(usize, usize)> = table.iter().map(|t| (t.t0, t.texels())).collect();
    let counts = read_counts(r, &table, &levels_at, texels as usize, &raws[0], max_lobes)?;
    let layout = Layout::new(levels_at, counts);
    let columns = decode_columns(r, &layout, raws, has_h)?;
    table
        .iter()
        .enumerate()
        .map(|(k, t)| build_level(r, k, t, &layout, &columns, has_h))
        .collect()
}

/// The memory (bytes) of the pyramid a level table describes: per lobe 40 bytes (`f64`) or 20
/// (`f32` levels), per texel a lobe start (4) and with horizon statistics 72 or 36.
fn pyramid_bytes(table: &[TableEntry], has_h: bool) -> u64 {
    table
        .iter()
        .map(|t| {
            let (lobe, hz) = if t.compact() {
                (LOBE_MEM / 2, HORIZON_MEM / 2)
            } else {
                (LOBE_MEM, HORIZON_MEM)
            };
            t.lobes as u64 * lobe + t.texels() as u64 * (4 + if has_h { hz } else { 0 })
        })
        .sum()
}

/// The level table (checked against `cols × rows` and `max_lobes`), with the pyramid's total
/// texels and lobes.
fn read_table(
    r: &mut Reader<'_>,
    cols: usize,
    rows: usize,
    nlev: usize,
    max_lobes: usize,
) -> Result<(Vec<TableEntry>, u64, u64)> {
    if ((r.b.len() - r.pos) as u64) < nlev as u64 * LEVEL_HEADER_BYTES {
        return Err(r.err("truncated in the level table".into()));
    }
    let mut table = Vec::with_capacity(nlev);
    let (mut ec, mut er) = (cols, rows);
    let (mut texels, mut lobes) = (0u64, 0u64);
    for k in 0..nlev {
        let nl = r.level_header(k, ec, er, max_lobes)?;
        let residual = Residual {
            mean: r.f64("residual")?,
            max: r.f64("residual")?,
            texels: r.u32("residual texels")?,
            shading_mean: None,
            shading_max: None,
        };
        table.push(TableEntry {
            cols: ec,
            rows: er,
            span: 1usize << k,
            lobes: nl,
            residual,
            t0: texels as usize,
        });
        texels += (ec * er) as u64;
        lobes += nl as u64;
        ec = ec.div_ceil(2);
        er = er.div_ceil(2);
    }
    Ok((table, texels, lobes))
}

/// Stream `s`: its header checked (id, reserved bytes, filter, the raw length `expect` the
/// table implies, deflate's largest ratio, the file's end), its bytes inflated and checked
/// against the header. Returns the raw bytes and whether they are filtered.
fn read_stream(r: &mut Reader<'_>, s: usize, expect: u64) -> Result<(Vec<u8>, bool)> {
    let name = STREAMS[s].0;
    let head = r.take(STREAM_HEADER, "a stream header")?;
    let (id, filter) = (head[0], head[1]);
    if id as usize != s || head[2] != 0 || head[3] != 0 || filter > 1 {
        return Err(r.err(format!(
            "stream {s} ({name}): bad header (id {id}, filter {filter})"
        )));
    }
    let raw_len = u64::from_le_bytes(head[4..12].try_into().unwrap());
    let comp_len = u64::from_le_bytes(head[12..20].try_into().unwrap());
    if raw_len != expect {
        return Err(r.err(format!(
            "stream {s} ({name}) claims {raw_len} bytes; the level table implies {expect}"
        )));
    }
    if raw_len
        > comp_len
            .saturating_mul(MAX_DEFLATE_RATIO)
            .saturating_add(RATIO_SLACK)
    {
        return Err(r.err(format!(
            "stream {s} ({name}) claims {raw_len} bytes from {comp_len} compressed bytes, \
             more than deflate's {MAX_DEFLATE_RATIO}:1 (a decompression bomb?)"
        )));
    }
    if ((r.b.len() - r.pos) as u64) < comp_len {
        return Err(r.err(format!("truncated in stream {s} ({name})")));
    }
    let comp = r.take(comp_len as usize, name)?;
    let mut raw = Vec::with_capacity(raw_len as usize);
    let mut d = flate2::read::DeflateDecoder::new(comp);
    (&mut d)
        .take(raw_len + 1)
        .read_to_end(&mut raw)
        .map_err(|e| {
            r.err(format!(
                "stream {s} ({name}): corrupt compressed data ({e})"
            ))
        })?;
    if raw.len() as u64 != raw_len {
        return Err(r.err(format!(
            "stream {s} ({name}) inflates to {}{} bytes, its header says {raw_len}",
            if raw.len() as u64 > raw_len {
                "more than "
            } else {
                ""
            },
            raw.len()
        )));
    }
    if d.total_in() != comp_len {
        return Err(r.err(format!(
            "stream {s} ({name}): {} bytes after the end of the compressed data",
            comp_len - d.total_in()
        )));
    }
    Ok((raw, filter == 1))
}

/// The columns of stream `s` from its raw bytes, or the error naming a value wider than the
/// stream's bits.
fn decode(
    r: &Reader<'_>,
    layout: &Layout,
    s: usize,
    raw: &(Vec<u8>, bool),
) -> Result<Vec<Vec<u32>>> {
    unplanes(layout, s, &raw.0, raw.1).map_err(|v| MapError::MapFormat {
        path: r.path.clone(),
        message: format!(
            "stream {s} ({}): stored value {v} is wider than its {} bits",
            STREAMS[s].0, STREAMS[s].4
        ),
    })
}

/// The lobe counts (stream 0), which lay out every other stream: each at most `max_lobes`,
/// each level's adding up to its table entry.
fn read_counts(
    r: &Reader<'_>,
    table: &[TableEntry],
    levels_at: &[(usize, usize)],
    texels: usize,
    raw: &(Vec<u8>, bool),
    max_lobes: usize,
) -> Result<Vec<u8>> {
    let probe = Layout {
        levels: levels_at.to_vec(),
        counts: vec![0; texels],
        start: vec![0; texels + 1],
    };
    let counts: Vec<u8> = decode(r, &probe, 0, raw)?
        .swap_remove(0)
        .into_iter()
        .map(|c| c as u8)
        .collect();
    drop(probe);
    for (k, t) in table.iter().enumerate() {
        let c = &counts[t.t0..t.t0 + t.texels()];
        if let Some(&bad) = c.iter().find(|&&c| c as usize > max_lobes) {
            return Err(r.err(format!("level {k}: a texel has {bad} lobes")));
        }
        let sum: usize = c.iter().map(|&c| c as usize).sum();
        if sum != t.lobes {
            return Err(r.err(format!(
                "level {k}: lobe counts add to {sum}, header says {}",
                t.lobes
            )));
        }
    }
    Ok(counts)
}

/// Streams 1–5 decoded, each stream's raw bytes freed once decoded.
fn decode_columns(
    r: &Reader<'_>,
    layout: &Layout,
    mut raws: Vec<(Vec<u8>, bool)>,
    has_h: bool,
) -> Result<Columns> {
    let mut next = |s: usize| {
        let c = decode(r, layout, s, &raws[s]);
        raws[s].0 = Vec::new();
        c
    };
    let axes = next(1)?;
    let weights = next(2)?.swap_remove(0);
    let etas = next(3)?.swap_remove(0);
    let (hw, ha) = if has_h {
        (next(4)?.swap_remove(0), next(5)?)
    } else {
        (Vec::new(), Vec::new())
    };
    Ok(Columns {
        axes,
        weights,
        etas,
        hw,
        ha,
    })
}

/// The sum of a texel's weight codes (texel `t` of level `k`), which must not be 0 when it
/// has lobes.
fn weight_sum(r: &Reader<'_>, k: usize, t: usize, codes: &[u32]) -> Result<u32> {
    let sum: u32 = codes.iter().sum();
    if !codes.is_empty() && sum == 0 {
        return Err(r.err(format!(
            "level {k}: texel {t} has lobes whose weights are all 0"
        )));
    }
    Ok(sum)
}

/// A horizon weight from its `f32` bits (level `k`): finite and ≥ 0.
fn horizon_weight(r: &Reader<'_>, k: usize, bits: u32) -> Result<f64> {
    let weight = f64::from(f32::from_bits(bits));
    if !(weight.is_finite() && weight >= 0.0) {
        return Err(r.err(format!("level {k}: horizon weight {weight}")));
    }
    Ok(weight)
}

/// Check the levels of a format-3 file after the common header as [`read_levels`] does, without
/// building them: the level table, then each stream inflated, decoded, checked and dropped
/// before the next (the lobe counts, every stream's width, each texel's weight codes, the
/// horizon weights). Its memory: the lobe layout (9 bytes per texel) and one stream, raw and
/// decoded.
pub(super) fn check_levels(
    r: &mut Reader<'_>,
    cols: usize,
    rows: usize,
    nlev: usize,
    max_lobes: usize,
    has_h: bool,
) -> Result<()> {
    let (table, texels, lobes) = read_table(r, cols, rows, nlev, max_lobes)?;
    let expect =
        |s: usize| if STREAMS[s].1 { lobes } else { texels } * (STREAMS[s].2 * STREAMS[s].3) as u64;
    let levels_at: Vec<(usize, usize)> = table.iter().map(|t| (t.t0, t.texels())).collect();
    let raw = read_stream(r, 0, expect(0))?;
    let counts = read_counts(r, &table, &levels_at, texels as usize, &raw, max_lobes)?;
    drop(raw);
    let layout = Layout::new(levels_at, counts);
    for s in 1..if has_h { STREAMS.len() } else { 4 } {
        let raw = read_stream(r, s, expect(s))?;
        let cols = decode(r, &layout, s, &raw)?;
        drop(raw);
        for (k, e) in table.iter().enumerate() {
            for t in e.t0..e.t0 + e.texels() {
                match s {
                    2 => {
                        let (a, b) = (layout.start[t], layout.start[t + 1]);
                        weight_sum(r, k, t - e.t0, &cols[0][a..b])?;
                    }
                    4 => {
                        horizon_weight(r, k, cols[0][t])?;
                    }
                    _ => break,
                }
            }
        }
    }
    Ok(())
}

/// Level `k` from the decoded columns: its lobes (a texel's weights normalised by their
/// codes' sum, which must not be 0) and horizon statistics (a weight that is negative or not
/// finite refused), in `f32` on big levels ([`TableEntry::compact`]).
fn build_level(
    r: &Reader<'_>,
    k: usize,
    e: &TableEntry,
    layout: &Layout,
    c: &Columns,
    has_h: bool,
) -> Result<Level> {
    let (n, t0) = (e.texels(), e.t0);
    let mut lobe_start = Vec::with_capacity(n + 1);
    let g0 = layout.start[t0];
    lobe_start.extend(layout.start[t0..=t0 + n].iter().map(|&s| (s - g0) as u32));
    let mut lobes = if e.compact() {
        Lobes::F32(Vec::with_capacity(e.lobes))
    } else {
        Lobes::F64(Vec::with_capacity(e.lobes))
    };
    for t in t0..t0 + n {
        let (a, b) = (layout.start[t], layout.start[t + 1]);
        let sum = weight_sum(r, k, t - t0, &c.weights[a..b])?;
        for i in a..b {
            lobes.push(PhongLobe {
                axis: oct_decode(c.axes[0][i], c.axes[1][i]),
                weight: f64::from(c.weights[i]) / f64::from(sum),
                exponent: eta_decode(c.etas[i] as u16),
            });
        }
    }
    let horizon = if has_h {
        let mut h = if e.compact() {
            Horizons::F32(Vec::with_capacity(n))
        } else {
            Horizons::F64(Vec::with_capacity(n))
        };
        for t in t0..t0 + n {
            let weight = horizon_weight(r, k, c.hw[t])?;
            let mut s = HorizonStats {
                weight,
                ..HorizonStats::default()
            };
            for d in 0..4 {
                let (qm, qs) = (c.ha[d][t], c.ha[4 + d][t]);
                s.mean[d] = angle_decode(qm as u16, MEAN_SPAN);
                let sd = angle_decode(qs as u16, SD_SPAN);
                s.var[d] = sd * sd;
            }
            h.extend_from_slice(&[s]);
        }
        Some(h)
    } else {
        None
    };
    Ok(Level {
        cols: e.cols,
        rows: e.rows,
        span: e.span,
        lobe_start,
        lobes,
        horizon,
        residual: e.residual,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_codes_are_within_their_bound() {
        let mut worst: f64 = 0.0;
        let pi = std::f64::consts::PI;
        for i in 0..200 {
            for j in 0..100 {
                let th = pi * (f64::from(j) + 0.5) / 100.0;
                let ph = 2.0 * pi * f64::from(i) / 200.0;
                let a = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                let (u, v) = oct_encode(a);
                worst = worst.max(oct_decode(u, v).angle_between(a));
            }
        }
        for a in [DVec3::Z, -DVec3::Z, DVec3::X, -DVec3::Y] {
            let (u, v) = oct_encode(a);
            worst = worst.max(oct_decode(u, v).angle_between(a));
        }
        assert!(worst < 2.9e-6, "{worst}");
    }

    #[test]
    fn weight_codes_add_up_and_read_back_to_themselves() {
        for w in [
            vec![1.0],
            vec![0.5, 0.5],
            vec![1.0 / 3.0; 3],
            vec![0.1, 0.2, 0.3, 0.15, 0.25],
            vec![1e-9, 1.0 - 1e-9],
            vec![0.125; 8],
        ] {
            let q = weight_codes(&w);
            assert_eq!(q.iter().sum::<u32>(), 65535, "{w:?}");
            for (x, c) in w.iter().zip(&q) {
                assert!((f64::from(*c) / Q - x).abs() < 1.0 / Q, "{w:?} {q:?}");
            }
            let back: Vec<f64> = q.iter().map(|&c| f64::from(c) / 65535.0).collect();
            assert_eq!(weight_codes(&back), q);
        }
    }

    #[test]
    fn exponent_and_angle_codes_are_within_their_bound() {
        assert_eq!(eta_decode(eta_encode(ETA_MAX)), ETA_MAX);
        assert_eq!(eta_decode(eta_encode(0.0)), 0.0);
        let mut worst: f64 = 0.0;
        let mut eta = 1.0;
        while eta < ETA_MAX {
            let back = eta_decode(eta_encode(eta));
            worst = worst.max((back - eta).abs() / eta / (1.0 + 1.0 / eta));
            eta *= 1.013;
        }
        assert!(worst < 1.06e-4, "{worst}");
        for x in [0.0, 1e-3, 0.3, 1.2, FRAC_PI_2] {
            let back = angle_decode(angle_encode(x, MEAN_SPAN), MEAN_SPAN);
            assert!(
                (back - x).abs() <= 0.5 * MEAN_SPAN / QH + 1e-15,
                "{x} {back}"
            );
        }
    }
}
