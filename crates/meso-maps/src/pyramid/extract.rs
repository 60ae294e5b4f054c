//! The extraction driver, [`extract`]: its parameter checks, the preparation of the facets and
//! horizon angles, and the levels fitted one after the other, each row batch in parallel on
//! rayon's pool, with progress reported by estimated work. The same driver streams the map
//! file instead of keeping the pyramid ([`extract_to_file`], [`extract_to_writer`]): each row
//! batch is written as a band of format 4 (`docs/map-format.md`) as soon as it is fitted.

use super::builder::{BandLevel, Carry, LevelBuilder};
use super::cost::{extract_work, pyramid_texels};
use super::level_fit::{ChildLobes, LevelFit, PrevHorizon, RowOut};
use super::{level_count, ExtractParams, Level, Method, Progress, Pyramid, Residual, Source};
use crate::error::{MapError, Result};
use crate::facets::{FacetSource, NormalMode};
use crate::fit::MAX_LOBES;
use crate::format::{check_band, write_band, write_level_end, Header, VERSION};
use crate::heightmap::Border;
use crate::horizon::HorizonMap;
use rayon::prelude::*;
use std::io::Write;
use std::path::Path;

/// Extract the pyramid of `source`: meso-normals, per-texel lobe fits at every level, horizon
/// statistics and per-level residuals. `progress` is called after every level (on the calling
/// thread). The work inside a level runs on rayon's pool.
pub fn extract(
    source: Source<'_>,
    params: &ExtractParams,
    progress: &mut dyn FnMut(Progress),
) -> Result<Pyramid> {
    let (h, levels) = run(source, params, progress, None)?;
    Ok(h.into_pyramid(levels))
}

/// What the streamed extraction reports of each level it wrote.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamedLevel {
    /// Texels along x.
    pub cols: usize,
    /// Texels along y.
    pub rows: usize,
    /// Lobes of the level.
    pub lobes: usize,
    /// Its fit residual.
    pub residual: Residual,
}

/// Extract the pyramid of `source` as [`extract`] does, writing it as a map file of format 4
/// (`docs/map-format.md`) at `path` as it goes: each row batch of each level is encoded,
/// checked as the reader will check it, written and dropped, so that memory holds the source,
/// the horizon angles (until level 2 is done), the previous level's horizon statistics and one
/// row batch, never the pyramid ([`super::extract_stream_bytes`]). The file is written
/// atomically (`meso_core::io::write_atomic_with`): on any error nothing is left and an
/// existing `path` is untouched. It reads back ([`Pyramid::read`]) as the pyramid [`extract`]
/// returns, written and read back, would.
///
/// # Errors
/// As [`extract`]; [`MapError::MapFormat`] when a value cannot be stored; [`MapError::Write`]
/// naming `path`.
pub fn extract_to_file(
    source: Source<'_>,
    params: &ExtractParams,
    path: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Vec<StreamedLevel>> {
    let mut failure = None;
    let mut levels = Vec::new();
    let written = meso_core::io::write_atomic_with(path, |w| {
        match extract_to_writer(source, params, w, path, progress) {
            Ok(l) => {
                levels = l;
                Ok(())
            }
            Err(MapError::Write { source, .. }) => Err(source),
            Err(e) => {
                failure = Some(e);
                Err(std::io::Error::other("the extraction failed"))
            }
        }
    });
    match (failure, written) {
        (Some(e), _) => Err(e),
        (None, Err(e)) => Err(MapError::Write {
            path: path.to_path_buf(),
            source: e,
        }),
        (None, Ok(())) => Ok(levels),
    }
}

/// [`extract_to_file`] into a writer (`path` only names the output in errors): the map file's
/// bytes in format 4, band by band. On error the writer holds a partial file.
///
/// # Errors
/// As [`extract_to_file`].
pub fn extract_to_writer(
    source: Source<'_>,
    params: &ExtractParams,
    w: &mut dyn Write,
    path: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Vec<StreamedLevel>> {
    let mut levels = Vec::new();
    run(
        source,
        params,
        progress,
        Some(Stream {
            w,
            path,
            levels: &mut levels,
        }),
    )?;
    Ok(levels)
}

/// Where the streamed extraction writes the levels it fits, band by band in format 4, and what
/// it reports of them.
struct Stream<'a> {
    w: &'a mut dyn Write,
    path: &'a Path,
    levels: &'a mut Vec<StreamedLevel>,
}

/// A level being fitted: assembled in memory or written band by band.
enum LevelOut {
    Memory(LevelBuilder),
    Stream(BandLevel),
}

/// The driver of [`extract`] and [`extract_to_writer`]: fits the levels of `source` one after
/// the other and keeps them (returned with the map file's header) or, given a `stream`, writes
/// them there (none returned).
fn run(
    source: Source<'_>,
    params: &ExtractParams,
    progress: &mut dyn FnMut(Progress),
    mut stream: Option<Stream<'_>>,
) -> Result<(Header, Vec<Level>)> {
    check_params(params)?;
    // Maps of faces and walls get more lobes a texel (`ExtractParams::walls_max_lobes`): from
    // here on the fit's `max_lobes` is the one this map gets, and the header records it.
    let params = &params.for_source(source);
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
            task: crate::pyramid::ProgressTask::Extract,
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
    // Every facet's bin of the entry grid, once (2 bytes a facet), for every level's merges.
    let bins = super::level_fit::facet_bins(&facets).map_err(|e| MapError::OutOfMemory {
        what: "the facets' bins".into(),
        source: e,
    })?;
    let nlev = level_count(facets.cols(), facets.rows());
    debug_assert_eq!(nlev, level_work.len());
    let header = Header {
        version: VERSION,
        width,
        height,
        cols: facets.cols(),
        rows: facets.rows(),
        texel_size,
        border,
        normal_mode: params.normal_mode,
        has_h: has_horizon,
        max_lobes: params.fit.max_lobes,
        nlev,
    };
    let write_err = |path: &Path, e: std::io::Error| {
        if e.kind() == std::io::ErrorKind::InvalidData {
            MapError::MapFormat {
                path: path.to_path_buf(),
                message: format!("not written: the map would be invalid ({e})"),
            }
        } else {
            MapError::Write {
                path: path.to_path_buf(),
                source: e,
            }
        }
    };
    if let Some(st) = &mut stream {
        header.write(st.w).map_err(|e| write_err(st.path, e))?;
    }
    let mut work_done = prep_work;
    report(0, 0, work_done);
    // The previous level: in memory the last of the levels; streamed, a level of its size
    // alone (its lobes are written), whose horizon statistics are always carried in `f64`.
    let mut stub: Option<Level> = None;
    let mut levels: Vec<Level> = Vec::with_capacity(if stream.is_some() { 0 } else { nlev });
    // What the next level reads of this one, beside the level itself: when the level is
    // stored in f32, its horizon statistics in f64. (Entries are not carried: each texel
    // merges its footprint's facets again, level by level, `level_fit::texel_entries`.)
    let mut prev = Carry::default();
    // The previous level's lobes, for a level that starts its smoothed refinement from them.
    let mut children: Option<ChildLobes> = None;
    let mut done = 0u64;
    let (mut cols, mut rows) = (facets.cols(), facets.rows());
    let (cols0, rows0) = (cols, rows);
    for (k, &work) in level_work.iter().enumerate() {
        let texels = cols * rows;
        let compact = texels >= params.compact_texels;
        let last = k + 1 == nlev;
        let prev_level = match &stream {
            None => levels.last(),
            Some(_) => stub.as_ref(),
        };
        let prev_horizon = match (prev_level, &horizon) {
            (None, _) => PrevHorizon::None,
            (Some(_), Some(map)) if k == 1 => PrevHorizon::Samples(map),
            (Some(_), Some(map)) if k == 2 => PrevHorizon::SampleBlocks {
                map,
                rows: rows0,
                cols: cols0,
            },
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
            prev: prev_level,
            bins: &bins,
            prev_horizon,
            residual_stride: texels.div_ceil(params.residual_texels.max(1)).max(1),
            params,
            em_cap: (params.fit.level_em_points / texels.max(1))
                .clamp(64, params.fit.max_em_points.max(64)),
            thorough: texels <= params.fit.thorough_texels,
            smooth: texels <= params.fit.smooth_texels,
            merged: super::level_fit::merges(params, k, texels),
            children: children.as_ref(),
        };
        // This level's lobes are kept for the next one when that one fits its smoothed levels
        // from its children's lobes (`FitParams::smooth_from_children`; ≤ 4 × `smooth_texels`
        // texels, a few hundred KB).
        let (next_cols, next_rows) = (cols.div_ceil(2), rows.div_ceil(2));
        let next_smooth =
            params.fit.smooth_exponent > 0.0 && next_cols * next_rows <= params.fit.smooth_texels;
        let mut next_children = (!last
            && params.method == Method::Lobes
            // Streamed, level 2 fits level 1's lobes again rather than keep them (≈ 23 bytes a
            // cell: the 4 GiB of an 8192² map's budget would not hold them).
            && ((k >= 1
                && !(k == 1 && stream.is_some())
                && super::level_fit::merges(params, k + 1, next_cols * next_rows))
                || (params.fit.smooth_from_children && next_smooth)))
            .then(|| ChildLobes {
                cols,
                rows,
                keep_lobes: stream.is_some(),
                ..Default::default()
            });
        let max_per_texel = params
            .fit
            .max_lobes
            .min(per_cell.saturating_mul(1usize << (2 * k.min(8))));
        if let Some(ch) = &mut next_children {
            // Exactly what the level can need (vectors grown by doubling could take twice it;
            // `STREAM_BYTES_PER_CELL` counts this).
            let reserve =
                |ch: &mut ChildLobes| -> std::result::Result<(), meso_core::budget::AllocError> {
                    meso_core::budget::try_reserve(&mut ch.weight, texels)?;
                    if ch.keep_lobes {
                        meso_core::budget::try_reserve(&mut ch.start, texels + 1)?;
                        meso_core::budget::try_reserve(&mut ch.lobes, texels * max_per_texel)?;
                    }
                    Ok(())
                };
            reserve(ch).map_err(oom)?;
        }
        // Level 2 pools level 1's statistics again from the samples (`SampleBlocks`): from
        // level 2 on, a level carries them for the next.
        let carry_horizon = has_horizon && !last && k > 1;
        let mut acc = match &stream {
            None => LevelOut::Memory(
                LevelBuilder::new(
                    texels,
                    max_per_texel,
                    has_horizon,
                    compact,
                    compact && carry_horizon,
                )
                .map_err(oom)?,
            ),
            Some(_) => LevelOut::Stream(BandLevel::new(carry_horizon)),
        };
        // Rows in batches: each batch's rows fitted in parallel and appended at once (or
        // written as a band), so that no more than a batch's row buffers exist beside the level.
        for r0 in (0..rows).step_by(ROW_BATCH) {
            let batch: Vec<RowOut> = (r0..(r0 + ROW_BATCH).min(rows))
                .into_par_iter()
                .map(|r| ctx.row(r))
                .collect();
            if let Some(ch) = &mut next_children {
                ch.extend(&batch);
            }
            match (&mut acc, &mut stream) {
                (LevelOut::Memory(acc), _) => acc.extend(batch),
                (LevelOut::Stream(acc), Some(Stream { w, path, .. })) => {
                    let band = acc.band(batch, (k, cols), has_horizon, compact);
                    let mut chunk = Vec::new();
                    write_band(&mut chunk, k, r0, &band, has_horizon)
                        .map_err(|e| write_err(path, e))?;
                    drop(band);
                    check_band(path, &header, k, (cols, rows), r0, &chunk).map_err(|e| {
                        MapError::MapFormat {
                            path: path.to_path_buf(),
                            message: format!("not written: the map would be invalid ({e})"),
                        }
                    })?;
                    w.write_all(&chunk).map_err(|e| write_err(path, e))?;
                }
                (LevelOut::Stream(_), None) => unreachable!("a streamed level has a stream"),
            }
        }
        match (acc, &mut stream) {
            (LevelOut::Memory(acc), _) => {
                let (level, carry) = acc.finish(k, cols, rows);
                levels.push(level);
                prev = carry;
            }
            (LevelOut::Stream(acc), Some(Stream { w, path, levels })) => {
                let residual = super::builder::residual(&acc.residual);
                write_level_end(*w, k, acc.lobes, &residual).map_err(|e| write_err(path, e))?;
                levels.push(StreamedLevel {
                    cols,
                    rows,
                    lobes: acc.lobes,
                    residual,
                });
                stub = Some(Level {
                    cols,
                    rows,
                    span: 1usize << k,
                    lobe_start: Vec::new(),
                    lobes: crate::compact::Lobes::default(),
                    horizon: None,
                    residual,
                });
                prev = acc.carry;
            }
            (LevelOut::Stream(_), None) => unreachable!("a streamed level has a stream"),
        }
        if k >= 2 {
            // Levels 1 and 2 have read the samples' horizon angles.
            horizon = None;
        }
        children = next_children;
        done += texels as u64;
        work_done += work;
        report(k + 1, done, if last { work_total } else { work_done });
        cols = cols.div_ceil(2);
        rows = rows.div_ceil(2);
    }
    if let Some(st) = &mut stream {
        st.w.flush().map_err(|e| write_err(st.path, e))?;
    }
    Ok((header, levels))
}

/// The levels of a pyramid over `cols × rows` level-0 cells that [`extract`] fits by merging
/// their children's lobes (`FitParams::merge_levels`; none with another method than
/// [`Method::Lobes`]), in order: what `meso extract` reports.
#[must_use]
pub fn merged_levels(cols: usize, rows: usize, params: &ExtractParams) -> Vec<usize> {
    super::level_sizes(cols, rows)
        .take(level_count(cols, rows))
        .enumerate()
        .filter(|&(k, (c, r))| super::level_fit::merges(params, k, c * r))
        .map(|(k, _)| k)
        .collect()
}

/// Rows of a level fitted in parallel before they are appended to the level.
const ROW_BATCH: usize = crate::format::BAND_ROWS;

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::{AXIS_MIN_Z, ETA_MAX, ETA_MIN};

    /// The coarse levels fitted from their children's lobes (`FitParams::smooth_from_children`)
    /// on a 256² Gaussian surface: every lobe in the fit's bounds (axis at z ≥ `AXIS_MIN_Z`,
    /// exponent in `[ETA_MIN, ETA_MAX]`), at most `max_lobes` a texel, weights summing to 1; the
    /// levels below the smoothed ones identical to the default fit's; and each smoothed level's
    /// mean shading error within 3 % of the default fit's (measured: within ±1 %, docs/
    /// benchmarks.md, "Extraction speed, 2026-12-04 (evening)").
    #[test]
    fn coarse_levels_from_children_keep_bounds_and_shading() {
        let map = crate::fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
        let base = ExtractParams::default();
        let mut from = ExtractParams::default();
        from.fit.smooth_from_children = true;
        let a = extract(Source::Heights(&map), &base, &mut |_| {}).unwrap();
        let b = extract(Source::Heights(&map), &from, &mut |_| {}).unwrap();
        assert_eq!(a.levels.len(), b.levels.len());
        let mut smoothed = 0;
        for (k, (la, lb)) in a.levels.iter().zip(&b.levels).enumerate() {
            for t in 0..lb.texels() {
                let (s, e) = (lb.lobe_start[t] as usize, lb.lobe_start[t + 1] as usize);
                assert!(e > s && e - s <= from.fit.max_lobes, "level {k} texel {t}");
                let mut w = 0.0;
                for l in lb.lobes.range(s, e) {
                    assert!(l.axis.z >= AXIS_MIN_Z - 1e-6, "level {k}: axis {}", l.axis);
                    assert!((ETA_MIN..=ETA_MAX).contains(&l.exponent), "level {k}");
                    w += l.weight;
                }
                assert!((w - 1.0).abs() < 1e-5, "level {k} texel {t}: weights {w}");
            }
            let (ra, rb) = (la.residual, lb.residual);
            if k == 0 || la.texels() > base.fit.smooth_texels {
                assert_eq!(la.lobes, lb.lobes, "level {k} is not a smoothed level");
                continue;
            }
            smoothed += 1;
            let (sa, sb) = (ra.shading_mean.unwrap(), rb.shading_mean.unwrap());
            println!("level {k}: shading {sa:.6} default, {sb:.6} from the children");
            assert!(sb <= 1.03 * sa, "level {k}: shading {sb} against {sa}");
        }
        assert!(smoothed >= 5, "{smoothed} smoothed levels");
    }

    /// Levels merged from their children (`FitParams::merge_levels`) against every level's own
    /// fit (`MergeLevels::None`), on three 256² maps (a gentle and a steep Gaussian surface and
    /// a weave): every lobe in the fit's bounds, at most `max_lobes` a texel, weights summing to
    /// 1; the levels `Plain` does not merge (level 0, the smoothed ones) identical to the own
    /// fit's; and each merged level's mean shading error (the NDF of the texel's own facets
    /// seen through the kernel: the truth the fit never saw) within 1.2× + 0.2 points of peak
    /// of the own fit's, with at most 0.6 more lobes per texel (measured: the tables of
    /// docs/heightmaps.md, "Levels merged from their children").
    #[test]
    fn merged_levels_keep_bounds_and_the_own_fits_shading() {
        use crate::fit::MergeLevels;
        let maps = [
            (
                "gaussian",
                crate::fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap(),
            ),
            (
                "steep gaussian",
                crate::fixtures::gaussian(256, 1.5, 1.5, 4, 1.0).unwrap(),
            ),
            ("woven", crate::fixtures::woven(256, 16, 0.1, 0.05).unwrap()),
        ];
        for (name, map) in &maps {
            let mut own = ExtractParams::default();
            own.fit.merge_levels = MergeLevels::None;
            let a = extract(Source::Heights(map), &own, &mut |_| {}).unwrap();
            let b = extract(Source::Heights(map), &ExtractParams::default(), &mut |_| {}).unwrap();
            let mut merged = 0;
            for (k, (la, lb)) in a.levels.iter().zip(&b.levels).enumerate() {
                for t in 0..lb.texels() {
                    let (s, e) = (lb.lobe_start[t] as usize, lb.lobe_start[t + 1] as usize);
                    assert!(
                        e > s && e - s <= 4,
                        "{name} level {k} texel {t}: {} lobes",
                        e - s
                    );
                    let mut w = 0.0;
                    for l in lb.lobes.range(s, e) {
                        assert!(
                            l.axis.z >= AXIS_MIN_Z - 1e-6,
                            "{name} level {k}: {}",
                            l.axis
                        );
                        assert!(
                            (ETA_MIN..=ETA_MAX).contains(&l.exponent),
                            "{name} level {k}"
                        );
                        w += l.weight;
                    }
                    assert!(
                        (w - 1.0).abs() < 1e-5,
                        "{name} level {k} texel {t}: weights {w}"
                    );
                }
                if k == 0 || la.texels() <= own.fit.smooth_texels {
                    assert_eq!(la.lobes, lb.lobes, "{name}: level {k} is not merged");
                    continue;
                }
                merged += 1;
                let (sa, sb) = (
                    la.residual.shading_mean.unwrap(),
                    lb.residual.shading_mean.unwrap(),
                );
                let per = |l: &Level| l.lobes.len() as f64 / l.texels() as f64;
                println!(
                    "{name} level {k}: shading {:.3} % own, {:.3} % merged; lobes per texel {:.2} / {:.2}",
                    100.0 * sa,
                    100.0 * sb,
                    per(la),
                    per(lb)
                );
                assert!(
                    sb <= 1.2 * sa + 0.002,
                    "{name} level {k}: shading {sb} against {sa}"
                );
                assert!(per(lb) <= per(la) + 0.6, "{name} level {k}: lobes");
            }
            assert!(merged >= 2, "{name}: {merged} merged levels");
        }
    }

    /// The merged levels read their children's lobes rounded to `f32` whether the level below
    /// is kept in `f32` or in `f64` in memory, or streamed: the same fits every way (levels all
    /// `f32` against all `f64`: the `f32` values the `f64` ones rounded), and the streamed map
    /// file's bytes those of the pyramid in memory, for `Plain` and `All`.
    #[test]
    fn merged_levels_are_the_same_in_f32_in_f64_and_streamed() {
        use crate::compact::Lobe32;
        use crate::fit::MergeLevels;
        let map = crate::fixtures::gaussian(128, 3.0, 0.15, 11, 0.1).unwrap();
        for merge in [MergeLevels::Plain, MergeLevels::All] {
            let mut p32 = ExtractParams::default();
            p32.fit.merge_levels = merge;
            p32.fit.smooth_texels = 64;
            p32.compact_texels = 0;
            let mut p64 = p32.clone();
            p64.compact_texels = usize::MAX;
            let a = extract(Source::Heights(&map), &p32, &mut |_| {}).unwrap();
            let b = extract(Source::Heights(&map), &p64, &mut |_| {}).unwrap();
            for (k, (la, lb)) in a.levels.iter().zip(&b.levels).enumerate() {
                assert_eq!(la.lobe_start, lb.lobe_start, "{merge:?} level {k}");
                for i in 0..la.lobes.len() {
                    let (x, y) = (
                        la.lobes.get(i),
                        Lobe32::from_phong(&lb.lobes.get(i)).to_phong(),
                    );
                    assert_eq!(x, y, "{merge:?} level {k} lobe {i}");
                }
            }
            let mut streamed = Vec::new();
            extract_to_writer(
                Source::Heights(&map),
                &p32,
                &mut streamed,
                Path::new("g.map"),
                &mut |_| {},
            )
            .unwrap();
            assert!(
                streamed == a.to_bytes(),
                "{merge:?}: streamed and in-memory bytes differ"
            );
        }
    }
}
