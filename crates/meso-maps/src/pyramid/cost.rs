//! The estimated cost of an extraction, known before it starts: its peak memory
//! ([`extract_bytes`], checked against the memory budget) and its work in cost units per part
//! and level ([`extract_work`], which weights [`super::Progress`] by time).

use super::{level_count, ExtractParams};
use crate::fit::MAX_LOBES;

/// Estimated cost units (≈ µs of one core) of computing the normals and horizon angles, per
/// height sample, and of a level-0 texel (no EM: its few entries are its lobes).
const PREP_WORK_PER_SAMPLE: u64 = 1;
/// Estimated cost units of one EM point of a texel's fit on a level fitted plainly.
const FIT_WORK_PLAIN: u64 = 4;
/// … on a level with the smoothed refinement (`FitParams::smooth_texels`).
const FIT_WORK_SMOOTH: u64 = 22;
/// … on such a level fitted from its children's lobes (`FitParams::smooth_from_children`: no
/// EM and no greedy start; level 5 of the 1024² Gaussian took ≈ 0.6× the time, 2026-12-04).
const FIT_WORK_SMOOTH_CHILDREN: u64 = 12;
/// Estimated cost units of a texel of a level fitted by merging its children's lobes
/// (`FitParams::merge_levels`; no EM points): ≈ 1.6 µs of one core a texel on level 1 (its
/// cells' facets merged), ≈ 2.7 µs on level 2 (16 children's lobes) of the 1024² Gaussian map
/// (2026-12-06).
const MERGE_WORK: u64 = 3;
/// … on a level fitted thoroughly (`FitParams::thorough_texels`).
const FIT_WORK_THOROUGH: u64 = 45;

/// Peak memory of [`extract`](super::extract) per level-0 cell with one normal per cell (bytes):
/// the normals, the level-0 fits (row buffers and their flat copies), the coarser levels, and
/// writing the map (the file's bytes and the reader's check of them). `meso extract` on rough
/// 16-bit maps measured 735–755 bytes per cell (peak RSS, triangles, 512² and 1024²;
/// docs/limits.md): with the per-sample term the estimate is 890, a 20% margin. Since the compact
/// levels (2026-12-02) the peak is 458 bytes per cell of heap at 256² and 354 of RSS at 1024², and
/// since the entries are no longer carried from level to level (2026-12-03) 339 bytes per cell of
/// heap at 256² (the map file's writing included) and 218 of RSS at 1024², so the estimate is a
/// looser upper bound (`crates/meso-maps/tests/extract_memory.rs` requires it to cover the heap
/// peak and stay within 3× of it).
pub const EXTRACT_BYTES_PER_CELL: u64 = 600;
/// Extra peak memory of [`extract`](super::extract) per cell for each further normal of the cell
/// (triangles: 2).
pub const EXTRACT_BYTES_PER_EXTRA_NORMAL: u64 = 250;
/// Peak memory of [`extract`](super::extract) per height sample: the eight horizon angles
/// (`u16`, [`crate::horizon::ANGLE_STEP`]: 16 bytes) and a margin (bytes). 40 until 2026-12-04,
/// when the four angles were `f64`; 12 until 2026-12-07, when there were four.
pub const EXTRACT_BYTES_PER_SAMPLE: u64 = 20;

/// The estimated peak memory (bytes) of [`extract`](super::extract) on a `cols × rows` cell grid
/// with `per_cell` normals per cell and `samples` height samples (0 for a normal map), including
/// writing the pyramid as a map file ([`Pyramid::write`](super::Pyramid::write)); the source map
/// itself is not counted.
#[must_use]
pub fn extract_bytes(cols: usize, rows: usize, per_cell: usize, samples: usize) -> u64 {
    let cells = (cols as u64).saturating_mul(rows as u64);
    let per =
        EXTRACT_BYTES_PER_CELL + EXTRACT_BYTES_PER_EXTRA_NORMAL * (per_cell.max(1) as u64 - 1);
    cells
        .saturating_mul(per)
        .saturating_add((samples as u64).saturating_mul(EXTRACT_BYTES_PER_SAMPLE))
}

/// Peak memory of the streamed extraction ([`extract_to_file`](super::extract_to_file)) per
/// level-0 cell (bytes), beside the horizon angles ([`EXTRACT_BYTES_PER_SAMPLE`]; 16 bytes a
/// sample are allocated, held until level 2 is done): level 2's horizon statistics in `f64`,
/// which level 3 reads (136 bytes a texel, a sixteenth of the cells: 8.5 bytes a cell; level 2
/// pools level 1's again from the samples, `level_fit::PrevHorizon::SampleBlocks`, so level 1
/// keeps none), the facets' entry-grid bins that every level reads (`level_fit::facet_bins`, 4
/// bytes a cell since 2026-12-04), level 2's lobes kept for the levels merged from them
/// (`level_fit::ChildLobes`: 11 bytes a lobe, 12 a texel, 4 lobes at most, reserved exactly:
/// ≤ 3.5 bytes a cell), and a margin.
///
/// History: 32 until 2026-12-07, when level 1 carried its statistics for level 2 (four
/// azimuths, 18 bytes a cell). Measured then (2026-12-03, `docs/benchmarks.md`, "Streamed
/// extraction"): 10.7 MB of heap at 256² against an estimate of 19.9 MB; peak RSS 123 / 288 /
/// 1 032 MB at 1024² / 2048² / 4096² (the generated map's 8 bytes a sample included) against
/// 136 / 423 / 1 450 MB estimated without it. `crates/meso-maps/tests/extract_memory.rs`
/// requires the estimate to cover the heap peak and stay within 4× of it.
pub const STREAM_BYTES_PER_CELL: u64 = 24;
/// Peak memory of the streamed extraction per texel of a row batch of level 0
/// ([`crate::format::BAND_ROWS`] rows, the widest batch): the batch's fitted rows, the band in
/// the level's precision, its streams' columns, byte planes and deflated bytes, and the band
/// checked back (≈ 450 bytes measured at 256² and 2048²).
pub const STREAM_BYTES_PER_BAND_TEXEL: u64 = 800;

/// The estimated peak memory (bytes) of the streamed extraction
/// ([`extract_to_file`](super::extract_to_file)) on a `cols × rows` cell grid with `per_cell`
/// normals per cell and `samples` height samples (0 for a normal map): no pyramid, but the
/// horizon angles ([`EXTRACT_BYTES_PER_SAMPLE`]), the previous level's horizon statistics and
/// one row batch of level 0 (the widest); the source map itself is not counted.
#[must_use]
pub fn extract_stream_bytes(cols: usize, rows: usize, per_cell: usize, samples: usize) -> u64 {
    let cells = (cols as u64).saturating_mul(rows as u64);
    let band = (cols as u64).saturating_mul(rows.min(crate::format::BAND_ROWS) as u64);
    let per_band_texel = STREAM_BYTES_PER_BAND_TEXEL
        + EXTRACT_BYTES_PER_EXTRA_NORMAL / 2 * (per_cell.max(1) as u64 - 1);
    cells
        .saturating_mul(STREAM_BYTES_PER_CELL)
        .saturating_add(band.saturating_mul(per_band_texel))
        .saturating_add((samples as u64).saturating_mul(EXTRACT_BYTES_PER_SAMPLE))
}

/// The estimated work of [`extract`](super::extract) on a `cols × rows` cell grid with `per_cell`
/// normals per cell (2 for triangles, 1 otherwise) and `samples` height samples (0 for a normal
/// map): the preparation (normals, horizons) and then each level, in cost units (≈ µs of one core).
/// A texel's fit costs its EM points (its footprint's facets, capped as [`extract`](super::extract)
/// caps them) × a factor of the level's fitting regime (plain, smoothed, thorough), measured per
/// level with `cargo run -p meso-maps --example level_times` on 64² to 256² Gaussian maps; merging
/// costs its entries (or, from `DENSE_LEVEL` on, its footprint's facets) and the residual its
/// entries. Used to weight
/// [`Progress`](super::Progress) by time rather than by texels (the coarse levels have few texels
/// and most of the time).
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
            if k > 0 && params.fit.smooth_from_children {
                FIT_WORK_SMOOTH_CHILDREN
            } else {
                FIT_WORK_SMOOTH
            }
        } else {
            FIT_WORK_PLAIN
        };
        // Merging: a texel of level 1 ≤ k < DENSE_LEVEL merges its footprint's entries again on
        // every level below it (`level_fit::texel_entries`), k linear merges of about its
        // entries each; above, one pass over its footprint's facets (`dense_entries`).
        let merges = if k >= super::level_fit::DENSE_LEVEL {
            facets / 8
        } else {
            (k as u64) * (entries / 4)
        };
        let fit = if super::level_fit::merges(params, k, texels) {
            t * (MERGE_WORK + if k == 1 { merges } else { 0 })
        } else {
            t * (1 + merges + per_point * points)
        };
        // The residual's histogram comes from the texel's entries.
        let residual = t.min(params.residual_texels.max(1) as u64) * entries / 4;
        out.push(fit + residual);
        c = c.div_ceil(2);
        r = r.div_ceil(2);
    }
    (prep, out)
}

/// Texels of all `levels` levels of a pyramid over `cols × rows` cells.
pub(super) fn pyramid_texels(cols: usize, rows: usize, levels: usize) -> u64 {
    super::level_sizes(cols, rows)
        .take(levels)
        .map(|(c, r)| (c * r) as u64)
        .sum()
}
