//! Quantisation terraces of 8-bit height maps: how many grid cells are exactly flat or one code
//! high ([`HeightMap::flat_cell_fraction`], [`HeightMap::terrace_stats`]) and their removal by
//! smoothing within each sample's quantisation interval ([`HeightMap::dequantize`]), which
//! loading applies when both fractions exceed [`TERRACE_FRACTION`].
//!
//! # Conventions
//! * A grid cell is the square of four neighbouring samples (row `i`, column `j` to `i + 1`,
//!   `j + 1`), wrapped or clamped by the map's [`Border`].
//! * Dequantisation moves no height by more than half a quantisation step.

use super::{Border, HeightMap};

/// Fraction of exactly flat grid cells, and of cells one code high, above which an 8-bit height
/// map is dequantised on load ([`HeightMap::dequantize`], [`HeightMap::terrace_stats`]).
pub const TERRACE_FRACTION: f64 = 0.02;
/// Smoothing-and-projection rounds of [`HeightMap::dequantize`].
pub const DEQUANTIZE_ITERATIONS: usize = 24;

impl HeightMap {
    /// Fraction of grid cells whose four corner heights are exactly equal (a flat facet pair).
    /// 8-bit height maps show many more than the surface has: the terraces of quantisation.
    #[must_use]
    pub fn flat_cell_fraction(&self) -> f64 {
        let (cx, cy) = (self.cells_x(), self.cells_y());
        let mut flat = 0usize;
        for i in 0..cy as isize {
            for j in 0..cx as isize {
                let h = self.at(i, j);
                if self.at(i, j + 1) == h && self.at(i + 1, j) == h && self.at(i + 1, j + 1) == h {
                    flat += 1;
                }
            }
        }
        flat as f64 / (cx * cy).max(1) as f64
    }

    /// The fractions of grid cells whose four corners are exactly equal and whose corners span
    /// exactly one quantisation `step` (within 1%): together, the signature of terraces.
    #[must_use]
    pub fn terrace_stats(&self, step: f64) -> (f64, f64) {
        let (cx, cy) = (self.cells_x(), self.cells_y());
        let (mut flat, mut one) = (0usize, 0usize);
        for i in 0..cy as isize {
            for j in 0..cx as isize {
                let c = [
                    self.at(i, j),
                    self.at(i, j + 1),
                    self.at(i + 1, j),
                    self.at(i + 1, j + 1),
                ];
                let lo = c.iter().cloned().fold(f64::INFINITY, f64::min);
                let hi = c.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
                if hi == lo {
                    flat += 1;
                } else if ((hi - lo) - step).abs() < 0.01 * step {
                    one += 1;
                }
            }
        }
        let n = (cx * cy).max(1) as f64;
        (flat as f64 / n, one as f64 / n)
    }

    /// Remove quantisation terraces from heights known to lie within `±step/2` of their stored
    /// values (an 8-bit image: `step = H/255`): alternate a 3×3 binomial smoothing with a
    /// projection back into each sample's quantisation interval ([`DEQUANTIZE_ITERATIONS`]
    /// rounds). The result is the smooth surface consistent with the codes: terraces become
    /// slopes, real edges (more than a step high) stay, and no height moves by more than half a
    /// step.
    pub fn dequantize(&mut self, step: f64) {
        let (w, h) = (self.width, self.height);
        let lo: Vec<f64> = self.heights.iter().map(|v| v - 0.5 * step).collect();
        let hi: Vec<f64> = self.heights.iter().map(|v| v + 0.5 * step).collect();
        let mut cur = self.heights.clone();
        let mut tmp = vec![0.0; cur.len()];
        let (wi, hi_) = (w as isize, h as isize);
        let border = self.border;
        let idx = move |r: isize, c: isize| -> usize {
            let (r, c) = match border {
                Border::Wrap => (r.rem_euclid(hi_), c.rem_euclid(wi)),
                Border::Clamp => (r.clamp(0, hi_ - 1), c.clamp(0, wi - 1)),
            };
            r as usize * w + c as usize
        };
        for _ in 0..DEQUANTIZE_ITERATIONS {
            use rayon::prelude::*;
            let src = &cur;
            tmp.par_chunks_mut(w).enumerate().for_each(|(i, row)| {
                let i = i as isize;
                for (j, out) in row.iter_mut().enumerate() {
                    let j = j as isize;
                    let mut acc = 0.0;
                    for (di, a) in [(-1isize, 1.0), (0, 2.0), (1, 1.0)] {
                        for (dj, b) in [(-1isize, 1.0), (0, 2.0), (1, 1.0)] {
                            acc += a * b * src[idx(i + di, j + dj)];
                        }
                    }
                    let k = i as usize * w + j as usize;
                    *out = (acc / 16.0).clamp(lo[k], hi[k]);
                }
            });
            std::mem::swap(&mut cur, &mut tmp);
        }
        self.heights = cur;
    }
}
