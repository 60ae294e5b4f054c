//! Map format version 4 (`docs/map-format.md`): the common header, then per level its rows in
//! bands, each band a chunk of format 3's streams (the same codes, byte planes, prediction and
//! deflate, [`super::v3`]) over the band's texels alone, then the level's end record (its lobe
//! count and residuals): the one format this build writes, band by band as an extraction fits
//! them ([`crate::pyramid::extract_to_file`], so no pyramid is ever held in memory) or from a
//! pyramid in memory ([`Pyramid::write_to`], the same bytes); read back into a [`Pyramid`] like
//! versions 2 and 3.
//!
//! ```text
//! band:      "BAND" level:u32 first_row:u32 rows:u32 lobes:u32, then the streams of
//!            format 3 (4, or 6 with horizon statistics) over the band's rows × cols texels
//! level end: "LEND" level:u32 lobes:u32 residual_mean:f64 residual_max:f64 texels:u32
//!            has_shading:u32 shading_mean:f64 shading_max:f64
//! ```
//!
//! Reading checks the chunks' order (levels in order, each level's bands covering its rows in
//! order, then its end record, whose lobe count must be the bands' sum), every stream header
//! against its band and the file's length, and the memory of the whole pyramid against the
//! budget, all before inflating anything.

use super::v3::{
    build_level, decode_columns, pyramid_bytes, read_counts, read_stream, stream_count,
    stream_header, unstorable_level, write_streams, Layout, TableEntry, STREAMS,
};
use super::{Header, Reader};
use crate::compact::{Horizons, Lobes, COMPACT_TEXELS, HORIZON_CODE_BYTES};
use crate::error::{MapError, Result};
use crate::pyramid::{Level, Pyramid, Residual};
use std::io::Write;
use std::path::Path;

/// The format version of this module.
pub const VERSION_4: u32 = 4;
/// Version 5: version 4 with the horizon statistics of the four diagonals beside the axes'
/// (a seventh stream in each band, `docs/map-format.md`), written since 2026-12-07.
pub const VERSION_5: u32 = 5;
/// Rows of a level per band when a pyramid in memory is written ([`Pyramid::write_to`]); the
/// streamed extraction writes its row batches, of as many rows.
pub const BAND_ROWS: usize = 64;
const BAND_TAG: [u8; 4] = *b"BAND";
const END_TAG: [u8; 4] = *b"LEND";
const END_BYTES: usize = 52;

/// Whether a level of `texels` texels is kept in `f32` in memory (as format 3's reader keeps it).
fn compact(texels: usize) -> bool {
    texels >= COMPACT_TEXELS
}

/// Write band `band` (rows `row0..row0 + band.rows` of level `k`) as a chunk: checked
/// ([`unstorable_level`]), then encoded. The caller writes the header first and the level's
/// end record after its last band.
///
/// # Errors
/// `InvalidData` naming the value a map file cannot hold; the writer's errors.
pub(crate) fn write_band(
    w: &mut dyn Write,
    k: usize,
    row0: usize,
    band: &Level,
    has_h: bool,
) -> std::io::Result<()> {
    if let Some(why) = unstorable_level(k, band) {
        return Err(std::io::Error::new(std::io::ErrorKind::InvalidData, why));
    }
    w.write_all(&BAND_TAG)?;
    for v in [k, row0, band.rows, band.lobes.len()] {
        w.write_all(&(v as u32).to_le_bytes())?;
    }
    write_streams(&[band], has_h, w)
}

/// Write the end record of level `k`: its lobe count and residuals.
pub(crate) fn write_level_end(
    w: &mut dyn Write,
    k: usize,
    lobes: usize,
    res: &Residual,
) -> std::io::Result<()> {
    w.write_all(&END_TAG)?;
    w.write_all(&(k as u32).to_le_bytes())?;
    w.write_all(&(lobes as u32).to_le_bytes())?;
    w.write_all(&res.mean.to_le_bytes())?;
    w.write_all(&res.max.to_le_bytes())?;
    w.write_all(&res.texels.to_le_bytes())?;
    let sh = res.shading_mean.zip(res.shading_max);
    w.write_all(&u32::from(sh.is_some()).to_le_bytes())?;
    let (m, x) = sh.unwrap_or((0.0, 0.0));
    w.write_all(&m.to_le_bytes())?;
    w.write_all(&x.to_le_bytes())
}

/// Rows `r0..r1` of level `l` as a band of its own (lobe starts from 0, lobes and horizon
/// statistics copied in the level's precision).
pub(crate) fn band_of(l: &Level, r0: usize, r1: usize) -> Level {
    let (t0, t1) = (r0 * l.cols, r1 * l.cols);
    let (a, b) = (l.lobe_start[t0] as usize, l.lobe_start[t1] as usize);
    let lobes = match &l.lobes {
        Lobes::F64(v) => Lobes::F64(v[a..b].to_vec()),
        Lobes::F32(v) => Lobes::F32(v[a..b].to_vec()),
        Lobes::Coded(v) => Lobes::Coded(v[a..b].to_vec()),
        Lobes::Lazy(v) => Lobes::Coded(v.lobe_codes(a, b)),
    };
    let horizon = l.horizon.as_ref().map(|h| match h {
        Horizons::F64(v) => Horizons::F64(v[t0..t1].to_vec()),
        Horizons::F32(v) => Horizons::F32(v[t0..t1].to_vec()),
        Horizons::Coded(v) => Horizons::Coded(v[t0..t1].to_vec()),
        Horizons::Lazy(v) => Horizons::Coded(v.horizon_codes(t0, t1)),
    });
    Level {
        cols: l.cols,
        rows: r1 - r0,
        span: l.span,
        lobe_start: l.lobe_start[t0..=t1].iter().map(|s| s - a as u32).collect(),
        lobes,
        horizon,
        residual: Residual::default(),
    }
}

/// Write the levels of `p` (after the common header) in format 4, in bands of [`BAND_ROWS`]
/// rows. The caller has checked that `p` is storable.
pub(in crate::format) fn write_levels(p: &Pyramid, w: &mut dyn Write) -> std::io::Result<()> {
    let has_h = p.levels[0].horizon.is_some();
    for (k, l) in p.levels.iter().enumerate() {
        for r0 in (0..l.rows).step_by(BAND_ROWS) {
            let band = band_of(l, r0, (r0 + BAND_ROWS).min(l.rows));
            write_band(w, k, r0, &band, has_h)?;
        }
        write_level_end(w, k, l.lobes.len(), &l.residual)?;
    }
    Ok(())
}

/// A band's chunk header as read: its first row, rows and lobes.
struct BandHead {
    row0: usize,
    rows: usize,
    lobes: usize,
}

/// The bytes a stream of a band of `texels` texels and `lobes` lobes inflates to.
fn expect(s: usize, texels: u64, lobes: u64) -> u64 {
    (if STREAMS[s].1 { lobes } else { texels }) * (STREAMS[s].2 * STREAMS[s].3) as u64
}

/// The header of the chunk at the reader (a band or the end of level `k`), checked against
/// level `k` (`cols × rows` texels, `next_row` the first row not yet read): the band's header,
/// or `None` for the level's end (whose record is left to read).
fn band_head(
    r: &mut Reader<'_>,
    h: &Header,
    k: usize,
    (cols, rows): (usize, usize),
    next_row: usize,
) -> Result<Option<BandHead>> {
    let at = r.pos;
    let tag = r.take(4, "a chunk tag")?;
    if tag == END_TAG {
        r.pos = at;
        return Ok(None);
    }
    if tag != BAND_TAG {
        return Err(r.err(format!(
            "level {k}: expected a band or the level's end at byte {at}, found {tag:02x?}"
        )));
    }
    let lk = r.u32("band level")? as usize;
    let row0 = r.u32("band first row")? as usize;
    let nrows = r.u32("band rows")? as usize;
    let lobes = r.u32("band lobes")? as usize;
    if lk != k || row0 != next_row || nrows == 0 || nrows > rows - row0.min(rows) {
        return Err(r.err(format!(
            "a band of level {lk}, rows {row0}..{}, where rows {next_row}.. of level {k} \
             ({rows} rows) were expected",
            row0 as u64 + nrows as u64
        )));
    }
    if lobes as u64 > (nrows * cols) as u64 * h.max_lobes as u64 {
        return Err(r.err(format!(
            "level {k}: a band of {} texels claims {lobes} lobes",
            nrows * cols
        )));
    }
    Ok(Some(BandHead {
        row0,
        rows: nrows,
        lobes,
    }))
}

/// The end record of level `k`, checked (its level, `lobes` the bands' sum, finite residuals
/// ≥ 0): the level's residual.
fn level_end(r: &mut Reader<'_>, k: usize, lobes: usize) -> Result<Residual> {
    if r.b.len() - r.pos < END_BYTES {
        return Err(r.err(format!("truncated in the end record of level {k}")));
    }
    let tag = r.take(4, "a chunk tag")?;
    if tag != END_TAG {
        return Err(r.err(format!("level {k}: expected its end record")));
    }
    let lk = r.u32("level")? as usize;
    let nl = r.u32("level lobes")? as usize;
    if lk != k || nl != lobes {
        return Err(r.err(format!(
            "the end of level {lk} claims {nl} lobes, where level {k}'s bands hold {lobes}"
        )));
    }
    let mut res = r.residual()?;
    let has_sh = r.u32("shading flag")?;
    let (m, x) = (r.f64("shading error")?, r.f64("shading error")?);
    if has_sh > 1 {
        return Err(r.err(format!("level {k}: bad shading flag {has_sh}")));
    }
    if has_sh == 1 {
        if !(m.is_finite() && x.is_finite() && m >= 0.0 && x >= 0.0) {
            return Err(r.err(format!("level {k}: bad shading error {m}/{x}")));
        }
        res.shading_mean = Some(m);
        res.shading_max = Some(x);
    }
    Ok(res)
}

/// Walk the chunks of a format-4 file after the common header without inflating anything:
/// their order, every band's and stream's header against its level and the file's length.
/// Returns the level table, the largest memory of reading one band, and the largest codes of
/// a band of level 0 (bytes: 11 a lobe, 28 a texel with horizon statistics).
fn scan(r: &mut Reader<'_>, h: &Header) -> Result<(Vec<TableEntry>, u64, u64)> {
    let n_streams = stream_count(h.has_h, h.version);
    let mut table = Vec::with_capacity(h.nlev);
    let (mut cols, mut rows, mut t0, mut band_max) = (h.cols, h.rows, 0usize, 0u64);
    let mut codes0 = 0u64;
    for k in 0..h.nlev {
        let (mut next, mut lobes) = (0usize, 0usize);
        while let Some(b) = {
            r.check_cut()?;
            band_head(r, h, k, (cols, rows), next)?
        } {
            let texels = (b.rows * cols) as u64;
            let mut need = 0;
            for (s, &(_, per_lobe, cols_of, _, _)) in STREAMS.iter().enumerate().take(n_streams) {
                let e = expect(s, texels, b.lobes as u64);
                let (_, _, comp) = stream_header(r, s, e)?;
                r.pos += comp as usize;
                // Inflated, decoded (4 bytes a value) and built (`f64`).
                need += e + 4 * cols_of as u64 * if per_lobe { b.lobes as u64 } else { texels };
            }
            band_max = band_max.max(need + 9 * texels + b.lobes as u64 * 40 + texels * 140);
            if k == 0 {
                codes0 = codes0.max(codes_bytes(b.lobes as u64, texels, h.has_h));
            }
            lobes += b.lobes;
            next = b.row0 + b.rows;
        }
        if next != rows {
            return Err(r.err(format!("level {k}: its bands end at row {next} of {rows}")));
        }
        let residual = level_end(r, k, lobes)?;
        table.push(TableEntry {
            cols,
            rows,
            span: 1 << k,
            lobes,
            residual,
            t0,
        });
        t0 += cols * rows;
        cols = cols.div_ceil(2);
        rows = rows.div_ceil(2);
    }
    Ok((table, band_max, codes0))
}

/// Read the band at the reader (of level `k`, described by `e`, its header already checked by
/// [`scan`]): its streams inflated and decoded, its lobe counts and values checked, built in
/// the level's precision.
pub(super) fn read_band(
    r: &mut Reader<'_>,
    h: &Header,
    k: usize,
    e: &TableEntry,
    next_row: usize,
    coded: bool,
) -> Result<Level> {
    let b = band_head(r, h, k, (e.cols, e.rows), next_row)?
        .ok_or_else(|| r.err(format!("level {k}: a band expected")))?;
    let texels = b.rows * e.cols;
    let n_streams = stream_count(h.has_h, h.version);
    let mut raws = Vec::with_capacity(n_streams);
    for s in 0..n_streams {
        raws.push(read_stream(r, s, expect(s, texels as u64, b.lobes as u64))?);
    }
    let entry = TableEntry {
        cols: e.cols,
        rows: b.rows,
        span: e.span,
        lobes: b.lobes,
        residual: Residual::default(),
        t0: 0,
    };
    let at = vec![(0, texels)];
    let counts = read_counts(r, &[entry], &at, texels, &raws[0], h.max_lobes)?;
    let layout = Layout::new(at, counts);
    let columns = decode_columns(r, &layout, raws, h.has_h)?;
    build_level(
        r,
        k,
        &entry,
        &layout,
        &columns,
        h.has_h,
        compact(e.texels()),
        coded,
    )
}

/// The memory (bytes) of the levels of `table` read with their codes kept on the compact
/// levels ([`read_levels`] with `coded`): per lobe 11 bytes ([`crate::compact::LobeCode`]) and
/// per texel its lobe start (4) and horizon codes (28, [`crate::compact::HorizonCode`]) on the
/// compact levels, [`pyramid_bytes`]'s on the others.
fn coded_pyramid_bytes(table: &[TableEntry], has_h: bool) -> u64 {
    table
        .iter()
        .map(|t| {
            if compact(t.texels()) {
                codes_bytes(t.lobes as u64, t.texels() as u64, has_h) + 4 * t.texels() as u64
            } else {
                pyramid_bytes(std::slice::from_ref(t), has_h)
            }
        })
        .sum()
}

/// Bytes of the codes of `lobes` lobes and `texels` texels' horizon statistics (11 a lobe, 28
/// a texel when the file has them, [`HORIZON_CODE_BYTES`]): a compact level's values as the
/// file codes them.
fn codes_bytes(lobes: u64, texels: u64, has_h: bool) -> u64 {
    lobes * 11 + texels * if has_h { HORIZON_CODE_BYTES as u64 } else { 0 }
}

/// Append band `b` to level `l` (same precision).
fn append(l: &mut Level, b: Level) {
    let base = *l.lobe_start.last().unwrap_or(&0);
    l.lobe_start
        .extend(b.lobe_start[1..].iter().map(|s| s + base));
    match (&mut l.lobes, b.lobes) {
        (Lobes::F64(a), Lobes::F64(mut x)) => a.append(&mut x),
        (Lobes::F32(a), Lobes::F32(mut x)) => a.append(&mut x),
        (Lobes::Coded(a), Lobes::Coded(mut x)) => a.append(&mut x),
        _ => unreachable!("a level's bands share its precision"),
    }
    match (&mut l.horizon, b.horizon) {
        (Some(Horizons::F64(a)), Some(Horizons::F64(mut x))) => a.append(&mut x),
        (Some(Horizons::F32(a)), Some(Horizons::F32(mut x))) => a.append(&mut x),
        (Some(Horizons::Coded(a)), Some(Horizons::Coded(mut x))) => a.append(&mut x),
        (None, None) => {}
        _ => unreachable!("a level's bands share its precision"),
    }
}

/// How [`read_levels`] reads a format-4 file's levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(in crate::format) enum Mode {
    /// Check every band, build nothing.
    Check,
    /// Build every level, the compact ones in `f32`.
    Full,
    /// Build every level, the compact ones as the file's codes.
    Coded,
    /// As `Coded`, but level 0 (when compact) held by band in the mapped file
    /// ([`super::lazy::LazyLevel`]): every band checked, then dropped.
    Lazy,
    /// `Coded` when the coded pyramid takes at most half the memory budget (the other half
    /// left to what is built from it) or `Lazy` would need as much, `Lazy` otherwise
    /// ([`lazy_pays`]): holding level 0 by band costs CPU
    /// when a view reads much of it (far view of a 4096² map: +28 % user CPU), so it is taken
    /// only where the memory asks for it.
    Auto,
}

/// [`Mode::Auto`]'s choice: level 0 held by band when the coded pyramid (`coded` bytes, as
/// read) would take more than half the `budget` and holding level 0 by band needs less
/// (`lazy` bytes: on a small map the cache of decoded bands can be all of level 0 and more).
fn lazy_pays(coded: u64, lazy: u64, budget: u64) -> bool {
    coded > budget / 2 && lazy < coded
}

/// The memory (bytes) that reading the levels in `mode` takes, from what [`scan`] found
/// (`table`, the largest band's decoding memory, level 0's largest band's codes), and whether
/// level 0 is then held by band (`mapped`: the reader holds a mapped file, which a level held
/// by band needs). What [`read_levels`] checks against the budget before inflating anything.
fn need_of(
    r: &Reader<'_>,
    h: &Header,
    mode: Mode,
    mapped: bool,
    (table, band_max, codes0): (&[TableEntry], u64, u64),
) -> (u64, bool) {
    let build = mode != Mode::Check;
    let coded = matches!(mode, Mode::Coded | Mode::Lazy | Mode::Auto);
    let can_lazy = mapped && table.first().is_some_and(|e| compact(e.texels()));
    let file = if r.releases() { 0 } else { r.b.len() as u64 };
    let coded_need = file + coded_pyramid_bytes(table, h.has_h) + band_max;
    // Level 0's lobe starts and decoded bands, the other levels coded.
    let lazy_need = || {
        let t0 = table[0].texels() as u64;
        file + coded_pyramid_bytes(&table[1..], h.has_h)
            + 4 * (t0 + 1)
            + super::lazy::held_bytes_bound(codes0, band_max)
    };
    let lazy0 = can_lazy
        && match mode {
            Mode::Lazy => true,
            Mode::Auto => lazy_pays(coded_need, lazy_need(), meso_core::budget::budget().bytes),
            _ => false,
        };
    let need = if lazy0 {
        lazy_need()
    } else if build && coded {
        coded_need
    } else if build {
        r.b.len() as u64 + pyramid_bytes(table, h.has_h) + band_max
    } else {
        band_max
    };
    (need, lazy0)
}

/// The memory (bytes) [`read_levels`] in [`Mode::Auto`] checks against the budget for the
/// levels after the common header, from the chunks' headers alone (nothing inflated):
/// `crate::Pyramid::read_compact_bytes`.
pub(in crate::format) fn auto_need(r: &mut Reader<'_>, h: &Header) -> Result<u64> {
    let (table, band_max, codes0) = scan(r, h)?;
    let mapped = r.mapped.is_some();
    Ok(need_of(r, h, Mode::Auto, mapped, (&table, band_max, codes0)).0)
}

/// Read (`mode`) or only check the levels of a format-4 file after the common header: the
/// chunks scanned ([`scan`]) and the memory checked against the budget before anything is
/// inflated, then band by band inflated, decoded, checked and appended to its level (or
/// dropped). Returns the levels (empty for [`Mode::Check`]). With [`Mode::Coded`] and
/// [`Mode::Lazy`], the compact levels keep the file's codes ([`Lobes::Coded`],
/// [`Horizons::Coded`]); with [`Mode::Lazy`] level 0, when compact, is held by band
/// ([`Lobes::Lazy`], [`Horizons::Lazy`]: `map` must be the reader's bytes). The reader's bytes
/// are released as they are read when it holds a mapped file (`Reader::release`), so that the
/// memory is the (coded) pyramid and one band, not the file besides. `report` gets a
/// [`crate::pyramid::ProgressTask::Read`] progress before the first band, after each band and
/// after each level (work: bytes of the levels read, ending at the total).
pub(in crate::format) fn read_levels(
    r: &mut Reader<'_>,
    h: &Header,
    mode: Mode,
    map: Option<&std::sync::Arc<super::lazy::MappedFile>>,
    report: &mut dyn FnMut(crate::pyramid::Progress),
) -> Result<Vec<Level>> {
    let start = r.pos;
    let (table, band_max, codes0) = scan(r, h)?;
    let end = r.pos;
    let build = mode != Mode::Check;
    let coded = matches!(mode, Mode::Coded | Mode::Lazy | Mode::Auto);
    let (need, lazy0) = need_of(r, h, mode, map.is_some(), (&table, band_max, codes0));
    meso_core::budget::check(&r.path, "reading the map file", need)?;
    r.pos = start;
    let texels_total = table.iter().map(|e| e.texels() as u64).sum::<u64>();
    let mut texels_done = 0u64;
    let mut progress = |levels_done: usize, texels_done: u64, at: usize| {
        report(crate::pyramid::Progress {
            task: crate::pyramid::ProgressTask::Read,
            levels_done,
            levels: table.len(),
            texels_done,
            texels_total,
            work_done: (at - start) as u64,
            work_total: ((end - start) as u64).max(1),
        });
    };
    progress(0, 0, start);
    let mut levels = Vec::with_capacity(if build { h.nlev } else { 0 });
    for (k, e) in table.iter().enumerate() {
        let c = compact(e.texels());
        let mut level = Level {
            cols: e.cols,
            rows: e.rows,
            span: e.span,
            lobe_start: Vec::with_capacity(if build { e.texels() + 1 } else { 1 }),
            lobes: Lobes::new(Vec::new(), c),
            horizon: h.has_h.then(|| Horizons::new(Vec::new(), c)),
            residual: e.residual,
        };
        level.lobe_start.push(0);
        let lazy = lazy0 && k == 0;
        if build && !lazy {
            if c && coded {
                level.lobes = Lobes::Coded(Vec::with_capacity(e.lobes));
                if h.has_h {
                    level.horizon = Some(Horizons::Coded(Vec::with_capacity(e.texels())));
                }
            }
            match &mut level.lobes {
                Lobes::F64(v) => v.reserve_exact(e.lobes),
                Lobes::F32(v) => v.reserve_exact(e.lobes),
                Lobes::Coded(v) => v.reserve_exact(e.lobes),
                Lobes::Lazy(_) => {}
            }
            match &mut level.horizon {
                Some(Horizons::F64(v)) => v.reserve_exact(e.texels()),
                Some(Horizons::F32(v)) => v.reserve_exact(e.texels()),
                Some(Horizons::Coded(v)) => v.reserve_exact(e.texels()),
                Some(Horizons::Lazy(_)) | None => {}
            }
        }
        let mut bands = Vec::new();
        let mut next = 0;
        while next < e.rows {
            // A mapped file cut short by another program meanwhile would fault where its cut
            // pages are read: refused first (one `fstat` a band).
            r.check_cut()?;
            let at = r.pos;
            let band = read_band(r, h, k, e, next, coded)?;
            if lazy {
                let lobe0 = *level.lobe_start.last().unwrap_or(&0);
                level
                    .lobe_start
                    .extend(band.lobe_start[1..].iter().map(|s| s + lobe0));
                bands.push(super::lazy::BandEntry {
                    at,
                    row0: next,
                    rows: band.rows,
                    lobe0: lobe0 as usize,
                    lobes: band.lobes.len(),
                });
            }
            next += band.rows;
            texels_done += (band.rows * e.cols) as u64;
            if build && !lazy {
                append(&mut level, band);
            }
            r.release();
            progress(k, texels_done, r.pos);
        }
        level_end(r, k, e.lobes)?;
        progress(k + 1, texels_done, r.pos);
        if let (true, Some(map)) = (lazy, map) {
            let l = std::sync::Arc::new(super::lazy::LazyLevel::new(
                std::sync::Arc::clone(map),
                &r.path,
                h,
                k,
                (e.cols, e.rows),
                bands,
                codes0,
                band_max,
            ));
            level.lobes = Lobes::Lazy(std::sync::Arc::clone(&l));
            level.horizon = h.has_h.then(|| Horizons::Lazy(l));
        }
        if build {
            levels.push(level);
        }
    }
    debug_assert_eq!(r.pos, end);
    Ok(levels)
}

/// Check one band chunk `bytes` (rows `row0..` of level `k` of `cols × rows` texels) as the
/// reader will: what the streamed extraction runs on each band before writing it.
pub(crate) fn check_band(
    path: &Path,
    h: &Header,
    k: usize,
    (cols, rows): (usize, usize),
    row0: usize,
    bytes: &[u8],
) -> Result<()> {
    let mut r = Reader::new(bytes, path);
    let e = TableEntry {
        cols,
        rows,
        span: 1 << k,
        lobes: 0,
        residual: Residual::default(),
        t0: 0,
    };
    read_band(&mut r, h, k, &e, row0, false)?;
    if r.pos != bytes.len() {
        return Err(MapError::MapFormat {
            path: path.to_path_buf(),
            message: format!("level {k}: a band with trailing bytes"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::lazy_pays;

    #[test]
    fn level_0_is_held_by_band_only_where_the_memory_asks_for_it() {
        const G: u64 = 1 << 30;
        // The default budget (4 GiB): a 4096² map coded (≈ 1 GB), an 8192² one (≈ 4.2 GB) by band.
        assert!(!lazy_pays(G, G / 2, 4 * G));
        assert!(lazy_pays(4 * G + G / 5, 2 * G, 4 * G));
        // Just over half the budget, and only if it needs less.
        assert!(!lazy_pays(2 * G, G, 4 * G));
        assert!(lazy_pays(2 * G + 1, G, 4 * G));
        assert!(!lazy_pays(3 * G, 3 * G, 4 * G));
    }
}
