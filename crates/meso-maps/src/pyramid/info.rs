//! The summary of a pyramid for `meso map info`: per level its size, lobe counts and
//! residuals ([`Pyramid::info`]), and how it prints.

use super::{Pyramid, Residual};
use crate::fit::MAX_LOBES;

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
        let hists: Vec<String> = self
            .levels
            .iter()
            .map(|l| {
                let hist: Vec<String> = l
                    .lobe_counts
                    .iter()
                    .enumerate()
                    .filter(|(_, c)| **c > 0)
                    .map(|(n, c)| format!("{n}:{c}"))
                    .collect();
                hist.join(" ")
            })
            .collect();
        // The histogram column is as wide as its widest entry, so no row runs into the next.
        let hw = hists
            .iter()
            .map(|h| h.chars().count())
            .max()
            .unwrap_or(0)
            .max("lobe-count histogram".len());
        writeln!(
            f,
            "level  texels       span  lobes     lobes/texel  {:<hw$}  residual mean/max (n)  shading error mean/max (% of peak)",
            "lobe-count histogram"
        )?;
        for ((k, l), hist) in self.levels.iter().enumerate().zip(&hists) {
            let shading = match (l.residual.shading_mean, l.residual.shading_max) {
                (Some(m), Some(x)) => format!("{:.2}/{:.2}", 100.0 * m, 100.0 * x),
                _ => "not recorded".to_string(),
            };
            writeln!(
                f,
                "{k:<5}  {:<11}  {:<5} {:<9} {:<12.3} {hist:<hw$}  {:<22} {shading}",
                format!("{}x{}", l.cols, l.rows),
                l.span,
                l.lobes,
                l.lobes as f64 / (l.cols * l.rows) as f64,
                format!(
                    "{:.4}/{:.4} ({})",
                    l.residual.mean, l.residual.max, l.residual.texels
                ),
            )?;
        }
        writeln!(
            f,
            "residual: the NDF residual over n texels sampled per level (at most 64, spread over \
             the level), mean and max of those: the relative L2 distance between the lobes' NDF \
             and the histogram of the texel's normals on equal-area bins of about 6° (0: equal; \
             1 or more when the two fall in different bins, as on a relief whose normals all \
             lie within a few degrees of +z, where four bins meet, however good the fit); \
             shading error: \
             the BRDF error of the lobes as a % of its peak, for the facet kernel `meso extract` \
             printed (the file does not record it), the measure of how the lobes shade"
        )?;
        Ok(())
    }
}

impl Pyramid {
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
