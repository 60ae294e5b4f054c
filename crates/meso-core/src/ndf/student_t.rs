//! The Student-t distribution of slopes (STD; Ribardière, Bringier, Meneveaux, Simonot 2017,
//! "STD: Student's t-Distribution of Slopes for Microfacet Based BRDFs"): the special functions
//! behind [`crate::ndf::Distribution::StudentT`].
//!
//! The slope density (slopes `s = −(m_x, m_y)/m_z`, isotropic roughness α) is
//!
//! ```text
//! P22(s) = (γ−1)^γ / (π α²) · (γ − 1 + |s|²/α²)^(−γ),     γ > 1,
//! ```
//!
//! which integrates to 1 over the slope plane (`u = |s|²/α²`: `∫ P22 d²s = (γ−1)^γ ∫₀^∞
//! (γ−1+u)^(−γ) du = 1`), and `D(m) = P22(s)/cos⁴θ = (1 + tan²θ/((γ−1)α²))^(−γ) / (π α² cos⁴θ)`
//! (anisotropic: `α²` → `α_x α_y`, `tan²θ/α²` → `e = (m_x²/α_x² + m_y²/α_y²)/m_z²`). γ = 2 is GGX;
//! γ → ∞ is Beckmann with the same α. It is a bivariate Student t with `ν = 2γ − 2` degrees of
//! freedom and scale `α/√2` per axis, so the slope along any direction is a univariate Student t
//! with `ν` degrees of freedom and scale `σ = α(φ)/√2`, and Smith's
//! `Λ(μ) = (1/μ) ∫_μ^∞ (q − μ) P2(q) dq` (`μ = cot θ`) has the closed form, with `k = μ/σ`,
//!
//! ```text
//! Λ = (ν + k²) / ((ν − 1) k) · f_ν(k) − S_ν(k),
//! f_ν(k) = Γ((ν+1)/2) / (√(νπ) Γ(ν/2)) · (1 + k²/ν)^(−(ν+1)/2),   S_ν(k) = ½ I_{ν/(ν+k²)}(ν/2, ½)
//! ```
//!
//! (`∫_k^∞ x f_ν(x) dx = (ν + k²) f_ν(k)/(ν − 1)`; `I` the regularised incomplete beta function,
//! evaluated by its continued fraction). `∂Λ/∂ln α = Λ + S_ν(k)`.
//!
//! The area ratio `A = E[√(1 + |s|²)]` is finite only for γ > 3/2 (the tail of `|s|` decays as
//! `|s|^(2−2γ)`), so meso's Eq. 1 form `n = D/A` needs `γ ∈` [`MIN_GAMMA`, [`MAX_GAMMA`]].

use crate::special::ln_gamma;

/// Smallest γ accepted: `A = ∫ D dω` grows as `1/(γ − 3/2)` and is infinite at 3/2.
pub const MIN_GAMMA: f64 = 1.51;
/// Largest γ accepted (γ → ∞ is Beckmann; at 1000 `D` is within about 0.1 % of it).
pub const MAX_GAMMA: f64 = 1000.0;

/// Constants of one γ (computed once per distribution).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StudentT {
    /// The shape γ.
    pub gamma: f64,
    /// Degrees of freedom of the 1-D slope, `ν = 2γ − 2`.
    nu: f64,
    /// `Γ((ν+1)/2) / (√(νπ) Γ(ν/2))`.
    f_norm: f64,
    /// `ln B(ν/2, ½)`.
    ln_beta: f64,
}

impl StudentT {
    /// The constants of shape γ (not validated: callers check [`MIN_GAMMA`] ≤ γ ≤ [`MAX_GAMMA`]).
    #[must_use]
    pub fn new(gamma: f64) -> StudentT {
        let nu = 2.0 * gamma - 2.0;
        let (lg_a, lg_h) = (ln_gamma(0.5 * nu), ln_gamma(0.5 * (nu + 1.0)));
        StudentT {
            gamma,
            nu,
            f_norm: (lg_h - lg_a).exp() / (nu * std::f64::consts::PI).sqrt(),
            ln_beta: lg_a + ln_gamma(0.5) - lg_h,
        }
    }

    /// `(1 + e/(γ−1))^(−γ)`: `D · π α_x α_y cos⁴θ` for `e = tan²θ/α²` (module docs).
    #[inline]
    #[must_use]
    pub fn shape(&self, e: f64) -> f64 {
        (-self.gamma * (e / (self.gamma - 1.0)).ln_1p()).exp()
    }

    /// Smith `Λ` and `∂Λ/∂ln α` for `a = 1/(α tan θ)` (α along the direction's azimuth), in
    /// closed form (module docs); `(0, 0)` where `Λ < 1e-300`.
    #[must_use]
    pub fn lambda_and_dlnalpha(&self, a: f64) -> (f64, f64) {
        let nu = self.nu;
        let k = std::f64::consts::SQRT_2 * a;
        let k2 = k * k;
        let f = self.f_norm * (-0.5 * (nu + 1.0) * (k2 / nu).ln_1p()).exp();
        let s = 0.5 * self.incomplete_beta(nu / (nu + k2), k2 / (nu + k2));
        let l = ((nu + k2) / ((nu - 1.0) * k) * f - s).max(0.0);
        if l < 1e-300 {
            return (0.0, 0.0);
        }
        (l, l + s)
    }

    /// Smith `Λ` for `a = 1/(α tan θ)` ([`StudentT::lambda_and_dlnalpha`]).
    #[inline]
    #[must_use]
    pub fn lambda(&self, a: f64) -> f64 {
        self.lambda_and_dlnalpha(a).0
    }

    /// `I_x(ν/2, ½)` with `y = 1 − x` given separately (no cancellation near `x = 1`).
    fn incomplete_beta(&self, x: f64, y: f64) -> f64 {
        let (a, b) = (0.5 * self.nu, 0.5);
        if x <= 0.0 {
            return 0.0;
        }
        if y <= 0.0 {
            return 1.0;
        }
        let front = (a * x.ln() + b * y.ln() - self.ln_beta).exp();
        if x < (a + 1.0) / (a + b + 2.0) {
            front * beta_cf(a, b, x) / a
        } else {
            1.0 - front * beta_cf(b, a, y) / b
        }
    }

    /// `A = E[√(1 + a²(ψ) u)]` for one slope azimuth, `a²(ψ)` the squared roughness along it and
    /// `u = |s|²/α(ψ)²` the scaled squared slope: `u = (γ−1) expm1(τ/(γ−1))` with `τ ~ Exp(1)`,
    /// so `A = ∫₀^∞ √(1 + a²(γ−1) expm1(τ/(γ−1))) e^(−τ) dτ`, by Gauss–Legendre on
    /// `τ = 40 t²` and on the tail `τ = 40 + T t²` (`T = 40/λ`, `λ = (2γ−3)/(2γ−2)` the tail's
    /// decay rate).
    #[must_use]
    pub fn area_ratio_along(&self, a2: f64, xs: &[f64], ws: &[f64]) -> f64 {
        let g1 = self.gamma - 1.0;
        let c = a2 * g1;
        let integrand = |tau: f64| {
            let x = tau / g1;
            let l = if x > 600.0 {
                c.ln() + x
            } else {
                (c * x.exp_m1()).ln_1p()
            };
            (0.5 * l - tau).exp()
        };
        let lambda = (2.0 * self.gamma - 3.0) / (2.0 * self.gamma - 2.0);
        let tail = 40.0 / lambda;
        let mut s = 0.0;
        for (x, w) in xs.iter().zip(ws) {
            let t = 0.5 * (x + 1.0);
            s += 0.5 * w * integrand(40.0 * t * t) * 80.0 * t;
            s += 0.5 * w * integrand(40.0 + tail * t * t) * 2.0 * tail * t;
        }
        s
    }

    /// A scaled squared slope `u = |s|²/α²` drawn from the lobe for `ξ ∈ [0, 1)`: the inverse of
    /// `P(U ≤ u) = 1 − ((γ−1)/(γ−1+u))^(γ−1)`.
    #[inline]
    #[must_use]
    pub fn sample_u(&self, xi: f64) -> f64 {
        let g1 = self.gamma - 1.0;
        g1 * (-(1.0 - xi).max(1e-300).ln() / g1).exp_m1()
    }
}

/// The continued fraction of the incomplete beta function (modified Lentz), to 1e-15.
fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / lentz_guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..=400 {
        let m = f64::from(m);
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 / lentz_guard(1.0 + aa * d);
        c = lentz_guard(1.0 + aa / c);
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 / lentz_guard(1.0 + aa * d);
        c = lentz_guard(1.0 + aa / c);
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// Lentz's guard: a denominator or ratio within 1e-300 of zero becomes 1e-300 (so the next
/// division stays finite).
#[inline]
fn lentz_guard(v: f64) -> f64 {
    const TINY: f64 = 1e-300;
    if v.abs() < TINY {
        TINY
    } else {
        v
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gamma_two_is_ggx_lambda() {
        let t = StudentT::new(2.0);
        for a in [0.01f64, 0.1, 0.5, 1.0, 3.0, 10.0, 100.0] {
            let x = 1.0 / (a * a);
            let ggx = 0.5 * x / (1.0 + (1.0 + x).sqrt());
            let (l, dl) = t.lambda_and_dlnalpha(a);
            assert!((l / ggx - 1.0).abs() < 1e-12, "a={a}: {l} vs {ggx}");
            let r = (1.0 + 1.0 / (a * a)).sqrt();
            let dggx = 0.5 / (a * a) / r;
            assert!((dl / dggx - 1.0).abs() < 1e-12, "a={a}: {dl} vs {dggx}");
        }
    }
}
