//! meso-core's closed form of Phong peaks convolved with a Phong transfer
//! ([`meso_core::convolution::phong_closed_form`]) together with its **analytic derivatives** with
//! respect to the lobe-model parameters, for the Levenberg–Marquardt Jacobian.
//!
//! Per lobe (unit axis `a`, exponent η, transfer exponent η_t, half vector `h`, light `i`):
//!
//! ```text
//! κ₁ = (η+2)/4,  κ₂ = η_t + 1,  v = κ₁ a + κ₂ h,  κ₃ = |v|,  c = v·i/κ₃
//! T  = C(κ₁) · M(κ₁, κ₂, κ₃) · E(κ₃, c)
//! C  = κ₁ / (2π (1 − e^(−2κ₁))),   M = 2π e^(κ₃−κ₁−κ₂) (1 − e^(−2κ₃)) / κ₃
//! S  = Σ_k w_k T_k / cos θi
//! ```
//!
//! `κ₁` is [`meso_core::sg::kappa_same_integral`] and `κ₂` [`meso_core::sg::kappa_transfer`]
//! (the closed form's mappings, see [`meso_core::sg`]); `C`, `M` and the product come from
//! [`meso_core::sg`] (`normaliser`, `integral`, `product`, whose `κ₃ − κ₁ − κ₂` has no
//! cancellation).
//!
//! `E(κ, c) = E[max(0, m·i)]` for `m ~ vMF(κ)` is meso-core's table over `(ln κ, c)` (64 × 129,
//! bilinear), read through [`meso_core::convolution::clamped_cosine_mean_grad`], whose bilinear
//! cell also gives `∂E/∂ln κ` and `∂E/∂c`. The derivatives follow by the chain rule:
//! `∂ln C/∂κ₁ = 1/κ₁ − 2/(e^(2κ₁) − 1)`, `∂ln M/∂κ₃ = 1 + 2/(e^(2κ₃) − 1) − 1/κ₃`,
//! `∂ln M/∂κ₁ = ∂ln M/∂κ₂ = −1`, `dκ₃ = v·dv/κ₃`, `dc = (i·dv)/κ₃ − c dκ₃/κ₃`.

use glam::DVec3;
use meso_core::sg;

pub use meso_core::convolution::clamped_cosine_mean_grad;

/// One lobe's term `T` (module docs) and its derivatives: `(T, ∂T/∂κ₁ (explicit), ∂T/∂κ₂
/// (explicit), ∂T/∂v)`; the total derivative along `dv` is `∂T/∂v · dv`.
#[inline]
#[must_use]
pub fn lobe_term_grad(axis: DVec3, k1: f64, k2: f64, h: DVec3, i: DVec3) -> (f64, f64, f64, DVec3) {
    let p = sg::product(axis, k1, h, k2);
    let (v, k3) = (p.v, p.kappa);
    let c1 = sg::normaliser(k1);
    let mass = p.ln_scale.exp() * sg::integral(k3);
    if k3 < 1e-9 {
        let (e, _, _) = clamped_cosine_mean_grad(k3, i.z);
        return (c1 * mass * e, 0.0, 0.0, DVec3::ZERO);
    }
    let c = v.dot(i) / k3;
    let (e, e_k, e_c) = clamped_cosine_mean_grad(k3, c);
    let t = c1 * mass * e;
    let dln_c1 = sg::normaliser_dln(k1);
    // ln M = κ₃ − κ₁ − κ₂ + ln integral(κ₃), and ln integral = −ln normaliser.
    let dln_m3 = 1.0 - sg::normaliser_dln(k3);
    let cm = c1 * mass;
    // dT/dv through κ₃ and c.
    let dv = cm * ((e * dln_m3 + e_k - e_c * c / k3) * v / k3 + e_c * i / k3);
    (t, t * (dln_c1 - 1.0), -t, dv)
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::spherical_direction_deg;
    use meso_core::ndf::PhongLobe;

    /// The rebuilt table and lobe terms reproduce meso-core's closed form.
    #[test]
    fn matches_meso_core_closed_form() {
        let cases = [
            (spherical_direction_deg(10.0, 30.0), 200.0, 100.0),
            (spherical_direction_deg(40.0, 250.0), 3.0, 5.0),
            (DVec3::Z, 1e5, 2e3),
            (spherical_direction_deg(70.0, 90.0), 30.0, 1.0),
        ];
        for (axis, eta, eta_t) in cases {
            for (ti, pi, to, po) in [
                (20.0, 180.0, 25.0, 10.0),
                (60.0, 0.0, 50.0, 150.0),
                (5.0, 10.0, 79.0, 300.0),
            ] {
                let wi = spherical_direction_deg(ti, pi);
                let wo = spherical_direction_deg(to, po);
                let h = (wi + wo).normalize();
                let l = PhongLobe::new(axis, 1.0, eta);
                let core =
                    meso_core::convolution::phong_closed_form(&[l], eta_t, [1.0; 3], wi, wo)[0];
                let (t, ..) = lobe_term_grad(
                    axis,
                    sg::kappa_same_integral(eta),
                    sg::kappa_transfer(eta_t),
                    h,
                    wi,
                );
                let ours = t / wi.z;
                assert!(
                    (ours - core).abs() <= 1e-12 * core.abs().max(1e-300),
                    "{ours} vs {core}"
                );
            }
        }
    }

    /// Derivatives against central differences (away from the table's cell edges the bilinear
    /// interpolant is smooth, so small steps agree).
    #[test]
    fn derivatives_match_differences() {
        let i = spherical_direction_deg(35.0, 170.0);
        let o = spherical_direction_deg(30.0, 20.0);
        let h = (i + o).normalize();
        let axis = spherical_direction_deg(8.0, 40.0);
        let (k1, k2) = (30.0, 60.0);
        let (_, dk1, dk2, dv) = lobe_term_grad(axis, k1, k2, h, i);
        let f = |a: DVec3, k1: f64, k2: f64| lobe_term_grad(a, k1, k2, h, i).0;
        let e = 1e-7;
        let n1 = (f(axis, k1 + e, k2) - f(axis, k1 - e, k2)) / (2.0 * e);
        let n2 = (f(axis, k1, k2 + e) - f(axis, k1, k2 - e)) / (2.0 * e);
        // dv along the axis (v = k1 a + k2 h) equals an explicit change of k1 minus its
        // explicit part: d/dk1 total = dk1 + dv·a.
        assert!(
            (dk1 + dv.dot(axis) - n1).abs() < 1e-5 * n1.abs().max(1e-9),
            "{dk1} {n1}"
        );
        assert!(
            (dk2 + dv.dot(h) - n2).abs() < 1e-5 * n2.abs().max(1e-9),
            "{dk2} {n2}"
        );
        for d in [DVec3::X, DVec3::Y, DVec3::Z] {
            // Perturb v through the axis scaled so that v moves by d·ε.
            let na = (f(axis + d * (e / k1), k1, k2) - f(axis - d * (e / k1), k1, k2)) / (2.0 * e);
            assert!(
                (dv.dot(d) - na).abs() < 1e-5 * na.abs().max(1e-9),
                "{dv} {na}"
            );
        }
    }
}
