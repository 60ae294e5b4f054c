//! Fitting one row of a level: each texel's entries (a level-0 cell's facets merged per bin,
//! or the merged entries of its up to four children), its horizon statistics merged from its
//! children's, its lobes by the extraction's method, and the NDF residual and shading error of
//! the texels the level samples.

use super::{footprint_bounds, ExtractParams, Level, Method};
use crate::compact::Horizons;
use crate::facets::FacetSource;
use crate::fit::{fit_lobes_with, merge_entries, ndf_l2_error, Entry};
use crate::horizon::{HorizonMap, HorizonStats};
use meso_core::ndf::PhongLobe;

/// One row of texels of a level, as [`LevelFit::row`] fits it.
pub(super) struct RowOut {
    pub(super) entries: Vec<Entry>,
    pub(super) ecount: Vec<u32>,
    pub(super) lobes: Vec<PhongLobe>,
    pub(super) lcount: Vec<u32>,
    pub(super) horizon: Vec<HorizonStats>,
    /// The NDF residual and shading error of the row's texels that the level's residual
    /// samples, in order.
    pub(super) residual: Vec<(f64, f64)>,
}

/// Where a level reads the horizon statistics of its children, in `f64`.
#[derive(Clone, Copy)]
pub(super) enum PrevHorizon<'a> {
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
pub(super) struct LevelFit<'a> {
    pub(super) cols: usize,
    pub(super) facets: FacetSource<'a>,
    /// The samples' horizon angles (level 0 only).
    pub(super) horizon: Option<&'a HorizonMap>,
    pub(super) prev: Option<&'a Level>,
    /// The previous level's entries; empty when the previous level is level 0 (its entries
    /// are merged from the facets again).
    pub(super) prev_entries: &'a [Entry],
    pub(super) prev_start: &'a [u32],
    pub(super) prev_horizon: PrevHorizon<'a>,
    /// Whether the next level reads this level's entries (not level 0's, not the top's).
    pub(super) keep_entries: bool,
    /// Texels `0, s, 2s, …` get their NDF residual measured.
    pub(super) residual_stride: usize,
    pub(super) params: &'a ExtractParams,
    pub(super) em_cap: usize,
    pub(super) thorough: bool,
    pub(super) smooth: bool,
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
    pub(super) fn row(&self, r: usize) -> RowOut {
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
