//! Which texels a shading call reads, and with what weights: the sample's footprint in level-0
//! cells, the level of detail ([`NdfMapped::lod`]) and the taps of the trilinear filter, the box
//! filter ([`NdfMapped::with_box_filter`], its level set by [`NdfMapped::with_box_detail`]) or
//! sharp magnification ([`NdfMapped::with_sharp_magnification`]).
//!
//! # Conventions
//! * A tap is `(level, texel, weight)`; the weights of a call sum to 1.
//! * Positions are in level-0 cells, centred where the renderer puts the sample's filter
//!   (`ShadingPoint::filter_uv`); texels wrap periodically.

use super::NdfMapped;
use crate::geometry::ShadingPoint;

/// One tap of a shading call: `(level, texel, weight)`.
pub(super) type Tap = (usize, usize, f64);

/// The most detail the box filter takes ([`NdfMapped::with_box_detail`]): texels down to a
/// sixty-fourth of the footprint box's longer side.
pub const MAX_BOX_DETAIL: f64 = 3.0;

/// The default box-filter detail of the glossy facets ([`default_box_detail`]: those whose
/// `½·log₂(λ_facet / 40)` reaches [`GLOSSY_BOX_DETAIL_FROM`], GGX or Beckmann α ≤ 0.158, Phong
/// η ≥ 80, mirrors). Measured against the bump map and the displaced geometry
/// (docs/heightmaps.md, "Glossy facets" and "Detail 3 for GGX α = 0.1 on more maps"): with
/// α = 0.05, 0.1 and 0.15 detail 3 was as close as the lower details or closer on every map
/// and distance tried, and at 32–64 cells per pixel far closer (the stone wall's far views at
/// α = 0.1 0.75 → 0.96–1.00 of the truth, at α = 0.15 0.69 → 0.98–0.99; a Gaussian height
/// map's far views at α = 0.1 0.218 → 0.040 in mean |ln ratio|); it cost 0.6–2.6× detail 2's
/// render time at α = 0.05, and against the fractional details it replaced 0.55–1.8× at 16
/// cells per pixel and 1.7–8× at 64 (docs/benchmarks.md, "What the finer box details cost
/// against the bump map").
pub const DEFAULT_MAX_BOX_DETAIL: f64 = MAX_BOX_DETAIL;

/// From this `½·log₂(λ_facet / 40)` on, the default detail is [`DEFAULT_MAX_BOX_DETAIL`]
/// ([`default_box_detail`]).
pub const GLOSSY_BOX_DETAIL_FROM: f64 = 0.5;

/// The default box-filter detail of the broad facets ([`default_box_detail`]: those below
/// [`GLOSSY_BOX_DETAIL_FROM`], Lambert, Phong η < 80, GGX or Beckmann α > 0.158). Measured
/// against the displaced geometry (`meso_maps::Gonio`, rays on the mesh; docs/heightmaps.md,
/// "Broad facets read two levels finer"): on the steep facade at 16 and 64 cells per pixel,
/// Lambert's far views came 0.094 and 0.252 off the geometry in mean |ln ratio| at detail 0
/// (up to 1.67× and 0.62×), 0.033 and 0.092 at detail 2 (0.024 and 0.064 at 3); GGX α = 0.2
/// 0.254 and 0.372 at its former fractional detail 0.16, 0.035 and 0.283 at 2; a steep real
/// wood texture 0.128 → 0.090 (Lambert, 64 cells per pixel); gentle maps alike at every
/// detail. It costs 3.4× detail 0's frame time at 16 cells per pixel and 7.6× at 64 through a
/// pinhole (Lambert; detail 3 21×), none up close (docs/benchmarks.md).
pub const BROAD_BOX_DETAIL: f64 = 2.0;

/// The box filter's default detail for facets of `transfer` ([`NdfMapped::with_box_detail`]):
/// [`DEFAULT_MAX_BOX_DETAIL`] (3) for glossy facets, [`BROAD_BOX_DETAIL`] (2) for the others.
/// A facet is glossy when half the base-2 log of how much sharper its highlight is than the
/// kernel the pyramid's lobes were fitted under, `½·log₂(λ_facet / λ_fit)` with λ_facet from
/// [`meso_maps::fit::facet_kernel_exponent`] (Phong η → η, Beckmann/GGX α → 2/α², Lambert → 2)
/// and λ_fit = [`meso_maps::fit::SHADING_KERNEL_EXPONENT`] (40), reaches
/// [`GLOSSY_BOX_DETAIL_FROM`]: GGX or Beckmann α ≤ 0.158, Phong η ≥ 80, and a mirror facet,
/// with no kernel. GGX α = 0.05, 0.1 and 0.15 → 3; α = 0.2, Phong η ≤ 40 and Lambert → 2.
/// The coarse levels' fitted lobes merge a texel's separate groups of normals (a facade's
/// faces and walls) and their visibility, so every facet reads finer texels than its
/// footprint; the glossy ones, whose narrow highlight the lobes follow least, one level more.
#[must_use]
pub fn default_box_detail(transfer: &meso_core::transfer::Transfer) -> f64 {
    match meso_maps::fit::facet_kernel_exponent(transfer) {
        Some(l)
            if 0.5 * (l / meso_maps::fit::SHADING_KERNEL_EXPONENT).log2()
                < GLOSSY_BOX_DETAIL_FROM =>
        {
            BROAD_BOX_DETAIL
        }
        _ => DEFAULT_MAX_BOX_DETAIL,
    }
}

/// Most texels along one axis of one level of a box-filter call: a box spans at most
/// `2^(3 + detail)` texels of its finer level, `+ 1` where it straddles texel edges (and one
/// spare).
const BOX_AXIS_TAPS: usize = (1 << (3 + MAX_BOX_DETAIL as usize)) + 2;

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
    pub(super) fn taps(&self, sp: &ShadingPoint, taps: &mut Vec<Tap>) {
        let fp = self.footprint_cells(sp);
        // Centred where the renderer puts the sample's filter (its stratum's centre).
        let (x, y) = crate::mapped::map_xy(
            sp.filter_uv.x,
            sp.filter_uv.y,
            self.texels_per_uv,
            self.levels[0].rows,
        );
        taps.clear();
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
                    taps.push((0, row * l.cols + col, w));
                }
            }
            return;
        }
        if self.box_filter && fp.is_finite() && fp > 0.0 {
            self.box_taps(sp, x, y, taps);
            return;
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
                    taps.push((lev, r * l.cols + c, w));
                }
            }
        }
    }

    /// The box filter's taps (see [`NdfMapped::with_box_filter`]) around `(x, y)` (in level-0
    /// cells), into `taps`: on the level whose texels are `2^−(2 + d)` to `2^−(3 + d)` of the
    /// box's longer side, `d` the detail ([`NdfMapped::with_box_detail`]), blended with the
    /// next coarser level.
    fn box_taps(&self, sp: &ShadingPoint, x: f64, y: f64, taps: &mut Vec<Tap>) {
        let k = self.texels_per_uv * self.footprint_scale;
        // The bounding box of the pixel's parallelogram in cells.
        let wx = ((sp.duvdx.x.abs() + sp.duvdy.x.abs()) * k).max(1e-9);
        let wy = ((sp.duvdx.y.abs() + sp.duvdy.y.abs()) * k).max(1e-9);
        let top = (self.levels.len() - 1) as f64;
        // Texels of an eighth to a quarter of the box's longer side at detail 0: at most 10 × 10
        // (and 6 × 6 on the coarser level blended in); each unit of detail halves them.
        let natural = (wx.max(wy).log2() - 2.0).clamp(0.0, top);
        // The detail goes no finer than the floor (a footprint already finer keeps its level).
        let lod = (natural - self.box_detail).max(natural.min(self.detail_floor as f64));
        let l0 = lod.floor() as usize;
        let l1 = (l0 + 1).min(self.levels.len() - 1);
        let t = lod - l0 as f64;
        for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
            if lw <= 0.0 {
                continue;
            }
            let l = &self.levels[lev];
            // Overlaps of [p − w/2, p + w/2] with the texels [c·s, (c + 1)·s), at most
            // `BOX_AXIS_TAPS`; a box wider than the level (`n` texels, which wrap) covers each
            // texel in several periods: each once, with its overlaps summed.
            let axis = |p: f64, w: f64, n: usize| -> ([(i64, f64); BOX_AXIS_TAPS], usize) {
                let mut out = [(0i64, 0.0f64); BOX_AXIS_TAPS];
                let (lo, hi) = ((p - 0.5 * w) / l.span, (p + 0.5 * w) / l.span);
                let w = hi - lo;
                if w > n as f64 && n <= BOX_AXIS_TAPS {
                    let nf = n as f64;
                    // Measure of [0, x) inside the texels ≡ j (mod n).
                    let covered = |x: f64, j: f64| {
                        let q = ((x - j) / nf).floor();
                        q + (x - j - nf * q).min(1.0)
                    };
                    for (j, o) in out.iter_mut().enumerate().take(n) {
                        let jf = j as f64;
                        *o = (j as i64, (covered(hi, jf) - covered(lo, jf)) / w);
                    }
                    return (out, n);
                }
                let mut m = 0;
                let mut c = lo.floor();
                while c < hi && m < BOX_AXIS_TAPS {
                    let o = ((c + 1.0).min(hi) - c.max(lo)) / w;
                    if o > 0.0 {
                        out[m] = (c as i64, o);
                        m += 1;
                    }
                    c += 1.0;
                }
                (out, m)
            };
            let ((ax, nx), (ay, ny)) = (axis(x, wx, l.cols), axis(y, wy, l.rows));
            let (sx, sy) = (
                ax[..nx].iter().map(|a| a.1).sum::<f64>(),
                ay[..ny].iter().map(|a| a.1).sum::<f64>(),
            );
            for &(r, wyr) in &ay[..ny] {
                let row = r.rem_euclid(l.rows as i64) as usize;
                for &(c, wxc) in &ax[..nx] {
                    let col = c.rem_euclid(l.cols as i64) as usize;
                    taps.push((lev, row * l.cols + col, lw * wxc / sx * wyr / sy));
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shader::local_point;
    use glam::DVec2;
    use meso_core::material::Material;
    use meso_maps::{extract, fixtures, ExtractParams, Source};

    /// The box filter's taps at detail 0, 1, 2 and 3 for a footprint of 64 cells: the level each
    /// reads (one finer a unit of detail; a fractional detail blends the two), the texels per
    /// axis (4, 8, 16, 32, + 1 where the box straddles texel edges) and weights summing to 1.
    #[test]
    fn box_detail_reads_finer_levels_with_weights_summing_to_one() {
        let map = fixtures::gaussian(256, 4.0, 0.1, 3, 0.01).unwrap();
        let pyr = extract(
            Source::Heights(&map),
            &ExtractParams::default(),
            &mut |_| {},
        )
        .unwrap();
        let surface = Material::from_toml_str("[transfer]\nkind = \"lambert\"\n").unwrap();
        let tpu = 256.0;
        let m = NdfMapped::new(&pyr, &surface, tpu, false).unwrap();
        assert_eq!(m.box_detail(), BROAD_BOX_DETAIL, "Lambert facets: detail 2");
        // A 64-cell box at (100.3, 57.8) cells: lod = log2(64) − 2 − detail.
        let sp = local_point(DVec2::new(100.3, 57.8) / tpu, 64.0 / tpu);
        for (detail, level, per_axis) in [
            (0.0, 4usize, 4usize),
            (1.0, 3, 8),
            (2.0, 2, 16),
            (3.0, 1, 32),
        ] {
            let m = m.clone().with_box_detail(detail);
            let mut taps = Vec::new();
            m.taps(&sp, &mut taps);
            assert!(
                taps.iter().all(|t| t.0 == level),
                "detail {detail}: {taps:?}"
            );
            let span = (1usize << level) as f64;
            // The box [68.3, 132.3) × [25.8, 89.8) in cells, in texels of the level.
            let cols = ((132.3 / span).ceil() - (68.3 / span).floor()) as usize;
            let rows = ((89.8 / span).ceil() - (25.8 / span).floor()) as usize;
            assert_eq!((cols, rows), (per_axis + 1, per_axis + 1));
            assert_eq!(taps.len(), cols * rows, "detail {detail}");
            let sum: f64 = taps.iter().map(|t| t.2).sum();
            assert!((sum - 1.0).abs() < 1e-12, "detail {detail}: {sum}");
        }
        // Halfway: the two levels blended half and half.
        let mut taps = Vec::new();
        m.clone().with_box_detail(0.5).taps(&sp, &mut taps);
        let on = |lev: usize| taps.iter().filter(|t| t.0 == lev).map(|t| t.2).sum::<f64>();
        assert!((on(3) - 0.5).abs() < 1e-12 && (on(4) - 0.5).abs() < 1e-12);
        // Clamped to [0, MAX_BOX_DETAIL]; a NaN leaves it as it was.
        assert_eq!(m.clone().with_box_detail(9.0).box_detail(), MAX_BOX_DETAIL);
        assert_eq!(m.clone().with_box_detail(-1.0).box_detail(), 0.0);
        assert_eq!(
            m.clone().with_box_detail(f64::NAN).box_detail(),
            BROAD_BOX_DETAIL
        );
        // The default follows the facet: 2 for the broad ones, 3 from ½·log₂(λ/40) = ½ on
        // (λ ≥ 80: GGX α ≤ 0.158, Phong η ≥ 80).
        let detail = |t: &str| {
            let s = Material::from_toml_str(&format!("[transfer]\n{t}\n")).unwrap();
            default_box_detail(&s.transfer)
        };
        assert_eq!(detail("kind = \"lambert\""), 2.0);
        assert_eq!(detail("kind = \"phong\"\nexponent = 20.0"), 2.0);
        assert_eq!(detail("kind = \"phong\"\nexponent = 79.0"), 2.0);
        assert_eq!(detail("kind = \"phong\"\nexponent = 80.0"), 3.0);
        let ggx = |a: f64| detail(&format!("kind = \"microfacet\"\nalpha = {a}"));
        assert_eq!(ggx(0.5), 2.0);
        assert_eq!(ggx(0.2), 2.0);
        assert_eq!(ggx(0.16), 2.0);
        assert_eq!(ggx(0.155), 3.0);
        assert_eq!(ggx(0.15), 3.0);
        assert_eq!(ggx(0.1), 3.0);
        assert_eq!(ggx(0.05), 3.0);
        let mirror = meso_core::transfer::Transfer::Mirror {
            fresnel: meso_core::transfer::Fresnel::None,
            specular: [1.0; 3],
        };
        assert_eq!(default_box_detail(&mirror), 3.0);
        // And the material takes it.
        let glossy =
            Material::from_toml_str("[transfer]\nkind = \"microfacet\"\nalpha = 0.05\n").unwrap();
        let g = NdfMapped::new(&pyr, &glossy, tpu, false).unwrap();
        assert_eq!(g.box_detail(), 3.0);
        // Under a table cap the detail takes a footprint no finer than the finest level whose
        // tables fit in half the cap: here level 3 (level 2's do not fit), so the 64-cell box
        // reads level 3, not 1; a footprint whose own level is finer keeps it.
        let facet = crate::mapped::Facet::new(&glossy.transfer);
        let bytes =
            |k: usize| super::super::build::level_tables_bytes(&pyr, k, &facet, false, false);
        let cap = usize::try_from(bytes(2) + bytes(3)).unwrap();
        assert!(bytes(2) > (cap / 2) as u64 && bytes(3) <= (cap / 2) as u64);
        let capped = NdfMapped::from_pyramid(pyr.clone(), &glossy, tpu, false)
            .unwrap()
            .with_table_cap(cap);
        let mut taps = Vec::new();
        capped.taps(&sp, &mut taps);
        assert!(taps.iter().all(|t| t.0 == 3), "{taps:?}");
        let near = local_point(DVec2::new(100.3, 57.8) / tpu, 6.0 / tpu);
        let mut natural = Vec::new();
        capped.taps(&near, &mut taps);
        capped
            .clone()
            .with_box_detail(0.0)
            .taps(&near, &mut natural);
        assert_eq!(taps, natural);
        assert!(taps.iter().any(|t| t.0 == 0));
        // A box wider than the level it reads (a view from very far, the top level clamped):
        // each texel once, its overlaps over the periods summed, not 66 × 66 taps.
        let far = local_point(DVec2::new(0.37, 0.81), 4000.0);
        let top = m.levels() - 1;
        for detail in [0.0, 2.0] {
            m.clone().with_box_detail(detail).taps(&far, &mut taps);
            let lev = top - detail as usize;
            let side = 1usize << (detail as usize);
            assert!(taps.iter().all(|t| t.0 == lev), "{taps:?}");
            assert_eq!(taps.len(), side * side, "{taps:?}");
            let mut seen: Vec<usize> = taps.iter().map(|t| t.1).collect();
            seen.sort_unstable();
            seen.dedup();
            assert_eq!(seen.len(), side * side);
            for t in &taps {
                let even = 1.0 / (side * side) as f64;
                assert!((t.2 - even).abs() < 1e-3 * even, "{taps:?}");
            }
            let sum: f64 = taps.iter().map(|t| t.2).sum();
            assert!((sum - 1.0).abs() < 1e-12);
        }
        let uncapped = NdfMapped::from_pyramid(pyr.clone(), &glossy, tpu, false).unwrap();
        uncapped.taps(&sp, &mut taps);
        // Detail 3: texels of 1/32–1/64 of the 64-cell box, level 1.
        assert!(taps.iter().all(|t| t.0 == 1), "{taps:?}");
    }
}
