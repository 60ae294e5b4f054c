//! Fitting one row of a level: each texel's entries (a level-0 cell's facets merged per bin,
//! or the merged entries of its up to four children), its horizon statistics merged from its
//! children's, its lobes by the extraction's method, and the NDF residual and shading error of
//! the texels the level samples.
//!
//! A texel's entries are computed from the facets of its footprint: below [`DENSE_LEVEL`] depth
//! first, the entries of each cell merged four children at a time (a linear k-way merge) up the
//! levels below; from [`DENSE_LEVEL`] on in one pass over the footprint's facets onto a dense
//! array of the entry grid. The same entries either way, up to the order of the sums. No
//! level's entries are kept: they were ≈ 80 bytes a cell per level, two levels of them alive at
//! once (docs/benchmarks.md, "Extraction memory: entries recomputed", and "Extraction speed:
//! entries in linear time").
//! Each facet's bin of the entry grid is computed once for the whole extraction
//! ([`facet_bins`], 2 bytes a facet) and read by every level's merges.

use super::{footprint_bounds, ExtractParams, Level, Method};
use crate::compact::{Horizons, Lobe32, LobeCode, Lobes};
use crate::facets::FacetSource;
use crate::fit::{
    entries_l2_error, exact_lobes, fit_lobes_seeded, merge_entries, merge_sorted_entries, Entry,
    KChoice, MergeLevels, ENTRY_GRID_RES,
};
use crate::horizon::{HorizonMap, HorizonStats};
use meso_core::ndf::PhongLobe;
use rayon::prelude::*;

/// One row of texels of a level, as [`LevelFit::row`] fits it.
pub(super) struct RowOut {
    pub(super) lobes: Vec<PhongLobe>,
    pub(super) lcount: Vec<u32>,
    pub(super) horizon: Vec<HorizonStats>,
    /// The NDF residual and shading error of the row's texels that the level's residual
    /// samples, in order.
    pub(super) residual: Vec<(f64, f64)>,
    /// Each texel's total facet weight (the sum of its entries' weights).
    pub(super) weight: Vec<f64>,
}

/// What the next level reads of a level's lobes when it fits from its children's lobes
/// (merged, [`merges`], or as the smoothed refinement's start, [`fit_lobes_seeded`]): each
/// texel's total facet weight (8 bytes a texel) and, when the level is not kept in memory (the
/// streamed extraction), its lobes as a map file codes them ([`child_lobe`], [`LobeCode`]: 11
/// bytes a lobe). In memory the next level reads the lobes from the level itself, coded the
/// same way, so that both extractions give the same pyramid.
#[derive(Default)]
pub(super) struct ChildLobes {
    /// Texels along x.
    pub(super) cols: usize,
    /// Texels along y.
    pub(super) rows: usize,
    /// Whether the lobes are kept here (`start`, `lobes`) rather than read from the level.
    pub(super) keep_lobes: bool,
    /// `start[t]..start[t + 1]` indexes `lobes` for texel `t`.
    pub(super) start: Vec<u32>,
    /// Each lobe coded ([`child_lobe`]).
    pub(super) lobes: Vec<LobeCode>,
    /// Each texel's total facet weight.
    pub(super) weight: Vec<f64>,
}

impl ChildLobes {
    /// Append a batch of rows (in order).
    pub(super) fn extend(&mut self, rows: &[RowOut]) {
        for row in rows {
            self.weight.extend_from_slice(&row.weight);
            if !self.keep_lobes {
                continue;
            }
            if self.start.is_empty() {
                self.start.push(0);
            }
            let mut at = *self.start.last().unwrap_or(&0);
            for &n in &row.lcount {
                at += n;
                self.start.push(at);
            }
            self.lobes
                .extend(row.lobes.iter().map(|l| LobeCode::from_phong(&rounded(l))));
        }
    }

    /// The lobes of the (up to four) children of texel `(r, c)` of the next level into `out`
    /// (cleared first), each weight times its child's share of their total weight, each lobe
    /// as [`child_lobe`] reads it; read from here or, when not kept, from `level` (the level
    /// these are the weights of). Returns the children's total weight.
    fn children_of(
        &self,
        level: Option<&Level>,
        r: usize,
        c: usize,
        out: &mut Vec<PhongLobe>,
    ) -> f64 {
        out.clear();
        let mut total = 0.0;
        for cr in 2 * r..(2 * r + 2).min(self.rows) {
            for cc in 2 * c..(2 * c + 2).min(self.cols) {
                total += self.weight[cr * self.cols + cc];
            }
        }
        if total <= 0.0 {
            return 0.0;
        }
        for cr in 2 * r..(2 * r + 2).min(self.rows) {
            for cc in 2 * c..(2 * c + 2).min(self.cols) {
                let t = cr * self.cols + cc;
                let share = self.weight[t] / total;
                let scaled = |l: PhongLobe| PhongLobe {
                    weight: l.weight * share,
                    ..l
                };
                match level {
                    Some(lv) if !self.keep_lobes => {
                        let (a, b) = (lv.lobe_start[t] as usize, lv.lobe_start[t + 1] as usize);
                        let f32_level = matches!(lv.lobes, Lobes::F32(_));
                        out.extend(lv.lobes.range(a, b).map(|l| {
                            // An `f32` level's lobe is the rounded one already.
                            let r = if f32_level { l } else { rounded(&l) };
                            scaled(LobeCode::from_phong(&r).to_phong())
                        }));
                    }
                    _ => {
                        let (a, b) = (self.start[t] as usize, self.start[t + 1] as usize);
                        out.extend(self.lobes[a..b].iter().map(|l| scaled(l.to_phong())));
                    }
                }
            }
        }
        total
    }
}

/// A lobe `l` (as fitted, `f64`) rounded to `f32` as a compact level keeps it ([`Lobe32`]).
fn rounded(l: &PhongLobe) -> PhongLobe {
    Lobe32::from_phong(l).to_phong()
}

/// A fitted lobe as the next level reads it when fitting from its children: rounded to `f32`
/// ([`rounded`]) and coded as a map file codes it ([`LobeCode`]: axis to 20-bit octahedral
/// codes, exponent to its 16-bit code), so that the in-memory and streamed extractions read
/// the very same values and the streamed one keeps 11 bytes a lobe.
fn child_lobe(l: &PhongLobe) -> PhongLobe {
    LobeCode::from_phong(&rounded(l)).to_phong()
}

/// Where a level reads the horizon statistics of its children, in `f64`.
#[derive(Clone, Copy)]
pub(super) enum PrevHorizon<'a> {
    /// No horizon statistics (a normal map), or level 0 (which reads the samples' angles).
    None,
    /// Level 1: level 0's statistics are the samples' own ([`HorizonMap::sample_stats`]).
    Samples(&'a HorizonMap),
    /// Level 2: level 1's statistics pooled again from the samples, each level-1 texel's
    /// 2 × 2 as level 1 pooled them (the very values, bit for bit), so that level 1 keeps no
    /// `f64` copy of its statistics (136 bytes a texel since the eight azimuths: 34 bytes a
    /// cell) while the samples' angles are still held. `rows` × `cols`: level 0's.
    SampleBlocks {
        map: &'a HorizonMap,
        rows: usize,
        cols: usize,
    },
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
            PrevHorizon::SampleBlocks { map, rows, cols } => {
                let mut s = HorizonStats::default();
                for cr in 2 * r..(2 * r + 2).min(*rows) {
                    for cc in 2 * c..(2 * c + 2).min(*cols) {
                        s.merge(&map.sample_stats(cr, cc));
                    }
                }
                Some(s)
            }
            PrevHorizon::Stats(v) => Some(v[r * cols + c]),
            PrevHorizon::Level(h) => Some(h.get(r * cols + c)),
        }
    }
}

/// Whether level `k` of `texels` texels is fitted by merging its children's lobes
/// ([`crate::FitParams::merge_levels`]; a level gets the smoothed refinement when
/// `smooth_exponent` is positive and it has at most `smooth_texels` texels): never level 0,
/// only with [`Method::Lobes`],
/// and not with the K chain or K by the shading error (their candidates are the texel's own
/// fits). The one rule the extraction, its cost estimate and its report read.
pub(super) fn merges(params: &ExtractParams, k: usize, texels: usize) -> bool {
    let fit = &params.fit;
    let refined = fit.smooth_exponent > 0.0 && texels <= fit.smooth_texels;
    k >= 1
        && params.method == Method::Lobes
        && !fit.k_chain
        && fit.k_choice == KChoice::Objective
        && match fit.merge_levels {
            MergeLevels::None => false,
            MergeLevels::Plain => !refined,
            MergeLevels::All => true,
        }
}

/// What fitting a level reads: the facets (levels 0 and 1) or the previous level's merged
/// entries, the previous level's horizon statistics, and the fit's settings for this level's
/// size.
pub(super) struct LevelFit<'a> {
    /// The level's index (0: the cells themselves).
    pub(super) k: usize,
    pub(super) cols: usize,
    pub(super) facets: FacetSource<'a>,
    /// The samples' horizon angles (level 0 only).
    pub(super) horizon: Option<&'a HorizonMap>,
    pub(super) prev: Option<&'a Level>,
    /// Every facet's bin of the entry grid ([`facet_bins`]): the merges of every level read
    /// them instead of binning each facet again.
    pub(super) bins: &'a [u16],
    pub(super) prev_horizon: PrevHorizon<'a>,
    /// Texels `0, s, 2s, …` get their NDF residual measured.
    pub(super) residual_stride: usize,
    pub(super) params: &'a ExtractParams,
    pub(super) em_cap: usize,
    pub(super) thorough: bool,
    pub(super) smooth: bool,
    /// Whether the level is fitted by merging its children's lobes ([`merges`]).
    pub(super) merged: bool,
    /// The previous level's lobes, when this level starts its smoothed refinement from its
    /// children's lobes ([`fit_lobes_seeded`]).
    pub(super) children: Option<&'a ChildLobes>,
}

/// Slots of [`facet_bins`] per cell (a cell has at most two facets; the second slot of a cell of
/// one facet is unused).
const BIN_SLOTS: usize = 2;

// The entry grid's bins fit the cache's `u16`.
const _: () = assert!(ENTRY_GRID_RES * ENTRY_GRID_RES <= 1 << 16);

/// The bin of the entry grid ([`Entry::new`]'s) of every facet of `facets`, [`BIN_SLOTS`] a cell
/// in row-major order (2 bytes a facet: 4 MB at 1024² triangles): computed once, in parallel,
/// and read by every level's merges (`cell_entries`, `dense_entries`) instead of an `atan` per
/// facet per level (the entries recomputed from the facets level by level, docs/benchmarks.md,
/// "Extraction speed (2026-12-04)"). The same bins, so the same entries.
///
/// # Errors
/// [`meso_core::budget::AllocError`] when the memory is not there.
pub(super) fn facet_bins(
    facets: &FacetSource<'_>,
) -> Result<Vec<u16>, meso_core::budget::AllocError> {
    let cols = facets.cols();
    let mut bins = meso_core::budget::try_vec(0u16, facets.rows() * cols * BIN_SLOTS)?;
    if cols > 0 {
        bins.par_chunks_mut(cols * BIN_SLOTS)
            .enumerate()
            .for_each(|(r, row)| {
                for (c, slots) in row.chunks_exact_mut(BIN_SLOTS).enumerate() {
                    let (f, n) = facets.cell(r, c);
                    for (slot, &(m, w)) in slots.iter_mut().zip(&f[..n]) {
                        *slot = Entry::new(m, w).bin as u16;
                    }
                }
            });
    }
    Ok(bins)
}

/// The lowest level whose texels compute their children's entries in parallel: a texel there
/// covers ≥ 4^8 cells, so only the few texels of the top levels (which leave cores idle when
/// fitted one per core) do.
const PARALLEL_SUBTREE_LEVEL: usize = 8;

/// The lowest level whose texels sum their footprint's facets onto a dense array of the entry
/// grid ([`LevelFit::dense_entries`]) instead of merging their children's entries level by
/// level: a texel there covers ≥ 4^5 cells (≥ 2048 facets), so reading out the grid's 65536
/// bins costs less than the merges.
pub(super) const DENSE_LEVEL: usize = 5;

thread_local! {
    /// The dense entry grid of [`LevelFit::dense_entries`] (weight and summed normals per bin,
    /// all zero between uses; 2 MB per thread that uses it) and the bins hit.
    static DENSE: std::cell::RefCell<DenseGrid> =
        const { std::cell::RefCell::new((Vec::new(), Vec::new())) };
}

/// Weight and summed normals per bin of the entry grid, and the bins hit.
type DenseGrid = (Vec<(f64, glam::DVec3)>, Vec<u32>);

/// A row's scratch buffers: the texel's merged entries, and per level `j` below it the merged
/// entries of the (up to four) children being merged into a texel of level `j` (`depth[0]`
/// holds a cell's single facets instead).
#[derive(Default)]
struct Scratch {
    merged: Vec<Entry>,
    depth: Vec<[Vec<Entry>; 4]>,
}

impl LevelFit<'_> {
    /// The merged entries, lobes, horizon statistics and sampled residuals of row `r`'s
    /// texels.
    pub(super) fn row(&self, r: usize) -> RowOut {
        let cols = self.cols;
        let mut out = RowOut {
            lobes: Vec::new(),
            lcount: Vec::with_capacity(cols),
            horizon: Vec::new(),
            residual: Vec::new(),
            weight: Vec::with_capacity(cols),
        };
        let mut kids = Vec::new();
        let mut buf = Scratch::default();
        buf.depth.resize_with(self.k + 1, Default::default);
        let mut scratch = Vec::new();
        let mut lobes = Vec::new();
        if self.merged {
            self.merged_row(r, &mut out, &mut buf, &mut kids, &mut lobes);
            return out;
        }
        for c in 0..cols {
            self.texel_entries(self.k, r, c, &mut buf.depth, &mut buf.merged);
            match self.prev {
                None => {
                    if let Some(h) = self.horizon {
                        out.horizon.push(h.sample_stats(r, c));
                    }
                }
                Some(prev) => self.merge_child_horizons(prev, r, c, &mut out.horizon),
            }
            out.weight.push(buf.merged.iter().map(|e| e.w).sum());
            // The children's lobes start the smoothed refinement only when asked to
            // (`FitParams::smooth_from_children`); they may be kept for the next level's merges.
            let children = self
                .children
                .filter(|_| self.params.fit.smooth_from_children);
            let children = children.map(|ch| {
                ch.children_of(self.prev, r, c, &mut kids);
                &kids[..]
            });
            self.fit_texel(&buf.merged, children, &mut scratch, &mut lobes);
            if (r * cols + c).is_multiple_of(self.residual_stride) {
                out.residual.push((
                    Self::residual(&buf.merged, &lobes),
                    crate::fit::shading_error(
                        &buf.merged,
                        &lobes,
                        self.params.fit.shading_exponent(),
                    ),
                ));
            }
            out.lobes.extend_from_slice(&lobes);
            out.lcount.push(lobes.len() as u32);
        }
        out
    }

    /// Row `r` of a level that [`merges`] its children: each texel's lobes its children's
    /// merged ([`crate::fit::merge_lobes`]); level 1's children are its cells' facets (each
    /// merged bin its own lobe, [`Self::cell_lobes`]), the levels above read the
    /// previous level's lobes ([`ChildLobes`]). The texel's facet weight is its children's
    /// sum; its entries are computed only where the residual is measured.
    fn merged_row(
        &self,
        r: usize,
        out: &mut RowOut,
        buf: &mut Scratch,
        kids: &mut Vec<PhongLobe>,
        lobes: &mut Vec<PhongLobe>,
    ) {
        let kmax = self.params.fit.max_lobes;
        let lambda = self.params.fit.shading_exponent();
        let mut child = Vec::new();
        // Level 2 streamed: its (up to four) children's refitted lobes and weights.
        let mut fits: [Vec<PhongLobe>; 4] = Default::default();
        for c in 0..self.cols {
            let sampled = (r * self.cols + c).is_multiple_of(self.residual_stride);
            let weight = match (self.k, self.children) {
                (1, _) => self.cell_lobes(r, c, buf, kids),
                (_, Some(ch)) => {
                    if sampled {
                        self.texel_entries(self.k, r, c, &mut buf.depth, &mut buf.merged);
                    }
                    ch.children_of(self.prev, r, c, kids)
                }
                (_, None) => {
                    // Level 2 of the streamed extraction: its children's (level 1's) lobes
                    // fitted again from their facets as level 1 fitted them, read as the
                    // in-memory extraction reads them ([`child_lobe`]).
                    debug_assert_eq!(self.k, 2, "only level 2 fits its children again");
                    let mut ws = [0.0; 4];
                    let mut n = 0;
                    let below = |m: usize| m.div_ceil(2);
                    let (rows1, cols1) = (below(self.facets.rows()), below(self.facets.cols()));
                    for cr in 2 * r..(2 * r + 2).min(rows1) {
                        for cc in 2 * c..(2 * c + 2).min(cols1) {
                            ws[n] = self.cell_lobes(cr, cc, buf, &mut child);
                            crate::fit::merge_lobes(&child, kmax, lambda, &mut fits[n]);
                            n += 1;
                        }
                    }
                    let total: f64 = ws[..n].iter().sum();
                    kids.clear();
                    if total > 0.0 {
                        for (f, w) in fits[..n].iter().zip(&ws) {
                            kids.extend(f.iter().map(|l| {
                                let c = child_lobe(l);
                                PhongLobe {
                                    weight: c.weight * (w / total),
                                    ..c
                                }
                            }));
                        }
                    }
                    if sampled {
                        self.texel_entries(self.k, r, c, &mut buf.depth, &mut buf.merged);
                    }
                    total
                }
            };
            if let Some(prev) = self.prev {
                self.merge_child_horizons(prev, r, c, &mut out.horizon);
            }
            out.weight.push(weight);
            crate::fit::merge_lobes(kids, kmax, lambda, lobes);
            if sampled {
                out.residual.push((
                    Self::residual(&buf.merged, lobes),
                    crate::fit::shading_error(&buf.merged, lobes, lambda),
                ));
            }
            out.lobes.extend_from_slice(lobes);
            out.lcount.push(lobes.len() as u32);
        }
    }

    /// Texel `(r, c)` of level 1 as the lobes a merge starts from: its cells' facets merged
    /// per bin of the entry grid (into `buf.merged`), each entry its own lobe, into `out`
    /// (empty for no weight). Returns the texel's facet weight.
    fn cell_lobes(&self, r: usize, c: usize, buf: &mut Scratch, out: &mut Vec<PhongLobe>) -> f64 {
        self.texel_entries(1, r, c, &mut buf.depth, &mut buf.merged);
        let w: f64 = buf.merged.iter().map(|e| e.w).sum();
        out.clear();
        if w > 0.0 {
            out.extend(exact_lobes(&buf.merged, w));
        }
        w
    }

    /// The relative NDF L2 error of a texel's lobes against its footprint's facets, from the
    /// texel's merged entries (the histogram of the facets themselves up to the order of the
    /// sums: `entries_l2_error`), not from another pass over the footprint.
    fn residual(merged: &[Entry], lobes: &[PhongLobe]) -> f64 {
        entries_l2_error(merged, |g, out| crate::fit::lobe_bin_mass(lobes, g, out))
    }

    /// The entries of level-0 cell `(r, c)`: its facets merged per bin.
    fn cell_entries(&self, r: usize, c: usize, singles: &mut Vec<Entry>, out: &mut Vec<Entry>) {
        singles.clear();
        singles.extend(self.cell_facet_entries(r, c));
        merge_entries(&[singles], out);
    }

    /// The entries of the facets of cell `(r, c)` (each its own, unmerged; bins from
    /// [`facet_bins`]), in the facets' order (as `FacetNormals::footprint` orders a footprint's
    /// facets: rows, then columns, then a cell's facets).
    #[inline]
    fn cell_facet_entries(&self, r: usize, c: usize) -> impl Iterator<Item = Entry> + '_ {
        let (f, n) = self.facets.cell(r, c);
        let at = (r * self.facets.cols() + c) * BIN_SLOTS;
        f.into_iter()
            .zip(&self.bins[at..at + n])
            .map(|((m, w), &bin)| Entry {
                bin: u32::from(bin),
                w,
                m: m * w,
            })
    }

    /// The merged entries of texel `(r, c)` of level `j`, into `out`: a cell's facets merged
    /// per bin (`j = 0`, through `depth[0][0]`), or the merged entries of its (up to four)
    /// children on level `j − 1`, each computed the same way into `depth[j]` (`depth` has at
    /// least `j + 1` levels of buffers).
    fn texel_entries(
        &self,
        j: usize,
        r: usize,
        c: usize,
        depth: &mut [[Vec<Entry>; 4]],
        out: &mut Vec<Entry>,
    ) {
        if j == 0 {
            self.cell_entries(r, c, &mut depth[0][0], out);
            return;
        }
        if (DENSE_LEVEL..PARALLEL_SUBTREE_LEVEL).contains(&j) {
            self.dense_entries(j, r, c, out);
            return;
        }
        // Level j − 1 has ⌈cells / 2^(j−1)⌉ texels along each side.
        let below = |n: usize| n.div_ceil(1 << (j - 1));
        let (rows, cols) = (below(self.facets.rows()), below(self.facets.cols()));
        let (lower, here) = depth.split_at_mut(j);
        let children = &mut here[0];
        let mut kids = [(0, 0); 4];
        let mut n = 0;
        for cr in 2 * r..(2 * r + 2).min(rows) {
            for cc in 2 * c..(2 * c + 2).min(cols) {
                kids[n] = (cr, cc);
                n += 1;
            }
        }
        if j >= PARALLEL_SUBTREE_LEVEL {
            // A big footprint (the few texels of the top levels): its children in parallel,
            // each with buffers of its own; the same merges, so the same numbers.
            let done: Vec<Vec<Entry>> = kids[..n]
                .par_iter()
                .map(|&(cr, cc)| {
                    let mut d: Vec<[Vec<Entry>; 4]> = Vec::new();
                    d.resize_with(j, Default::default);
                    let mut v = Vec::new();
                    self.texel_entries(j - 1, cr, cc, &mut d, &mut v);
                    v
                })
                .collect();
            for (slot, v) in children.iter_mut().zip(done) {
                *slot = v;
            }
        } else {
            for (slot, &(cr, cc)) in children.iter_mut().zip(&kids[..n]) {
                self.texel_entries(j - 1, cr, cc, lower, slot);
            }
        }
        let mut lists: [&[Entry]; 4] = [&[]; 4];
        for (i, list) in lists.iter_mut().enumerate().take(n) {
            *list = &children[i];
        }
        merge_sorted_entries(&lists[..n], out);
    }

    /// The merged entries of texel `(r, c)` of level `j`, into `out`, in one pass: every facet
    /// of its footprint added onto a dense array of the entry grid's bins, then the hit bins
    /// read out in order. The same entries as the merge tree's, up to the order of the sums
    /// (the facets' order here); one pass over the facets instead of `j` merges, for the big
    /// footprints (≥ 4^[`DENSE_LEVEL`] cells) where reading out the whole grid costs little.
    fn dense_entries(&self, j: usize, r: usize, c: usize, out: &mut Vec<Entry>) {
        let (r0, r1, c0, c1) =
            footprint_bounds(self.facets.rows(), self.facets.cols(), 1 << j, r, c);
        DENSE.with(|d| {
            let (grid, hit) = &mut *d.borrow_mut();
            let bins = ENTRY_GRID_RES * ENTRY_GRID_RES;
            if grid.len() != bins {
                grid.clear();
                grid.resize(bins, (0.0, glam::DVec3::ZERO));
            }
            hit.clear();
            for r in r0..r1 {
                for c in c0..c1 {
                    for e in self.cell_facet_entries(r, c) {
                        let b = &mut grid[e.bin as usize];
                        if b.0 == 0.0 && b.1 == glam::DVec3::ZERO {
                            hit.push(e.bin);
                        }
                        b.0 += e.w;
                        b.1 += e.m;
                    }
                }
            }
            // The hit bins in order, each read and cleared.
            hit.sort_unstable();
            hit.dedup();
            out.clear();
            out.extend(hit.iter().map(|&bin| {
                let b = std::mem::take(&mut grid[bin as usize]);
                Entry {
                    bin,
                    w: b.0,
                    m: b.1,
                }
            }));
        });
    }

    /// The horizon statistics of texel `(r, c)` of this level, merged from its (up to four)
    /// children in `prev` and pushed onto `horizon` (nothing for a map without them).
    fn merge_child_horizons(
        &self,
        prev: &Level,
        r: usize,
        c: usize,
        horizon: &mut Vec<HorizonStats>,
    ) {
        let mut hs = HorizonStats::default();
        let mut has_h = false;
        for cr in 2 * r..(2 * r + 2).min(prev.rows) {
            for cc in 2 * c..(2 * c + 2).min(prev.cols) {
                if let Some(h) = self.prev_horizon.get(cr, cc, prev.cols) {
                    hs.merge(&h);
                    has_h = true;
                }
            }
        }
        if has_h {
            horizon.push(hs);
        }
    }

    /// The lobes of one texel's merged entries, by the extraction's method.
    fn fit_texel(
        &self,
        merged: &[Entry],
        children: Option<&[PhongLobe]>,
        scratch: &mut Vec<(glam::DVec3, f64)>,
        lobes: &mut Vec<PhongLobe>,
    ) {
        match self.params.method {
            Method::Lobes => fit_lobes_seeded(
                merged,
                &self.params.fit,
                self.em_cap,
                self.thorough,
                self.smooth,
                children,
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
