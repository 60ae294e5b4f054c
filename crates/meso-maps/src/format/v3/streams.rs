//! The streams of format 3 (module docs of `v3`): their table, the lobe layout whose
//! previous-texel slots predict each value, the byte planes (filtered or not) and deflate on
//! writing, and on reading one stream's header checked (deflate's largest ratio included)
//! before it is inflated, and its columns decoded.

use crate::error::{MapError, Result};
use crate::format::Reader;
use std::io::{Read, Write};

/// deflate's largest expansion: a stream may not claim more than this many bytes per
/// compressed byte (plus 1024 bytes of slack).
pub const MAX_DEFLATE_RATIO: u64 = 1032;
const RATIO_SLACK: u64 = 1024;
/// Bytes of a stream header: id, filter, 2 reserved, raw length (u64), compressed length (u64).
const STREAM_HEADER: usize = 20;
/// The streams, in file order: name, per-lobe (else per-texel), columns, bytes per value,
/// bits per value (a stored value or prediction residual above them is refused).
/// The sixth, the diagonals' horizon angles, is in files of version 5 only
/// ([`stream_count`]).
pub(in crate::format) const STREAMS: [(&str, bool, usize, usize, u32); 7] = [
    ("lobe counts", false, 1, 1, 8),
    ("lobe axes", true, 2, 3, 20),
    ("lobe weights", true, 1, 2, 16),
    ("lobe exponents", true, 1, 2, 16),
    ("horizon weights", false, 1, 4, 32),
    ("horizon angles", false, 8, 2, 12),
    ("diagonal horizon angles", false, 8, 2, 12),
];

/// The number of streams of a file (a band in formats 4 and 5) of `version`: 4 without horizon
/// statistics; with them 6 before version 5 (the axes' angles), 7 from it (and the diagonals').
pub(in crate::format) fn stream_count(has_h: bool, version: u32) -> usize {
    match (has_h, version >= crate::format::VERSION_5) {
        (false, _) => 4,
        (true, false) => 6,
        (true, true) => 7,
    }
}

fn mask(bits: u32) -> u32 {
    if bits >= 32 {
        u32::MAX
    } else {
        (1u32 << bits) - 1
    }
}

/// Where each level's texels and lobes start in the whole-pyramid arrays.
pub(in crate::format) struct Layout {
    /// Per level: (first texel, texels).
    pub(super) levels: Vec<(usize, usize)>,
    /// Lobe counts of every texel, all levels, finest first.
    pub(super) counts: Vec<u8>,
    /// First lobe of every texel (global), plus the end.
    pub(super) start: Vec<usize>,
}

impl Layout {
    pub(in crate::format) fn new(levels: Vec<(usize, usize)>, counts: Vec<u8>) -> Layout {
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
pub(super) fn planes(
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
            // The stored values, plane by plane (the layout visits every value once, in
            // order: the first too wide is the first in the column).
            let mut col = vec![0u32; n];
            for b in 0..bytes {
                let plane = &raw[base + b * n..base + (b + 1) * n];
                for (v, &x) in col.iter_mut().zip(plane) {
                    *v |= u32::from(x) << (8 * b);
                }
            }
            if let Some(&v) = col.iter().find(|&&v| v & !mask != 0) {
                bad.get_or_insert(v);
            }
            for v in &mut col {
                *v &= mask;
            }
            // Then each value plus its predictor's, already final (mod 2^bits: the sum's low
            // bits depend on the addends' low bits only).
            if delta {
                layout.for_each_pred(per_lobe, |i, pred| {
                    if let Some(p) = pred {
                        col[i] = col[i].wrapping_add(col[p]) & mask;
                    }
                });
            }
            col
        })
        .collect();
    match bad {
        Some(v) => Err(v),
        None => Ok(out),
    }
}

pub(super) fn deflate(raw: &[u8]) -> Vec<u8> {
    let mut e = flate2::write::DeflateEncoder::new(
        Vec::with_capacity(raw.len() / 2),
        flate2::Compression::default(),
    );
    e.write_all(raw).expect("writing to memory cannot fail");
    e.finish().expect("writing to memory cannot fail")
}

/// The header of stream `s`, checked (id, reserved bytes, filter, the raw length `expect` the
/// table implies, deflate's largest ratio, the file's end): its filter, raw and compressed
/// lengths. The compressed bytes follow.
pub(in crate::format) fn stream_header(
    r: &mut Reader<'_>,
    s: usize,
    expect: u64,
) -> Result<(u8, u64, u64)> {
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
    Ok((filter, raw_len, comp_len))
}

/// Stream `s`: its header checked ([`stream_header`]), its bytes inflated and checked against
/// the header. Returns the raw bytes and whether they are filtered.
pub(in crate::format) fn read_stream(
    r: &mut Reader<'_>,
    s: usize,
    expect: u64,
) -> Result<(Vec<u8>, bool)> {
    let name = STREAMS[s].0;
    let (filter, raw_len, comp_len) = stream_header(r, s, expect)?;
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
pub(super) fn decode(
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
