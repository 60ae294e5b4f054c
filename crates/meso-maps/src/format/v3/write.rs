//! Format 3's encoders, which format 4 writes per band (module docs of `v3`): what a pyramid
//! must hold to be stored, its values as the streams' columns of codes, and the streams (each
//! deflated with or without prediction, whichever is smaller). The format-3 file layout (one
//! level table and one set of streams for the whole pyramid) is no longer written.

use super::codes::{angle_encode, eta_encode, oct_encode, weight_codes, MEAN_SPAN, SD_SPAN};
use super::streams::{deflate, planes, stream_count, Layout, STREAMS};
use crate::compact::Horizons;
use crate::limits::ETA_MAX;
use crate::pyramid::{Level, Pyramid};
use std::io::Write;

/// Why `pyramid` cannot be stored (a value a map file cannot hold), or `None`.
pub(in crate::format) fn unstorable(p: &Pyramid) -> Option<String> {
    p.levels
        .iter()
        .enumerate()
        .find_map(|(k, l)| unstorable_level(k, l))
}

/// Why level `k` (or a band of its rows, format 4) cannot be stored, or `None`.
pub(in crate::format) fn unstorable_level(k: usize, l: &Level) -> Option<String> {
    {
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

/// The raw (unfiltered) columns of stream `s` of `parts` (format 4: one band of a level's
/// rows).
fn columns(parts: &[&Level], s: usize) -> Vec<Vec<u32>> {
    let lobes = || parts.iter().flat_map(|l| l.lobes.iter());
    let horizon = || {
        parts
            .iter()
            .flat_map(|l| l.horizon.iter().flat_map(Horizons::iter))
    };
    match s {
        0 => vec![parts
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
            for l in parts {
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
            // Stream 5: the axes' (directions 0–3); stream 6: the diagonals' (4–7).
            let dirs = if s == 5 { 0..4 } else { 4..8 };
            let mut cols = Vec::with_capacity(8);
            for d in dirs.clone() {
                cols.push(
                    horizon()
                        .map(|h| u32::from(angle_encode(h.mean[d], MEAN_SPAN)))
                        .collect(),
                );
            }
            for d in dirs {
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

/// Write the streams of `parts` (format 4: one band of a level's rows; format 3 wrote every
/// level of the pyramid at once), each value predicted from the same slot of the previous
/// texel of its part.
/// The caller has checked [`unstorable_level`].
pub(in crate::format) fn write_streams(
    parts: &[&Level],
    has_h: bool,
    w: &mut dyn Write,
) -> std::io::Result<()> {
    let mut levels = Vec::with_capacity(parts.len());
    let mut t0 = 0;
    for l in parts {
        levels.push((t0, l.texels()));
        t0 += l.texels();
    }
    let counts: Vec<u8> = columns(parts, 0)[0].iter().map(|&c| c as u8).collect();
    let layout = Layout::new(levels, counts);
    let n = stream_count(has_h, crate::format::VERSION);
    // One stream at a time (its columns, both byte-plane layouts and their deflated bytes are
    // all that is held beside the pyramid), compressed with and without prediction in
    // parallel; the smaller is kept.
    for (s, &(_, per_lobe, _, bytes, bits)) in STREAMS.iter().enumerate().take(n) {
        let cols = columns(parts, s);
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
