//! The normal and GGX-roughness mip chains.
//!
//! # Conventions
//! * Maps are row-major in meso's map order: row 0 is y = 0, the image's **bottom** row
//!   (`meso_maps::heightmap`). Converting to images (top row first) is [`crate::texture`]'s job.
//! * Level `k` has `max(1, ⌊W / 2ᵏ⌋) × max(1, ⌊H / 2ᵏ⌋)` texels (the KTX2 / OpenGL rule), down
//!   to 1 × 1. Texel `(i, j)` of level `k` covers the level-0 texels of rows
//!   `⌊i·H/Hₖ⌋ .. ⌊(i+1)·H/Hₖ⌋` and columns `⌊j·W/Wₖ⌋ .. ⌊(j+1)·W/Wₖ⌋` — the 2ᵏ × 2ᵏ box for
//!   power-of-two sizes.
//! * **Normals** (the standard mip): the plain average of the footprint's level-0 unit normals,
//!   renormalised.
//! * **Roughness**: level 0 is the base α. A coarser texel's α is the one that minimises the RMS
//!   difference between one GGX lobe about its renormalised normal and the average of the
//!   footprint's level-0 lobes (each about its own normal, with its own base α), on the fixed
//!   direction set of [`crate::ggx::direction_pairs`] — what a supersampled render sees.
//! * **Anisotropic roughness** ([`build_chain_aniso`], optional): the same target and error, on
//!   the direction set with half-vector azimuths every 45° ([`crate::ggx::ANISO_HALF_PHIS_DEG`]),
//!   fitted by one anisotropic GGX lobe ([`crate::ggx::fit_aniso`]): `alphas` then hold `α_b`
//!   (the smaller width) and [`MipLevel::aniso`] the larger width `α_t` and its direction.

use crate::batch::PairArrays;
use crate::ggx::{self, FineTexel};
use crate::ExportError;
use glam::DVec3;
use rayon::prelude::*;

/// The level-0 input: a unit normal and a GGX width α per texel, row-major in map order.
#[derive(Clone, Debug, PartialEq)]
pub struct BaseMaps {
    /// Texels along x.
    pub width: usize,
    /// Texels along y.
    pub height: usize,
    /// Unit normals (tangent frame), `width × height`, map row order.
    pub normals: Vec<DVec3>,
    /// GGX widths α (not glTF roughness), `width × height`, map row order.
    pub alphas: Vec<f64>,
}

impl BaseMaps {
    /// Validated base maps: non-empty, matching lengths, unit finite normals with `n_z > 0`,
    /// finite α in `[0, 1]` (raised to [`ggx::MIN_ALPHA`]).
    ///
    /// # Errors
    /// [`ExportError::Invalid`] naming the first problem.
    pub fn new(
        width: usize,
        height: usize,
        normals: Vec<DVec3>,
        alphas: Vec<f64>,
    ) -> Result<BaseMaps, ExportError> {
        if width == 0 || height == 0 {
            return Err(ExportError::Invalid(format!(
                "the map is {width} × {height} texels: nothing to export"
            )));
        }
        if normals.len() != width * height || alphas.len() != width * height {
            return Err(ExportError::Invalid(format!(
                "{} normals and {} roughness values for a {width} × {height} map",
                normals.len(),
                alphas.len()
            )));
        }
        for (k, n) in normals.iter().enumerate() {
            if !n.is_finite() || (n.length() - 1.0).abs() > 1e-6 || n.z <= 0.0 {
                return Err(ExportError::Invalid(format!(
                    "normal at row {}, column {} is not a unit vector above the surface: {n}",
                    k / width,
                    k % width
                )));
            }
        }
        let mut alphas = alphas;
        for (k, a) in alphas.iter_mut().enumerate() {
            if !a.is_finite() || *a < 0.0 || *a > 1.0 {
                return Err(ExportError::Invalid(format!(
                    "α at row {}, column {} is {a}, outside [0, 1]",
                    k / width,
                    k % width
                )));
            }
            *a = a.max(ggx::MIN_ALPHA);
        }
        Ok(BaseMaps {
            width,
            height,
            normals,
            alphas,
        })
    }
}

/// One mip level of both chains.
#[derive(Clone, Debug, PartialEq)]
pub struct MipLevel {
    /// Texels along x.
    pub width: usize,
    /// Texels along y.
    pub height: usize,
    /// Renormalised box-filtered unit normals, map row order.
    pub normals: Vec<DVec3>,
    /// Fitted GGX widths α, map row order.
    pub alphas: Vec<f64>,
    /// Per-texel relative fit error `rms / peak` (0 at level 0), map row order: the RMS
    /// difference over the fit's direction pairs and the footprint's normals' mirror peaks
    /// ([`ggx::peak_pairs`]) over the highest supersampled value of both.
    pub errors: Vec<f64>,
    /// Per-texel relative error of the standard mip (the base α — the footprint's mean α —
    /// about the averaged normal, no added variance) on the same direction set, for comparison.
    pub errors_plain: Vec<f64>,
    /// The anisotropic part of the fit, when the chain was built by [`build_chain_aniso`]
    /// (then `alphas` are the widths `α_b` across the direction and `errors` the anisotropic
    /// lobe's errors).
    pub aniso: Option<AnisoLevel>,
}

/// The anisotropic part of one level ([`build_chain_aniso`]), map row order.
#[derive(Clone, Debug, PartialEq)]
pub struct AnisoLevel {
    /// GGX widths `α_t ≥ α_b` along the direction `angles` (level 0: the base α).
    pub alpha_t: Vec<f64>,
    /// Direction of `α_t`, radians in `[0, π)` counter-clockwise from +x towards +y (up the
    /// image) in the texture's tangent frame (level 0: 0).
    pub angles: Vec<f64>,
    /// Per-texel relative error `rms / peak` of the *isotropic* fit on the same (45°)
    /// direction set, for comparison with `errors` (0 at level 0).
    pub errors_iso: Vec<f64>,
}

/// Means over one level of the anisotropic fit ([`LevelStats::aniso`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoStats {
    /// Mean `α_t` (the larger width).
    pub mean_alpha_t: f64,
    /// Mean KHR_materials_anisotropy strength `s = √((α_t − α_b)/(1 − α_b))` (unquantised).
    pub mean_strength: f64,
    /// Mean error of the isotropic fit on the same direction set, % of each texel's peak.
    pub mean_iso_error_pct: f64,
    /// Largest per-texel error of the isotropic fit on the same direction set, % of the peak.
    pub max_iso_error_pct: f64,
}

/// KHR_materials_anisotropy's strength `s` for widths `alpha_t ≥ alpha_b`: the spec's
/// `α_t = mix(α_b, 1, s²)` solved for `s`, `s = √((α_t − α_b)/(1 − α_b))` clamped to `[0, 1]`
/// (0 when `α_b ≥ 1`).
#[must_use]
pub fn anisotropy_strength(alpha_t: f64, alpha_b: f64) -> f64 {
    if alpha_b >= 1.0 {
        return 0.0;
    }
    ((alpha_t - alpha_b) / (1.0 - alpha_b))
        .clamp(0.0, 1.0)
        .sqrt()
}

/// Summary of one level's fit, relative errors in % of the supersampled BRDF peak (each
/// texel's, on its fit's direction pairs and its normals' mirror peaks: [`MipLevel::errors`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelStats {
    /// Level index (0 = full resolution).
    pub level: usize,
    /// Texels along x.
    pub width: usize,
    /// Texels along y.
    pub height: usize,
    /// Mean α over the level.
    pub mean_alpha: f64,
    /// Mean over texels of the fitted lobe's RMS error, % of each texel's peak.
    pub mean_error_pct: f64,
    /// Largest per-texel error of the fitted lobe, % of the peak.
    pub max_error_pct: f64,
    /// Mean error of the standard mip (mean base α, no added variance), % of the peak.
    pub mean_plain_error_pct: f64,
    /// The anisotropic fit's means, for a chain built by [`build_chain_aniso`] (then
    /// `mean_alpha` is the mean `α_b` and the errors above are the anisotropic lobe's).
    pub aniso: Option<AnisoStats>,
}

impl MipLevel {
    /// The level's summary statistics.
    #[must_use]
    pub fn stats(&self, level: usize) -> LevelStats {
        let n = self.alphas.len().max(1) as f64;
        LevelStats {
            level,
            width: self.width,
            height: self.height,
            mean_alpha: self.alphas.iter().sum::<f64>() / n,
            mean_error_pct: 100.0 * self.errors.iter().sum::<f64>() / n,
            max_error_pct: 100.0 * self.errors.iter().copied().fold(0.0, f64::max),
            mean_plain_error_pct: 100.0 * self.errors_plain.iter().sum::<f64>() / n,
            aniso: self.aniso.as_ref().map(|a| AnisoStats {
                mean_alpha_t: a.alpha_t.iter().sum::<f64>() / n,
                mean_strength: a
                    .alpha_t
                    .iter()
                    .zip(&self.alphas)
                    .map(|(&t, &b)| anisotropy_strength(t, b))
                    .sum::<f64>()
                    / n,
                mean_iso_error_pct: 100.0 * a.errors_iso.iter().sum::<f64>() / n,
                max_iso_error_pct: 100.0 * a.errors_iso.iter().copied().fold(0.0, f64::max),
            }),
        }
    }
}

/// Number of levels of a full chain for a `width × height` level 0: `⌊log₂ max(W, H)⌋ + 1`.
#[must_use]
pub fn level_count(width: usize, height: usize) -> usize {
    let m = width.max(height).max(1);
    (usize::BITS - m.leading_zeros()) as usize
}

/// Size of level `k`: `max(1, ⌊W / 2ᵏ⌋) × max(1, ⌊H / 2ᵏ⌋)`.
#[must_use]
pub fn level_size(width: usize, height: usize, k: usize) -> (usize, usize) {
    ((width >> k).max(1), (height >> k).max(1))
}

/// Level-0 index range `a .. b` covered by coarse index `i` of `coarse` along an axis of `fine`.
fn span(i: usize, fine: usize, coarse: usize) -> (usize, usize) {
    (
        i * fine / coarse,
        ((i + 1) * fine / coarse).max(i * fine / coarse + 1),
    )
}

/// The level-0 texels under texel `(i, j)` of a `wk × hk` level.
#[must_use]
pub fn footprint(base: &BaseMaps, wk: usize, hk: usize, i: usize, j: usize) -> Vec<FineTexel> {
    let (r0, r1) = span(i, base.height, hk);
    let (c0, c1) = span(j, base.width, wk);
    let mut v = Vec::with_capacity((r1 - r0) * (c1 - c0));
    for r in r0..r1 {
        for c in c0..c1 {
            let k = r * base.width + c;
            v.push(FineTexel {
                normal: base.normals[k],
                alpha: base.alphas[k],
            });
        }
    }
    v
}

/// The renormalised average of the footprint's normals (+z if they cancel).
#[must_use]
pub fn average_normal(fine: &[FineTexel]) -> DVec3 {
    let s: DVec3 = fine.iter().map(|t| t.normal).sum();
    let n = s.normalize_or_zero();
    if n == DVec3::ZERO || n.z <= 0.0 {
        DVec3::Z
    } else {
        n
    }
}

/// One fitted texel of a coarse level.
struct TexelFit {
    normal: DVec3,
    /// α (isotropic) or α_b (anisotropic).
    alpha: f64,
    error: f64,
    plain: f64,
    /// `(α_t, angle, isotropic error)` of the anisotropic fit.
    aniso: Option<(f64, f64, f64)>,
}

/// The supersampled average of `fine`'s lobes on the pairs `arrays`, in parallel over large
/// footprints.
fn target_of(fine: &[FineTexel], arrays: &PairArrays) -> Vec<f64> {
    if fine.len() > 4096 {
        fine.par_chunks(1024)
            .map(|c| {
                let mut v = ggx::average_shaded_on(c, arrays);
                v.iter_mut().for_each(|x| *x *= c.len() as f64);
                v
            })
            .reduce(
                || vec![0.0; arrays.len()],
                |mut a, b| {
                    a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                    a
                },
            )
            .into_iter()
            .map(|x| x / fine.len() as f64)
            .collect()
    } else {
        ggx::average_shaded_on(fine, arrays)
    }
}

/// Fit one texel of a coarse level, isotropic or (with `anisotropic`) anisotropic.
fn fit_texel(fine: &[FineTexel], anisotropic: bool) -> TexelFit {
    let nbar = average_normal(fine);
    let width = ggx::footprint_width(fine, nbar);
    let pairs = if anisotropic {
        ggx::direction_pairs_with(nbar, width, &ggx::ANISO_HALF_PHIS_DEG)
    } else {
        ggx::direction_pairs(nbar, width)
    };
    // The pairs as flat arrays once, for the target, the standard mip's error and the fit.
    let arrays = PairArrays::new(&pairs);
    let target = target_of(fine, &arrays);
    let mean_alpha = fine.iter().map(|t| t.alpha).sum::<f64>() / fine.len() as f64;
    // One prepared search for the standard mip's error and the fit (`ggx::rms_error`'s
    // numbers).
    let mut search = ggx::IsoSearch::on(&target, nbar, &arrays);
    let plain = search.rms(mean_alpha);
    // The errors are reported on the fit's pairs and at the footprint's normals' own mirror
    // peaks (`ggx::peak_pairs`), relative to the highest value of both.
    let peaks = ggx::peak_pairs(fine, nbar);
    let peak_target = if peaks.is_empty() {
        Vec::new()
    } else {
        target_of(fine, &PairArrays::new(&peaks))
    };
    let n = pairs.len();
    let rel = |rms: f64, peak: f64, model: &dyn Fn(DVec3, DVec3) -> f64| {
        ggx::relative_error_with(rms, n, peak, &peaks, &peak_target, model)
    };
    if anisotropic {
        let fit = ggx::fit_aniso_with(fine, &mut search, &target, nbar, &pairs);
        let lobe = ggx::AnisoGgx::new(nbar, fit.angle, fit.alpha_t, fit.alpha_b);
        TexelFit {
            normal: nbar,
            alpha: fit.alpha_b,
            error: rel(fit.rms, fit.peak, &|l, v| lobe.shaded(l, v)),
            plain: rel(plain, fit.peak, &|l, v| ggx::shaded(nbar, mean_alpha, l, v)),
            aniso: Some((
                fit.alpha_t,
                fit.angle,
                rel(fit.iso_rms, fit.peak, &|l, v| {
                    ggx::shaded(nbar, fit.iso_alpha, l, v)
                }),
            )),
        }
    } else {
        let fit = search.fit(ggx::MIN_ALPHA);
        TexelFit {
            normal: nbar,
            alpha: fit.alpha,
            error: rel(fit.rms, fit.peak, &|l, v| {
                ggx::shaded(nbar, fit.alpha, l, v)
            }),
            plain: rel(plain, fit.peak, &|l, v| ggx::shaded(nbar, mean_alpha, l, v)),
            aniso: None,
        }
    }
}

/// Build level `k` of both chains from the level-0 maps (isotropic roughness).
#[must_use]
pub fn build_level(base: &BaseMaps, k: usize) -> MipLevel {
    build_level_with(base, k, false)
}

/// Build level `k` of the chains, with anisotropic roughness when `anisotropic` (level 0 is
/// then the base α in both widths, direction 0).
#[must_use]
pub fn build_level_with(base: &BaseMaps, k: usize, anisotropic: bool) -> MipLevel {
    let (wk, hk) = level_size(base.width, base.height, k);
    if k == 0 {
        let n = base.width * base.height;
        return MipLevel {
            width: wk,
            height: hk,
            normals: base.normals.clone(),
            alphas: base.alphas.clone(),
            errors: vec![0.0; n],
            errors_plain: vec![0.0; n],
            aniso: anisotropic.then(|| AnisoLevel {
                alpha_t: base.alphas.clone(),
                angles: vec![0.0; n],
                errors_iso: vec![0.0; n],
            }),
        };
    }
    let texels: Vec<TexelFit> = (0..wk * hk)
        .into_par_iter()
        .map(|t| fit_texel(&footprint(base, wk, hk, t / wk, t % wk), anisotropic))
        .collect();
    MipLevel {
        width: wk,
        height: hk,
        normals: texels.iter().map(|t| t.normal).collect(),
        alphas: texels.iter().map(|t| t.alpha).collect(),
        errors: texels.iter().map(|t| t.error).collect(),
        errors_plain: texels.iter().map(|t| t.plain).collect(),
        aniso: anisotropic.then(|| AnisoLevel {
            alpha_t: texels
                .iter()
                .map(|t| t.aniso.map_or(t.alpha, |a| a.0))
                .collect(),
            angles: texels
                .iter()
                .map(|t| t.aniso.map_or(0.0, |a| a.1))
                .collect(),
            errors_iso: texels
                .iter()
                .map(|t| t.aniso.map_or(t.error, |a| a.2))
                .collect(),
        }),
    }
}

/// The full chains, level 0 (the base maps) down to 1 × 1.
#[must_use]
pub fn build_chain(base: &BaseMaps) -> Vec<MipLevel> {
    (0..level_count(base.width, base.height))
        .map(|k| build_level(base, k))
        .collect()
}

/// The full chains with anisotropic roughness ([`ggx::fit_aniso`]), level 0 down to 1 × 1.
#[must_use]
pub fn build_chain_aniso(base: &BaseMaps) -> Vec<MipLevel> {
    (0..level_count(base.width, base.height))
        .map(|k| build_level_with(base, k, true))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tilted unit normal: `deg` from +z towards azimuth `az_deg`.
    fn tilted(deg: f64, az_deg: f64) -> DVec3 {
        let (t, p) = (deg.to_radians(), az_deg.to_radians());
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    }

    #[test]
    fn a_footprint_of_separate_narrow_peaks_is_measured_at_its_peaks() {
        // A steep facade's footprint: flat tops (0°), a slope (45°) and walls (74°), narrow
        // lobes (α = 0.05). The fit's pairs, laid out in units of the footprint's width, fall
        // between the peaks: measured there alone the error read several times the "peak".
        let normals = vec![
            tilted(0.0, 0.0),
            tilted(74.0, 0.0),
            tilted(45.0, 90.0),
            tilted(74.0, 0.0),
        ];
        let fine: Vec<FineTexel> = normals
            .iter()
            .map(|&normal| FineTexel {
                normal,
                alpha: 0.05,
            })
            .collect();
        let nbar = average_normal(&fine);
        let old = ggx::fit_alpha(&fine, nbar);
        let base = BaseMaps::new(2, 2, normals, vec![0.05; 4]).unwrap();
        let level = build_level(&base, 1);
        let err = level.errors[0];
        // The same α as the fit on its own pairs; the error now against the footprint's own
        // peaks, which the one lobe about the averaged normal misses: measured 16 % of them
        // (the lobe of one normal, below, 0).
        assert_eq!(level.alphas[0], old.alpha);
        assert!(old.rms / old.peak > 1.0, "the case: {}", old.rms / old.peak);
        assert!((0.1..1.0).contains(&err), "{err}");
        // The peak the error is relative to is the footprint's highest value at its normals'
        // mirror peaks.
        let peaks = ggx::peak_pairs(&fine, nbar);
        let at_peaks = ggx::average_shaded(&fine, &peaks);
        let highest = at_peaks.iter().copied().fold(0.0, f64::max);
        assert!(highest > 10.0 * old.peak, "{highest} vs {}", old.peak);
        // A footprint of one normal: its peak is the fit's own pair at the averaged normal, and
        // the lobe fits it exactly.
        let flat = BaseMaps::new(2, 2, vec![tilted(10.0, 30.0); 4], vec![0.1; 4]).unwrap();
        let level = build_level(&flat, 1);
        assert!(level.errors[0] < 1e-3, "{}", level.errors[0]);
    }

    #[test]
    fn level_sizes_follow_the_ktx_rule() {
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(8, 8), 4);
        assert_eq!(level_count(8, 3), 4);
        assert_eq!(level_count(5, 1), 3);
        assert_eq!(level_size(8, 3, 2), (2, 1));
        assert_eq!(level_size(8, 3, 3), (1, 1));
    }

    #[test]
    fn footprints_tile_the_base_for_odd_sizes() {
        let (w, h) = (7, 5);
        let base = BaseMaps::new(w, h, vec![DVec3::Z; w * h], vec![0.1; w * h]).unwrap();
        for k in 1..level_count(w, h) {
            let (wk, hk) = level_size(w, h, k);
            let total: usize = (0..hk)
                .flat_map(|i| (0..wk).map(move |j| (i, j)))
                .map(|(i, j)| footprint(&base, wk, hk, i, j).len())
                .sum();
            assert_eq!(total, w * h, "level {k}");
        }
    }

    /// The averaged normal is the renormalised vector sum, by hand.
    #[test]
    fn renormalised_average() {
        let a = DVec3::new(0.6, 0.0, 0.8);
        let b = DVec3::new(0.0, -0.6, 0.8);
        let fine = [a, b].map(|n| FineTexel {
            normal: n,
            alpha: 0.1,
        });
        let n = average_normal(&fine);
        let want = DVec3::new(0.3, -0.3, 0.8) / (0.09_f64 + 0.09 + 0.64).sqrt();
        assert!((n - want).length() < 1e-12);
        assert!((n.length() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn bad_base_maps_are_refused() {
        assert!(BaseMaps::new(0, 4, vec![], vec![]).is_err());
        assert!(BaseMaps::new(1, 1, vec![DVec3::Z], vec![1.5]).is_err());
        assert!(BaseMaps::new(1, 1, vec![-DVec3::Z], vec![0.5]).is_err());
        assert!(BaseMaps::new(1, 1, vec![DVec3::new(0.0, 0.0, 2.0)], vec![0.5]).is_err());
        assert!(BaseMaps::new(2, 1, vec![DVec3::Z], vec![0.5]).is_err());
    }
}
