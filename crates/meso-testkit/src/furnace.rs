//! Energy and symmetry checks of a BRDF `f(i, o)` (both directions unit, local frame, pointing
//! away from the surface; see [`meso_core::frame`]).

use crate::Rng;
use glam::DVec3;
use meso_core::quadrature::integrate_hemisphere;
use rand::RngExt;
use std::f64::consts::PI;

/// The directional albedo `ρ(i) = ∫_{z>0} f(i, o) cos θ_o dω_o` for one incident direction — the
/// radiance a BRDF reflects towards `i` in a white furnace (uniform unit illumination).
///
/// Quadrature: `n_theta` Gauss–Legendre nodes in `cos θ_o ∈ [0, 1]` × `n_phi` uniform azimuths.
/// Smooth lobes converge fast; for a lobe of angular width `w` radians use about `4/w` nodes in
/// each direction. An energy-conserving BRDF has `ρ(i) ≤ 1` for every `i`.
#[must_use]
pub fn white_furnace(
    brdf: impl Fn(DVec3, DVec3) -> f64,
    i: DVec3,
    n_theta: usize,
    n_phi: usize,
) -> f64 {
    integrate_hemisphere(|o| brdf(i, o) * o.z, n_theta, n_phi)
}

/// [`white_furnace`] at `n_incident` incident directions with θ_i spread uniformly over
/// `(0°, 90°)` (cell midpoints) in the plane φ_i = 0: `(θ_i, ρ(θ_i))` pairs.
#[must_use]
pub fn white_furnace_sweep(
    brdf: impl Fn(DVec3, DVec3) -> f64,
    n_incident: usize,
    n_theta: usize,
    n_phi: usize,
) -> Vec<(f64, f64)> {
    (0..n_incident)
        .map(|k| {
            let theta = 0.5 * PI * (k as f64 + 0.5) / n_incident as f64;
            let i = meso_core::frame::spherical_direction(theta, 0.0);
            (theta, white_furnace(&brdf, i, n_theta, n_phi))
        })
        .collect()
}

/// The largest relative violation of Helmholtz reciprocity over `pairs`:
/// `max |f(i, o) − f(o, i)| / max(|f(i, o)|, |f(o, i)|)`, pairs where both values are zero skipped.
/// Returns 0 for a reciprocal BRDF (up to rounding) and `NaN` if any value is NaN.
#[must_use]
pub fn reciprocity_error(
    brdf: impl Fn(DVec3, DVec3) -> f64,
    pairs: impl IntoIterator<Item = (DVec3, DVec3)>,
) -> f64 {
    let mut worst = 0.0f64;
    for (i, o) in pairs {
        let (a, b) = (brdf(i, o), brdf(o, i));
        if a.is_nan() || b.is_nan() {
            return f64::NAN;
        }
        let scale = a.abs().max(b.abs());
        if scale > 0.0 {
            worst = worst.max((a - b).abs() / scale);
        }
    }
    worst
}

/// `n` pairs of directions drawn uniformly and independently on the upper hemisphere.
#[must_use]
pub fn random_hemisphere_pairs(rng: &mut Rng, n: usize) -> Vec<(DVec3, DVec3)> {
    (0..n)
        .map(|_| {
            let i = crate::reference::uniform_hemisphere([rng.random(), rng.random()]);
            let o = crate::reference::uniform_hemisphere([rng.random(), rng.random()]);
            (i, o)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::{half_vector, spherical_direction_deg};

    #[test]
    fn lambert_albedo_is_exact() {
        let rho = 0.8;
        for (_, a) in white_furnace_sweep(|_, _| rho / PI, 9, 2, 1) {
            assert!((a - rho).abs() < 1e-14);
        }
    }

    #[test]
    fn normalised_lobe_albedo_converges() {
        // f = (n+2)/(2π) cosⁿθ_o has ∫ f cos θ_o dω_o = 1 for every i.
        let n = 50;
        let f = |_: DVec3, o: DVec3| (n as f64 + 2.0) / (2.0 * PI) * o.z.max(0.0).powi(n);
        let i = spherical_direction_deg(40.0, 10.0);
        assert!(
            (white_furnace(f, i, 26, 1) - 1.0).abs() < 1e-13,
            "degree 51 needs 26 nodes"
        );
        assert!(
            (white_furnace(f, i, 10, 1) - 1.0).abs() > 1e-6,
            "10 nodes are not enough"
        );
    }

    #[test]
    fn reciprocity() {
        let mut rng = crate::rng(7);
        let pairs = random_hemisphere_pairs(&mut rng, 2000);
        // Blinn–Phong in the half vector is reciprocal.
        let blinn = |i: DVec3, o: DVec3| half_vector(i, o).map_or(0.0, |h| h.z.max(0.0).powi(30));
        assert!(reciprocity_error(blinn, pairs.iter().copied()) < 1e-12);
        // A lobe in o alone is not.
        let one_sided = |_: DVec3, o: DVec3| o.z.powi(8);
        assert!(reciprocity_error(one_sided, pairs.iter().copied()) > 0.5);
        assert_eq!(reciprocity_error(|_, _| 0.0, pairs.iter().copied()), 0.0);
        assert!(reciprocity_error(|_, _| f64::NAN, pairs).is_nan());
    }
}
