//! The von Mises–Fisher distribution (spherical Gaussian) `∝ e^{κ(a·m − 1)}` as a stand-in for a
//! Phong peak (Eq. 12): kept for its paths, the functions live in [`crate::sg`] (the one
//! spherical-Gaussian module, with the lobe type, its normaliser, products and the named
//! Phong ↔ spherical-Gaussian mappings).

pub use crate::sg::{kappa_from_mean_cos, mean_cos, phong_peak_mean_cos};

/// The concentration of the spherical Gaussian that stands in for a Phong peak of exponent
/// `eta`: the same mean cosine, [`crate::sg::kappa_same_mean_cos`] (see its mapping table).
#[must_use]
pub fn phong_peak_kappa(eta: f64) -> f64 {
    crate::sg::kappa_same_mean_cos(eta)
}
