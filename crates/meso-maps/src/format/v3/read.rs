//! Reading format 3 (module docs of `v3`): the level table, the memory budget, the streams
//! inflated and decoded, the lobe counts, weight codes and horizon weights checked, the levels
//! built; or the same checks stream by stream without building the levels.

use super::codes::angle_encode;
use super::codes::{angle_decode, eta_decode, oct_decode, MEAN_SPAN, SD_SPAN};
use super::streams::{decode, read_stream, stream_count, Layout, STREAMS};
use super::table::{pyramid_bytes, read_table, TableEntry};
use crate::compact::{HorizonCode, Horizons, LobeCode, Lobes};
use crate::error::Result;
use crate::format::{Header, Reader};
use crate::horizon::{HorizonStats, HORIZON_DIRECTIONS};
use crate::pyramid::Level;
use meso_core::ndf::PhongLobe;

/// The decoded columns of streams 1–6: octahedral axis codes (u, v), weight codes, exponent
/// codes, horizon weights (`f32` bits) and the horizon angle codes: the axes' 4 means and 4
/// standard deviations, then (version 5) the diagonals'.
pub(in crate::format) struct Columns {
    axes: Vec<Vec<u32>>,
    weights: Vec<u32>,
    etas: Vec<u32>,
    hw: Vec<u32>,
    ha: Vec<Vec<u32>>,
}

impl Columns {
    /// The horizon angle codes of texel `t` (all levels' texels, finest first): the means' and
    /// the standard deviations' per direction of [`crate::HORIZON_AZIMUTHS_DEG`]. A file before
    /// version 5 has the axes' only: each diagonal's mean code is the mean of its two
    /// neighbours' (rounded half up) and its standard deviation that of the mean of their
    /// variances, as `HorizonStats::from_axes` fills them.
    fn horizon_codes(&self, t: usize) -> ([u16; HORIZON_DIRECTIONS], [u16; HORIZON_DIRECTIONS]) {
        let q = |c: usize| self.ha[c][t] as u16;
        if self.ha.len() == 4 * HORIZON_DIRECTIONS / 2 {
            // Version 5: axes' means, axes' sds, diagonals' means, diagonals' sds.
            let slot = |d: usize, sd: bool| {
                let (block, i) = if d < 4 { (0, d) } else { (2, d - 4) };
                q(4 * (block + usize::from(sd)) + i)
            };
            return (
                std::array::from_fn(|d| slot(d, false)),
                std::array::from_fn(|d| slot(d, true)),
            );
        }
        let mut mean = [0u16; HORIZON_DIRECTIONS];
        let mut sd = [0u16; HORIZON_DIRECTIONS];
        for d in 0..4 {
            mean[d] = q(d);
            sd[d] = q(4 + d);
        }
        for k in 0..4 {
            let (a, b) = (k, (k + 1) % 4);
            mean[4 + k] = (u32::from(mean[a]) + u32::from(mean[b])).div_ceil(2) as u16;
            let (sa, sb) = (angle_decode(sd[a], SD_SPAN), angle_decode(sd[b], SD_SPAN));
            sd[4 + k] = angle_encode((0.5 * (sa * sa + sb * sb)).sqrt(), SD_SPAN);
        }
        (mean, sd)
    }
}

/// Read the levels of a format-3 file after the common header (`docs/map-format.md`): the
/// level table, the memory budget, the streams inflated, the lobe counts checked, the columns
/// decoded, the levels built.
pub(in crate::format) fn read_levels(r: &mut Reader<'_>, h: &Header) -> Result<Vec<Level>> {
    let (max_lobes, has_h) = (h.max_lobes, h.has_h);
    let (table, texels, lobes) = read_table(r, h)?;
    let n_streams = stream_count(has_h, h.version);
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
        .map(|(k, t)| build_level(r, k, t, &layout, &columns, has_h, t.compact(), false))
        .collect()
}

/// The lobe counts (stream 0), which lay out every other stream: each at most `max_lobes`,
/// each level's adding up to its table entry.
pub(in crate::format) fn read_counts(
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
pub(in crate::format) fn decode_columns(
    r: &Reader<'_>,
    layout: &Layout,
    mut raws: Vec<(Vec<u8>, bool)>,
    has_h: bool,
) -> Result<Columns> {
    // Version 5 has the diagonals' angles (stream 6).
    let diagonals = raws.len() > 6;
    let mut next = |s: usize| {
        let c = decode(r, layout, s, &raws[s]);
        raws[s].0 = Vec::new();
        c
    };
    let axes = next(1)?;
    let weights = next(2)?.swap_remove(0);
    let etas = next(3)?.swap_remove(0);
    let (hw, ha) = if has_h {
        let hw = next(4)?.swap_remove(0);
        let mut ha = next(5)?;
        if diagonals {
            ha.extend(next(6)?);
        }
        (hw, ha)
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
pub(in crate::format) fn check_levels(r: &mut Reader<'_>, h: &Header) -> Result<()> {
    let (max_lobes, has_h) = (h.max_lobes, h.has_h);
    let (table, texels, lobes) = read_table(r, h)?;
    let expect =
        |s: usize| if STREAMS[s].1 { lobes } else { texels } * (STREAMS[s].2 * STREAMS[s].3) as u64;
    let levels_at: Vec<(usize, usize)> = table.iter().map(|t| (t.t0, t.texels())).collect();
    let raw = read_stream(r, 0, expect(0))?;
    let counts = read_counts(r, &table, &levels_at, texels as usize, &raw, max_lobes)?;
    drop(raw);
    let layout = Layout::new(levels_at, counts);
    for s in 1..stream_count(has_h, h.version) {
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
/// finite refused), as the file's codes when `compact` and `coded` (`Pyramid::read_coded`),
/// in `f32` when `compact` (format 3: [`TableEntry::compact`]; format 4, whose
/// entry is a band of a level's rows: the level's).
#[allow(clippy::too_many_arguments)]
pub(in crate::format) fn build_level(
    r: &Reader<'_>,
    k: usize,
    e: &TableEntry,
    layout: &Layout,
    c: &Columns,
    has_h: bool,
    compact: bool,
    coded: bool,
) -> Result<Level> {
    let (n, t0) = (e.texels(), e.t0);
    let mut lobe_start = Vec::with_capacity(n + 1);
    let g0 = layout.start[t0];
    lobe_start.extend(layout.start[t0..=t0 + n].iter().map(|&s| (s - g0) as u32));
    let coded = compact && coded;
    let mut lobes = if coded {
        Lobes::Coded(Vec::with_capacity(e.lobes))
    } else if compact {
        Lobes::F32(Vec::with_capacity(e.lobes))
    } else {
        Lobes::F64(Vec::with_capacity(e.lobes))
    };
    for t in t0..t0 + n {
        let (a, b) = (layout.start[t], layout.start[t + 1]);
        let sum = weight_sum(r, k, t - t0, &c.weights[a..b])?;
        if let Lobes::Coded(v) = &mut lobes {
            // The codes as they are, the weight as `Lobe32` rounds it.
            v.extend((a..b).map(|i| {
                let w = f64::from(c.weights[i]) / f64::from(sum);
                LobeCode::new(c.axes[0][i], c.axes[1][i], c.etas[i] as u16, w as f32)
            }));
            continue;
        }
        for i in a..b {
            lobes.push(PhongLobe {
                axis: oct_decode(c.axes[0][i], c.axes[1][i]),
                weight: f64::from(c.weights[i]) / f64::from(sum),
                exponent: eta_decode(c.etas[i] as u16),
            });
        }
    }
    let horizon = if has_h {
        let mut h = if coded {
            Horizons::Coded(Vec::with_capacity(n))
        } else if compact {
            Horizons::F32(Vec::with_capacity(n))
        } else {
            Horizons::F64(Vec::with_capacity(n))
        };
        for t in t0..t0 + n {
            let weight = horizon_weight(r, k, c.hw[t])?;
            let (mean, sd) = c.horizon_codes(t);
            if let Horizons::Coded(v) = &mut h {
                v.push(HorizonCode::new(weight as f32, mean, sd));
                continue;
            }
            let mut s = HorizonStats {
                weight,
                ..HorizonStats::default()
            };
            for d in 0..HORIZON_DIRECTIONS {
                s.mean[d] = angle_decode(mean[d], MEAN_SPAN);
                let sd = angle_decode(sd[d], SD_SPAN);
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
