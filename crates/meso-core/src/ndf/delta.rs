//! Delta sums — the multiple surface of Eq. 3: `n(m) = Σ w_i δ(m − N_i)`, the limit η → ∞ of
//! Phong peaks. Weights are probabilities summing to 1. The density is singular, so integrals
//! against it are exact finite sums (Eq. 4 and Eq. 11); evaluation at a direction returns 0.

use glam::DVec3;

/// One normal of a multiple surface: a unit direction in the local frame and its weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WeightedNormal {
    /// Unit normal in the local frame.
    pub normal: DVec3,
    /// Probability weight (share of the surface area with this normal).
    pub weight: f64,
}

/// A multiple surface: a finite set of normals with probability weights.
#[derive(Clone, Debug, PartialEq)]
pub struct DeltaSum {
    normals: Vec<WeightedNormal>,
    cdf: Vec<f64>,
}

impl DeltaSum {
    /// Build from weighted normals; weights are normalised to sum to 1, normals to unit length.
    ///
    /// # Errors
    /// Empty lists, negative / non-finite weights, zero total weight, invalid normals.
    pub fn new(normals: Vec<WeightedNormal>) -> Result<DeltaSum, crate::NdfError> {
        let normals = super::normalize_weights(normals, |n| n.weight, |n, w| n.weight = w)?;
        let mut out = Vec::with_capacity(normals.len());
        for (k, n) in normals.into_iter().enumerate() {
            let l = n.normal.length();
            if !(l.is_finite() && l > 1e-12) {
                return Err(crate::NdfError::Invalid(format!(
                    "normal {}: not a finite non-zero vector",
                    k + 1
                )));
            }
            out.push(WeightedNormal {
                normal: n.normal / l,
                weight: n.weight,
            });
        }
        let cdf = super::cumulative(out.iter().map(|n| n.weight));
        Ok(DeltaSum { normals: out, cdf })
    }

    /// The single normal of a plain surface, +z.
    #[must_use]
    pub fn surface_normal() -> DeltaSum {
        DeltaSum::new(vec![WeightedNormal {
            normal: DVec3::Z,
            weight: 1.0,
        }])
        .expect("one unit normal is valid")
    }

    /// The weighted normals (weights sum to 1).
    #[must_use]
    pub fn normals(&self) -> &[WeightedNormal] {
        &self.normals
    }

    /// Choose one of the normals with probability equal to its weight.
    #[must_use]
    pub fn sample(&self, u: f64) -> DVec3 {
        self.normals[super::pick(&self.cdf, u).0].normal
    }
}
