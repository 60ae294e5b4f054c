//! Phong peaks, Eq. 12: `n(m) = Σ c_i (N_i · H(N_i, m))^η_i`.
//!
//! `N_i · H(N_i, m) = cos(α/2)` with α the angle between the lobe axis `N_i` and `m`, so one peak
//! is `cos^η(α/2) = ((1 + cos α)/2)^(η/2)`. It is positive over the whole sphere (zero only at the
//! antipode), and its exact integral is
//!
//! ```text
//! ∫ cos^η(α/2) dω = 2π ∫_{-1}^{1} ((1+u)/2)^{η/2} du = 8π/(η+2).
//! ```
//!
//! A [`PhongLobe`] stores the *probability* `weight` of its peak; its density is
//! `weight · (η+2)/(8π) · cos^η(α/2)` in 1/sr, so a lobe set whose weights sum to 1 is an NDF in the
//! Eq. 1 convention.
//!
//! Sampling is exact: with `u = cos α`, the CDF in `s = ((1+u)/2)^{η/2+1}` is uniform, so
//! `cos α = 2 s^{1/(η/2+1)} − 1`, φ uniform around the axis.

use crate::frame::Frame;
use glam::DVec3;
use std::f64::consts::PI;

/// One Phong peak of Eq. 12: a unit `axis` (local frame), a probability `weight` and an exponent
/// `η ≥ 0` applied to `cos(α/2)`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhongLobe {
    /// Unit lobe axis `N_i` in the local frame (normal +z).
    pub axis: DVec3,
    /// Probability weight (the share of normals in this lobe); non-negative.
    pub weight: f64,
    /// Exponent η on `cos(α/2)`; non-negative. η = 0 is the uniform sphere.
    pub exponent: f64,
}

impl PhongLobe {
    /// A lobe; `axis` is normalised here.
    #[must_use]
    pub fn new(axis: DVec3, weight: f64, exponent: f64) -> PhongLobe {
        PhongLobe {
            axis: axis.normalize(),
            weight,
            exponent,
        }
    }

    /// `(η+2)/(8π)`: the factor that makes `cos^η(α/2)` integrate to 1 over the sphere.
    #[inline]
    #[must_use]
    pub fn normalization(exponent: f64) -> f64 {
        (exponent + 2.0) / (8.0 * PI)
    }

    /// The unnormalised peak `cos^η(α/2)` at the unit direction `m` (Eq. 12, one term, c = 1).
    #[inline]
    #[must_use]
    pub fn peak(&self, m: DVec3) -> f64 {
        let half_cos2 = (0.5 * (1.0 + self.axis.dot(m))).max(0.0);
        half_cos2.powf(0.5 * self.exponent)
    }

    /// The weighted, normalised density `weight · (η+2)/(8π) · cos^η(α/2)` in 1/sr.
    #[inline]
    #[must_use]
    pub fn density(&self, m: DVec3) -> f64 {
        self.weight * Self::normalization(self.exponent) * self.peak(m)
    }

    /// The normalised density of this lobe alone (weight ignored), in 1/sr.
    #[inline]
    #[must_use]
    pub fn unit_density(&self, m: DVec3) -> f64 {
        Self::normalization(self.exponent) * self.peak(m)
    }

    /// Sample a direction from this lobe's unit density, `u ∈ [0,1)²`.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let cos_a = Self::sample_cos(self.exponent, u[0]);
        let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
        let phi = 2.0 * PI * u[1];
        let local = DVec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a);
        Frame::from_normal(self.axis).to_world(local)
    }

    /// The inverse CDF of `cos α` for exponent η: `2 s^{1/(η/2+1)} − 1`.
    #[inline]
    #[must_use]
    pub fn sample_cos(exponent: f64, s: f64) -> f64 {
        (2.0 * s.max(0.0).powf(1.0 / (0.5 * exponent + 1.0)) - 1.0).clamp(-1.0, 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_integral() {
        // ∫ cos^η(α/2) dω = 8π/(η+2), by 1-D quadrature in u = cos α.
        for eta in [0.0, 1.0, 7.5, 100.0] {
            let n = 200_000;
            let mut s = 0.0;
            for k in 0..n {
                let u = -1.0 + 2.0 * (k as f64 + 0.5) / n as f64;
                s += (0.5 * (1.0 + u)).powf(0.5 * eta);
            }
            let integral = 2.0 * PI * s * 2.0 / n as f64;
            let exact = 8.0 * PI / (eta + 2.0);
            assert!((integral / exact - 1.0).abs() < 1e-6, "eta {eta}");
        }
    }
}

/// A sum of Phong peaks (Eq. 12) with probability weights summing to 1.
#[derive(Clone, Debug, PartialEq)]
pub struct PhongPeaks {
    lobes: Vec<PhongLobe>,
    /// Cumulative weights, for choosing a lobe when sampling.
    cdf: Vec<f64>,
}

impl PhongPeaks {
    /// Build from lobes; the weights are normalised to sum to 1.
    ///
    /// # Errors
    /// When there are no lobes, a weight or exponent is negative or not finite, an axis is not a
    /// finite non-zero vector, or the weights sum to zero.
    pub fn new(lobes: Vec<PhongLobe>) -> Result<PhongPeaks, crate::NdfError> {
        let lobes = super::normalize_weights(lobes, |l| l.weight, |l, w| l.weight = w)?;
        for (k, l) in lobes.iter().enumerate() {
            if !(l.exponent.is_finite() && l.exponent >= 0.0) {
                return Err(crate::NdfError::Invalid(format!(
                    "lobe {}: exponent must be a finite number >= 0, got {}",
                    k + 1,
                    l.exponent
                )));
            }
        }
        let lobes: Vec<PhongLobe> = lobes
            .into_iter()
            .map(|l| PhongLobe::new(l.axis, l.weight, l.exponent))
            .collect();
        let cdf = super::cumulative(lobes.iter().map(|l| l.weight));
        Ok(PhongPeaks { lobes, cdf })
    }

    /// The lobes (weights sum to 1).
    #[must_use]
    pub fn lobes(&self) -> &[PhongLobe] {
        &self.lobes
    }

    /// Density in 1/sr at the unit direction `m`.
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        self.lobes.iter().map(|l| l.density(m)).sum()
    }

    /// Sample the mixture exactly: choose a lobe by weight with `u[0]`, rescale, sample it.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let (k, u0) = super::pick(&self.cdf, u[0]);
        self.lobes[k].sample([u0, u[1]])
    }
}
