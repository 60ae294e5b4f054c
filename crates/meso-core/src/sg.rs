//! Spherical Gaussians (von Mises–Fisher lobes), written once: the lobe
//! `A · e^{κ(a·m − 1)}` on the unit sphere, its normaliser, integral, mean cosine, the product of
//! two lobes, the inverse-CDF sampler of its cosine, and the mappings from Phong shapes to it.
//!
//! Closed forms of products and convolutions of spherical Gaussians make them the fast path
//! wherever a lobe meets a facet BRDF: meso-core's [`crate::convolution::phong_closed_form`]
//! (and the fits of `meso-measured`, which use the same closed form with its derivatives),
//! `meso-render`'s NDF-mapped material and `meso-maps`' smoothed lobe fits.
//!
//! # Phong ↔ spherical-Gaussian mappings
//! A Phong peak of the NDF (Eq. 12) `(η+2)/(8π) · cos^η(α/2)` (α the angle to its axis), or a
//! Phong facet term `max(0, m·h)^η`, is replaced by a spherical Gaussian `e^{κ(a·m − 1)}`. There
//! is no single right κ: each caller matches the property its result depends on.
//!
//! | mapping | κ | property kept | used by |
//! |---|---|---|---|
//! | [`kappa_same_integral`] | `(η+2)/4` | the peak's integral `8π/(η+2)` equals the Gaussian's `2π/κ` (so the normalised peak heights agree) | [`crate::convolution::phong_closed_form`], `meso-measured`'s lobe model and its Jacobian (`meso_measured::model::vmf`) |
//! | [`kappa_transfer`] | `η+1` | the facet term `max(0, m·h)^η`'s integral `2π/(η+1)` equals the Gaussian's `2π/κ` | the same closed form, and `meso-render`'s `NdfMapped` under Phong facets |
//! | [`kappa_same_mean_cos`] | `A⁻¹(η/(η+4))` | the peak's mean cosine to its axis `η/(η+4)` (so its projected area and spread) | `meso-render`'s `NdfMapped` texel lobes (whose projected area `E[m_z⁺]` normalises each lobe), `meso-maps`' smoothed refinement (which maps back with [`eta_same_mean_cos`]) |
//! | [`kappa_same_curvature`] (inverse [`eta_same_curvature`]) | `η/4` | equal to second order at the peak: the same small-angle variance `E[α²] ≈ 8/η` (slope variance) | the sampling warps of [`crate::convolution`] and `meso-maps`' vMF baseline (`η = 4κ`, the reverse direction) |
//!
//! Why the closed form and `NdfMapped` map the same NDF peak differently: the closed form of
//! Eq. 2 is dominated by the height of the product of the two lobes at its peak, which the
//! integral-preserving κ gets right for sharp lobes (and `meso-measured` fits exponents through
//! it, so changing it would change every fitted material); `NdfMapped` and the smoothed fit need
//! the lobe's spread (its projected area and mean normal), which the mean cosine fixes. For a
//! sharp peak the three NDF mappings, `(η+2)/4`, `≈ (η+4)/4` and `η/4`, agree to `O(1/η)`.

use glam::DVec3;
use std::f64::consts::PI;

/// A spherical Gaussian `amplitude · e^{κ(axis·m − 1)}` (its peak value is `amplitude`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sg {
    /// Unit axis.
    pub axis: DVec3,
    /// Concentration κ ≥ 0.
    pub kappa: f64,
    /// Value at the axis.
    pub amplitude: f64,
}

impl Sg {
    /// The lobe `amplitude · e^{κ(axis·m − 1)}` (`axis` is used as given: unit length expected).
    #[must_use]
    pub fn new(axis: DVec3, kappa: f64, amplitude: f64) -> Sg {
        Sg {
            axis,
            kappa,
            amplitude,
        }
    }

    /// The lobe normalised on the sphere (a von Mises–Fisher density, 1/sr).
    #[must_use]
    pub fn normalised(axis: DVec3, kappa: f64) -> Sg {
        Sg::new(axis, kappa, normaliser(kappa))
    }

    /// The value at the unit direction `m`.
    #[inline]
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        self.amplitude * (self.kappa * (self.axis.dot(m) - 1.0)).exp()
    }

    /// `∫ sg dω` over the sphere.
    #[must_use]
    pub fn integral(&self) -> f64 {
        self.amplitude * integral(self.kappa)
    }

    /// Mean cosine to the axis ([`mean_cos`]).
    #[must_use]
    pub fn mean_cos(&self) -> f64 {
        mean_cos(self.kappa)
    }

    /// The product of two lobes, itself a spherical Gaussian ([`product`]); a product of
    /// concentration 0 (opposite axes, equal κ) keeps this lobe's axis.
    #[must_use]
    pub fn product(&self, other: &Sg) -> Sg {
        let p = product(self.axis, self.kappa, other.axis, other.kappa);
        Sg {
            axis: if p.kappa > 0.0 {
                p.v / p.kappa
            } else {
                self.axis
            },
            kappa: p.kappa,
            amplitude: self.amplitude * other.amplitude * p.ln_scale.exp(),
        }
    }
}

/// The normaliser `κ / (2π (1 − e^{−2κ}))` of `e^{κ(a·m − 1)}` on the sphere (1/sr): stable for
/// all κ ≥ 0 (`exp_m1`; `(1 + κ)/(4π)` below κ = 1e-8, the uniform density `1/(4π)` at 0).
#[inline]
#[must_use]
pub fn normaliser(kappa: f64) -> f64 {
    if kappa < 1e-8 {
        (1.0 + kappa) / (4.0 * PI)
    } else {
        kappa / (2.0 * PI * (-(-2.0 * kappa).exp_m1()))
    }
}

/// `2π ×` [`normaliser`]: `κ / (1 − e^{−2κ})` (`(1 + κ)/2` below κ = 1e-8), the form used next
/// to a product integral whose `2π` cancels the normaliser's.
#[inline]
#[must_use]
pub fn normaliser_2pi(kappa: f64) -> f64 {
    if kappa < 1e-8 {
        0.5 * (1.0 + kappa)
    } else {
        kappa / -(-2.0 * kappa).exp_m1()
    }
}

/// `d ln(normaliser)/dκ = 1/κ − 2/(e^{2κ} − 1)` (= `1 − mean_cos(κ)`; `1 − κ/3 + κ³/45` below
/// κ = 1e-3).
#[inline]
#[must_use]
pub fn normaliser_dln(kappa: f64) -> f64 {
    if kappa < 1e-3 {
        1.0 - kappa / 3.0 + kappa * kappa * kappa / 45.0
    } else {
        1.0 / kappa - 2.0 / (2.0 * kappa).exp_m1()
    }
}

/// `∫ e^{κ(a·m − 1)} dω = 2π (1 − e^{−2κ})/κ` over the sphere (4π at κ = 0).
#[inline]
#[must_use]
pub fn integral(kappa: f64) -> f64 {
    2.0 * PI * integral_per_2pi(kappa)
}

/// [`integral`]` / 2π = (1 − e^{−2κ})/κ`: `2 − 2κ` below κ = 1e-8, `1/κ` above 20 (where
/// `e^{−2κ}` is below half an ulp of 1, so the result is the same and no `exp` is spent).
#[inline]
#[must_use]
pub fn integral_per_2pi(kappa: f64) -> f64 {
    if kappa < 1e-8 {
        2.0 - 2.0 * kappa
    } else if kappa > 20.0 {
        1.0 / kappa
    } else {
        -(-2.0 * kappa).exp_m1() / kappa
    }
}

/// The product `e^{κ₁(a₁·m − 1)} · e^{κ₂(a₂·m − 1)} = e^{ln_scale} · e^{κ(â·m − 1)}` of
/// [`product`]: `v = κ₁a₁ + κ₂a₂`, `κ = |v|`, axis `â = v/κ`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SgProduct {
    /// `κ₁a₁ + κ₂a₂` (the axis times κ).
    pub v: DVec3,
    /// Concentration `|v|`.
    pub kappa: f64,
    /// `κ − κ₁ − κ₂ ≤ 0`, computed without cancellation.
    pub ln_scale: f64,
}

/// The product of the unit-peak lobes `(a₁, κ₁)` and `(a₂, κ₂)` ([`SgProduct`]), with
/// `κ − κ₁ − κ₂ = (κ² − (κ₁ + κ₂)²)/(κ + κ₁ + κ₂)` and
/// `κ² − (κ₁ + κ₂)² = 2κ₁κ₂(a₁·a₂ − 1) + κ₁²(|a₁|² − 1) + κ₂²(|a₂|² − 1)`: no cancellation for
/// sharp, nearly aligned lobes, and exact (`|v| − κ₁ − κ₂`) for axes off the unit sphere too,
/// so that derivatives with respect to `v` hold in every direction (the last two terms vanish
/// for unit axes).
#[inline]
#[must_use]
pub fn product(a1: DVec3, k1: f64, a2: DVec3, k2: f64) -> SgProduct {
    let v = k1 * a1 + k2 * a2;
    let kappa = v.length();
    let den = kappa + k1 + k2;
    let ln_scale = if den > 0.0 {
        (2.0 * k1 * k2 * (a1.dot(a2) - 1.0)
            + k1 * k1 * (a1.length_squared() - 1.0)
            + k2 * k2 * (a2.length_squared() - 1.0))
            / den
    } else {
        0.0
    };
    SgProduct { v, kappa, ln_scale }
}

/// Mean cosine to the axis of the normalised lobe of concentration `kappa` ≥ 0 on the whole
/// sphere: the Langevin function `A(κ) = coth κ − 1/κ` (`κ/3 − κ³/45` below 1e-3, `1 − 1/κ`
/// beyond 20, where the two differ by less than 1e-16).
#[inline]
#[must_use]
pub fn mean_cos(kappa: f64) -> f64 {
    if kappa < 1e-3 {
        kappa / 3.0 - kappa * kappa * kappa / 45.0
    } else if kappa > 20.0 {
        1.0 - 1.0 / kappa
    } else {
        1.0 / kappa.tanh() - 1.0 / kappa
    }
}

/// The concentration κ whose mean cosine ([`mean_cos`]) is `mu` (clamped to `[0, 1)`):
/// Banerjee et al.'s approximation `μ(3 − μ²)/(1 − μ²)`, then Newton on `A(κ) = μ` with
/// `A' = 1/κ² − 1/sinh²κ`. Relative accuracy ≈ 1e-12 (tested).
#[must_use]
pub fn kappa_from_mean_cos(mu: f64) -> f64 {
    let mu = mu.clamp(0.0, 1.0 - 1e-12);
    if mu < 1e-9 {
        return 3.0 * mu;
    }
    let mut k = mu * (3.0 - mu * mu) / (1.0 - mu * mu);
    for _ in 0..6 {
        let d = if k > 20.0 {
            1.0 / (k * k)
        } else {
            1.0 / (k * k) - 1.0 / k.sinh().powi(2)
        };
        if d <= 0.0 {
            break;
        }
        k = (k - (mean_cos(k) - mu) / d).max(0.5 * k);
    }
    k
}

/// The cosine `w = m·a` of a sample of the normalised lobe from a uniform `u ∈ [0, 1)`: the
/// inverse CDF `w = 1 + ln(u + (1 − u) e^{−2κ})/κ` (Wood 1994, Jakob 2012), written as
/// `1 + ln_1p((1 − u)(e^{−2κ} − 1))/κ` (no cancellation for small κ; uniform `2u − 1` at κ = 0),
/// clamped to `[−1, 1]`.
#[inline]
#[must_use]
pub fn sample_cos(kappa: f64, u: f64) -> f64 {
    if kappa <= 0.0 {
        return (2.0 * u - 1.0).clamp(-1.0, 1.0);
    }
    (1.0 + ((1.0 - u) * (-2.0 * kappa).exp_m1()).ln_1p() / kappa).clamp(-1.0, 1.0)
}

/// Mean cosine to the axis of the Phong peak `(η + 2)/(8π) · cos^η(α/2)` (Eq. 12, α the angle
/// to the axis): `η/(η + 4)`.
#[inline]
#[must_use]
pub fn phong_peak_mean_cos(eta: f64) -> f64 {
    eta / (eta + 4.0)
}

/// **Same mean cosine:** the κ whose lobe has the Phong peak's mean cosine `η/(η + 4)`
/// ([`phong_peak_mean_cos`]). Keeps the lobe's spread, hence its projected area `E[m_z⁺]` and
/// mean normal: `meso-render`'s `NdfMapped` (texel lobes, normalised by their projected area)
/// and `meso-maps`' smoothed refinement (whose fitted κ go back to exponents by
/// [`eta_same_mean_cos`], an exact inverse).
#[must_use]
pub fn kappa_same_mean_cos(eta: f64) -> f64 {
    kappa_from_mean_cos(phong_peak_mean_cos(eta))
}

/// The Phong exponent `η = 4A/(1 − A)` (`A = mean_cos(κ)`, `1 − A` floored at 1e-12) whose peak
/// has the mean cosine of the lobe of concentration κ: the inverse of [`kappa_same_mean_cos`].
#[must_use]
pub fn eta_same_mean_cos(kappa: f64) -> f64 {
    let mc = mean_cos(kappa);
    4.0 * mc / (1.0 - mc).max(1e-12)
}

/// **Same integral:** `κ = (η + 2)/4`, the κ whose Gaussian's integral without its antipodal
/// tail, `2π/κ`, is the integral `8π/(η + 2)` of the Phong peak's shape `cos^η(α/2)`; so the
/// normalised lobes have the same height at the axis (to `e^{−2κ}`). The NDF lobe of
/// [`crate::convolution::phong_closed_form`], and so of `meso-measured`'s fitted closed form,
/// whose height at the peak of the product decides the highlight.
#[inline]
#[must_use]
pub fn kappa_same_integral(eta: f64) -> f64 {
    0.25 * (eta + 2.0)
}

/// **Transfer:** `κ = η + 1` for the Phong facet term `max(0, m·h)^η`, the κ whose Gaussian
/// `e^{κ(m·h − 1)}` has its integral `2π/(η + 1)` (to `e^{−2κ}`). Used for the facet term by
/// [`crate::convolution::phong_closed_form`], `meso-measured`'s lobe model and `meso-render`'s
/// `NdfMapped` (which also corrects by the ratio of the two forms at the product's axis).
#[inline]
#[must_use]
pub fn kappa_transfer(eta: f64) -> f64 {
    eta + 1.0
}

/// **Same curvature:** `κ = η/4`, the κ that matches the Phong peak `cos^η(α/2)` to second order
/// at its axis (`ln cos^η(α/2) ≈ −ηα²/8`, `κ(cos α − 1) ≈ −κα²/2`): the same small-angle
/// variance `E[α²] ≈ 8/η` (slope variance) of a sharp lobe. Its inverse `η = 4κ` builds the
/// sampling warps of a vMF NDF in [`crate::convolution`] and the Phong lobe of `meso-maps`'
/// vMF baseline.
#[inline]
#[must_use]
pub fn kappa_same_curvature(eta: f64) -> f64 {
    0.25 * eta
}

/// The Phong exponent `η = 4κ` matching the lobe of concentration κ to second order at its axis:
/// the inverse of [`kappa_same_curvature`] (the direction the warps and the vMF baseline need).
#[inline]
#[must_use]
pub fn eta_same_curvature(kappa: f64) -> f64 {
    4.0 * kappa
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::gauss_legendre_interval;

    /// `∫_0^π f(α) sin α dα · 2π` for a lobe `f` concentrated within `~1/√k` of α = 0 (composite
    /// Gauss–Legendre on panels that follow the lobe's width).
    fn integrate_polar(f: impl Fn(f64) -> f64, k: f64) -> f64 {
        let width = (1.0 / k.max(1e-12)).sqrt();
        let mut edges = vec![0.0];
        let mut x = 0.05 * width;
        while x < PI {
            edges.push(x);
            x *= 1.25;
        }
        edges.push(PI);
        edges.push(0.5 * PI);
        // Graded towards the antipode too, where a broad Phong peak has a root singularity.
        edges.extend((0..40).map(|j| PI - 0.5f64.powi(j + 1)));
        edges.retain(|&x| x >= 0.0);
        edges.sort_by(f64::total_cmp);
        let mut s = 0.0;
        for w in edges.windows(2) {
            let (xs, ws) = gauss_legendre_interval(16, w[0], w[1]);
            for (a, wt) in xs.iter().zip(&ws) {
                s += wt * f(*a) * a.sin();
            }
        }
        2.0 * PI * s
    }

    const KAPPAS: [f64; 11] = [1e-4, 1e-3, 0.01, 0.1, 1.0, 5.0, 19.0, 21.0, 100.0, 1e3, 1e4];

    #[test]
    fn normalised_lobe_integrates_to_one() {
        for k in KAPPAS {
            let lobe = Sg::normalised(DVec3::Z, k);
            let q = integrate_polar(|a| lobe.eval(DVec3::new(a.sin(), 0.0, a.cos())), k);
            assert!((q - 1.0).abs() < 1e-12, "κ = {k}: {q}");
            assert!((lobe.integral() - 1.0).abs() < 1e-14, "κ = {k}");
            assert!((normaliser_2pi(k) / (2.0 * PI * normaliser(k)) - 1.0).abs() < 1e-15);
            assert!((integral(k) * normaliser(k) - 1.0).abs() < 1e-15);
        }
        assert_eq!(normaliser(0.0), 1.0 / (4.0 * PI));
        assert_eq!(integral(0.0), 4.0 * PI);
        // Continuity across the small-κ and large-κ branches.
        for k in [1e-8, 20.0] {
            let (lo, hi) = (k * (1.0 - 1e-12), k * (1.0 + 1e-12));
            assert!((normaliser(lo) / normaliser(hi) - 1.0).abs() < 1e-11);
            assert!((integral_per_2pi(lo) / integral_per_2pi(hi) - 1.0).abs() < 1e-11);
        }
    }

    #[test]
    fn normaliser_dln_matches_differences() {
        for k in [1e-5f64, 1e-3, 0.5, 3.0, 40.0] {
            let e = 1e-6 * k.max(1.0);
            let d = (normaliser(k + e).ln() - normaliser(k - e).ln()) / (2.0 * e);
            assert!((normaliser_dln(k) - d).abs() < 1e-7, "κ = {k}");
            assert!(
                (normaliser_dln(k) - (1.0 - mean_cos(k))).abs() < 1e-12,
                "κ = {k}"
            );
        }
    }

    #[test]
    fn product_is_a_gaussian_with_its_integral() {
        let a1 = DVec3::new(0.3, -0.5, 0.8).normalize();
        let a2 = DVec3::new(-0.6, 0.1, 0.7).normalize();
        for (k1, k2) in [(0.5, 2.0), (8.0, 40.0), (300.0, 150.0), (1e4, 1e4)] {
            let (s1, s2) = (Sg::new(a1, k1, 1.5), Sg::new(a2, k2, 0.25));
            let p = s1.product(&s2);
            // Pointwise identity.
            for m in [a1, a2, (a1 + a2).normalize(), DVec3::Z, -a1] {
                let want = s1.eval(m) * s2.eval(m);
                let got = p.eval(m);
                assert!(
                    (got - want).abs() <= 1e-11 * want + 1e-290,
                    "κ {k1}, {k2}: {got} vs {want}"
                );
            }
            // Its integral against a quadrature in the product's frame.
            let f = crate::frame::Frame::from_normal(p.axis);
            let np = 64;
            let q = integrate_polar(
                |a| {
                    (0..np)
                        .map(|j| {
                            let phi = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                            let m = f.to_world(DVec3::new(
                                a.sin() * phi.cos(),
                                a.sin() * phi.sin(),
                                a.cos(),
                            ));
                            s1.eval(m) * s2.eval(m)
                        })
                        .sum::<f64>()
                        / np as f64
                },
                p.kappa,
            );
            assert!(
                (p.integral() - q).abs() <= 1e-10 * q.max(1e-300),
                "κ {k1}, {k2}: {} vs {q}",
                p.integral()
            );
        }
        // Sharp, nearly aligned lobes: ln_scale without cancellation.
        let (k, theta) = (1e10, 1e-4f64.atan());
        let b = DVec3::new(1e-4, 0.0, 1.0).normalize();
        let pr = product(DVec3::Z, k, b, k);
        // κ₃ − 2κ = 2κ cos(θ/2) − 2κ = −4κ sin²(θ/4).
        let want = -4.0 * k * (0.25 * theta).sin().powi(2);
        assert!(
            (pr.ln_scale / want - 1.0).abs() < 1e-7,
            "{} vs {want}",
            pr.ln_scale
        );
        // Opposite axes of equal κ: the uniform product.
        let o = product(DVec3::Z, 3.0, -DVec3::Z, 3.0);
        assert_eq!(o.kappa, 0.0);
        assert!((o.ln_scale + 6.0).abs() < 1e-15);
    }

    #[test]
    fn mean_cos_matches_quadrature() {
        for k in KAPPAS {
            let lobe = Sg::normalised(DVec3::Z, k);
            let q = integrate_polar(
                |a| a.cos() * lobe.eval(DVec3::new(a.sin(), 0.0, a.cos())),
                k,
            );
            assert!(
                (mean_cos(k) - q).abs() < 1e-12,
                "κ = {k}: {} vs {q}",
                mean_cos(k)
            );
            assert_eq!(lobe.mean_cos(), mean_cos(k));
        }
    }

    #[test]
    fn kappa_inverts_mean_cos() {
        for k in [1e-3, 0.1, 1.0, 5.0, 19.0, 21.0, 300.0, 1e5] {
            let back = kappa_from_mean_cos(mean_cos(k));
            assert!((back / k - 1.0).abs() < 1e-9, "κ = {k}: {back}");
        }
        for eta in [0.5, 4.0, 40.0, 1e3, 1e6] {
            let back = eta_same_mean_cos(kappa_same_mean_cos(eta));
            assert!((back / eta - 1.0).abs() < 1e-8, "η = {eta}: {back}");
        }
    }

    #[test]
    fn sample_cos_inverts_the_cdf() {
        for k in [1e-6, 0.01, 1.0, 30.0, 1e4] {
            // P(w ≤ sample_cos(u)) = u: the CDF (e^{κ(w−1)} − e^{−2κ})/(1 − e^{−2κ}).
            for u in [0.0, 0.1, 0.5, 0.9, 0.999] {
                let w = sample_cos(k, u);
                let cdf = ((k * (w - 1.0)).exp_m1() - (-2.0 * k).exp_m1()) / -(-2.0 * k).exp_m1();
                assert!((cdf - u).abs() < 1e-9, "κ {k}, u {u}: {cdf}");
            }
        }
        assert_eq!(sample_cos(0.0, 0.25), -0.5);
    }

    /// The Phong peak's shape `cos^η(α/2)`.
    fn peak(eta: f64) -> impl Fn(f64) -> f64 {
        move |a: f64| (0.5 * a).cos().powf(eta)
    }

    #[test]
    fn same_integral_mapping() {
        for eta in [1.0, 10.0, 200.0, 1e4] {
            let k = kappa_same_integral(eta);
            let q = integrate_polar(peak(eta), eta);
            assert!((q / (8.0 * PI / (eta + 2.0)) - 1.0).abs() < 1e-12);
            // The Gaussian's integral without its antipodal tail.
            let g = integral(k) / -(-2.0 * k).exp_m1();
            assert!((g / q - 1.0).abs() < 1e-12, "η = {eta}: {g} vs {q}");
            // So the normalised heights agree but for the Gaussian's factor 1/(1 − e^{−2κ}).
            let h = (eta + 2.0) / (8.0 * PI);
            assert!((normaliser(k) * -(-2.0 * k).exp_m1() / h - 1.0).abs() < 1e-14);
        }
    }

    #[test]
    fn transfer_mapping() {
        for eta in [1.0, 10.0, 200.0, 1e4] {
            let k = kappa_transfer(eta);
            let q = integrate_polar(|a| a.cos().max(0.0).powf(eta), eta);
            let g = integral(k) / -(-2.0 * k).exp_m1();
            assert!((g / q - 1.0).abs() < 1e-9, "η = {eta}: {g} vs {q}");
        }
    }

    #[test]
    fn same_mean_cos_mapping() {
        for eta in [0.5, 4.0, 40.0, 400.0, 1e4] {
            let f = peak(eta);
            let num = integrate_polar(|a| a.cos() * f(a), eta);
            let den = integrate_polar(&f, eta);
            let q = num / den;
            assert!(
                (phong_peak_mean_cos(eta) - q).abs() < 1e-12,
                "η = {eta}: {q}"
            );
            assert!(
                (mean_cos(kappa_same_mean_cos(eta)) - q).abs() < 1e-11,
                "η = {eta}"
            );
        }
    }

    #[test]
    fn same_curvature_mapping() {
        for eta in [4.0, 40.0, 1e3] {
            let k = kappa_same_curvature(eta);
            // Second derivative of the log shapes at the axis.
            let e = 1e-4;
            let d2 = |g: &dyn Fn(f64) -> f64| (g(e) - 2.0 * g(0.0) + g(-e)) / (e * e);
            let phong = d2(&|a: f64| eta * (0.5 * a).cos().ln());
            let sg = d2(&|a: f64| k * (a.cos() - 1.0));
            assert!(
                (phong / sg - 1.0).abs() < 1e-5,
                "η = {eta}: {phong} vs {sg}"
            );
            assert_eq!(eta_same_curvature(k), eta);
        }
        // The small-angle variance E[α²] of the two agrees for a sharp lobe.
        let eta = 1e5;
        let k = kappa_same_curvature(eta);
        let var = |f: &dyn Fn(f64) -> f64| {
            integrate_polar(|a| a * a * f(a), eta) / integrate_polar(f, eta)
        };
        let vp = var(&peak(eta));
        let vs = var(&|a: f64| (k * (a.cos() - 1.0)).exp());
        assert!((vp / vs - 1.0).abs() < 1e-3, "{vp} vs {vs}");
        assert!((vs * eta / 8.0 - 1.0).abs() < 1e-3, "{vs}");
    }
}
