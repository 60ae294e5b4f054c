//! The NDF pyramid: for every texel of every level, a few Phong lobes fitted to the meso-normals
//! of its footprint, plus horizon statistics.
//!
//! * Level 0 has one texel per grid cell (two triangle normals, or one normal with central
//!   differences or for normal maps).
//! * Level k has `⌈cols/2^k⌉ × ⌈rows/2^k⌉` texels; texel `(r, c)` covers cells
//!   `r·2^k .. min((r+1)·2^k, rows)` × `c·2^k .. min((c+1)·2^k, cols)`. Maps whose sides are not
//!   powers of two get a **ragged** last row/column (smaller footprints), not padding.
//! * The top level is the first with a single texel; it covers the whole map.
//! * Each level reports its fit residual ([`Residual`]): the relative NDF L2 error of
//!   `crate::fit::ndf_l2_error` over all its texels, or a strided sample of
//!   `residual_texels` of them on large levels.

use crate::compact::{Horizons, Lobes, COMPACT_TEXELS};
use crate::error::{MapError, Result};
use crate::facets::{FacetNormals, FacetSource, NormalMode};
use crate::fit::{fit_lobes_with, merge_entries, ndf_l2_error, Entry, FitParams, MAX_LOBES};
use crate::heightmap::{Border, HeightMap, NormalMap};
use crate::horizon::{HorizonMap, HorizonStats};
use meso_core::ndf::PhongLobe;
use rayon::prelude::*;

/// What to extract from.
#[derive(Clone, Copy, Debug)]
pub enum Source<'a> {
    /// A height map (normals from triangles or central differences, plus horizon angles).
    Heights(&'a HeightMap),
    /// A tangent-space normal map (normals only; no horizon statistics).
    Normals(&'a NormalMap),
}

/// Parameters of [`extract`].
#[derive(Clone, Debug, PartialEq)]
pub struct ExtractParams {
    /// Lobe fit parameters (max lobes, likelihood threshold, EM budget).
    pub fit: FitParams,
    /// Triangles (default) or central differences.
    pub normal_mode: NormalMode,
    /// Texels per level on which the NDF residual is measured (all when the level has fewer;
    /// default 64).
    pub residual_texels: usize,
    /// What to store per texel: fitted lobes (default) or a single-lobe baseline.
    pub method: Method,
    /// Levels with at least this many texels keep their lobes and horizon statistics in `f32`
    /// (half the memory; [`crate::compact`]), smaller ones in `f64` (default
    /// [`COMPACT_TEXELS`]; `usize::MAX` keeps every level in `f64`, 0 none). The fit itself
    /// always runs in `f64`, and each level is fitted from the `f64` data of the one below.
    pub compact_texels: usize,
}

/// What [`extract`] stores per texel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Method {
    /// Up to `max_lobes` fitted Phong peaks (the multiple surface).
    #[default]
    Lobes,
    /// A single-lobe baseline, converted to one Phong peak ([`crate::baseline::baseline_lobes`]):
    /// the map file stores isotropic Phong lobes only, so LEAN is isotropised.
    Baseline(crate::baseline::Baseline),
}

impl Default for ExtractParams {
    fn default() -> Self {
        ExtractParams {
            fit: FitParams::default(),
            normal_mode: NormalMode::Triangles,
            residual_texels: 64,
            method: Method::Lobes,
            compact_texels: COMPACT_TEXELS,
        }
    }
}

/// Progress of [`extract`]: reported once before any work (everything at 0, the totals set),
/// once the normals and horizon angles are computed, and after each level.
///
/// `work_done / work_total` is the fraction of the expected *time* done: work is counted in
/// estimated cost units ([`extract_work`]: the normals and horizons per sample, and per level
/// the merging, the EM fit on its capped point set and the residual's footprint visits), so the
/// few coarse levels, each fitted thoroughly on many points, weigh what they cost rather than
/// their handful of texels. `work_done` only grows and ends equal to `work_total`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Progress {
    /// Levels finished so far.
    pub levels_done: usize,
    /// Total number of levels.
    pub levels: usize,
    /// Texels fitted so far (all levels).
    pub texels_done: u64,
    /// Texels to fit in all.
    pub texels_total: u64,
    /// Work done so far (estimated cost units, see [`extract_work`]).
    pub work_done: u64,
    /// All the work of the extraction (estimated cost units); > 0.
    pub work_total: u64,
}

/// Estimated cost units (≈ µs of one core) of computing the normals and horizon angles, per
/// height sample, and of a level-0 texel (no EM: its few entries are its lobes).
const PREP_WORK_PER_SAMPLE: u64 = 1;
/// Estimated cost units of one EM point of a texel's fit on a level fitted plainly.
const FIT_WORK_PLAIN: u64 = 4;
/// … on a level with the smoothed refinement (`FitParams::smooth_texels`).
const FIT_WORK_SMOOTH: u64 = 22;
/// … on a level fitted thoroughly (`FitParams::thorough_texels`).
const FIT_WORK_THOROUGH: u64 = 45;

/// Peak memory of [`extract`] per level-0 cell with one normal per cell (bytes): the normals,
/// the level-0 fits (row buffers and their flat copies), the coarser levels, and writing the map
/// (the file's bytes and the reader's check of them). `meso extract` on rough 16-bit maps
/// measured 735–755 bytes per cell (peak RSS, triangles, 512² and 1024²; docs/limits.md):
/// with the per-sample term the estimate is 890, a 20% margin. Since the compact levels
/// (2026-12-02) the peak is 458 bytes per cell of heap at 256² and 354 of RSS at 1024², so the
/// estimate is a looser upper bound (`crates/meso-maps/tests/extract_memory.rs` requires it to
/// cover the heap peak and stay within 3× of it).
pub const EXTRACT_BYTES_PER_CELL: u64 = 600;
/// Extra peak memory of [`extract`] per cell for each further normal of the cell (triangles: 2).
pub const EXTRACT_BYTES_PER_EXTRA_NORMAL: u64 = 250;
/// Peak memory of [`extract`] per height sample (horizon angles, bytes).
pub const EXTRACT_BYTES_PER_SAMPLE: u64 = 40;

/// The estimated peak memory (bytes) of [`extract`] on a `cols × rows` cell grid with
/// `per_cell` normals per cell and `samples` height samples (0 for a normal map), including
/// writing the pyramid as a map file ([`Pyramid::write`]); the source map itself is not
/// counted.
#[must_use]
pub fn extract_bytes(cols: usize, rows: usize, per_cell: usize, samples: usize) -> u64 {
    let cells = (cols as u64).saturating_mul(rows as u64);
    let per =
        EXTRACT_BYTES_PER_CELL + EXTRACT_BYTES_PER_EXTRA_NORMAL * (per_cell.max(1) as u64 - 1);
    cells
        .saturating_mul(per)
        .saturating_add((samples as u64).saturating_mul(EXTRACT_BYTES_PER_SAMPLE))
}

/// The estimated work of [`extract`] on a `cols × rows` cell grid with `per_cell` normals per
/// cell (2 for triangles, 1 otherwise) and `samples` height samples (0 for a normal map): the
/// preparation (normals, horizons) and then each level, in cost units (≈ µs of one core). A
/// texel's fit costs its EM points (its footprint's facets, capped as [`extract`] caps them) ×
/// a factor of the level's fitting regime (plain, smoothed, thorough), measured per level with
/// `cargo run -p meso-maps --example level_times` on 64² to 256² Gaussian maps; merging costs
/// its entries and the residual its footprint facets. Used to weight [`Progress`] by time
/// rather than by texels (the coarse levels have few texels and most of the time).
#[must_use]
pub fn extract_work(
    cols: usize,
    rows: usize,
    per_cell: usize,
    samples: usize,
    params: &ExtractParams,
) -> (u64, Vec<u64>) {
    let prep = (samples.max(cols * rows) as u64) * PREP_WORK_PER_SAMPLE;
    let nlev = level_count(cols, rows);
    let cells = (cols as u64) * (rows as u64);
    let kmax = params.fit.max_lobes.clamp(1, MAX_LOBES) as u64;
    let bins = (crate::fit::ENTRY_GRID_RES * crate::fit::ENTRY_GRID_RES) as u64;
    let mut out = Vec::with_capacity(nlev);
    let (mut c, mut r) = (cols, rows);
    for k in 0..nlev {
        let texels = c * r;
        let t = texels as u64;
        let span2 = 1u64 << (2 * k.min(31));
        let facets = span2.min(cells).max(1) * per_cell as u64;
        let entries = facets.min(bins);
        let cap = (params.fit.level_em_points / texels.max(1))
            .clamp(64, params.fit.max_em_points.max(64)) as u64;
        let points = if entries <= kmax { 0 } else { entries.min(cap) };
        let per_point = if texels <= params.fit.thorough_texels {
            FIT_WORK_THOROUGH
        } else if texels <= params.fit.smooth_texels {
            FIT_WORK_SMOOTH
        } else {
            FIT_WORK_PLAIN
        };
        let fit = t * (1 + entries / 4 + per_point * points);
        let residual = t.min(params.residual_texels.max(1) as u64) * facets / 4;
        out.push(fit + residual);
        c = c.div_ceil(2);
        r = r.div_ceil(2);
    }
    (prep, out)
}

/// The fit residuals of one level, measured on a sample of its texels (`texels` of them,
/// evenly strided): the binned NDF error and the shading error.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Residual {
    /// Mean relative NDF L2 error over the measured texels ([`crate::fit::ndf_l2_error`]).
    pub mean: f64,
    /// Largest relative NDF L2 error among them.
    pub max: f64,
    /// Number of texels measured.
    pub texels: u32,
    /// Mean shading error over the measured texels, as a fraction of each texel's peak
    /// ([`crate::fit::shading_error`]: the lobes against the footprint's normals, both seen
    /// through a facet kernel of the fit's `smooth_exponent`, RMS over the half vectors;
    /// 0.01 = 1 %). `None` for map files that did not record it (format 2, and format-3 files
    /// written before it was recorded).
    pub shading_mean: Option<f64>,
    /// Largest shading error among the measured texels (fraction of its peak); `None` as above.
    pub shading_max: Option<f64>,
}

/// One level of the pyramid.
#[derive(Clone, Debug, PartialEq)]
pub struct Level {
    /// Texels along x.
    pub cols: usize,
    /// Texels along y.
    pub rows: usize,
    /// Footprint side in level-0 cells (2^k).
    pub span: usize,
    /// `lobe_start[t]..lobe_start[t+1]` indexes `lobes` for texel `t = row·cols + col`.
    pub lobe_start: Vec<u32>,
    /// All lobes of the level (local frame, normal +z; weights of a texel sum to 1), in `f64`
    /// or, on big levels, `f32` ([`crate::compact`]); read as [`PhongLobe`]s.
    pub lobes: Lobes,
    /// Horizon statistics per texel (height maps only), in `f64` or `f32` like the lobes.
    pub horizon: Option<Horizons>,
    /// Fit residual.
    pub residual: Residual,
}

impl Level {
    /// The lobes of texel `(row, col)` in `f64` (on an `f32` level, the weights renormalised to
    /// sum to 1 in `f64`).
    pub fn texel_lobes(&self, row: usize, col: usize) -> Result<Vec<PhongLobe>> {
        let t = self.index(row, col)?;
        Ok(self.lobes_of(t))
    }
    /// The lobes of texel `t = row·cols + col` (as [`Level::texel_lobes`]).
    ///
    /// # Panics
    /// `t ≥ texels()`.
    #[must_use]
    pub fn lobes_of(&self, t: usize) -> Vec<PhongLobe> {
        let (a, b) = (self.lobe_start[t] as usize, self.lobe_start[t + 1] as usize);
        let mut out: Vec<PhongLobe> = self.lobes.range(a, b).collect();
        if self.lobes.is_compact() {
            let s: f64 = out.iter().map(|l| l.weight).sum();
            if s > 0.0 {
                for l in &mut out {
                    l.weight /= s;
                }
            }
        }
        out
    }
    /// The horizon statistics of texel `(row, col)` (`None` for normal maps).
    pub fn texel_horizon(&self, row: usize, col: usize) -> Result<Option<HorizonStats>> {
        let t = self.index(row, col)?;
        Ok(self.horizon.as_ref().map(|h| h.get(t)))
    }
    /// Keep the lobes and horizon statistics in `f32` ([`crate::compact`]); a no-op on a
    /// level already compact.
    pub fn compact(&mut self) {
        if let Lobes::F64(v) = &mut self.lobes {
            let v = std::mem::take(v);
            self.lobes = Lobes::new(v, true);
        }
        if let Some(Horizons::F64(v)) = &mut self.horizon {
            let v = std::mem::take(v);
            self.horizon = Some(Horizons::new(v, true));
        }
    }
    /// Bytes the level's lobes, lobe starts and horizon statistics occupy.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.lobes.bytes()
            + self.lobe_start.len() * 4
            + self.horizon.as_ref().map_or(0, Horizons::bytes)
    }
    fn index(&self, row: usize, col: usize) -> Result<usize> {
        if row >= self.rows {
            return Err(MapError::OutOfRange {
                what: "row",
                index: row,
                count: self.rows,
            });
        }
        if col >= self.cols {
            return Err(MapError::OutOfRange {
                what: "column",
                index: col,
                count: self.cols,
            });
        }
        Ok(row * self.cols + col)
    }
    /// Number of texels.
    #[must_use]
    pub fn texels(&self) -> usize {
        self.cols * self.rows
    }
}

/// An extracted pyramid (see the module docs). Written and read by `Pyramid::write`/`read`.
#[derive(Clone, Debug, PartialEq)]
pub struct Pyramid {
    /// Samples along x of the source map.
    pub width: usize,
    /// Samples along y of the source map.
    pub height: usize,
    /// Texel size S (length units; 1 for normal maps).
    pub texel_size: f64,
    /// Border mode of the source.
    pub border: Border,
    /// How normals were derived.
    pub normal_mode: NormalMode,
    /// `max_lobes` used for the fit.
    pub max_lobes: usize,
    /// Levels, finest (0) first; the last has one texel.
    pub levels: Vec<Level>,
}

/// Summary of a pyramid for `meso map info`.
#[derive(Clone, Debug, PartialEq)]
pub struct PyramidInfo {
    /// Source size in samples.
    pub width: usize,
    /// Source size in samples.
    pub height: usize,
    /// Texel size.
    pub texel_size: f64,
    /// Per level: `(cols, rows, span, total lobes, histogram of lobe counts 0..=MAX_LOBES,
    /// residual)`.
    pub levels: Vec<LevelInfo>,
}

/// Summary of one level.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelInfo {
    /// Texels along x.
    pub cols: usize,
    /// Texels along y.
    pub rows: usize,
    /// Footprint side in cells.
    pub span: usize,
    /// Total number of lobes.
    pub lobes: usize,
    /// `lobe_counts[k]` = number of texels with k lobes.
    pub lobe_counts: Vec<usize>,
    /// Fit residual.
    pub residual: Residual,
}

impl std::fmt::Display for PyramidInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(
            f,
            "map {}x{} samples, texel size {}, {} levels",
            self.width,
            self.height,
            self.texel_size,
            self.levels.len()
        )?;
        writeln!(
            f,
            "level  texels       span  lobes     lobes/texel  lobe-count histogram  residual mean/max (n)  shading error mean/max (% of peak)"
        )?;
        for (k, l) in self.levels.iter().enumerate() {
            let hist: Vec<String> = l
                .lobe_counts
                .iter()
                .enumerate()
                .filter(|(_, c)| **c > 0)
                .map(|(n, c)| format!("{n}:{c}"))
                .collect();
            let shading = match (l.residual.shading_mean, l.residual.shading_max) {
                (Some(m), Some(x)) => format!("{:.2}/{:.2}", 100.0 * m, 100.0 * x),
                _ => "not recorded".to_string(),
            };
            writeln!(
                f,
                "{k:<5}  {:<11}  {:<5} {:<9} {:<12.3} {:<21} {:<22} {shading}",
                format!("{}x{}", l.cols, l.rows),
                l.span,
                l.lobes,
                l.lobes as f64 / (l.cols * l.rows) as f64,
                hist.join(" "),
                format!(
                    "{:.4}/{:.4} ({})",
                    l.residual.mean, l.residual.max, l.residual.texels
                ),
            )?;
        }
        Ok(())
    }
}

impl Pyramid {
    /// The top level (one texel covering the whole map).
    #[must_use]
    pub fn top(&self) -> &Level {
        self.levels
            .last()
            .expect("a pyramid has at least one level")
    }
    /// Level `k`, or an error naming the range.
    pub fn level(&self, k: usize) -> Result<&Level> {
        self.levels.get(k).ok_or(MapError::OutOfRange {
            what: "level",
            index: k,
            count: self.levels.len(),
        })
    }
    /// Keep the levels of at least `min_texels` texels in `f32` ([`Level::compact`]).
    pub fn compact(&mut self, min_texels: usize) {
        for l in &mut self.levels {
            if l.texels() >= min_texels {
                l.compact();
            }
        }
    }
    /// A summary: sizes, lobe counts and residuals per level.
    #[must_use]
    pub fn info(&self) -> PyramidInfo {
        PyramidInfo {
            width: self.width,
            height: self.height,
            texel_size: self.texel_size,
            levels: self
                .levels
                .iter()
                .map(|l| {
                    let mut counts = vec![0; MAX_LOBES + 1];
                    for t in 0..l.texels() {
                        let n = (l.lobe_start[t + 1] - l.lobe_start[t]) as usize;
                        counts[n.min(MAX_LOBES)] += 1;
                    }
                    LevelInfo {
                        cols: l.cols,
                        rows: l.rows,
                        span: l.span,
                        lobes: l.lobes.len(),
                        lobe_counts: counts,
                        residual: l.residual,
                    }
                })
                .collect(),
        }
    }
}

/// Number of levels of a `cols × rows` cell grid (level 0 … the first 1×1 level).
#[must_use]
pub fn level_count(cols: usize, rows: usize) -> usize {
    let mut n = 1;
    let (mut c, mut r) = (cols, rows);
    while c > 1 || r > 1 {
        c = c.div_ceil(2);
        r = r.div_ceil(2);
        n += 1;
    }
    n
}

/// Extract the pyramid of `source`: meso-normals, per-texel lobe fits at every level, horizon
/// statistics and per-level residuals. `progress` is called after every level (on the calling
/// thread). The work inside a level runs on rayon's pool.
pub fn extract(
    source: Source<'_>,
    params: &ExtractParams,
    progress: &mut dyn FnMut(Progress),
) -> Result<Pyramid> {
    check_params(params)?;
    let (cells_x, cells_y, per_cell, samples) = match source {
        Source::Heights(m) => (
            m.cells_x(),
            m.cells_y(),
            match params.normal_mode {
                NormalMode::Triangles => 2,
                NormalMode::CentralDifferences => 1,
            },
            m.width() * m.height(),
        ),
        Source::Normals(n) => (n.width(), n.height(), 1, 0),
    };
    let (prep_work, level_work) = extract_work(cells_x, cells_y, per_cell, samples, params);
    let work_total = (prep_work + level_work.iter().sum::<u64>()).max(1);
    let texels_total = pyramid_texels(cells_x, cells_y, level_work.len());
    let mut report = |levels_done: usize, texels_done: u64, work_done: u64| {
        progress(Progress {
            levels_done,
            levels: level_work.len(),
            texels_done,
            texels_total,
            work_done: work_done.min(work_total),
            work_total,
        });
    };
    report(0, 0, 0);
    let oom = |e: meso_core::budget::AllocError| MapError::OutOfMemory {
        what: "the NDF pyramid".into(),
        source: e,
    };
    // The facets are computed from the map cell by cell when a level reads them (level 0's
    // fits, level 1's merges and the residuals), never stored; the horizon angles only serve
    // level 0 and are freed after it.
    let (facets, mut horizon, width, height, texel_size, border) = match source {
        Source::Heights(m) => (
            FacetSource::Heights(m, params.normal_mode),
            Some(HorizonMap::compute(m)),
            m.width(),
            m.height(),
            m.texel_size(),
            m.border(),
        ),
        Source::Normals(n) => (
            FacetSource::Normals(n),
            None,
            n.width(),
            n.height(),
            1.0,
            Border::Wrap,
        ),
    };
    let has_horizon = horizon.is_some();
    let nlev = level_count(facets.cols(), facets.rows());
    debug_assert_eq!(nlev, level_work.len());
    let mut work_done = prep_work;
    report(0, 0, work_done);
    let mut levels: Vec<Level> = Vec::with_capacity(nlev);
    // What the next level reads of this one, beside the level itself: its entries (none for
    // level 0: level 1 merges its children's entries from the facets again, as level 0 did)
    // and, when the level is stored in f32, its horizon statistics in f64.
    let mut prev = Carry::default();
    let mut done = 0u64;
    let (mut cols, mut rows) = (facets.cols(), facets.rows());
    for (k, &work) in level_work.iter().enumerate() {
        let texels = cols * rows;
        let compact = texels >= params.compact_texels;
        let last = k + 1 == nlev;
        let prev_horizon = match (levels.last(), &horizon) {
            (None, _) => PrevHorizon::None,
            (Some(_), Some(map)) if k == 1 => PrevHorizon::Samples(map),
            (Some(l), _) => match (&prev.horizon, &l.horizon) {
                (Some(h), _) => PrevHorizon::Stats(h),
                (None, Some(h)) => PrevHorizon::Level(h),
                (None, None) => PrevHorizon::None,
            },
        };
        let ctx = LevelFit {
            cols,
            facets,
            horizon: if k == 0 { horizon.as_ref() } else { None },
            prev: levels.last(),
            prev_entries: &prev.entries,
            prev_start: &prev.start,
            prev_horizon,
            keep_entries: k > 0 && !last,
            residual_stride: texels.div_ceil(params.residual_texels.max(1)).max(1),
            params,
            em_cap: (params.fit.level_em_points / texels.max(1))
                .clamp(64, params.fit.max_em_points.max(64)),
            thorough: texels <= params.fit.thorough_texels,
            smooth: texels <= params.fit.smooth_texels,
        };
        let max_per_texel = params
            .fit
            .max_lobes
            .min(per_cell.saturating_mul(1usize << (2 * k.min(8))));
        let mut acc = LevelBuilder::new(
            texels,
            max_per_texel,
            has_horizon,
            compact,
            compact && has_horizon && !last && k > 0,
        )
        .map_err(oom)?;
        // Rows in batches: each batch's rows fitted in parallel and appended at once, so that
        // no more than a batch's row buffers exist beside the level.
        for r0 in (0..rows).step_by(ROW_BATCH) {
            let batch: Vec<RowOut> = (r0..(r0 + ROW_BATCH).min(rows))
                .into_par_iter()
                .map(|r| ctx.row(r))
                .collect();
            acc.extend(batch);
        }
        let (level, carry) = acc.finish(k, cols, rows);
        levels.push(level);
        prev = carry;
        if k >= 1 {
            // Level 1 has read the samples' horizon angles.
            horizon = None;
        }
        done += texels as u64;
        work_done += work;
        report(k + 1, done, if last { work_total } else { work_done });
        cols = cols.div_ceil(2);
        rows = rows.div_ceil(2);
    }
    Ok(Pyramid {
        width,
        height,
        texel_size,
        border,
        normal_mode: params.normal_mode,
        max_lobes: params.fit.max_lobes,
        levels,
    })
}

/// Rows of a level fitted in parallel before they are appended to the level.
const ROW_BATCH: usize = 64;

/// The checks of [`extract`]'s parameters.
fn check_params(params: &ExtractParams) -> Result<()> {
    if params.fit.max_lobes == 0 || params.fit.max_lobes > MAX_LOBES {
        return Err(MapError::InvalidParameter {
            name: "max_lobes",
            value: params.fit.max_lobes.to_string(),
            reason: "must be between 1 and 8",
        });
    }
    if !(params.fit.min_gain.is_finite() && params.fit.min_gain >= 0.0) {
        return Err(MapError::InvalidParameter {
            name: "min_gain",
            value: params.fit.min_gain.to_string(),
            reason: "must be a finite number ≥ 0",
        });
    }
    Ok(())
}

/// Texels of all `levels` levels of a pyramid over `cols × rows` cells.
fn pyramid_texels(cols: usize, rows: usize, levels: usize) -> u64 {
    let (mut c, mut r, mut t) = (cols, rows, 0u64);
    for _ in 0..levels {
        t += (c * r) as u64;
        c = c.div_ceil(2);
        r = r.div_ceil(2);
    }
    t
}

/// One row of texels of a level, as [`LevelFit::row`] fits it.
struct RowOut {
    entries: Vec<Entry>,
    ecount: Vec<u32>,
    lobes: Vec<PhongLobe>,
    lcount: Vec<u32>,
    horizon: Vec<HorizonStats>,
    /// The NDF residual and shading error of the row's texels that the level's residual
    /// samples, in order.
    residual: Vec<(f64, f64)>,
}

/// Where a level reads the horizon statistics of its children, in `f64`.
#[derive(Clone, Copy)]
enum PrevHorizon<'a> {
    /// No horizon statistics (a normal map), or level 0 (which reads the samples' angles).
    None,
    /// Level 1: level 0's statistics are the samples' own ([`HorizonMap::sample_stats`]).
    Samples(&'a HorizonMap),
    /// The previous level's statistics kept in `f64` beside its `f32` copy.
    Stats(&'a [HorizonStats]),
    /// The previous level's own (`f64`) statistics.
    Level(&'a Horizons),
}

impl PrevHorizon<'_> {
    /// Texel `(r, c)` of a previous level of `cols` columns, or `None`.
    #[inline]
    fn get(&self, r: usize, c: usize, cols: usize) -> Option<HorizonStats> {
        match self {
            PrevHorizon::None => None,
            PrevHorizon::Samples(m) => Some(m.sample_stats(r, c)),
            PrevHorizon::Stats(v) => Some(v[r * cols + c]),
            PrevHorizon::Level(h) => Some(h.get(r * cols + c)),
        }
    }
}

/// What fitting a level reads: the facets (levels 0 and 1) or the previous level's merged
/// entries, the previous level's horizon statistics, and the fit's settings for this level's
/// size.
struct LevelFit<'a> {
    cols: usize,
    facets: FacetSource<'a>,
    /// The samples' horizon angles (level 0 only).
    horizon: Option<&'a HorizonMap>,
    prev: Option<&'a Level>,
    /// The previous level's entries; empty when the previous level is level 0 (its entries
    /// are merged from the facets again).
    prev_entries: &'a [Entry],
    prev_start: &'a [u32],
    prev_horizon: PrevHorizon<'a>,
    /// Whether the next level reads this level's entries (not level 0's, not the top's).
    keep_entries: bool,
    /// Texels `0, s, 2s, …` get their NDF residual measured.
    residual_stride: usize,
    params: &'a ExtractParams,
    em_cap: usize,
    thorough: bool,
    smooth: bool,
}

/// A texel's scratch buffers: its merged entries and those of its (up to four) children.
#[derive(Default)]
struct Scratch {
    merged: Vec<Entry>,
    singles: Vec<Entry>,
    children: [Vec<Entry>; 4],
}

impl LevelFit<'_> {
    /// The merged entries, lobes, horizon statistics and sampled residuals of row `r`'s
    /// texels.
    fn row(&self, r: usize) -> RowOut {
        let cols = self.cols;
        let mut out = RowOut {
            entries: Vec::new(),
            ecount: Vec::with_capacity(cols),
            lobes: Vec::new(),
            lcount: Vec::with_capacity(cols),
            horizon: Vec::new(),
            residual: Vec::new(),
        };
        let mut buf = Scratch::default();
        let mut scratch = Vec::new();
        let mut lobes = Vec::new();
        for c in 0..cols {
            match self.prev {
                None => {
                    self.cell_entries(r, c, &mut buf.singles, &mut buf.merged);
                    if let Some(h) = self.horizon {
                        out.horizon.push(h.sample_stats(r, c));
                    }
                }
                Some(prev) => self.merge_children(prev, r, c, &mut buf, &mut out.horizon),
            }
            self.fit_texel(&buf.merged, &mut scratch, &mut lobes);
            if (r * cols + c).is_multiple_of(self.residual_stride) {
                out.residual.push((
                    self.residual(r, c, &lobes),
                    crate::fit::shading_error(&buf.merged, &lobes, self.shading_exponent()),
                ));
            }
            if self.keep_entries {
                out.entries.extend_from_slice(&buf.merged);
                out.ecount.push(buf.merged.len() as u32);
            }
            out.lobes.extend_from_slice(&lobes);
            out.lcount.push(lobes.len() as u32);
        }
        out
    }

    /// The kernel exponent of the shading error: the fit's `smooth_exponent`, or
    /// [`crate::fit::SHADING_KERNEL_EXPONENT`] when that is 0.
    fn shading_exponent(&self) -> f64 {
        let l = self.params.fit.smooth_exponent;
        if l.is_finite() && l > 0.0 {
            l
        } else {
            crate::fit::SHADING_KERNEL_EXPONENT
        }
    }

    /// The relative NDF L2 error of texel `(r, c)`'s lobes against its footprint's facets.
    fn residual(&self, r: usize, c: usize, lobes: &[PhongLobe]) -> f64 {
        let span = self.prev.map_or(1, |p| 2 * p.span);
        let (r0, r1, c0, c1) = footprint_bounds(self.facets.rows(), self.facets.cols(), span, r, c);
        ndf_l2_error(self.facets.footprint(r0, r1, c0, c1), |g, out| {
            crate::fit::lobe_bin_mass(lobes, g, out)
        })
    }

    /// The entries of level-0 cell `(r, c)`: its facets merged per bin.
    fn cell_entries(&self, r: usize, c: usize, singles: &mut Vec<Entry>, out: &mut Vec<Entry>) {
        singles.clear();
        for (n, w) in self.facets.footprint(r, r + 1, c, c + 1) {
            singles.push(Entry::new(n, w));
        }
        merge_entries(&[singles], out);
    }

    /// Texel `(r, c)` of this level from its (up to four) children in `prev`: their entries
    /// (stored, or for level 0's children merged from the facets again) merged into
    /// `buf.merged`, their horizon statistics merged onto `horizon`.
    fn merge_children(
        &self,
        prev: &Level,
        r: usize,
        c: usize,
        buf: &mut Scratch,
        horizon: &mut Vec<HorizonStats>,
    ) {
        let from_facets = self.prev_start.is_empty();
        let mut hs = HorizonStats::default();
        let mut has_h = false;
        let mut ts = [0usize; 4];
        let mut n = 0;
        for cr in 2 * r..(2 * r + 2).min(prev.rows) {
            for cc in 2 * c..(2 * c + 2).min(prev.cols) {
                if from_facets {
                    self.cell_entries(cr, cc, &mut buf.singles, &mut buf.children[n]);
                }
                ts[n] = cr * prev.cols + cc;
                n += 1;
                if let Some(h) = self.prev_horizon.get(cr, cc, prev.cols) {
                    hs.merge(&h);
                    has_h = true;
                }
            }
        }
        let mut lists: [&[Entry]; 4] = [&[]; 4];
        for (i, list) in lists.iter_mut().enumerate().take(n) {
            *list = if from_facets {
                &buf.children[i]
            } else {
                let t = ts[i];
                &self.prev_entries[self.prev_start[t] as usize..self.prev_start[t + 1] as usize]
            };
        }
        merge_entries(&lists[..n], &mut buf.merged);
        if has_h {
            horizon.push(hs);
        }
    }

    /// The lobes of one texel's merged entries, by the extraction's method.
    fn fit_texel(
        &self,
        merged: &[Entry],
        scratch: &mut Vec<(glam::DVec3, f64)>,
        lobes: &mut Vec<PhongLobe>,
    ) {
        match self.params.method {
            Method::Lobes => fit_lobes_with(
                merged,
                &self.params.fit,
                self.em_cap,
                self.thorough,
                self.smooth,
                scratch,
                lobes,
            ),
            Method::Baseline(b) => {
                let pts: Vec<(glam::DVec3, f64)> = merged.iter().map(|e| (e.mean(), e.w)).collect();
                lobes.clear();
                lobes.extend(crate::baseline::baseline_lobes(b, &pts));
            }
        }
    }
}

/// What a level hands to the next beside itself: its entries, flat, with per-texel offsets
/// `start` (empty when the next level does not read them), and its horizon statistics in
/// `f64` when the level keeps them in `f32`.
#[derive(Default)]
struct Carry {
    entries: Vec<Entry>,
    start: Vec<u32>,
    horizon: Option<Vec<HorizonStats>>,
}

/// A level being assembled from its rows, batch by batch.
struct LevelBuilder {
    carry: Carry,
    lobes: Lobes,
    lstart: Vec<u32>,
    horizon: Option<Horizons>,
    residual: Vec<(f64, f64)>,
}

impl LevelBuilder {
    /// Room for `texels` texels of at most `max_per_texel` lobes each (reserved, not touched),
    /// stored in `f32` when `compact`, with an `f64` copy of the horizon statistics when
    /// `carry_horizon`; or the failed allocation.
    fn new(
        texels: usize,
        max_per_texel: usize,
        has_horizon: bool,
        compact: bool,
        carry_horizon: bool,
    ) -> std::result::Result<LevelBuilder, meso_core::budget::AllocError> {
        use meso_core::budget::try_with_capacity;
        let mut lstart = try_with_capacity(texels + 1)?;
        lstart.push(0u32);
        let n = texels.saturating_mul(max_per_texel.max(1));
        Ok(LevelBuilder {
            carry: Carry {
                horizon: if carry_horizon {
                    Some(try_with_capacity(texels)?)
                } else {
                    None
                },
                ..Carry::default()
            },
            lobes: if compact {
                Lobes::F32(try_with_capacity(n)?)
            } else {
                Lobes::F64(try_with_capacity(n)?)
            },
            lstart,
            horizon: match (has_horizon, compact) {
                (false, _) => None,
                (true, true) => Some(Horizons::F32(try_with_capacity(texels)?)),
                (true, false) => Some(Horizons::F64(try_with_capacity(texels)?)),
            },
            residual: Vec::new(),
        })
    }

    /// Append a batch of rows (in order), freeing their buffers.
    fn extend(&mut self, rows: Vec<RowOut>) {
        for ro in rows {
            if !ro.ecount.is_empty() {
                let e = &mut self.carry;
                if e.start.is_empty() {
                    e.start.push(0u32);
                }
                for ec in &ro.ecount {
                    e.start.push(e.start.last().unwrap() + ec);
                }
                e.entries.extend_from_slice(&ro.entries);
            }
            for lc in &ro.lcount {
                self.lstart.push(self.lstart.last().unwrap() + lc);
            }
            self.lobes.extend_from_slice(&ro.lobes);
            if let Some(h) = &mut self.horizon {
                h.extend_from_slice(&ro.horizon);
            }
            if let Some(h) = &mut self.carry.horizon {
                h.extend_from_slice(&ro.horizon);
            }
            self.residual.extend_from_slice(&ro.residual);
        }
    }

    /// Level `k` (`cols × rows` texels) with its residual, and what the next level reads.
    fn finish(mut self, k: usize, cols: usize, rows: usize) -> (Level, Carry) {
        self.lobes.shrink_to_fit();
        let errs = &self.residual;
        let level = Level {
            cols,
            rows,
            span: 1usize << k,
            lobe_start: self.lstart,
            lobes: self.lobes,
            horizon: self.horizon,
            residual: Residual {
                mean: errs.iter().map(|e| e.0).sum::<f64>() / errs.len().max(1) as f64,
                max: errs.iter().map(|e| e.0).fold(0.0, f64::max),
                texels: errs.len() as u32,
                shading_mean: Some(
                    errs.iter().map(|e| e.1).sum::<f64>() / errs.len().max(1) as f64,
                ),
                shading_max: Some(errs.iter().map(|e| e.1).fold(0.0, f64::max)),
            },
        };
        (level, self.carry)
    }
}

/// Cells covered by texel `(r, c)` of a level with footprint side `span`.
#[must_use]
pub fn footprint_cells(
    facets: &FacetNormals,
    span: usize,
    r: usize,
    c: usize,
) -> (usize, usize, usize, usize) {
    footprint_bounds(facets.rows, facets.cols, span, r, c)
}

/// [`footprint_cells`] on a grid of `rows × cols` cells.
fn footprint_bounds(
    rows: usize,
    cols: usize,
    span: usize,
    r: usize,
    c: usize,
) -> (usize, usize, usize, usize) {
    (
        r * span,
        ((r + 1) * span).min(rows),
        c * span,
        ((c + 1) * span).min(cols),
    )
}
