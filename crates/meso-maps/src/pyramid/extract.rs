//! The extraction driver, [`extract`]: its parameter checks, the preparation of the facets and
//! horizon angles, and the levels fitted one after the other, each row batch in parallel on
//! rayon's pool, with progress reported by estimated work.

use super::builder::{Carry, LevelBuilder};
use super::cost::{extract_work, pyramid_texels};
use super::level_fit::{LevelFit, PrevHorizon, RowOut};
use super::{level_count, ExtractParams, Level, Progress, Pyramid, Source};
use crate::error::{MapError, Result};
use crate::facets::{FacetSource, NormalMode};
use crate::fit::MAX_LOBES;
use crate::heightmap::Border;
use crate::horizon::HorizonMap;
use rayon::prelude::*;

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
    // What the next level reads of this one, beside the level itself: when the level is
    // stored in f32, its horizon statistics in f64. (Entries are not carried: each texel
    // merges its footprint's facets again, level by level, `level_fit::texel_entries`.)
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
            k,
            cols,
            facets,
            horizon: if k == 0 { horizon.as_ref() } else { None },
            prev: levels.last(),
            prev_horizon,
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
