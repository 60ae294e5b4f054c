//! The isotropic GGX (Trowbridge–Reitz) specular lobe that engines shade with, and the
//! per-texel fit of a coarse mip texel's α to the average of its fine texels' lobes.
//!
//! # Conventions
//! * Directions are unit vectors in the surface's tangent frame: x right, y up in the image,
//!   z out of the surface (meso's map frame, OpenGL / glTF tangent space).
//! * α is the GGX width (the `α` of `D(h) = α² / (π ((n·h)²(α² − 1) + 1)²)`), **not** glTF's
//!   perceptual roughness `r`; glTF's `roughnessFactor` and the G channel of a
//!   metallicRoughness texture hold `r` with `α = r²` ([`alpha_to_roughness`]).
//! * The quantity compared is the *shaded lobe* `s(n, α; l, v) = f(l, v) · (n·l)` in 1/sr, with
//!   `f = D(h) G₂(l, v) / (4 (n·l)(n·v))` the GGX microfacet BRDF without Fresnel (F = 1) and
//!   `G₂` Smith's height-correlated masking–shadowing: what a renderer adds up per pixel under a
//!   directional light of unit irradiance at normal incidence. `s = 0` when `l` or `v` is below
//!   the shading normal's horizon.

use glam::DVec3;
use std::f64::consts::PI;

/// Smallest α the fit and the exporter use (a near-mirror; glTF roughness ≈ 0.032).
pub const MIN_ALPHA: f64 = 1e-3;

/// glTF perceptual roughness `r = √α` for a GGX width α (clamped to `[0, 1]`).
#[must_use]
pub fn alpha_to_roughness(alpha: f64) -> f64 {
    alpha.max(0.0).sqrt().min(1.0)
}

/// GGX width `α = r²` for a glTF perceptual roughness `r` (clamped to `[0, 1]` first).
#[must_use]
pub fn roughness_to_alpha(r: f64) -> f64 {
    let r = r.clamp(0.0, 1.0);
    r * r
}

/// GGX normal distribution `D(h)` (1/sr) about the unit normal `n`, width `alpha`.
#[must_use]
pub fn d_ggx(n: DVec3, h: DVec3, alpha: f64) -> f64 {
    let c = n.dot(h);
    if c <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let t = c * c * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// Smith's Λ for GGX at cosine `c = n·w` (> 0) and width `alpha`.
#[inline]
fn lambda(c: f64, alpha: f64) -> f64 {
    let c2 = c * c;
    let tan2 = (1.0 - c2).max(0.0) / c2;
    0.5 * ((1.0 + alpha * alpha * tan2).sqrt() - 1.0)
}

/// The shaded GGX lobe `s(n, α; l, v) = f(l, v)·(n·l)` (1/sr): the microfacet BRDF without
/// Fresnel times the cosine at the light, with Smith's height-correlated `G₂`; 0 below the
/// horizon of `n`. `n`, `l`, `v` are unit vectors; `l` points to the light, `v` to the viewer.
#[must_use]
pub fn shaded(n: DVec3, alpha: f64, l: DVec3, v: DVec3) -> f64 {
    let nl = n.dot(l);
    let nv = n.dot(v);
    if nl <= 0.0 || nv <= 0.0 {
        return 0.0;
    }
    let h = (l + v).normalize_or_zero();
    if h == DVec3::ZERO {
        return 0.0;
    }
    let g2 = 1.0 / (1.0 + lambda(nl, alpha) + lambda(nv, alpha));
    d_ggx(n, h, alpha) * g2 / (4.0 * nv)
}

/// An orthonormal tangent frame `(t, b)` completing the unit vector `n` (`t × b = n`).
#[must_use]
pub fn frame(n: DVec3) -> (DVec3, DVec3) {
    // Frisvad / Duff et al. 2017 branchless basis.
    let s = 1.0_f64.copysign(n.z);
    let a = -1.0 / (s + n.z);
    let b = n.x * n.y * a;
    let t = DVec3::new(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
    let bt = DVec3::new(b, s + n.y * n.y * a, -n.y);
    (t, bt)
}

/// One fine texel of a mip footprint: its unit normal and its GGX width α.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FineTexel {
    /// Unit shading normal (tangent frame).
    pub normal: DVec3,
    /// GGX width α of the texel's own lobe.
    pub alpha: f64,
}

/// View elevations of the fixed direction set, in degrees from the averaged normal.
pub const VIEW_THETAS_DEG: [f64; 3] = [0.0, 30.0, 60.0];
/// View azimuths (degrees) used at each non-zero view elevation.
pub const VIEW_PHIS_DEG: [f64; 3] = [0.0, 120.0, 240.0];
/// Half-vector tilts from the averaged normal, as multiples `c` of the footprint's lobe width
/// `w`: `tan θ_h = c·w`.
pub const HALF_TILTS: [f64; 5] = [0.0, 0.5, 1.0, 2.0, 4.0];
/// Half-vector azimuths (degrees) used at each non-zero tilt.
pub const HALF_PHIS_DEG: [f64; 4] = [0.0, 90.0, 180.0, 270.0];
/// Lowest elevation (cosine about the macro-surface normal +z) a direction of the set may have.
pub const MIN_COS_Z: f64 = 0.05;

/// The footprint's lobe width `w = √(mean α² + mean tan²∠(nᵢ, n̄))` that scales the half-vector
/// tilts of the fixed direction set (dimensionless, capped at 2).
#[must_use]
pub fn footprint_width(fine: &[FineTexel], nbar: DVec3) -> f64 {
    if fine.is_empty() {
        return MIN_ALPHA;
    }
    let mut acc = 0.0;
    for t in fine {
        let c = t.normal.dot(nbar).clamp(1e-3, 1.0);
        acc += t.alpha * t.alpha + (1.0 - c * c) / (c * c);
    }
    (acc / fine.len() as f64).sqrt().clamp(MIN_ALPHA, 2.0)
}

/// The fixed set of direction pairs `(l, v)` a coarse texel is fitted on, built in the frame of
/// its averaged normal `nbar`: views at [`VIEW_THETAS_DEG`] × [`VIEW_PHIS_DEG`] from `nbar`,
/// lights mirrored about half-vectors tilted from `nbar` by `tan θ_h = c·w` for `c` in
/// [`HALF_TILTS`] at [`HALF_PHIS_DEG`] (the set is fixed in lobe-width units, so narrow and wide
/// lobes are sampled alike). Pairs with either direction below `MIN_COS_Z` about the macro
/// surface (+z) or below the horizon of `nbar` are dropped.
#[must_use]
pub fn direction_pairs(nbar: DVec3, width: f64) -> Vec<(DVec3, DVec3)> {
    let (t, b) = frame(nbar);
    let dir = |theta: f64, phi: f64| {
        (t * (theta.sin() * phi.cos()) + b * (theta.sin() * phi.sin()) + nbar * theta.cos())
            .normalize()
    };
    let mut views = Vec::new();
    for &th in &VIEW_THETAS_DEG {
        if th == 0.0 {
            views.push(nbar);
        } else {
            for &ph in &VIEW_PHIS_DEG {
                views.push(dir(th.to_radians(), ph.to_radians()));
            }
        }
    }
    let mut halves = Vec::new();
    for &c in &HALF_TILTS {
        if c == 0.0 {
            halves.push(nbar);
        } else {
            for &ph in &HALF_PHIS_DEG {
                halves.push(dir((c * width).atan(), ph.to_radians()));
            }
        }
    }
    let mut pairs = Vec::with_capacity(views.len() * halves.len());
    for &v in &views {
        for &h in &halves {
            let l = 2.0 * v.dot(h) * h - v;
            if l.z >= MIN_COS_Z && v.z >= MIN_COS_Z && l.dot(nbar) > 0.0 {
                pairs.push((l.normalize(), v));
            }
        }
    }
    pairs
}

/// The supersampled target: the average over `fine` of each texel's shaded lobe at every pair.
#[must_use]
pub fn average_shaded(fine: &[FineTexel], pairs: &[(DVec3, DVec3)]) -> Vec<f64> {
    let mut acc = vec![0.0; pairs.len()];
    for t in fine {
        for (a, &(l, v)) in acc.iter_mut().zip(pairs) {
            *a += shaded(t.normal, t.alpha, l, v);
        }
    }
    let n = fine.len().max(1) as f64;
    acc.iter_mut().for_each(|a| *a /= n);
    acc
}

/// RMS difference (1/sr) over `pairs` between `target` and one GGX lobe about `nbar` of width
/// `alpha`.
#[must_use]
pub fn rms_error(target: &[f64], nbar: DVec3, alpha: f64, pairs: &[(DVec3, DVec3)]) -> f64 {
    if pairs.is_empty() {
        return 0.0;
    }
    let s: f64 = target
        .iter()
        .zip(pairs)
        .map(|(t, &(l, v))| {
            let d = t - shaded(nbar, alpha, l, v);
            d * d
        })
        .sum();
    (s / pairs.len() as f64).sqrt()
}

/// The outcome of fitting one coarse texel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaFit {
    /// The fitted GGX width α (in `[MIN_ALPHA, 1]`).
    pub alpha: f64,
    /// RMS error of the fitted lobe against the supersampled average (1/sr).
    pub rms: f64,
    /// Peak of the supersampled average over the pairs (1/sr); `rms / peak` is the relative
    /// error.
    pub peak: f64,
}

/// Scan points (log-spaced in α) before the golden-section refinement.
pub const SCAN_POINTS: usize = 24;
/// Golden-section iterations after the scan (the bracket shrinks by 0.618 each).
pub const GOLDEN_ITERATIONS: usize = 30;

/// Minimise `err(α)` over `α ∈ [lo, hi]`: a log-spaced scan of [`SCAN_POINTS`] points, then a
/// golden-section search on `ln α` inside the bracket around the best scan point.
pub fn minimise_alpha(lo: f64, hi: f64, err: impl Fn(f64) -> f64) -> (f64, f64) {
    let (a, b) = (lo.ln(), hi.ln());
    let xs: Vec<f64> = (0..SCAN_POINTS)
        .map(|k| a + (b - a) * k as f64 / (SCAN_POINTS - 1) as f64)
        .collect();
    let es: Vec<f64> = xs.iter().map(|&x| err(x.exp())).collect();
    let best = (0..SCAN_POINTS)
        .min_by(|&i, &j| es[i].total_cmp(&es[j]))
        .unwrap_or(0);
    let mut lo_x = xs[best.saturating_sub(1)];
    let mut hi_x = xs[(best + 1).min(SCAN_POINTS - 1)];
    let g = (5.0_f64.sqrt() - 1.0) / 2.0;
    let mut x1 = hi_x - g * (hi_x - lo_x);
    let mut x2 = lo_x + g * (hi_x - lo_x);
    let mut f1 = err(x1.exp());
    let mut f2 = err(x2.exp());
    for _ in 0..GOLDEN_ITERATIONS {
        if f1 < f2 {
            hi_x = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi_x - g * (hi_x - lo_x);
            f1 = err(x1.exp());
        } else {
            lo_x = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo_x + g * (hi_x - lo_x);
            f2 = err(x2.exp());
        }
    }
    let (mut x, mut f) = if f1 < f2 { (x1, f1) } else { (x2, f2) };
    if es[best] < f {
        x = xs[best];
        f = es[best];
    }
    (x.exp(), f)
}

/// Fit one coarse texel: the α of a single GGX lobe about `nbar` (the renormalised average
/// normal) that minimises the RMS difference to the average of the `fine` texels' lobes on the
/// fixed direction set ([`direction_pairs`]). The search runs over `[MIN_ALPHA, 1]`.
#[must_use]
pub fn fit_alpha(fine: &[FineTexel], nbar: DVec3) -> AlphaFit {
    let width = footprint_width(fine, nbar);
    let pairs = direction_pairs(nbar, width);
    let target = average_shaded(fine, &pairs);
    fit_alpha_on(&target, nbar, &pairs)
}

/// [`fit_alpha`] with the direction set and the supersampled target given.
#[must_use]
pub fn fit_alpha_on(target: &[f64], nbar: DVec3, pairs: &[(DVec3, DVec3)]) -> AlphaFit {
    let peak = target.iter().copied().fold(0.0, f64::max);
    let (alpha, rms) = minimise_alpha(MIN_ALPHA, 1.0, |a| rms_error(target, nbar, a, pairs));
    AlphaFit { alpha, rms, peak }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ D(h)(n·h) dω_h = 1 for GGX, by midpoint quadrature over the hemisphere.
    #[test]
    fn ggx_projected_area_is_one() {
        for &alpha in &[0.05, 0.3, 0.8] {
            let n = DVec3::Z;
            let (nt, np) = (4000, 64);
            let mut s = 0.0;
            for i in 0..nt {
                // Substitution t = θ², denser near the pole for narrow lobes.
                let u = (i as f64 + 0.5) / nt as f64;
                let th = u * u * PI / 2.0;
                let dth = 2.0 * u * PI / 2.0 / nt as f64;
                for j in 0..np {
                    let ph = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                    let h = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                    s += d_ggx(n, h, alpha) * th.cos() * th.sin() * dth * (2.0 * PI / np as f64);
                }
            }
            assert!((s - 1.0).abs() < 2e-3, "α = {alpha}: ∫ D cos = {s}");
        }
    }

    #[test]
    fn frame_is_orthonormal() {
        for n in [
            DVec3::Z,
            DVec3::new(0.3, -0.4, 0.866).normalize(),
            -DVec3::Z,
        ] {
            let (t, b) = frame(n);
            assert!(t.dot(b).abs() < 1e-12 && t.dot(n).abs() < 1e-12);
            assert!((t.cross(b) - n).length() < 1e-12);
        }
    }

    #[test]
    fn roughness_alpha_round_trip() {
        for r in [0.0, 0.1, 0.5, 1.0] {
            assert!((alpha_to_roughness(roughness_to_alpha(r)) - r).abs() < 1e-15);
        }
        assert_eq!(roughness_to_alpha(2.0), 1.0);
    }

    /// Identical fine texels: the fit returns their own α with (near) zero error.
    #[test]
    fn identical_texels_keep_their_alpha() {
        let n = DVec3::new(0.2, 0.1, 1.0).normalize();
        for &a in &[0.02, 0.15, 0.6] {
            let fine = vec![
                FineTexel {
                    normal: n,
                    alpha: a
                };
                4
            ];
            let fit = fit_alpha(&fine, n);
            assert!((fit.alpha / a - 1.0).abs() < 1e-4, "{a} → {}", fit.alpha);
            assert!(fit.rms <= 1e-6 * fit.peak);
        }
    }

    #[test]
    fn minimiser_finds_a_known_minimum() {
        let (a, _) = minimise_alpha(1e-3, 1.0, |a| (a.ln() - 0.3_f64.ln()).powi(2));
        assert!((a - 0.3).abs() < 1e-6);
        // A minimum at the lower end of the bracket.
        let (a, _) = minimise_alpha(1e-3, 1.0, |a| a);
        assert!((a - 1e-3).abs() < 1e-6);
    }
}
