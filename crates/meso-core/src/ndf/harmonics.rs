//! NDFs as real spherical harmonics up to a user-chosen band (the "simple NDFs" of §2.1).
//!
//! `n(m) = Σ_{l ≤ L} Σ_m c_lm Y_lm(m)` with orthonormal real SH ([`crate::sh`]). The integral over
//! the sphere is exactly `c_00 · 2√π`, so normalisation (Eq. 1) is `c_00 = 1/(2√π)`; the
//! truncated series can dip below zero near sharp features (Gibbs ringing), which is reported by
//! [`Harmonics::negative_mass`]. Sampling uses a table of `max(0, n)` on an equal-area grid fine
//! enough for the band; the sampler's pdf is that table ([`Harmonics::pdf`]), not `n` itself.

use super::Tabulated;
use crate::grid::EqualAreaGrid;
use crate::quadrature::SphereQuadrature;
use crate::sh::{sh_count, sh_project_with, sh_reconstruct};
use glam::DVec3;
use std::f64::consts::PI;

/// Largest band accepted (the evaluation cost grows as (L+1)²).
pub const MAX_BAND: usize = 64;

/// An SH-expanded NDF.
#[derive(Clone, Debug, PartialEq)]
pub struct Harmonics {
    lmax: usize,
    coeffs: Vec<f64>,
    sampler: Tabulated,
}

impl Harmonics {
    /// From coefficients (index `l² + l + m`); the series is rescaled so that `c_00 = 1/(2√π)`.
    ///
    /// # Errors
    /// Band above [`MAX_BAND`], wrong coefficient count, non-finite values, `c_00 ≤ 0`.
    pub fn from_coeffs(lmax: usize, mut coeffs: Vec<f64>) -> Result<Harmonics, crate::NdfError> {
        if lmax > MAX_BAND {
            return Err(crate::NdfError::Invalid(format!(
                "spherical harmonics band {lmax} is above the limit {MAX_BAND}"
            )));
        }
        if coeffs.len() != sh_count(lmax) {
            return Err(crate::NdfError::Invalid(format!(
                "band {lmax} needs {} coefficients, got {}",
                sh_count(lmax),
                coeffs.len()
            )));
        }
        if coeffs.iter().any(|c| !c.is_finite()) {
            return Err(crate::NdfError::Invalid(
                "spherical harmonics coefficients must be finite".into(),
            ));
        }
        if coeffs[0] <= 0.0 {
            return Err(crate::NdfError::Invalid(
                "spherical harmonics: c_00 must be > 0 (the NDF must have positive mass)".into(),
            ));
        }
        let scale = 1.0 / (2.0 * PI.sqrt() * coeffs[0]);
        coeffs.iter_mut().for_each(|c| *c *= scale);
        let cells = (8 * (lmax + 1) * (lmax + 1)).max(2048);
        let grid = EqualAreaGrid::with_cells(cells);
        let sampler = Tabulated::from_fn(grid, 3, |w| sh_reconstruct(&coeffs, lmax, w).max(0.0))?;
        Ok(Harmonics {
            lmax,
            coeffs,
            sampler,
        })
    }

    /// Project any density `f` (1/sr) onto bands `0..=lmax`, with a quadrature exact for
    /// band-limited functions and `oversample`× finer than the band (use ≥ 4 for peaked `f`).
    ///
    /// # Errors
    /// As [`Harmonics::from_coeffs`].
    pub fn project(
        lmax: usize,
        oversample: usize,
        f: impl Fn(DVec3) -> f64,
    ) -> Result<Harmonics, crate::NdfError> {
        if lmax > MAX_BAND {
            return Err(crate::NdfError::Invalid(format!(
                "spherical harmonics band {lmax} is above the limit {MAX_BAND}"
            )));
        }
        let quad = SphereQuadrature::for_band(lmax * oversample.max(1) + 2);
        let coeffs = sh_project_with(lmax, f, &quad);
        Harmonics::from_coeffs(lmax, coeffs)
    }

    /// The band limit L.
    #[must_use]
    pub fn lmax(&self) -> usize {
        self.lmax
    }

    /// The coefficients (index `l² + l + m`).
    #[must_use]
    pub fn coeffs(&self) -> &[f64] {
        &self.coeffs
    }

    /// The truncated series at `m`, 1/sr (may be slightly negative, see the module docs).
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        sh_reconstruct(&self.coeffs, self.lmax, m)
    }

    /// Sample from the tabulated `max(0, n)`.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        self.sampler.sample(u)
    }

    /// The table of `max(0, n)` that [`Harmonics::sample`] draws from.
    #[must_use]
    pub fn sampling_table(&self) -> &Tabulated {
        &self.sampler
    }

    /// The density of [`Harmonics::sample`].
    #[must_use]
    pub fn pdf(&self, m: DVec3) -> f64 {
        self.sampler.eval(m)
    }

    /// `∫ max(0, −n) dω`: how much negative density the truncation left (0 for a positive series).
    #[must_use]
    pub fn negative_mass(&self) -> f64 {
        SphereQuadrature::for_band(2 * self.lmax + 8).integrate(|w| (-self.eval(w)).max(0.0))
    }

    /// The L2 truncation error `(∫ (f − n_L)² dω)^{1/2}` against a reference density `f`.
    #[must_use]
    pub fn l2_error(&self, f: impl Fn(DVec3) -> f64, quad: &SphereQuadrature) -> f64 {
        quad.integrate(|w| (f(w) - self.eval(w)).powi(2)).sqrt()
    }
}
