//! The GGX (Trowbridge–Reitz) specular lobe that engines shade with, isotropic and anisotropic
//! (KHR_materials_anisotropy's `α_t`, `α_b`), and the per-texel fits of a coarse mip texel's lobe
//! to the average of its fine texels' lobes: [`fit_alpha`] (one α) and [`fit_aniso`] (`α_t`,
//! `α_b` and the direction of `α_t`), both by the RMS difference of [`rms_error_of`].
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
//! * An anisotropic lobe ([`AnisoGgx`]) has its widths along an orthonormal pair `(T, B)`
//!   perpendicular to its normal `n`: `T` is the tangent-plane direction at angle `ψ`
//!   (radians, counter-clockwise from +x towards +y, the image's right towards its top)
//!   projected onto the plane perpendicular to `n`, and `B = n × T`. `α_t` is the width along
//!   `T`, `α_b` along `B` (glTF: `T` is the "direction of increased anisotropy roughness").

use crate::batch::{AnisoPairs, LobeGeometry, PairArrays, WIDTH_LANES};
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
    d_ggx_cos(n.dot(h), alpha)
}

/// [`d_ggx`] of the cosine `c = n·h`.
#[inline]
fn d_ggx_cos(c: f64, alpha: f64) -> f64 {
    if c <= 0.0 {
        return 0.0;
    }
    d_ggx_cc(c * c, alpha * alpha)
}

/// [`d_ggx`] of the squared cosine `cc = (n·h)²` (for `n·h > 0`) and `a2 = α²`.
#[inline(always)]
fn d_ggx_cc(cc: f64, a2: f64) -> f64 {
    let t = cc * (a2 - 1.0) + 1.0;
    a2 / (PI * t * t)
}

/// What Smith's Λ of a direction at cosine `c` (> 0) about the normal reads of it: `c²` and
/// `(1 − c²)⁺` (the squared sine, never negative), the form [`shaded_parts`] takes.
#[inline(always)]
pub(crate) fn cos_sin2(c: f64) -> (f64, f64) {
    let c2 = c * c;
    (c2, (1.0 - c2).max(0.0))
}

/// `R = √(c² + α² s²)` of a direction at cosine `c` about the normal (`c2 = c²`,
/// `s2 = (1 − c²)⁺`, `a2 = α²`): Smith's GGX `Λ = ½(√(1 + α² tan²θ) − 1) = ½(R/c − 1)`.
#[inline(always)]
fn smith_r(c2: f64, s2: f64, a2: f64) -> f64 {
    (c2 + a2 * s2).sqrt()
}

/// `2π`.
const TWO_PI: f64 = 2.0 * PI;

/// The shaded lobe ([`shaded`]) from what it reads of the geometry, for `n·l`, `n·v`, `n·h`
/// all > 0: `nl = n·l`, `nv = n·v`, their [`cos_sin2`] `(nl2, sl2)` and `(nv2, sv2)`,
/// `cc = (n·h)²`, and `a2 = α²`. With `R_w = √((n·w)² + α²(1 − (n·w)²))`,
/// `1 + Λ(l) + Λ(v) = ½(R_l/(n·l) + R_v/(n·v))`, so
/// `s = D G₂ / (4 n·v) = α² (n·l) / (2π t² (R_l n·v + R_v n·l))` with
/// `t = (n·h)²(α² − 1) + 1`: two square roots and one division. One formula for [`shaded`] and
/// the batched loops of `crate::batch`.
#[inline(always)]
pub(crate) fn shaded_parts(
    nl: f64,
    nv: f64,
    (nl2, sl2): (f64, f64),
    (nv2, sv2): (f64, f64),
    cc: f64,
    a2: f64,
) -> f64 {
    let rl = smith_r(nl2, sl2, a2);
    let rv = smith_r(nv2, sv2, a2);
    let t = cc * (a2 - 1.0) + 1.0;
    a2 * nl / (TWO_PI * t * t * (rl * nv + rv * nl))
}

/// The shaded GGX lobe `s(n, α; l, v) = f(l, v)·(n·l)` (1/sr): the microfacet BRDF without
/// Fresnel times the cosine at the light, with Smith's height-correlated `G₂`; 0 below the
/// horizon of `n`. `n`, `l`, `v` are unit vectors; `l` points to the light, `v` to the viewer.
#[must_use]
pub fn shaded(n: DVec3, alpha: f64, l: DVec3, v: DVec3) -> f64 {
    cosines(n, l, v, (l + v).normalize_or_zero()).map_or(0.0, |c| shaded_cos(c, alpha))
}

/// What [`shaded`] reads of the geometry, which does not depend on the width: `[n·l, n·v, n·h]`
/// for the normal `n`, the pair `(l, v)` and its half vector `h` (unit, or zero when `l = −v`);
/// `None` where the shaded lobe is 0 at every width (either direction below the horizon of
/// `n`, or no half vector). The searches over α compute it once per pair.
#[inline]
fn cosines(n: DVec3, l: DVec3, v: DVec3, h: DVec3) -> Option<[f64; 3]> {
    let nl = n.dot(l);
    let nv = n.dot(v);
    if nl <= 0.0 || nv <= 0.0 || h == DVec3::ZERO {
        return None;
    }
    Some([nl, nv, n.dot(h)])
}

/// [`shaded`] from its [`cosines`].
#[inline]
fn shaded_cos([nl, nv, c]: [f64; 3], alpha: f64) -> f64 {
    // `n·h ≤ 0`: D = 0.
    if c <= 0.0 {
        return 0.0;
    }
    shaded_parts(nl, nv, cos_sin2(nl), cos_sin2(nv), c * c, alpha * alpha)
}

/// An anisotropic GGX lobe with its frame resolved (see the module's conventions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoGgx {
    /// Unit normal `n` of the lobe (tangent frame of the texture).
    pub normal: DVec3,
    /// Unit direction `T ⊥ n` along which the width is `alpha_t`.
    pub tangent: DVec3,
    /// Unit direction `B = n × T` along which the width is `alpha_b`.
    pub bitangent: DVec3,
    /// GGX width along `T` (dimensionless, > 0).
    pub alpha_t: f64,
    /// GGX width along `B` (dimensionless, > 0).
    pub alpha_b: f64,
}

impl AnisoGgx {
    /// The lobe about the unit normal `normal` whose width `alpha_t` lies along the direction
    /// at angle `angle` (radians, counter-clockwise from +x towards +y of the texture's tangent
    /// frame) projected onto the plane perpendicular to `normal`, and `alpha_b` across it.
    /// For `normal = +z` this is glTF's `T = (cos ψ, sin ψ, 0)`, `B = (−sin ψ, cos ψ, 0)`.
    #[must_use]
    pub fn new(normal: DVec3, angle: f64, alpha_t: f64, alpha_b: f64) -> AnisoGgx {
        let e = DVec3::new(angle.cos(), angle.sin(), 0.0);
        let mut t = (e - normal * normal.dot(e)).normalize_or_zero();
        if t == DVec3::ZERO {
            t = frame(normal).0;
        }
        AnisoGgx {
            normal,
            tangent: t,
            bitangent: normal.cross(t),
            alpha_t,
            alpha_b,
        }
    }

    /// The anisotropic GGX distribution `D(h) = 1 / (π α_t α_b ((h·T/α_t)² + (h·B/α_b)² +
    /// (h·n)²)²)` (1/sr) for a unit `h`; 0 where `h·n ≤ 0`. Equals [`d_ggx`] for
    /// `α_t = α_b`, and `∫ D(h)(h·n) dω_h = 1`.
    #[must_use]
    pub fn d(&self, h: DVec3) -> f64 {
        let c = self.normal.dot(h);
        if c <= 0.0 {
            return 0.0;
        }
        let x = self.tangent.dot(h) / self.alpha_t;
        let y = self.bitangent.dot(h) / self.alpha_b;
        let q = x * x + y * y + c * c;
        1.0 / (PI * self.alpha_t * self.alpha_b * q * q)
    }

    /// Smith's Λ of the anisotropic GGX for a unit direction `w` above the lobe's horizon:
    /// `½(√(1 + (α_t² (w·T)² + α_b² (w·B)²)/(w·n)²) − 1)`.
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        let c = self.normal.dot(w);
        let x = self.alpha_t * self.tangent.dot(w);
        let y = self.alpha_b * self.bitangent.dot(w);
        0.5 * ((1.0 + (x * x + y * y) / (c * c)).sqrt() - 1.0)
    }

    /// The shaded lobe `s = f(l, v)·(n·l)` (1/sr) of this anisotropic GGX, exactly as
    /// [`shaded`] with `D` and Smith's height-correlated `G₂ = 1/(1 + Λ(l) + Λ(v))` of the
    /// anisotropic lobe; 0 below the horizon of `n`.
    #[must_use]
    pub fn shaded(&self, l: DVec3, v: DVec3) -> f64 {
        let nl = self.normal.dot(l);
        let nv = self.normal.dot(v);
        if nl <= 0.0 || nv <= 0.0 {
            return 0.0;
        }
        let h = (l + v).normalize_or_zero();
        if h == DVec3::ZERO {
            return 0.0;
        }
        let g2 = 1.0 / (1.0 + self.lambda(l) + self.lambda(v));
        self.d(h) * g2 / (4.0 * nv)
    }
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
/// Half-vector azimuths (degrees) of the anisotropic fit's direction set: every 45°. Four
/// azimuths 90° apart cannot tell a lobe stretched along 45° from an isotropic one (its width
/// is the same along 0° and 90°), nor ψ from −ψ; eight can.
pub const ANISO_HALF_PHIS_DEG: [f64; 8] = [0.0, 45.0, 90.0, 135.0, 180.0, 225.0, 270.0, 315.0];
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
    direction_pairs_with(nbar, width, &HALF_PHIS_DEG)
}

/// [`direction_pairs`] with the half-vector azimuths `half_phis_deg` (degrees, in the frame
/// [`frame`] of `nbar`) instead of [`HALF_PHIS_DEG`]; the anisotropic fit uses
/// [`ANISO_HALF_PHIS_DEG`].
#[must_use]
pub fn direction_pairs_with(nbar: DVec3, width: f64, half_phis_deg: &[f64]) -> Vec<(DVec3, DVec3)> {
    let (t, b) = frame(nbar);
    // Each angle's sine and cosine once (the same calls on the same angles as one `dir(θ, φ)`
    // per direction would make).
    let sc = |angle: f64| (angle.sin(), angle.cos());
    let dir = |(sin_t, cos_t): (f64, f64), (sin_p, cos_p): (f64, f64)| {
        (t * (sin_t * cos_p) + b * (sin_t * sin_p) + nbar * cos_t).normalize()
    };
    let view_phis = VIEW_PHIS_DEG.map(|ph| sc(ph.to_radians()));
    let mut views = Vec::with_capacity(VIEW_THETAS_DEG.len() * VIEW_PHIS_DEG.len());
    for &th in &VIEW_THETAS_DEG {
        if th == 0.0 {
            views.push(nbar);
        } else {
            let theta = sc(th.to_radians());
            for &phi in &view_phis {
                views.push(dir(theta, phi));
            }
        }
    }
    let half_phis: Vec<(f64, f64)> = half_phis_deg.iter().map(|ph| sc(ph.to_radians())).collect();
    let mut halves = Vec::with_capacity(HALF_TILTS.len() * half_phis.len());
    for &c in &HALF_TILTS {
        if c == 0.0 {
            halves.push(nbar);
        } else {
            let theta = sc((c * width).atan());
            for &phi in &half_phis {
                halves.push(dir(theta, phi));
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

/// Most distinct normals [`peak_pairs`] adds a pair for.
pub const PEAK_NORMALS: usize = 16;

/// Footprint texels [`peak_pairs`] looks at, at most (evenly strided over the footprint).
pub const PEAK_CANDIDATES: usize = 64;

/// Normals closer than this (degrees) count as one in [`peak_pairs`].
pub const PEAK_MERGE_DEG: f64 = 2.0;

/// The pairs at the mirror peaks of a footprint's normals: for each of its distinct normals
/// `n` (up to [`PEAK_NORMALS`], within [`PEAK_MERGE_DEG`] counted as one, read from at most
/// [`PEAK_CANDIDATES`] of its texels), the viewer along `nbar` and the light mirrored about
/// `n`, where both lie at least `MIN_COS_Z` above the macro surface and the light above
/// `nbar`'s horizon. The fit's pairs ([`direction_pairs`]) are fixed in units of the
/// footprint's width; where its normals split into separate narrow peaks (steep faces and
/// walls) they can fall between them, and an error measured there alone compares the lobe
/// with a "peak" far below the footprint's own (`meso export` reported up to 286 % of it on a
/// steep facade). The reported errors ([`crate::mips::LevelStats`]) are measured on both sets.
#[must_use]
pub fn peak_pairs(fine: &[FineTexel], nbar: DVec3) -> Vec<(DVec3, DVec3)> {
    let merge = PEAK_MERGE_DEG.to_radians().cos();
    let stride = fine.len().div_ceil(PEAK_CANDIDATES).max(1);
    let mut normals: Vec<DVec3> = Vec::with_capacity(PEAK_NORMALS);
    for t in fine.iter().step_by(stride) {
        if normals.len() == PEAK_NORMALS {
            break;
        }
        if normals.iter().all(|m| m.dot(t.normal) < merge) {
            normals.push(t.normal);
        }
    }
    let v = nbar;
    if v.z < MIN_COS_Z {
        return Vec::new();
    }
    normals
        .iter()
        .filter_map(|&n| {
            let l = 2.0 * v.dot(n) * n - v;
            (l.z >= MIN_COS_Z && l.dot(nbar) > 0.0).then(|| (l.normalize(), v))
        })
        .collect()
}

/// A fit's error as reported: the RMS difference over the fit's pairs (`rms`, on `count`
/// pairs) and the pairs `extra` (target `extra_target`) together, over the highest target
/// value of both (`peak`, the fit pairs'); `model(l, v)` the fitted lobe (1/sr). A fraction
/// (0 where every target is 0).
#[must_use]
pub fn relative_error_with(
    rms: f64,
    count: usize,
    peak: f64,
    extra: &[(DVec3, DVec3)],
    extra_target: &[f64],
    model: impl Fn(DVec3, DVec3) -> f64,
) -> f64 {
    let peak = extra_target.iter().copied().fold(peak, f64::max);
    let n = count + extra.len();
    if peak <= 0.0 || n == 0 {
        return 0.0;
    }
    let extra_sq: f64 = extra
        .iter()
        .zip(extra_target)
        .map(|(&(l, v), t)| {
            let d = t - model(l, v);
            d * d
        })
        .sum();
    ((rms * rms * count as f64 + extra_sq) / n as f64).sqrt() / peak
}

/// The supersampled target: the average over `fine` of each texel's shaded lobe at every pair.
/// Each pair's sum is added up in the order of `fine`.
#[must_use]
pub fn average_shaded(fine: &[FineTexel], pairs: &[(DVec3, DVec3)]) -> Vec<f64> {
    average_shaded_on(fine, &PairArrays::new(pairs))
}

/// [`average_shaded`] on the pairs as flat arrays (half vectors once per pair): all pairs of
/// one fine texel at once (SIMD lanes doing the scalar operations: `crate::batch`).
pub(crate) fn average_shaded_on(fine: &[FineTexel], arrays: &PairArrays) -> Vec<f64> {
    let mut acc = vec![0.0; arrays.len()];
    for t in fine {
        arrays.accumulate_shaded(t.normal, t.alpha, &mut acc);
    }
    let n = fine.len().max(1) as f64;
    acc.iter_mut().for_each(|a| *a /= n);
    acc
}

/// RMS difference (1/sr) over `pairs` between `target` and one GGX lobe about `nbar` of width
/// `alpha`.
#[must_use]
pub fn rms_error(target: &[f64], nbar: DVec3, alpha: f64, pairs: &[(DVec3, DVec3)]) -> f64 {
    rms_error_of(target, pairs, |l, v| shaded(nbar, alpha, l, v))
}

/// The one error of every fit here: the RMS difference (1/sr) over `pairs` between `target`
/// and a model's shaded lobe `model(l, v)` (1/sr); 0 for no pairs.
#[must_use]
pub fn rms_error_of(
    target: &[f64],
    pairs: &[(DVec3, DVec3)],
    model: impl Fn(DVec3, DVec3) -> f64,
) -> f64 {
    rms_of(target, pairs.iter().map(|&(l, v)| model(l, v)), pairs.len())
}

/// `√(Σ (target − value)² / count)` over `target` and `values` in step; 0 for `count = 0`.
fn rms_of(target: &[f64], values: impl Iterator<Item = f64>, count: usize) -> f64 {
    if count == 0 {
        return 0.0;
    }
    let s: f64 = target
        .iter()
        .zip(values)
        .map(|(t, m)| {
            let d = t - m;
            d * d
        })
        .sum();
    (s / count as f64).sqrt()
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

/// Scan points (log-spaced in α) before the refinement.
pub const SCAN_POINTS: usize = 24;
/// Tolerance of the refinement after the scan, in `ln α`: it stops when the minimum is
/// bracketed to within about twice this (relative precision of α ≈ 2·10⁻⁷, that of the 30
/// golden-section steps it replaces).
pub const LN_ALPHA_TOLERANCE: f64 = 1e-7;
/// Most error evaluations of the refinement after the scan (it needs 6–12 on smooth error
/// curves; 40 is more than golden-section steps alone take to reach [`LN_ALPHA_TOLERANCE`]).
pub const REFINE_ITERATIONS: usize = 40;

/// Minimise `err(α)` over `α ∈ [lo, hi]`: a log-spaced scan of [`SCAN_POINTS`] points, then
/// Brent's method (parabolic steps through the three best points, golden-section steps where
/// those do not shrink the bracket) on `ln α` inside the bracket around the best scan point,
/// to [`LN_ALPHA_TOLERANCE`]. Returns `(α, err(α))`; never worse than the best scan point.
pub fn minimise_alpha(lo: f64, hi: f64, mut err: impl FnMut(f64) -> f64) -> (f64, f64) {
    let xs = scan_points(lo, hi);
    let es = xs.map(|x| err(x.exp()));
    refine_scan(&xs, &es, err)
}

/// The scan of [`minimise_alpha`]: [`SCAN_POINTS`] values of `ln α`, evenly spaced from
/// `ln lo` to `ln hi`.
fn scan_points(lo: f64, hi: f64) -> [f64; SCAN_POINTS] {
    let (a, b) = (lo.ln(), hi.ln());
    std::array::from_fn(|k| a + (b - a) * k as f64 / (SCAN_POINTS - 1) as f64)
}

/// The rest of [`minimise_alpha`] once the errors `es` at the scan points `xs` (`ln α`) are
/// known: Brent's method in the bracket around the best of them, started from the three scan
/// points there. Its parabolas are fitted to the squared error (smooth at an exact fit, where
/// the RMS has a corner); comparisons are the same either way.
fn refine_scan(
    xs: &[f64; SCAN_POINTS],
    es: &[f64; SCAN_POINTS],
    mut err: impl FnMut(f64) -> f64,
) -> (f64, f64) {
    let n = SCAN_POINTS;
    let best = (0..n).min_by(|&i, &j| es[i].total_cmp(&es[j])).unwrap_or(0);
    let tol = LN_ALPHA_TOLERANCE;
    // At an end of the range: when the error does not fall within the tolerance of it, the
    // minimum is there (Brent's steps would only creep towards the end at the golden rate).
    if best == 0 || best == n - 1 {
        let inward = if best == 0 {
            xs[0] + tol
        } else {
            xs[n - 1] - tol
        };
        if err(inward.exp()) >= es[best] {
            return (xs[best].exp(), es[best]);
        }
    }
    let (mut a, mut b) = (xs[best.saturating_sub(1)], xs[(best + 1).min(n - 1)]);
    // x: the best point so far (its RMS `fx_rms`), w the second best, v the previous w; the
    // scan's neighbours of the best point start as w and v.
    let (mut x, mut fx, mut fx_rms) = (xs[best], es[best] * es[best], es[best]);
    let (i, j) = match best {
        0 => (1, 2),
        k if k == n - 1 => (n - 2, n - 3),
        k if es[k - 1] <= es[k + 1] => (k - 1, k + 1),
        k => (k + 1, k - 1),
    };
    let (mut w, mut fw) = (xs[i], es[i] * es[i]);
    let (mut v, mut fv) = (xs[j], es[j] * es[j]);
    let c = 0.5 * (3.0 - 5.0_f64.sqrt());
    // The step before last (`e`) is the bracket, so that a first parabolic step is allowed.
    let (mut d, mut e) = (0.0_f64, b - a);
    for _ in 0..REFINE_ITERATIONS {
        let xm = 0.5 * (a + b);
        if (x - xm).abs() <= 2.0 * tol - 0.5 * (b - a) {
            break;
        }
        let mut parabolic = false;
        if e.abs() > tol {
            // The vertex of the parabola through (x, fx), (w, fw), (v, fv): x + p/q.
            let r = (x - w) * (fx - fv);
            let q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            let mut q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            } else {
                q = -q;
            }
            // Accepted when it lies inside the bracket and moves less than half the step
            // before last (else the parabola is not converging).
            if p.abs() < (0.5 * q * e).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = p / q;
                let u = x + d;
                if u - a < 2.0 * tol || b - u < 2.0 * tol {
                    d = tol.copysign(xm - x);
                }
                parabolic = true;
            }
        }
        if !parabolic {
            e = if x >= xm { a - x } else { b - x };
            d = c * e;
        }
        let u = if d.abs() >= tol {
            x + d
        } else {
            x + tol.copysign(d)
        };
        let fu_rms = err(u.exp());
        let fu = fu_rms * fu_rms;
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv) = (w, fw);
            (w, fw) = (x, fx);
            (x, fx, fx_rms) = (u, fu, fu_rms);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv) = (w, fw);
                (w, fw) = (u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    (x.exp(), fx_rms)
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
    fit_alpha_on_range(target, nbar, pairs, MIN_ALPHA)
}

/// [`fit_alpha_on`] with the search over `[lo, 1]` instead of `[MIN_ALPHA, 1]` (`lo` clamped to
/// `[MIN_ALPHA, 1]`).
#[must_use]
pub fn fit_alpha_on_range(
    target: &[f64],
    nbar: DVec3,
    pairs: &[(DVec3, DVec3)],
    lo: f64,
) -> AlphaFit {
    IsoSearch::new(target, nbar, pairs).fit(lo)
}

/// The isotropic fit of one coarse texel, prepared: the lobe's geometry about `nbar` at every
/// pair once ([`LobeGeometry`]); each width then costs two square roots and three divisions
/// per pair, all pairs at once. The same numbers as [`rms_error`] (its operations, in its
/// order).
pub(crate) struct IsoSearch<'a> {
    target: &'a [f64],
    geometry: LobeGeometry,
    scratch: Vec<f64>,
    peak: f64,
}

impl<'a> IsoSearch<'a> {
    /// The search for the supersampled `target` on `pairs` about the unit normal `nbar`.
    pub(crate) fn new(target: &'a [f64], nbar: DVec3, pairs: &[(DVec3, DVec3)]) -> Self {
        Self::on(target, nbar, &PairArrays::new(pairs))
    }

    /// [`IsoSearch::new`] on the pairs as flat arrays.
    pub(crate) fn on(target: &'a [f64], nbar: DVec3, arrays: &PairArrays) -> Self {
        IsoSearch {
            target,
            geometry: LobeGeometry::new(nbar, arrays),
            scratch: Vec::with_capacity(arrays.len()),
            peak: target.iter().copied().fold(0.0, f64::max),
        }
    }

    /// RMS difference (1/sr) between the target and the lobe of width `alpha`: [`rms_error`].
    pub(crate) fn rms(&mut self, alpha: f64) -> f64 {
        self.geometry.rms(self.target, alpha, &mut self.scratch)
    }

    /// The best α in `[lo, 1]` (`lo` clamped to `[MIN_ALPHA, 1]`) by [`minimise_alpha`], its
    /// scan [`WIDTH_LANES`] widths at a time.
    pub(crate) fn fit(&mut self, lo: f64) -> AlphaFit {
        let lo = lo.clamp(MIN_ALPHA, 1.0);
        let xs = scan_points(lo, 1.0);
        let mut es = [0.0; SCAN_POINTS];
        for (x, e) in xs.chunks(WIDTH_LANES).zip(es.chunks_mut(WIDTH_LANES)) {
            // A short last chunk is padded with its last width.
            let alphas = std::array::from_fn(|j| x[j.min(x.len() - 1)].exp());
            let rms = self.geometry.rms_of_widths(self.target, &alphas);
            e.copy_from_slice(&rms[..e.len()]);
        }
        let (alpha, rms) = refine_scan(&xs, &es, |a| self.rms(a));
        AlphaFit {
            alpha,
            rms,
            peak: self.peak,
        }
    }
}

/// The outcome of fitting one coarse texel with an anisotropic GGX lobe ([`fit_aniso`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AnisoFit {
    /// Width along the direction `angle` (the larger one: `alpha_t ≥ alpha_b`), in
    /// `[α₀, 1]` with `α₀` the footprint's smallest base α ([`base_alpha_floor`]).
    pub alpha_t: f64,
    /// Width across it, in `[α₀, 1]`.
    pub alpha_b: f64,
    /// Direction of `alpha_t` in the texture's tangent frame, radians in `[0, π)`,
    /// counter-clockwise from +x (right) towards +y (up the image); see [`AnisoGgx::new`].
    /// 0 when the lobe is isotropic.
    pub angle: f64,
    /// RMS error of the anisotropic lobe against the supersampled average (1/sr).
    pub rms: f64,
    /// The isotropic fit on the same direction set ([`fit_alpha_on`], refitted on `[α₀, 1]`
    /// when it falls below the footprint's smallest base α `α₀`): its α …
    pub iso_alpha: f64,
    /// … and its RMS error (1/sr); `rms ≤ iso_rms` always (the isotropic lobe is kept when
    /// the anisotropic search finds nothing better).
    pub iso_rms: f64,
    /// Peak of the supersampled average over the pairs (1/sr).
    pub peak: f64,
}

/// Levenberg–Marquardt iterations of the anisotropic fit ([`meso_core::lm`]).
pub const ANISO_LM_ITERATIONS: usize = 40;

/// The anisotropic fit as a least-squares problem for [`meso_core::lm`]: parameters
/// `(ln α_x, ln α_y, ψ)` with `α_x` along the direction at angle `ψ`; residuals the lobe's
/// shaded values minus the target on the direction set (so the cost is a multiple of
/// [`rms_error_of`]'s square); Jacobian by forward differences.
/// The pairs' width-independent geometry is computed once ([`AnisoPairs`]) and every
/// evaluation does all pairs at once (SIMD lanes, [`AnisoGgx::shaded`]'s operations).
struct AnisoProblem<'a> {
    target: &'a [f64],
    pairs: AnisoPairs,
    nbar: DVec3,
}

impl AnisoProblem<'_> {
    fn lobe(&self, p: &[f64]) -> AnisoGgx {
        AnisoGgx::new(self.nbar, p[2], p[0].exp(), p[1].exp())
    }
    fn residuals(&self, p: &[f64], out: &mut [f64]) -> f64 {
        let m = out.len().min(self.target.len());
        let out = &mut out[..m];
        self.pairs.residuals(&self.lobe(p), self.target, out);
        // The cost added up in pair order.
        let mut c = 0.0;
        for o in out.iter() {
            c += *o * *o;
        }
        0.5 * c
    }
}

impl meso_core::lm::VectorProblem for AnisoProblem<'_> {
    fn n_params(&self) -> usize {
        3
    }
    fn cost(&self, p: &[f64]) -> f64 {
        let mut r = vec![0.0; self.pairs.len()];
        self.residuals(p, &mut r)
    }
    fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
        let m = self.pairs.len();
        let mut r = vec![0.0; m];
        let cost = self.residuals(p, &mut r);
        let mut cols = vec![0.0; 3 * m];
        let mut q = [p[0], p[1], p[2]];
        for j in 0..3 {
            let step = 1e-6;
            q[j] = p[j] + step;
            let col = &mut cols[j * m..(j + 1) * m];
            // The residuals only: their cost is not needed here.
            self.pairs.residuals(&self.lobe(&q), self.target, col);
            for (c, r0) in col.iter_mut().zip(&r) {
                *c = (*c - r0) / step;
            }
            q[j] = p[j];
        }
        // Jᵀr and the six distinct entries of the symmetric JᵀJ in one pass over the pairs:
        // nine independent sums, each added in pair order from `Sum`'s starting value, as nine
        // separate `.sum()`s would (and `x·y = y·x` exactly, so the mirrored entries agree).
        let (c0, c1, c2) = (&cols[..m], &cols[m..2 * m], &cols[2 * m..]);
        let start: f64 = std::iter::empty::<f64>().sum();
        let mut s = [start; 9];
        for i in 0..m {
            let (x0, x1, x2, ri) = (c0[i], c1[i], c2[i], r[i]);
            s[0] += x0 * ri;
            s[1] += x1 * ri;
            s[2] += x2 * ri;
            s[3] += x0 * x0;
            s[4] += x0 * x1;
            s[5] += x0 * x2;
            s[6] += x1 * x1;
            s[7] += x1 * x2;
            s[8] += x2 * x2;
        }
        jtr[..3].copy_from_slice(&s[..3]);
        jtj[..9].copy_from_slice(&[s[3], s[4], s[5], s[4], s[6], s[7], s[5], s[7], s[8]]);
        cost
    }
}

/// A starting point `(α_x, α_y, ψ)` for the anisotropic fit from the footprint's second
/// moments: the covariance of the fine normals' slopes in the tangent plane of `nbar` (axes
/// `T(0)` and `nbar × T(0)` of [`AnisoGgx::new`]) plus `mean α²/2` on its diagonal, whose
/// principal axis gives `ψ` and whose eigenvalue ratio `λ₁/λ₂` splits `iso_alpha` into
/// `α_x = iso_alpha·(λ₁/λ₂)^¼`, `α_y = iso_alpha·(λ₂/λ₁)^¼`.
#[must_use]
pub fn moment_start(fine: &[FineTexel], nbar: DVec3, iso_alpha: f64) -> (f64, f64, f64) {
    let f = AnisoGgx::new(nbar, 0.0, 1.0, 1.0);
    let (mut sxx, mut syy, mut sxy, mut a2) = (0.0, 0.0, 0.0, 0.0);
    for t in fine {
        let c = t.normal.dot(nbar).max(1e-3);
        let x = t.normal.dot(f.tangent) / c;
        let y = t.normal.dot(f.bitangent) / c;
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
        a2 += t.alpha * t.alpha;
    }
    let n = fine.len().max(1) as f64;
    let (sxx, syy, sxy) = (sxx / n + a2 / (2.0 * n), syy / n + a2 / (2.0 * n), sxy / n);
    let psi = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    let mean = 0.5 * (sxx + syy);
    let dev = (0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy).sqrt();
    let (l1, l2) = (mean + dev, (mean - dev).max(1e-12 * mean.max(1e-300)));
    let ratio = (l1 / l2).powf(0.25).min(1e3);
    (iso_alpha * ratio, iso_alpha / ratio, psi)
}

/// The smallest base α of the `fine` texels, clamped to `[MIN_ALPHA, 1]` ([`MIN_ALPHA`] for
/// none): the lower bound of both widths of an anisotropic fit ([`fit_aniso_on`]), since the
/// base lobes convolved with the footprint's spread of normals are nowhere narrower than the
/// narrowest of them.
#[must_use]
pub fn base_alpha_floor(fine: &[FineTexel]) -> f64 {
    fine.iter()
        .map(|t| t.alpha)
        .fold(f64::INFINITY, f64::min)
        .clamp(MIN_ALPHA, 1.0)
}

/// Fit one coarse texel with an anisotropic GGX lobe about `nbar`: `α_t`, `α_b` and the
/// direction of `α_t` minimising the same RMS difference as [`fit_alpha`] ([`rms_error_of`]),
/// to the average of the `fine` texels' lobes, on the direction set with half-vector azimuths
/// every 45° ([`direction_pairs_with`], [`ANISO_HALF_PHIS_DEG`]).
#[must_use]
pub fn fit_aniso(fine: &[FineTexel], nbar: DVec3) -> AnisoFit {
    let width = footprint_width(fine, nbar);
    let pairs = direction_pairs_with(nbar, width, &ANISO_HALF_PHIS_DEG);
    let target = average_shaded(fine, &pairs);
    fit_aniso_on(fine, &target, nbar, &pairs)
}

/// [`fit_aniso`] with the direction set and the supersampled target given (`fine` only
/// supplies the starting point, [`moment_start`]). The isotropic fit on the same set comes
/// first; Levenberg–Marquardt ([`meso_core::lm::minimize_boxed`], `ln α` in
/// `[ln α₀, 0]` with `α₀` the footprint's smallest base α, [`base_alpha_floor`]: no width
/// narrower than the base lobe) then starts from the moments; the result is put in canonical form
/// (`α_t ≥ α_b`, `angle ∈ [0, π)`), and the isotropic lobe is returned instead when it is at
/// least as good.
#[must_use]
pub fn fit_aniso_on(
    fine: &[FineTexel],
    target: &[f64],
    nbar: DVec3,
    pairs: &[(DVec3, DVec3)],
) -> AnisoFit {
    fit_aniso_with(
        fine,
        &mut IsoSearch::new(target, nbar, pairs),
        target,
        nbar,
        pairs,
    )
}

/// [`fit_aniso_on`] with its isotropic search prepared (`iso` was made from `target`, `nbar`
/// and `pairs`).
pub(crate) fn fit_aniso_with(
    fine: &[FineTexel],
    iso: &mut IsoSearch<'_>,
    target: &[f64],
    nbar: DVec3,
    pairs: &[(DVec3, DVec3)],
) -> AnisoFit {
    // A filtered lobe (the base lobes spread by the footprint's normals) is nowhere narrower
    // than the narrowest base lobe it averages: both widths are kept at or above it.
    let floor = base_alpha_floor(fine);
    let search = iso;
    let mut iso = search.fit(MIN_ALPHA);
    if iso.alpha < floor {
        iso = search.fit(floor);
    }
    let mut best = AnisoFit {
        alpha_t: iso.alpha,
        alpha_b: iso.alpha,
        angle: 0.0,
        rms: iso.rms,
        iso_alpha: iso.alpha,
        iso_rms: iso.rms,
        peak: iso.peak,
    };
    if pairs.is_empty() || iso.rms <= 1e-9 * iso.peak {
        return best;
    }
    let problem = AnisoProblem {
        target,
        pairs: AnisoPairs::new(nbar, pairs),
        nbar,
    };
    let (ax, ay, psi) = moment_start(fine, nbar, iso.alpha);
    let lo = floor.ln();
    let bounds = [(lo, 0.0), (lo, 0.0), (psi - 2.0 * PI, psi + 2.0 * PI)];
    let opts = meso_core::lm::LmOptions {
        max_iterations: ANISO_LM_ITERATIONS,
        rel_tolerance: 1e-7,
        ..Default::default()
    };
    let (p, _) = meso_core::lm::minimize_boxed(&problem, &[ax.ln(), ay.ln(), psi], &bounds, &opts);
    let (mut at, mut ab, mut angle) = (p[0].exp(), p[1].exp(), p[2]);
    if at < ab {
        std::mem::swap(&mut at, &mut ab);
        angle += PI / 2.0;
    }
    let angle = match angle.rem_euclid(PI) {
        a if a < PI => a,
        _ => 0.0,
    };
    let lobe = AnisoGgx::new(nbar, angle, at, ab);
    let rms = rms_error_of(target, pairs, |l, v| lobe.shaded(l, v));
    if rms < best.rms {
        best.alpha_t = at;
        best.alpha_b = ab;
        best.angle = angle;
        best.rms = rms;
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    #[test]
    fn peak_pairs_hit_each_distinct_normals_mirror_peak() {
        let tilt = |deg: f64, az: f64| {
            let (t, p) = (deg.to_radians(), az.to_radians());
            DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
        };
        // Two texels alike, one within 1° of another (counted as one), and one so steep that
        // its mirror light would lie below the macro surface (dropped).
        let normals = [
            tilt(0.0, 0.0),
            tilt(0.0, 0.0),
            tilt(30.0, 0.0),
            tilt(31.0, 0.0),
            tilt(40.0, 90.0),
            tilt(80.0, 180.0),
        ];
        let fine: Vec<FineTexel> = normals
            .iter()
            .map(|&normal| FineTexel { normal, alpha: 0.1 })
            .collect();
        let nbar = DVec3::Z;
        let pairs = peak_pairs(&fine, nbar);
        assert_eq!(pairs.len(), 3, "{pairs:?}");
        for (&(l, v), want) in pairs.iter().zip([normals[0], normals[2], normals[4]]) {
            assert_eq!(v, nbar);
            assert!((l.length() - 1.0).abs() < 1e-12);
            let h = (l + v).normalize();
            assert!(h.dot(want) > 1.0 - 1e-12, "{h} vs {want}");
        }
        // At most PEAK_NORMALS pairs, however many distinct normals.
        let many: Vec<FineTexel> = (0..400)
            .map(|k| FineTexel {
                normal: tilt(20.0 + 0.1 * f64::from(k % 50), f64::from(k) * 7.3),
                alpha: 0.1,
            })
            .collect();
        assert!(peak_pairs(&many, nbar).len() <= PEAK_NORMALS);
        // Below the viewer's floor: none.
        assert!(peak_pairs(&fine, tilt(89.0, 0.0)).is_empty());
    }

    #[test]
    fn the_reported_error_adds_the_extra_pairs_to_the_fits() {
        // rms 0.3 over 4 pairs; two more pairs missing by 2 and 0 under a peak of 4.
        let extra = [(DVec3::Z, DVec3::Z), (DVec3::X, DVec3::Z)];
        let got = relative_error_with(0.3, 4, 1.0, &extra, &[4.0, 1.0], |l, _| {
            if l == DVec3::Z {
                2.0
            } else {
                1.0
            }
        });
        let want = ((0.09 * 4.0 + 4.0) / 6.0f64).sqrt() / 4.0;
        assert!((got - want).abs() < 1e-15, "{got} vs {want}");
        // No extra pairs: the fit's own error.
        assert_eq!(relative_error_with(0.3, 4, 2.0, &[], &[], |_, _| 0.0), 0.15);
    }

    /// The refinement [`minimise_alpha`] had before Brent's method (until 2026-12-05): 30
    /// golden-section steps in the bracket around the best scan point; the reference of
    /// `brent_refinement_finds_the_golden_section_minimum`.
    fn refine_golden(
        xs: &[f64; SCAN_POINTS],
        es: &[f64; SCAN_POINTS],
        mut err: impl FnMut(f64) -> f64,
    ) -> (f64, f64) {
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
        for _ in 0..30 {
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

    /// `∫ D(h)(n·h) dω_h` over the hemisphere of `n` by the midpoint rule on `nt × np` cells in
    /// `(u, φ)`, `θ = u² π/2` (denser near the pole for narrow lobes); `d(θ, φ)` is `D` at the
    /// direction of polar angle `θ` from `n` and azimuth `φ` (radians).
    fn projected_area(nt: usize, np: usize, d: impl Fn(f64, f64) -> f64) -> f64 {
        let mut s = 0.0;
        for i in 0..nt {
            let u = (i as f64 + 0.5) / nt as f64;
            let th = u * u * PI / 2.0;
            let dth = 2.0 * u * PI / 2.0 / nt as f64;
            for j in 0..np {
                let ph = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
                s += d(th, ph) * th.cos() * th.sin() * dth * (2.0 * PI / np as f64);
            }
        }
        s
    }

    /// ∫ D(h)(n·h) dω_h = 1 for GGX, by midpoint quadrature over the hemisphere.
    #[test]
    fn ggx_projected_area_is_one() {
        for &alpha in &[0.05, 0.3, 0.8] {
            let n = DVec3::Z;
            let s = projected_area(4000, 64, |th, ph| {
                let h = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                d_ggx(n, h, alpha)
            });
            assert!((s - 1.0).abs() < 2e-3, "α = {alpha}: ∫ D cos = {s}");
        }
    }

    /// ∫ D(h)(n·h) dω_h = 1 for the anisotropic GGX (closed form: the projected area of the
    /// microsurface is the macro surface's), by midpoint quadrature over the hemisphere of its
    /// own normal, for several widths, ratios up to 50, directions and tilted normals.
    #[test]
    fn aniso_ggx_projected_area_is_one() {
        let normals = [DVec3::Z, DVec3::new(0.3, -0.2, 0.9).normalize()];
        for n in normals {
            let (ft, fb) = frame(n);
            for &(at, ab, psi) in &[
                (0.3, 0.3, 0.0),
                (0.5, 0.1, 0.4),
                (0.8, 0.05, 2.0),
                (0.02, 1.0, 1.0),
            ] {
                let lobe = AnisoGgx::new(n, psi, at, ab);
                let s = projected_area(3000, 720, |th, ph| {
                    lobe.d(ft * (th.sin() * ph.cos()) + fb * (th.sin() * ph.sin()) + n * th.cos())
                });
                assert!(
                    (s - 1.0).abs() < 3e-3,
                    "n = {n}, α = ({at}, {ab}), ψ = {psi}: ∫ D cos = {s}"
                );
            }
        }
    }

    /// With α_t = α_b the anisotropic lobe is the isotropic one: D, and the shaded lobe with
    /// its Smith G₂, agree with [`d_ggx`] and [`shaded`] at random directions; and its frame is
    /// the glTF one for n = +z.
    #[test]
    fn aniso_ggx_with_equal_widths_is_the_isotropic_one() {
        let mut rng = meso_testkit::rng(12345);
        let mut rnd = || rng.random::<f64>();
        let unit = |rnd: &mut dyn FnMut() -> f64| {
            let z = rnd();
            let ph = 2.0 * PI * rnd();
            let r = (1.0 - z * z).sqrt();
            DVec3::new(r * ph.cos(), r * ph.sin(), z)
        };
        for _ in 0..2000 {
            let n = (unit(&mut rnd) + DVec3::Z * 2.0).normalize();
            let (l, v) = (unit(&mut rnd), unit(&mut rnd));
            let a = 0.01 + rnd();
            let lobe = AnisoGgx::new(n, 2.0 * PI * rnd(), a, a);
            let h = (l + v).normalize();
            let (d0, d1) = (d_ggx(n, h, a), lobe.d(h));
            assert!((d0 - d1).abs() <= 1e-12 * d0.max(1e-300), "{d0} {d1}");
            let (s0, s1) = (shaded(n, a, l, v), lobe.shaded(l, v));
            assert!((s0 - s1).abs() <= 1e-12 * s0.max(1e-300), "{s0} {s1}");
        }
        let f = AnisoGgx::new(DVec3::Z, 0.5, 0.3, 0.1);
        assert!((f.tangent - DVec3::new(0.5f64.cos(), 0.5f64.sin(), 0.0)).length() < 1e-15);
        assert!((f.bitangent - DVec3::new(-0.5f64.sin(), 0.5f64.cos(), 0.0)).length() < 1e-15);
    }

    /// The glTF spec's own form of D (`a² w²² / π` with `f = (α_b t·h, α_t b·h, α_t α_b n·h)`,
    /// `w² = a² / f·f`, `a² = α_t α_b`), written out independently, gives the same values.
    #[test]
    fn aniso_ggx_matches_the_khr_formula() {
        let n = DVec3::new(0.1, 0.2, 1.0).normalize();
        let lobe = AnisoGgx::new(n, 0.7, 0.6, 0.15);
        for k in 0..200 {
            let (th, ph) = (k as f64 * 0.0071, k as f64 * 0.37);
            let h = lobe.tangent * (th.sin() * ph.cos())
                + lobe.bitangent * (th.sin() * ph.sin())
                + n * th.cos();
            let a2 = lobe.alpha_t * lobe.alpha_b;
            let f = DVec3::new(
                lobe.alpha_b * lobe.tangent.dot(h),
                lobe.alpha_t * lobe.bitangent.dot(h),
                a2 * n.dot(h),
            );
            let w2 = a2 / f.dot(f);
            let khr = a2 * w2 * w2 / PI;
            assert!((khr - lobe.d(h)).abs() <= 1e-12 * khr);
        }
    }

    /// A target that *is* an anisotropic GGX lobe is recovered: widths within 1 %, direction
    /// within 0.5°, for directions off the direction set's azimuths.
    #[test]
    fn aniso_fit_recovers_a_known_lobe() {
        let n = DVec3::new(0.05, -0.1, 1.0).normalize();
        for &(at, ab, psi_deg) in &[(0.4, 0.1, 30.0), (0.25, 0.12, 100.0), (0.6, 0.3, 160.0)] {
            let psi: f64 = f64::to_radians(psi_deg);
            let truth = AnisoGgx::new(n, psi, at, ab);
            let w = (0.5 * (at * at + ab * ab)).sqrt();
            let pairs = direction_pairs_with(n, w, &ANISO_HALF_PHIS_DEG);
            let target: Vec<f64> = pairs.iter().map(|&(l, v)| truth.shaded(l, v)).collect();
            // Fine texels whose moments point roughly the right way (the start only).
            let fine = [
                FineTexel {
                    normal: n,
                    alpha: ab,
                },
                FineTexel {
                    normal: (n + truth.tangent * 0.3).normalize(),
                    alpha: ab,
                },
                FineTexel {
                    normal: (n - truth.tangent * 0.3).normalize(),
                    alpha: ab,
                },
            ];
            let fit = fit_aniso_on(&fine, &target, n, &pairs);
            let dpsi = (fit.angle - psi).rem_euclid(PI);
            let dpsi = dpsi.min(PI - dpsi).to_degrees();
            assert!(
                (fit.alpha_t / at - 1.0).abs() < 0.01 && (fit.alpha_b / ab - 1.0).abs() < 0.01,
                "({at}, {ab}) → ({}, {})",
                fit.alpha_t,
                fit.alpha_b
            );
            assert!(dpsi < 0.5, "ψ {psi_deg}° → {}°", fit.angle.to_degrees());
            assert!(fit.rms < 1e-3 * fit.peak && fit.rms < 0.1 * fit.iso_rms);
        }
    }

    /// The one-division form of the shaded lobe is the textbook `D G₂ / (4 n·v)` with
    /// `Λ = ½(√(1 + α² tan²θ) − 1)` (the form used until 2026-12-05) to rounding: within
    /// 10⁻¹³ relative at random directions, grazing ones (cosines down to 10⁻⁴) and widths
    /// 0.001–1.
    #[test]
    fn one_division_form_is_the_textbook_lobe() {
        let mut rng = meso_testkit::rng(77);
        let mut rnd = move || rng.random::<f64>();
        let mut worst = 0.0_f64;
        for k in 0..20000 {
            let n = DVec3::new(rnd() - 0.5, rnd() - 0.5, 1.0).normalize();
            let (t, b) = frame(n);
            // Cosines about n uniform, or (one in four) within 10⁻⁴–10⁻² of grazing.
            let mut dir = |grazing: bool| {
                let c = if grazing {
                    10f64.powf(-4.0 + 2.0 * rnd())
                } else {
                    rnd().max(1e-4)
                };
                let s = (1.0 - c * c).sqrt();
                let ph = 2.0 * PI * rnd();
                (t * ph.cos() + b * ph.sin()) * s + n * c
            };
            let (l, v) = (dir(k % 4 == 1), dir(k % 4 == 2));
            let alpha = 10f64.powf(-3.0 * rnd());
            let (nl, nv) = (n.dot(l), n.dot(v));
            let h = (l + v).normalize();
            let lam = |c: f64| 0.5 * ((1.0 + alpha * alpha * (1.0 - c * c) / (c * c)).sqrt() - 1.0);
            let want = d_ggx(n, h, alpha) / (1.0 + lam(nl) + lam(nv)) / (4.0 * nv);
            let got = shaded(n, alpha, l, v);
            let rel = (got - want).abs() / want.max(1e-300);
            worst = worst.max(rel);
            assert!(
                rel <= 1e-13,
                "n·l {nl}, n·v {nv}, α {alpha}: {got} vs {want}"
            );
        }
        eprintln!("largest relative difference {worst:.1e}");
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

    /// Brent's refinement finds the minimum the 30 golden-section steps found, on the fits of
    /// random footprints (2 to 64 fine texels, normals up to ≈ 50° off, base α 0.01–0.6):
    /// `ln α` within 10⁻⁶, the error no larger (beyond 10⁻⁹ of it, or than at the golden
    /// α moved by twice [`LN_ALPHA_TOLERANCE`]), in fewer than half the evaluations.
    #[test]
    fn brent_refinement_finds_the_golden_section_minimum() {
        let mut rng = meso_testkit::rng(2024);
        let mut rnd = move || rng.random::<f64>();
        let (mut brent_evals, mut golden_evals, mut worst) = (0usize, 0usize, 0.0_f64);
        for case in 0..400 {
            let k = 2 + (rnd() * 63.0) as usize;
            let spread = 1.2 * rnd();
            let base = 0.01 + 0.59 * rnd() * rnd();
            let fine: Vec<FineTexel> = (0..k)
                .map(|_| FineTexel {
                    normal: DVec3::new(spread * (rnd() - 0.5), spread * (rnd() - 0.5), 1.0)
                        .normalize(),
                    alpha: if case % 2 == 0 {
                        base
                    } else {
                        base * (0.5 + rnd())
                    },
                })
                .collect();
            let nbar = crate::mips::average_normal(&fine);
            let pairs = direction_pairs(nbar, footprint_width(&fine, nbar));
            let target = average_shaded(&fine, &pairs);
            let mut search = IsoSearch::new(&target, nbar, &pairs);
            let xs = scan_points(MIN_ALPHA, 1.0);
            let es = xs.map(|x| search.rms(x.exp()));
            let (ab, eb) = refine_scan(&xs, &es, |a| {
                brent_evals += 1;
                search.rms(a)
            });
            let (ag, eg) = refine_golden(&xs, &es, |a| {
                golden_evals += 1;
                search.rms(a)
            });
            let dx = (ab.ln() - ag.ln()).abs();
            worst = worst.max(dx);
            assert!(dx < 1e-6, "case {case}: α {ab} (Brent) vs {ag} (golden)");
            // No larger than the golden section's, or than its α moved by twice the tolerance
            // (the precision both searches have) when the error rises that steeply (near-exact
            // fits).
            let moved = (2.0 * LN_ALPHA_TOLERANCE).exp();
            let near = search.rms(ag * moved).min(search.rms(ag / moved));
            assert!(
                eb <= eg * (1.0 + 1e-9) || eb <= near,
                "case {case}: error {eb} vs {eg} ({near} at ±2 tolerances), α {ab} vs {ag}"
            );
            assert_eq!(search.rms(ab), eb, "case {case}: the error returned is α's");
        }
        assert!(
            2 * brent_evals < golden_evals,
            "{brent_evals} evaluations (Brent) vs {golden_evals} (golden section)"
        );
        eprintln!(
            "Brent: {brent_evals} evaluations, golden section: {golden_evals}; \
             largest |Δ ln α| {worst:.2e}"
        );
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
