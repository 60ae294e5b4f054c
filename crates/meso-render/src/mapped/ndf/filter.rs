//! Which texels a shading call reads, and with what weights: the sample's footprint in level-0
//! cells, the level of detail ([`NdfMapped::lod`]) and the taps of the trilinear filter, the box
//! filter ([`NdfMapped::with_box_filter`]) or sharp magnification
//! ([`NdfMapped::with_sharp_magnification`]).
//!
//! # Conventions
//! * A tap is `(level, texel, weight)`; the weights of a call sum to 1.
//! * Positions are in level-0 cells, centred where the renderer puts the sample's filter
//!   (`ShadingPoint::filter_uv`); texels wrap periodically.

use super::NdfMapped;
use crate::geometry::ShadingPoint;

/// Most taps of one shading call: 8 for the trilinear filter, up to 10 × 10 + 6 × 6 for the
/// box filter.
pub(super) const MAX_TAPS: usize = 136;
/// Up to [`MAX_TAPS`] `(level, texel, weight)` taps of the filter.
pub(super) type Taps = ([(usize, usize, f64); MAX_TAPS], usize);

impl NdfMapped {
    /// The sample's footprint at `sp` in level-0 cells (the ray differentials, which the
    /// renderer shrinks to the sample's stratum with several samples per pixel, times
    /// [`NdfMapped::with_footprint_scale`]).
    fn footprint_cells(&self, sp: &ShadingPoint) -> f64 {
        sp.uv_footprint() * self.texels_per_uv * self.footprint_scale
    }

    /// The continuous level of detail used at `sp`: `log2(footprint in cells) − ½`, clamped to
    /// `[0, levels − 1]`.
    #[must_use]
    pub fn lod(&self, sp: &ShadingPoint) -> f64 {
        let fp = self.footprint_cells(sp);
        let top = (self.levels.len() - 1) as f64;
        if fp > 0.0 && fp.is_finite() {
            (fp.log2() - 0.5).clamp(0.0, top)
        } else if fp.is_finite() {
            0.0
        } else {
            top
        }
    }

    /// The taps at `sp`: trilinear, or with sharp magnification below level 0 (footprints
    /// under √2 cells) the cells
    /// overlapping a box of width `c = √(fp² − 1)` around the point (`c = 1` is the bilinear
    /// filter; the cell's own box plus this one have the footprint's variance), down to the
    /// single cell under the point.
    pub(super) fn taps(&self, sp: &ShadingPoint) -> Taps {
        let fp = self.footprint_cells(sp);
        // Centred where the renderer puts the sample's filter (its stratum's centre).
        let (x, y) = crate::mapped::map_xy(
            sp.filter_uv.x,
            sp.filter_uv.y,
            self.texels_per_uv,
            self.levels[0].rows,
        );
        let mut taps = [(0usize, 0usize, 0.0f64); MAX_TAPS];
        let mut n = 0;
        if self.sharp_magnification && fp.is_finite() && fp < std::f64::consts::SQRT_2 {
            let c = (fp * fp - 1.0).max(0.0).sqrt();
            let l = &self.levels[0];
            // Overlaps of [p − c/2, p + c/2] with the cells (at most two; weights sum to 1).
            let axis = |p: f64| -> [(i64, f64); 2] {
                if c < 1e-9 {
                    return [(p.floor() as i64, 1.0), (0, 0.0)];
                }
                let (lo, hi) = (p - 0.5 * c, p + 0.5 * c);
                let j = lo.floor();
                let w0 = ((j + 1.0).min(hi) - lo) / c;
                [(j as i64, w0), (j as i64 + 1, 1.0 - w0)]
            };
            for (r, wy) in axis(y) {
                for (cc, wx) in axis(x) {
                    let w = wx * wy;
                    if w <= 0.0 {
                        continue;
                    }
                    let col = cc.rem_euclid(l.cols as i64) as usize;
                    let row = r.rem_euclid(l.rows as i64) as usize;
                    taps[n] = (0, row * l.cols + col, w);
                    n += 1;
                }
            }
            return (taps, n);
        }
        if self.box_filter && fp.is_finite() && fp > 0.0 {
            return self.box_taps(sp, x, y);
        }
        let lod = self.lod(sp);
        let l0 = lod.floor() as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let t = lod - l0 as f64;
        for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw <= 0.0 {
                continue;
            }
            let l = &self.levels[lev];
            let tx = x / l.span - 0.5;
            let ty = y / l.span - 0.5;
            let (fx, fy) = (tx.floor(), ty.floor());
            let (ax, ay) = (tx - fx, ty - fy);
            for (dy, wy) in [(0i64, 1.0 - ay), (1, ay)] {
                for (dx, wx) in [(0i64, 1.0 - ax), (1, ax)] {
                    let w = lw * wx * wy;
                    if w <= 0.0 {
                        continue;
                    }
                    let c = (fx as i64 + dx).rem_euclid(l.cols as i64) as usize;
                    let r = (fy as i64 + dy).rem_euclid(l.rows as i64) as usize;
                    taps[n] = (lev, r * l.cols + c, w);
                    n += 1;
                }
            }
        }
        (taps, n)
    }

    /// The box filter's taps (see [`NdfMapped::with_box_filter`]) around `(x, y)` (in level-0
    /// cells).
    fn box_taps(&self, sp: &ShadingPoint, x: f64, y: f64) -> Taps {
        let k = self.texels_per_uv * self.footprint_scale;
        // The bounding box of the pixel's parallelogram in cells.
        let wx = ((sp.duvdx.x.abs() + sp.duvdy.x.abs()) * k).max(1e-9);
        let wy = ((sp.duvdx.y.abs() + sp.duvdy.y.abs()) * k).max(1e-9);
        let top = (self.levels.len() - 1) as f64;
        // Texels of an eighth to a quarter of the box's longer side: at most 10 × 10 (and 6 × 6
        // on the coarser level blended in).
        let lod = (wx.max(wy).log2() - 2.0).clamp(0.0, top);
        let l0 = lod.floor() as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let t = lod - l0 as f64;
        let mut taps = [(0usize, 0usize, 0.0f64); MAX_TAPS];
        let mut n = 0;
        for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw <= 0.0 {
                continue;
            }
            let l = &self.levels[lev];
            // Overlaps of [p − w/2, p + w/2] with the texels [c·s, (c + 1)·s), at most 10.
            let axis = |p: f64, w: f64| -> ([(i64, f64); 10], usize) {
                let mut out = [(0i64, 0.0f64); 10];
                let (lo, hi) = ((p - 0.5 * w) / l.span, (p + 0.5 * w) / l.span);
                let w = hi - lo;
                let mut m = 0;
                let mut c = lo.floor();
                while c < hi && m < 10 {
                    let o = ((c + 1.0).min(hi) - c.max(lo)) / w;
                    if o > 0.0 {
                        out[m] = (c as i64, o);
                        m += 1;
                    }
                    c += 1.0;
                }
                (out, m)
            };
            let ((ax, nx), (ay, ny)) = (axis(x, wx), axis(y, wy));
            let (sx, sy) = (
                ax[..nx].iter().map(|a| a.1).sum::<f64>(),
                ay[..ny].iter().map(|a| a.1).sum::<f64>(),
            );
            for &(r, wyr) in &ay[..ny] {
                for &(c, wxc) in &ax[..nx] {
                    if n == MAX_TAPS {
                        break;
                    }
                    let col = c.rem_euclid(l.cols as i64) as usize;
                    let row = r.rem_euclid(l.rows as i64) as usize;
                    taps[n] = (lev, row * l.cols + col, lw * wxc / sx * wyr / sy);
                    n += 1;
                }
            }
        }
        (taps, n)
    }
}
