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
//!
//! This file holds the public types (the source, the parameters, progress, levels and the
//! pyramid) and the level geometry ([`level_count`], [`footprint_cells`]). The rest, by concern:
//! the per-texel queries and the `f32` compaction of levels and pyramids in `access.rs`; the
//! summary for `meso map info` ([`PyramidInfo`]) in `info.rs`; the estimated memory and work of
//! an extraction ([`extract_bytes`], [`extract_work`]) in `cost.rs`; the driver ([`extract`]:
//! parameter checks, level by level, rows in batches) in `extract.rs`; fitting one row of a
//! level (merging the children's entries and horizon statistics, fitting, sampled residuals) in
//! `level_fit.rs`; assembling a level from its rows into `f64` or `f32` storage, and what it
//! hands to the next level, in `builder.rs`; what each lobe stands for, handed down from the
//! level-0 normals (its share of its texel's projected area and the horizon statistics of the
//! cells it stands for: [`lobe_stats`]), in `shares.rs`.

mod access;
mod builder;
mod cost;
mod extract;
mod info;
mod level_fit;
mod shares;

pub use cost::{
    extract_bytes, extract_stream_bytes, extract_work, EXTRACT_BYTES_PER_CELL,
    EXTRACT_BYTES_PER_EXTRA_NORMAL, EXTRACT_BYTES_PER_SAMPLE, STREAM_BYTES_PER_BAND_TEXEL,
    STREAM_BYTES_PER_CELL,
};
pub use extract::{extract, extract_to_file, extract_to_writer, merged_levels, StreamedLevel};
pub use info::{LevelInfo, PyramidInfo};
pub use shares::{
    lobe_stats, lobe_stats_by_cell, lobe_stats_by_cell_reporting, peak_projected_area,
    rect_lobe_stats_by_cell, texel_lobe_stats, LevelStats, LobeStat, LobeStats, JOINT_CELLS_SIDE,
    JOINT_FROM_LEVEL,
};

use crate::compact::{Horizons, Lobes, COMPACT_TEXELS};
use crate::facets::{FacetNormals, NormalMode};
use crate::fit::FitParams;
use crate::heightmap::{Border, HeightMap, NormalMap};

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
    /// The most lobes a texel of a map of *faces and walls* is fitted with, in place of
    /// `fit.max_lobes` when larger: a map at least [`WALL_SHARE`] of whose projected area is
    /// more than 45° from +z and at least [`FACE_SHARE`] within 10° of it ([`relief_shares`]:
    /// architecture, bricks, stones, terraced relief). Default [`WALLS_MAX_LOBES`]; 0 (or any
    /// value up to `fit.max_lobes`) keeps `fit.max_lobes` on every map, as
    /// [`ExtractParams::with_max_lobes`] does for a K the user asked for. See
    /// [`ExtractParams::max_lobes_for`].
    pub walls_max_lobes: usize,
}

/// The default [`ExtractParams::walls_max_lobes`]: six lobes a texel on maps of faces and
/// walls. Measured (docs/heightmaps.md, "Six lobes on maps of faces and walls"): the steep
/// facade's coarse texels hold its flat tops and its walls facing four ways, five groups of
/// normals, which four lobes merge; with six, its far views under a light behind the viewer
/// went from 1.2–3.2× the bump-mapped truth to 1.07–1.14× (GGX α = 0.1), and its 90-scene
/// sweep's error fell for every facet tried (GGX α = 0.05, 0.1, 0.2, Lambert); eight lobes
/// were no closer. A continuous relief (a Gaussian surface, even a steep one) gained nothing
/// and is not counted.
pub const WALLS_MAX_LOBES: usize = 6;

/// The share of a map's projected area more than 45° from +z from which it has walls
/// ([`ExtractParams::walls_max_lobes`]).
pub const WALL_SHARE: f64 = 0.1;

/// The share of a map's projected area within 10° of +z from which it has faces
/// ([`ExtractParams::walls_max_lobes`]).
pub const FACE_SHARE: f64 = 0.1;

impl ExtractParams {
    /// These parameters with at most `k` lobes a texel on every map, of faces and walls or
    /// not (`fit.max_lobes = k`, [`ExtractParams::walls_max_lobes`] off): for a K the user
    /// asked for.
    #[must_use]
    pub fn with_max_lobes(mut self, k: usize) -> ExtractParams {
        self.fit.max_lobes = k;
        self.walls_max_lobes = 0;
        self
    }

    /// The most lobes a texel of `source` is fitted with: `fit.max_lobes`, or
    /// [`ExtractParams::walls_max_lobes`] if larger and the map is one of faces and walls
    /// ([`relief_shares`] at least [`FACE_SHARE`] and [`WALL_SHARE`]). Capped at
    /// [`crate::fit::MAX_LOBES`].
    #[must_use]
    pub fn max_lobes_for(&self, source: Source<'_>) -> usize {
        let k = self.fit.max_lobes;
        if self.walls_max_lobes > k {
            let (faces, walls) = relief_shares(source, self.normal_mode);
            if faces >= FACE_SHARE && walls >= WALL_SHARE {
                return self.walls_max_lobes.min(crate::fit::MAX_LOBES);
            }
        }
        k
    }

    /// These parameters as they extract `source`: `fit.max_lobes` the one it gets
    /// ([`ExtractParams::max_lobes_for`]), on every map from here on.
    #[must_use]
    pub fn for_source(&self, source: Source<'_>) -> ExtractParams {
        self.clone().with_max_lobes(self.max_lobes_for(source))
    }
}

/// The shares of `source`'s projected area (level 0's facets, with `normal_mode` for a height
/// map) whose normal is within 10° of +z (faces) and more than 45° from it (walls), each in
/// `[0, 1]`; `(0, 0)` for a map without facets.
#[must_use]
pub fn relief_shares(source: Source<'_>, normal_mode: NormalMode) -> (f64, f64) {
    use rayon::prelude::*;
    let facets = match source {
        Source::Heights(m) => crate::facets::FacetSource::Heights(m, normal_mode),
        Source::Normals(n) => crate::facets::FacetSource::Normals(n),
    };
    let face_cos = 10f64.to_radians().cos();
    let (faces, walls, total) = (0..facets.rows())
        .into_par_iter()
        .map(|r| {
            let mut acc = (0.0, 0.0, 0.0);
            for c in 0..facets.cols() {
                let (f, n) = facets.cell(r, c);
                // The facets' weights are their areas: projected, `w·m_z`.
                for &(m, w) in &f[..n] {
                    let p = w * m.z;
                    acc.2 += p;
                    if m.z > face_cos {
                        acc.0 += p;
                    } else if m.z < std::f64::consts::FRAC_1_SQRT_2 {
                        acc.1 += p;
                    }
                }
            }
            acc
        })
        .reduce(|| (0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2));
    if total > 0.0 {
        (faces / total, walls / total)
    } else {
        (0.0, 0.0)
    }
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
            walls_max_lobes: WALLS_MAX_LOBES,
        }
    }
}

/// What a [`Progress`] report is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ProgressTask {
    /// Fitting a pyramid ([`extract`]): work in estimated cost units.
    #[default]
    Extract,
    /// Marching the horizons of a facet NDF (`MapsResolver`'s `represent = "facets"`): work in
    /// rows of cells, `levels` 0.
    Facets,
    /// Reading and checking a map file ([`Pyramid::read_compact_reporting`]): work in bytes of
    /// its levels, texels in the levels' rows read.
    Read,
    /// Summing what each lobe of a pyramid stands for, the renderer's tables
    /// ([`lobe_stats_by_cell_reporting`]): every coarse level visits every level-0 cell, so
    /// work and texels count the level-0 cells visited (twice at the levels whose every cell
    /// also gives a joint horizon distribution, which cost about that much more).
    Tables,
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
    /// What is being done: fitting a pyramid, marching a facet NDF's horizons or reading a
    /// map file.
    pub task: ProgressTask,
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
    /// or, on big levels, `f32` ([`crate::compact`]); read as
    /// [`PhongLobe`](meso_core::ndf::PhongLobe)s.
    pub lobes: Lobes,
    /// Horizon statistics per texel (height maps only), in `f64` or `f32` like the lobes.
    pub horizon: Option<Horizons>,
    /// Fit residual.
    pub residual: Residual,
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

/// Number of levels of a `cols × rows` cell grid (level 0 … the first 1×1 level).
#[must_use]
pub fn level_count(cols: usize, rows: usize) -> usize {
    level_sizes(cols, rows).count()
}

/// The `(cols, rows)` of every level of a `cols × rows` cell grid, level 0 first: each level
/// halves the one below rounding up (a texel covers 2 × 2 texels below, fewer at an odd edge),
/// down to the first 1 × 1 level.
pub fn level_sizes(cols: usize, rows: usize) -> impl Iterator<Item = (usize, usize)> {
    std::iter::successors(Some((cols, rows)), |&(c, r)| {
        (c > 1 || r > 1).then(|| (c.div_ceil(2), r.div_ceil(2)))
    })
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
