//! A weighted sum of Beckmann / GGX lobes on the normal: the "sum of simple NDFs" of Eq. 7 with
//! lobes that have long tails (GGX) or Gaussian slopes (Beckmann).
//!
//! Each lobe `k` is a [`Microfacet`] in the Eq. 1 convention, `n_k = D_k / A_k` (∫ n_k dω = 1),
//! and the mixture is `n = Σ w_k n_k` with weights `w_k ≥ 0` summing to 1, so it integrates to
//! 1 too. In the microfacet convention (`∫ D (m·z) dω = 1`) the mixture is
//!
//! ```text
//! P = ∫_{z>0} n (m·z) dω = Σ w_k P_k,   P_k = 1/A_k,
//! D = n / P = Σ c_k D_k,               c_k = w_k P_k / P   (Σ c_k = 1),
//! Λ(ω) = Σ c_k Λ_k(ω)
//! ```
//!
//! — the last because the projected area towards ω, `(1 + Λ) cos θ = ∫ D (ω·m)⁺ dω_m`, is linear
//! in `D`. Everything is therefore in closed form: Smith masking ([`Mixture::lambda`]) and the
//! microfacet BRDF of mirror facets (`crate::shading::FastBrdf`). The sampler picks lobe `k` with
//! probability `c_k` (its share of the projected area) and draws from that lobe's `D_k (m·z)`,
//! so its density is the mixture's `D(m)(m·z)`, as for a single [`Microfacet`].

use super::microfacet::{Distribution, Microfacet};
use glam::DVec3;

/// One lobe of a [`Mixture`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MixtureLobe {
    /// The lobe (Beckmann or GGX).
    pub microfacet: Microfacet,
    /// Its weight in the Eq. 1 density (normalised: the weights of a mixture sum to 1).
    pub weight: f64,
}

/// Most lobes of a mixture.
pub const MAX_MIXTURE_LOBES: usize = 64;

/// A weighted sum of Beckmann / GGX lobes (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Mixture {
    lobes: Vec<MixtureLobe>,
    /// `c_k = w_k P_k / P`, the lobes' weights in `D`.
    d_weights: Vec<f64>,
    /// Running sums of `d_weights` (the sampler's lobe choice).
    cdf: Vec<f64>,
    /// `P = Σ w_k / A_k`.
    projected_area: f64,
}

impl Mixture {
    /// A mixture of `(lobe, weight)` pairs; the weights are rescaled to sum to 1.
    ///
    /// # Errors
    /// When the list is empty or longer than [`MAX_MIXTURE_LOBES`], or a weight is negative or
    /// not finite, or the weights sum to zero.
    pub fn new(lobes: Vec<(Microfacet, f64)>) -> Result<Mixture, crate::NdfError> {
        if lobes.len() > MAX_MIXTURE_LOBES {
            return Err(crate::NdfError::Invalid(format!(
                "a mixture has at most {MAX_MIXTURE_LOBES} lobes, got {}",
                lobes.len()
            )));
        }
        let lobes = super::normalize_weights(
            lobes
                .into_iter()
                .map(|(microfacet, weight)| MixtureLobe { microfacet, weight })
                .collect(),
            |l| l.weight,
            |l, w| l.weight = w,
        )?;
        let projected_area: f64 = lobes
            .iter()
            .map(|l| l.weight / l.microfacet.area_ratio())
            .sum();
        let d_weights: Vec<f64> = lobes
            .iter()
            .map(|l| l.weight / l.microfacet.area_ratio() / projected_area)
            .collect();
        let cdf = super::cumulative(d_weights.iter().copied());
        Ok(Mixture {
            lobes,
            d_weights,
            cdf,
            projected_area,
        })
    }

    /// Isotropic lobes `(distribution, α, weight)`.
    ///
    /// # Errors
    /// As [`Mixture::new`] and [`Microfacet::isotropic`].
    pub fn isotropic(lobes: &[(Distribution, f64, f64)]) -> Result<Mixture, crate::NdfError> {
        let v = lobes
            .iter()
            .enumerate()
            .map(|(k, &(d, a, w))| {
                Microfacet::isotropic(d, a)
                    .map(|m| (m, w))
                    .map_err(|e| crate::NdfError::Invalid(format!("lobe {}: {e}", k + 1)))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Mixture::new(v)
    }

    /// The lobes (weights summing to 1).
    #[must_use]
    pub fn lobes(&self) -> &[MixtureLobe] {
        &self.lobes
    }

    /// The lobes' weights in the microfacet `D`, `c_k = w_k P_k / P` (sum 1).
    #[must_use]
    pub fn d_weights(&self) -> &[f64] {
        &self.d_weights
    }

    /// `P = ∫_{z>0} n (m·z) dω = Σ w_k / A_k` (dimensionless, ≤ 1).
    #[must_use]
    pub fn projected_area(&self) -> f64 {
        self.projected_area
    }

    /// True when every lobe is isotropic.
    #[must_use]
    pub fn is_isotropic(&self) -> bool {
        self.lobes.iter().all(|l| l.microfacet.is_isotropic())
    }

    /// The Eq. 1 density `n(m) = Σ w_k D_k(m)/A_k` (1/sr).
    #[inline]
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        self.d(m) * self.projected_area
    }

    /// `D(m) = Σ c_k D_k(m)` in the microfacet convention (1/sr, `∫ D (m·z) dω = 1`).
    #[inline]
    #[must_use]
    pub fn d(&self, m: DVec3) -> f64 {
        self.lobes
            .iter()
            .zip(&self.d_weights)
            .map(|(l, c)| c * l.microfacet.d(m))
            .sum()
    }

    /// [`Mixture::d`] of an isotropic mixture at the normal making cosine `cos_theta` with +z.
    #[inline]
    #[must_use]
    pub fn d_isotropic(&self, cos_theta: f64) -> f64 {
        self.lobes
            .iter()
            .zip(&self.d_weights)
            .map(|(l, c)| c * l.microfacet.d_isotropic(cos_theta))
            .sum()
    }

    /// Smith `Λ(w) = Σ c_k Λ_k(w)` (module docs), closed form.
    #[inline]
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        self.lobes
            .iter()
            .zip(&self.d_weights)
            .map(|(l, c)| c * l.microfacet.lambda(w))
            .sum()
    }

    /// [`Mixture::lambda`] of an isotropic mixture for a direction of cosine `cos_theta`.
    #[inline]
    #[must_use]
    pub fn lambda_isotropic(&self, cos_theta: f64) -> f64 {
        if cos_theta <= 0.0 {
            return f64::INFINITY;
        }
        self.lobes
            .iter()
            .zip(&self.d_weights)
            .map(|(l, c)| c * l.microfacet.lambda_isotropic(cos_theta))
            .sum()
    }

    /// Draw `m` with density `D(m)(m·z)` ([`Mixture::pdf`]): lobe `k` with probability `c_k`,
    /// then its own sampler.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let (k, r) = super::pick(&self.cdf, u[0]);
        self.lobes[k].microfacet.sample([r, u[1]])
    }

    /// The density of [`Mixture::sample`]: `D(m)(m·z)` in 1/sr.
    #[must_use]
    pub fn pdf(&self, m: DVec3) -> f64 {
        self.d(m) * m.z.max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_are_normalised_and_bad_ones_refused() {
        let g = Microfacet::isotropic(Distribution::Ggx, 0.1).unwrap();
        let b = Microfacet::isotropic(Distribution::Beckmann, 0.4).unwrap();
        let m = Mixture::new(vec![(g, 3.0), (b, 1.0)]).unwrap();
        assert!((m.lobes()[0].weight - 0.75).abs() < 1e-15);
        assert!((m.d_weights().iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let p = 0.75 / g.area_ratio() + 0.25 / b.area_ratio();
        assert!((m.projected_area() - p).abs() < 1e-15);
        assert!(Mixture::new(vec![]).is_err());
        assert!(Mixture::new(vec![(g, -1.0)]).is_err());
        assert!(Mixture::new(vec![(g, 0.0)]).is_err());
        assert!(Mixture::new(vec![(g, f64::NAN)]).is_err());
        // One lobe: exactly the lobe.
        let one = Mixture::new(vec![(g, 2.0)]).unwrap();
        let w = crate::frame::spherical_direction_deg(40.0, 10.0);
        assert!((one.eval(w) - g.eval(w)).abs() < 1e-15 * g.eval(w));
        assert!((one.lambda(w) - g.lambda(w)).abs() < 1e-15);
    }
}
