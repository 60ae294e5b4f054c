//! Normal distribution functions, normalised as in Eq. 1: `∫ n(m) dω = 1` over the whole sphere,
//! `m` a unit direction in the local frame ([`crate::frame`]); densities are in 1/sr.
//!
//! The representations form a closed set, [`Ndf`], dispatched by `match` (no virtual calls):
//!
//! | variant | paper | density | sampler pdf |
//! |---|---|---|---|
//! | [`Ndf::PhongPeaks`] | Eq. 12 | Σ wᵢ (η+2)/(8π) cos^η(αᵢ/2) | exact |
//! | [`Ndf::Deltas`] | Eq. 3 | Σ wᵢ δ(m − Nᵢ) (singular) | discrete |
//! | [`Ndf::Harmonics`] | §2.1 | truncated real SH series | table of max(0, n) |
//! | [`Ndf::Tabulated`] | — | piecewise constant, equal-area grid | exact |
//! | [`Ndf::Sphere`] | Eq. 14 | 1/(4π) | exact |
//! | [`Ndf::Cylinder`] | Eq. 15 | δ(m·a)/(2π) (singular, a great circle) | uniform on the circle |
//! | [`Ndf::VonMisesFisher`] | — | κ e^{κ(μ·m−1)} / (2π(1−e^{−2κ})) | exact |
//! | [`Ndf::Microfacet`] | — | Beckmann / GGX / Student-t `D(m)/A` | `D(m)(m·z)` |
//! | [`Ndf::Mixture`] | Eq. 7 | Σ wₖ Dₖ(m)/Aₖ (Beckmann / GGX / Student-t lobes) | `D(m)(m·z)` |
//! | [`Ndf::Radial`] | §3.3 | isotropic, linear in `θ_m` between nodes (non-parametric, measured) | band means |
//!
//! For the relation to the microfacet convention `∫ D(m)(m·z) dω = 1` see [`microfacet`].

pub mod analytic;
pub mod delta;
pub mod harmonics;
pub mod microfacet;
pub mod mixture;
pub mod phong;
pub mod radial;
pub mod student_t;
pub mod tabulated;
pub mod vmf;

pub use analytic::{Cylinder, Sphere, VonMisesFisher};
pub use delta::{DeltaSum, WeightedNormal};
pub use harmonics::Harmonics;
pub use microfacet::{Distribution, Microfacet};
pub use mixture::{Mixture, MixtureLobe};
pub use phong::{PhongLobe, PhongPeaks};
pub use radial::Radial;
pub use tabulated::Tabulated;

use crate::NdfError;
use glam::{DMat3, DVec3};

/// A normal distribution function in one of meso's representations.
#[derive(Clone, Debug, PartialEq)]
pub enum Ndf {
    /// Sum of Phong peaks, Eq. 12.
    PhongPeaks(PhongPeaks),
    /// Multiple surface: a finite set of normals, Eq. 3.
    Deltas(DeltaSum),
    /// Truncated real spherical-harmonics series.
    Harmonics(Harmonics),
    /// Piecewise constant on the equal-area grid.
    Tabulated(Tabulated),
    /// The sphere, Eq. 14.
    Sphere(Sphere),
    /// A cylinder, Eq. 15.
    Cylinder(Cylinder),
    /// A von Mises–Fisher lobe.
    VonMisesFisher(VonMisesFisher),
    /// Beckmann or GGX in the Eq. 1 convention.
    Microfacet(Microfacet),
    /// A weighted sum of Beckmann / GGX lobes in the Eq. 1 convention ([`mixture`]).
    Mixture(Mixture),
    /// Isotropic, tabulated in `θ_m` (the non-parametric NDF of a measured material).
    Radial(Radial),
}

impl Ndf {
    /// The single normal of a plain surface (+z), a one-element delta sum.
    #[must_use]
    pub fn surface_normal() -> Ndf {
        Ndf::Deltas(DeltaSum::surface_normal())
    }

    /// A short name of the representation.
    #[must_use]
    pub fn kind(&self) -> &'static str {
        match self {
            Ndf::PhongPeaks(_) => "phong-peaks",
            Ndf::Deltas(_) => "deltas",
            Ndf::Harmonics(_) => "harmonics",
            Ndf::Tabulated(_) => "tabulated",
            Ndf::Sphere(_) => "sphere",
            Ndf::Cylinder(_) => "cylinder",
            Ndf::VonMisesFisher(_) => "vmf",
            Ndf::Microfacet(m) => m.distribution.name(),
            Ndf::Mixture(_) => "mixture",
            Ndf::Radial(_) => "radial",
        }
    }

    /// True for the singular representations (deltas, cylinder) whose density is not a function:
    /// [`Ndf::eval`] returns 0 for them and integrals are taken exactly (sums / 1-D integrals).
    #[must_use]
    pub fn is_singular(&self) -> bool {
        matches!(self, Ndf::Deltas(_) | Ndf::Cylinder(_))
    }

    /// True when the NDF is known to be rotationally symmetric about the surface normal (+z):
    /// Phong peaks and vMF lobes whose axes are +z, isotropic Beckmann / GGX and mixtures of
    /// them, the sphere.
    /// False means "not known": other NDFs may still happen to be isotropic.
    #[must_use]
    pub fn is_isotropic(&self) -> bool {
        let on_normal = |a: DVec3| a.x == 0.0 && a.y == 0.0 && a.z > 0.0;
        match self {
            Ndf::PhongPeaks(p) => p.lobes().iter().all(|l| on_normal(l.axis)),
            Ndf::VonMisesFisher(v) => on_normal(v.mu),
            Ndf::Microfacet(m) => m.alpha_x == m.alpha_y,
            Ndf::Mixture(m) => m.is_isotropic(),
            Ndf::Sphere(_) | Ndf::Radial(_) => true,
            Ndf::Deltas(_) | Ndf::Harmonics(_) | Ndf::Tabulated(_) | Ndf::Cylinder(_) => false,
        }
    }

    /// The density `n(m)` in 1/sr at the unit direction `m` (0 for singular NDFs).
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        match self {
            Ndf::PhongPeaks(p) => p.eval(m),
            Ndf::Deltas(_) | Ndf::Cylinder(_) => 0.0,
            Ndf::Harmonics(h) => h.eval(m),
            Ndf::Tabulated(t) => t.eval(m),
            Ndf::Sphere(s) => s.eval(m),
            Ndf::VonMisesFisher(v) => v.eval(m),
            Ndf::Microfacet(mf) => mf.eval(m),
            Ndf::Mixture(mx) => mx.eval(m),
            Ndf::Radial(r) => r.eval(m),
        }
    }

    /// Draw a normal; `u ∈ [0,1)²`. Its density is [`Ndf::pdf`] (for singular NDFs the draw follows
    /// the weights / the circle exactly).
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        match self {
            Ndf::PhongPeaks(p) => p.sample(u),
            Ndf::Deltas(d) => d.sample(u[0]),
            Ndf::Harmonics(h) => h.sample(u),
            Ndf::Tabulated(t) => t.sample(u),
            Ndf::Sphere(s) => s.sample(u),
            Ndf::Cylinder(c) => c.sample(u[0]),
            Ndf::VonMisesFisher(v) => v.sample(u),
            Ndf::Microfacet(mf) => mf.sample(u),
            Ndf::Mixture(mx) => mx.sample(u),
            Ndf::Radial(r) => r.sample(u),
        }
    }

    /// The density (1/sr) of [`Ndf::sample`] at `m`; 0 for singular NDFs.
    #[must_use]
    pub fn pdf(&self, m: DVec3) -> f64 {
        match self {
            Ndf::Harmonics(h) => h.pdf(m),
            Ndf::Microfacet(mf) => mf.pdf(m),
            Ndf::Mixture(mx) => mx.pdf(m),
            Ndf::Radial(r) => r.pdf(m),
            other => other.eval(m),
        }
    }
}

/// Moments of an NDF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NdfStats {
    /// `∫ n dω` (1 for a normalised NDF, Eq. 1).
    pub integral: f64,
    /// `∫ n(m) m dω` — its length is below 1 for a spread distribution.
    pub mean_normal: DVec3,
    /// `∫ n (m − μ)(m − μ)ᵀ dω`, a symmetric 3×3 matrix.
    pub covariance: DMat3,
}

/// Check weights (finite, ≥ 0, positive sum) and rescale them to sum to 1 (weights whose sum
/// overflows `f64` are divided by the largest first).
pub(crate) fn normalize_weights<T>(
    mut items: Vec<T>,
    get: impl Fn(&T) -> f64,
    set: impl Fn(&mut T, f64),
) -> Result<Vec<T>, NdfError> {
    if items.is_empty() {
        return Err(NdfError::Invalid("the NDF has no lobes".into()));
    }
    for (k, it) in items.iter().enumerate() {
        let w = get(it);
        if !(w.is_finite() && w >= 0.0) {
            return Err(NdfError::Invalid(format!(
                "lobe {}: weight must be a finite number >= 0, got {}",
                k + 1,
                crate::display::Num(w)
            )));
        }
    }
    let total: f64 = items.iter().map(&get).sum();
    // Weights whose sum overflows (1e308 + 1e308) are scaled by the largest first; others are
    // divided by their sum as they are.
    let (scale, total) = if total.is_finite() {
        (1.0, total)
    } else {
        let max = items.iter().map(&get).fold(0.0, f64::max);
        (max, items.iter().map(|it| get(it) / max).sum())
    };
    if total <= 0.0 {
        return Err(NdfError::Invalid(
            "the lobe weights sum to zero (an NDF needs positive total weight)".into(),
        ));
    }
    for it in &mut items {
        let w = get(it) / scale / total;
        set(it, w);
    }
    Ok(items)
}

/// Running sums of non-negative weights, normalised to end at 1.
pub(crate) fn cumulative(weights: impl Iterator<Item = f64>) -> Vec<f64> {
    let mut acc = 0.0;
    let mut cdf: Vec<f64> = weights
        .map(|w| {
            acc += w;
            acc
        })
        .collect();
    let total = acc.max(f64::MIN_POSITIVE);
    cdf.iter_mut().for_each(|c| *c /= total);
    if let Some(last) = cdf.last_mut() {
        *last = 1.0;
    }
    cdf
}

/// Choose the interval of `cdf` containing `u` and rescale `u` to `[0,1)` inside it.
pub(crate) fn pick(cdf: &[f64], u: f64) -> (usize, f64) {
    let k = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
    let lo = if k == 0 { 0.0 } else { cdf[k - 1] };
    let width = cdf[k] - lo;
    let r = if width > 0.0 { (u - lo) / width } else { 0.5 };
    (k, r.clamp(0.0, 1.0 - f64::EPSILON))
}
