//! The lobe-sum NDF with the **microfacet transfer**: K Phong peaks (Eq. 12) as the NDF of a
//! microfacet surface of perfect mirrors with Schlick Fresnel and height-correlated Smith
//! masking–shadowing, plus a Lambertian term — the material
//!
//! ```toml
//! form = "microfacet"
//! [ndf]
//! kind = "phong-peaks"
//! lobes = [ … ]
//! [transfer]
//! kind = "mirror"
//! fresnel = "schlick"
//! f0 = [r, g, b]
//! specular = [r, g, b]
//! [shadowing]
//! kind = "smith"
//! [diffuse]
//! albedo = [r, g, b]
//! ```
//!
//! which meso-core evaluates as `f = albedo/π + specular · D(h) F(i·h) G₂(i, o) / (4 cos θi cos θo)` with
//! `D = n / ∫_{z>0} n (m·z) dω` and `G₂ = 1/(1 + Λ(i) + Λ(o))`, `Λ` integrated numerically from
//! the NDF.
//!
//! # Fast approximation used for fitting
//! * `D(h) = n(h) / P`, `n` the Phong peaks exactly, and the projected area
//!   `P = Σ w_k P_k`, `P_k ≈ P↑(η_k) · cos θ_k` where `θ_k` is the axis' angle to the normal and
//!   `P↑(η) = ∫_{z>0} (η+2)/(8π) cos^η(α/2) (m·z) dω` for a lobe on the normal, in closed form
//!   (`a = η/2`, [`projected_area_on_normal`]):
//!   `P↑ = (η+2)/2 · [2(1 − 2^−(a+2))/(a+2) − (1 − 2^−(a+1))/(a+1)]`.
//!   (Over the whole sphere `∫ n (m·z) dω = η/(η+4) · cos θ_k` exactly; the hemisphere restriction
//!   matters only for broad lobes, where the `cos θ_k` factor is approximate.)
//! * `Λ(ω)`: Beckmann's `Λ` with the equivalent roughness of the mixture's slope second moment
//!   along the azimuth of `ω`: in slope space lobe k has mean `t_k = (μx, μy)/μz` and per-axis
//!   variance `4/η_k` (the von Mises–Fisher κ = η/4 of `cos^η(α/2)`), so
//!   `M = Σ_k w'_k (t_k t_kᵀ + 4/η_k I)` with `w'_k = w_k P_k / P` and `α_φ² = 2 uᵀ M u`,
//!   `u = (cos φ, sin φ)` (clamped to `α ≤ 4`).
//! * `F` is Schlick's, `F = f0 + (1 − f0)(1 − i·h)⁵`, scaled per channel by the mirror's
//!   `specular = s ∈ [0, 1]` (without it the specular lobe could not be dimmer than Fresnel
//!   allows: `F` rises to 1 at grazing and `D` is normalised). So `s F = s f0 + s (1 − f0)(1 − c)⁵`
//!   and the linear basis lobes are `X = D G₂ / (4 cos θi cos θo)` with amplitude
//!   `u = s f0` and `X (1 − c)⁵` with amplitude `g = s (1 − f0)`, both in `[0, 1]` per channel.
//!   Every `(u, g)` with `u + g ≤ 1` is exactly one `(s, f0) = (u + g, u/(u + g))`; the fit
//!   bounds `u` and `g` separately, and the rare `u + g > 1` (a specular part brighter than any
//!   mirror facet gives) is written with both scaled by `1/(u + g)` ([`LobeMicrofacetModel::params`]).
//!   The model without the scale (`g = 1 − u`, `s = 1`) is a special case.
//!
//! The approximation is exact for `D` when the lobes are sharp or on the normal and close for
//! `Λ` when the mixture is near Beckmann; `meso fit` reports the exact error of the written
//! material (quadrature of meso-core) next to the fitted one.

use super::baselines::Microfacet;
use super::lobes::{
    decode_lobes, encode_lobes, file_phong_peaks, fit_peaks_progressive, peak_axis_parameters,
    peak_bounds, peak_parameter_names, peak_sharpness_parameters, MAX_LOBES,
};
use crate::fit::{BrdfModel, FitError, FitOptions, FitResult};
use crate::samples::SampleSet;
use glam::DVec3;
use meso_core::material::MaterialSpec;
use meso_core::ndf::{Ndf, PhongLobe};
use meso_core::NdfError;
use std::f64::consts::PI;

/// `ln η` bounds: η ∈ [10, 10⁶]. Broader peaks put much of their mass near or below the horizon,
/// where the fast `D` and `Λ` are poor (measured: 17–35 % from the exact material with η = 1
/// lobes); the Lambert term takes the broad reflection instead.
const LN_ETA: (f64, f64) = (std::f64::consts::LN_10, 6.0 * std::f64::consts::LN_10);

/// `∫_{z>0} (η+2)/(8π) cos^η(α/2) (m·z) dω` for a Phong peak on the normal (α = θ), closed form
/// (module docs), dimensionless: `¼` at η = 0 (the upper half of the uniform sphere), → 1 as
/// η → ∞.
#[must_use]
pub fn projected_area_on_normal(eta: f64) -> f64 {
    let a = 0.5 * eta;
    let t2 = (-(a + 2.0) * std::f64::consts::LN_2).exp();
    let t1 = (-(a + 1.0) * std::f64::consts::LN_2).exp();
    0.5 * (eta + 2.0) * (2.0 * (1.0 - t2) / (a + 2.0) - (1.0 - t1) / (a + 1.0))
}

/// [`projected_area_on_normal`] and its derivative with respect to η.
fn projected_area_on_normal_grad(eta: f64) -> (f64, f64) {
    let a = 0.5 * eta;
    let ln2 = std::f64::consts::LN_2;
    let t2 = (-(a + 2.0) * ln2).exp();
    let t1 = (-(a + 1.0) * ln2).exp();
    let b = 2.0 * (1.0 - t2) / (a + 2.0) - (1.0 - t1) / (a + 1.0);
    let db = 2.0 * ln2 * t2 / (a + 2.0)
        - 2.0 * (1.0 - t2) / ((a + 2.0) * (a + 2.0))
        - ln2 * t1 / (a + 1.0)
        + (1.0 - t1) / ((a + 1.0) * (a + 1.0));
    // P↑ = (a + 1)·b(a), dη = 2 da.
    ((a + 1.0) * b, 0.5 * (b + (a + 1.0) * db))
}

/// Beckmann's `Λ` (as [`Microfacet::lambda`]) and `∂Λ/∂α` for `cos θ = c`: with
/// `ν = 1/(α tan θ)`, `Λ = ½(−erfc ν + e^(−ν²)/(ν√π))` and `∂Λ/∂α = ½ e^(−ν²)/(√π ν α)`.
fn beckmann_lambda_grad(alpha: f64, c: f64) -> (f64, f64) {
    let s2 = (1.0 - c * c).max(0.0);
    if s2 <= 0.0 {
        return (0.0, 0.0);
    }
    let tan = s2.sqrt() / c;
    let nu = 1.0 / (alpha * tan);
    let e = (-nu * nu).exp();
    let sp = PI.sqrt();
    (
        0.5 * (-libm::erfc(nu) + e / (nu * sp)),
        0.5 * e / (sp * nu * alpha),
    )
}

/// The fast microfacet evaluation of the module docs for normalised lobes: returns
/// `D(h) G₂(i, o) / (4 cos θi cos θo)` (1/sr) and `c = i·h`; `None` below the horizon.
#[must_use]
pub fn microfacet_lobes_fast(lobes: &[PhongLobe], wi: DVec3, wo: DVec3) -> Option<(f64, f64)> {
    let h = super::upper_half_vector(wi, wo)?;
    let mut n = 0.0;
    let mut p = 0.0;
    let mut m = [0.0f64; 3]; // slope second moment xx, xy, yy (unnormalised by p)
    for l in lobes {
        n += l.density(h);
        let pk = l.weight * projected_area_on_normal(l.exponent) * l.axis.z.max(1e-6);
        p += pk;
        let (tx, ty) = (l.axis.x / l.axis.z.max(1e-6), l.axis.y / l.axis.z.max(1e-6));
        let v = 4.0 / l.exponent.max(1e-6);
        m[0] += pk * (tx * tx + v);
        m[1] += pk * tx * ty;
        m[2] += pk * (ty * ty + v);
    }
    if p <= 0.0 {
        return None;
    }
    let lambda = |w: DVec3| {
        let r = (w.x * w.x + w.y * w.y).sqrt();
        if r < 1e-12 {
            return 0.0;
        }
        let (ux, uy) = (w.x / r, w.y / r);
        let a2 = 2.0 * (m[0] * ux * ux + 2.0 * m[1] * ux * uy + m[2] * uy * uy) / p;
        Microfacet::COOK_TORRANCE.lambda(a2.sqrt().clamp(1e-4, 4.0), w.z)
    };
    let g2 = 1.0 / (1.0 + lambda(wi) + lambda(wo));
    Some((n / p * g2 / (4.0 * wi.z * wo.z), wi.dot(h)))
}

/// The K-peak NDF with the microfacet mirror transfer (module docs); `k` in `1..=MAX_LOBES`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LobeMicrofacetModel {
    /// Number of Phong peaks.
    pub k: usize,
}

/// A concrete microfacet lobe material (fitted or generating parameters).
#[derive(Clone, Debug, PartialEq)]
pub struct LobeMicrofacetParams {
    /// The Phong peaks (unit axes, weights summing to 1).
    pub lobes: Vec<PhongLobe>,
    /// Schlick's reflectance at normal incidence per channel, in [0, 1].
    pub f0: [f64; 3],
    /// The mirror's per-channel specular scale `s` in [0, 1] (dimensionless; 1: the plain
    /// Fresnel mirror).
    pub specular: [f64; 3],
    /// Lambertian albedo per channel, in [0, 1].
    pub albedo: [f64; 3],
}

impl LobeMicrofacetParams {
    /// The fast-approximation BRDF (1/sr) per channel (what the fit minimises).
    #[must_use]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        let s = microfacet_lobes_fast(&self.lobes, wi, wo);
        if !(wi.z > 0.0 && wo.z > 0.0) {
            return [0.0; 3];
        }
        super::mirror_brdf(s, self.f0, self.specular, self.albedo)
    }

    /// The material (module docs): the Phong peaks (axes snapped to the degrees the file holds) under
    /// [`super::mirror_material`].
    ///
    /// # Errors
    /// Lobes that make no NDF (non-finite or negative weights or exponents).
    pub fn to_spec(&self) -> Result<MaterialSpec, NdfError> {
        Ok(super::mirror_material(
            Ndf::PhongPeaks(file_phong_peaks(&self.lobes)?),
            self.f0,
            self.specular,
            self.albedo,
        ))
    }

    /// The material as meso TOML ([`LobeMicrofacetParams::to_spec`], module docs); `comment`
    /// lines are prepended as `#` comments.
    #[must_use]
    pub fn to_material_toml(&self, comment: &str) -> String {
        super::material_file(self.to_spec(), comment)
    }
}

impl LobeMicrofacetModel {
    /// A model with `k` lobes (clamped to `1..=MAX_LOBES`).
    #[must_use]
    pub fn new(k: usize) -> LobeMicrofacetModel {
        LobeMicrofacetModel {
            k: k.clamp(1, MAX_LOBES),
        }
    }

    /// Physical parameters from a fit of this model: `specular = u + g`, `f0 = u/(u + g)` from
    /// the amplitudes `u`, `g` of the two specular basis lobes (module docs); where `u + g > 1`
    /// both are first scaled by `1/(u + g)`, so that `specular ≤ 1` (the written material is then
    /// dimmer than the fitted form); `f0 = 0` where `u + g = 0` (no specular).
    #[must_use]
    pub fn params(&self, fit: &FitResult) -> LobeMicrofacetParams {
        self.params_from(&fit.theta, &fit.amps)
    }

    /// Physical parameters from `θ` and amplitudes (`[albedo, u, g]`, as
    /// [`LobeMicrofacetModel::params`]).
    #[must_use]
    pub fn params_from(&self, theta: &[f64], amps: &[[f64; 3]]) -> LobeMicrofacetParams {
        let lobes = decode_lobes(self.k, theta);
        let (f0, specular) = super::mirror_from_amplitudes(amps);
        LobeMicrofacetParams {
            lobes: lobes[..self.k].to_vec(),
            f0,
            specular,
            albedo: amps[0],
        }
    }

    /// `θ` encoding `p` (`p.lobes.len()` must equal `k`).
    #[must_use]
    pub fn theta_of(&self, p: &LobeMicrofacetParams) -> Vec<f64> {
        encode_lobes(&p.lobes)
    }
}

impl BrdfModel for LobeMicrofacetModel {
    fn name(&self) -> String {
        format!("lobes-{}-microfacet", self.k)
    }

    fn nonlinear_names(&self) -> Vec<String> {
        peak_parameter_names(self.k)
    }

    fn basis_names(&self) -> Vec<String> {
        super::mirror_basis_names()
    }

    fn axis_parameters(&self) -> Vec<usize> {
        peak_axis_parameters(self.k)
    }

    fn sharpness_parameters(&self) -> Vec<(usize, f64)> {
        peak_sharpness_parameters(self.k)
    }

    fn amplitude_bounds(&self) -> Vec<(f64, f64)> {
        super::mirror_amplitude_bounds()
    }

    fn amplitude_sums(&self) -> Vec<(Vec<usize>, f64)> {
        super::mirror_amplitude_sums()
    }

    fn bounds(&self) -> Vec<(f64, f64)> {
        peak_bounds(self.k, LN_ETA)
    }

    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        // Blinn-equivalent sharpness e (D ≈ exp(−e θh²/2)) ↔ η = 4e; lobes on the normal.
        let grid = super::lobes::start_sharpness_grid(self.k);
        grid.iter()
            .map(|es| {
                let mut t = Vec::new();
                for j in 0..self.k {
                    let e = es[j.min(es.len() - 1)] * (1.0 + 0.1 * (j / es.len()) as f64);
                    t.extend([0.0, 0.0, (4.0 * e).clamp(10.0_f64, 1e6).ln()]);
                }
                t.extend(std::iter::repeat_n(0.0, self.k - 1));
                t
            })
            .collect()
    }

    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let lobes = decode_lobes(self.k, theta);
        out[0] = 1.0 / PI;
        match microfacet_lobes_fast(&lobes[..self.k], wi, wo) {
            Some((d, c)) => super::split_schlick(out, d, super::schlick_m5(c)),
            None => {
                out[1] = 0.0;
                out[2] = 0.0;
            }
        }
    }

    fn basis_gradient(
        &self,
        theta: &[f64],
        wi: DVec3,
        wo: DVec3,
        out: &mut [f64],
        grad: &mut [f64],
    ) -> bool {
        self.gradient(theta, wi, wo, out, grad);
        true
    }
}

impl LobeMicrofacetModel {
    /// Analytic derivatives of [`microfacet_lobes_fast`] (module docs) with respect to `θ`
    /// (per lobe `ax, ay, ln η`, then the logits), into `grad[q·3 + j]` for the basis lobes
    /// `j = 1, 2` (`j = 0`, the Lambert term, has none).
    fn gradient(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64], grad: &mut [f64]) {
        let k = self.k;
        let nt = 4 * k - 1;
        grad[..3 * nt].fill(0.0);
        out[0] = 1.0 / PI;
        out[1] = 0.0;
        out[2] = 0.0;
        let Some(h) = super::upper_half_vector(wi, wo) else {
            return;
        };
        let lobes = decode_lobes(k, theta);
        // Per lobe: unit density ρ at h and ∂ρ/∂ln η, ρ η/(4q) (∂ρ/∂a = that · h), the
        // projected area P↑ with ∂P↑/∂ln η, the slope-moment contribution.
        let mut rho = [0.0; MAX_LOBES];
        let mut rho_eta = [0.0; MAX_LOBES];
        let mut rho_a = [0.0; MAX_LOBES];
        let mut pa = [0.0; MAX_LOBES];
        let mut pa_eta = [0.0; MAX_LOBES];
        let mut pk = [0.0; MAX_LOBES];
        let mut mom = [[0.0; 3]; MAX_LOBES];
        let (mut n, mut p) = (0.0, 0.0);
        let mut m = [0.0f64; 3];
        for (j, l) in lobes.iter().enumerate().take(k) {
            let eta = l.exponent;
            let q = (0.5 * (1.0 + l.axis.dot(h))).max(0.0);
            let peak = q.powf(0.5 * eta);
            rho[j] = PhongLobe::normalization(eta) * peak;
            if q > 0.0 {
                rho_eta[j] = eta * rho[j] * (1.0 / (eta + 2.0) + 0.5 * q.ln());
                rho_a[j] = rho[j] * eta / (4.0 * q);
            }
            n += l.weight * rho[j];
            let (a0, da0) = projected_area_on_normal_grad(eta);
            pa[j] = a0;
            pa_eta[j] = da0 * eta;
            pk[j] = l.weight * a0 * l.axis.z;
            p += pk[j];
            let (tx, ty) = (theta[3 * j], theta[3 * j + 1]);
            let v = 4.0 / eta;
            mom[j] = [tx * tx + v, tx * ty, ty * ty + v];
            for (mq, x) in m.iter_mut().zip(mom[j]) {
                *mq += pk[j] * x;
            }
        }
        if p <= 0.0 {
            return;
        }
        // Λ of each direction: α² = 2 uᵀMu / P along the azimuth u.
        let dirs = [wi, wo].map(|w| {
            let r = (w.x * w.x + w.y * w.y).sqrt();
            if r < 1e-12 {
                return None;
            }
            let (ux, uy) = (w.x / r, w.y / r);
            let uu = [ux * ux, 2.0 * ux * uy, uy * uy];
            let q: f64 = (0..3).map(|t| m[t] * uu[t]).sum();
            let a2 = 2.0 * q / p;
            let alpha = a2.sqrt();
            let clamped = !(1e-4..=4.0).contains(&alpha);
            let (lam, dlam) = beckmann_lambda_grad(alpha.clamp(1e-4, 4.0), w.z);
            Some((uu, a2, alpha, clamped, lam, dlam))
        });
        let lam_sum: f64 = dirs.iter().flatten().map(|d| d.4).sum();
        let g2 = 1.0 / (1.0 + lam_sum);
        let kk = 1.0 / (4.0 * wi.z * wo.z);
        let x = n / p * g2 * kk;
        let m5 = super::schlick_m5(wi.dot(h));
        super::split_schlick(out, x, m5);
        // dX from (dn, dP, dM) of one parameter.
        let dx = |dn: f64, dp: f64, dm: [f64; 3]| -> f64 {
            let mut dlam = 0.0;
            for (uu, a2, alpha, clamped, _, dl) in dirs.iter().flatten() {
                if *clamped {
                    continue;
                }
                let dq: f64 = (0..3).map(|t| dm[t] * uu[t]).sum();
                let da2 = (2.0 * dq - a2 * dp) / p;
                dlam += dl * da2 / (2.0 * alpha);
            }
            let dg2 = -g2 * g2 * dlam;
            kk * (g2 * (dn - n * dp / p) / p + n / p * dg2)
        };
        let mut put = |q: usize, d: f64| super::split_schlick(&mut grad[3 * q..], d, m5);
        for (j, l) in lobes.iter().enumerate().take(k) {
            let w = l.weight;
            let a = l.axis;
            // ln η.
            let dp = w * a.z * pa_eta[j];
            let v = 4.0 / l.exponent;
            let dm = [0, 1, 2].map(|t| dp * mom[j][t] + pk[j] * [-v, 0.0, -v][t]);
            put(3 * j + 2, dx(w * rho_eta[j], dp, dm));
            // Axis: ∂a/∂ax = (e_x − a a_x)/r; slopes t = (ax, ay).
            let (tx, ty) = (theta[3 * j], theta[3 * j + 1]);
            let r = DVec3::new(tx, ty, 1.0).length();
            let ah = a.dot(h);
            for (comp, dmom) in [(0usize, [2.0 * tx, ty, 0.0]), (1, [0.0, tx, 2.0 * ty])] {
                let (ac, hc) = if comp == 0 { (a.x, h.x) } else { (a.y, h.y) };
                let dn = w * rho_a[j] * (hc - ah * ac) / r;
                let dp = w * pa[j] * (-a.z * ac / r);
                let dm = [0, 1, 2].map(|t| dp * mom[j][t] + pk[j] * dmom[t]);
                put(3 * j + comp, dx(dn, dp, dm));
            }
        }
        // Softmax weights: ∂w_j/∂logit_i = w_j (δ_ji − w_i).
        for i in 1..k {
            let wi_ = lobes[i].weight;
            let dn = wi_ * (rho[i] - n);
            let dp = pk[i] - wi_ * p;
            let dm = [0, 1, 2].map(|t| pk[i] * mom[i][t] - wi_ * m[t]);
            put(3 * k + i - 1, dx(dn, dp, dm));
        }
    }
}

/// Fit microfacet lobe sums with 1, 2, …, `k` lobes progressively, as
/// [`super::fit_lobes_progressive`]: each new lobe is also seeded at the half vectors where the
/// data most exceed the previous fit. Returns every model fitted with its result.
pub fn fit_microfacet_lobes_progressive(
    k: usize,
    data: &SampleSet,
    opts: &FitOptions,
) -> Result<Vec<(LobeMicrofacetModel, FitResult)>, FitError> {
    fit_peaks_progressive(
        k,
        data,
        opts,
        |j| LobeMicrofacetModel { k: j },
        |m, prev, h, e, [keep, w]| {
            let eta = (4.0 * e).clamp(10.0_f64, 1e6);
            let p = match prev {
                Some((pm, r)) => {
                    let mut p = pm.params(r);
                    p.lobes.iter_mut().for_each(|l| l.weight *= keep);
                    p.lobes.push(PhongLobe::new(h, w, eta));
                    p
                }
                None => LobeMicrofacetParams {
                    lobes: vec![PhongLobe::new(h, 1.0, eta)],
                    f0: [0.0; 3],
                    specular: [1.0; 3],
                    albedo: [0.0; 3],
                },
            };
            m.theta_of(&p)
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::spherical_direction_deg;
    use meso_core::material::Material;

    /// Independent truth: midpoint quadrature of `∫_{z>0} n (m·z) dω` for a lobe on the normal.
    #[test]
    fn projected_area_closed_form_matches_quadrature() {
        for eta in [0.0, 1.0, 4.0, 30.0, 500.0] {
            let l = PhongLobe::new(DVec3::Z, 1.0, eta);
            let nt = 4000;
            let mut q = 0.0;
            for a in 0..nt {
                let t = 0.5 * PI * (a as f64 + 0.5) / nt as f64;
                let m = meso_core::frame::spherical_direction(t, 0.0);
                q += l.unit_density(m) * t.cos() * t.sin();
            }
            q *= 2.0 * PI * 0.5 * PI / nt as f64;
            let cf = projected_area_on_normal(eta);
            assert!((cf - q).abs() < 1e-5, "η {eta}: {cf} vs {q}");
        }
        assert!((projected_area_on_normal(0.0) - 0.25).abs() < 1e-12);
    }

    /// The fast approximation against meso-core's exact microfacet evaluation of the written
    /// material, for a sharp lobe on the normal (D exact, Λ near Beckmann).
    #[test]
    fn fast_form_matches_the_written_material() {
        let p = LobeMicrofacetParams {
            lobes: vec![PhongLobe::new(DVec3::Z, 1.0, 400.0)],
            f0: [0.9, 0.5, 0.1],
            specular: [0.8, 0.3, 1.0],
            albedo: [0.1, 0.2, 0.3],
        };
        let m = Material::from_toml_str(&p.to_material_toml("test")).expect("valid material");
        for (ti, pi, to, po) in [
            (10.0, 0.0, 10.0, 180.0),
            (30.0, 20.0, 25.0, 190.0),
            (60.0, 0.0, 55.0, 180.0),
            (70.0, 90.0, 70.0, 270.0),
        ] {
            let wi = spherical_direction_deg(ti, pi);
            let wo = spherical_direction_deg(to, po);
            let exact = m.brdf(wi, wo);
            let fast = p.eval(wi, wo);
            for c in 0..3 {
                assert!(
                    (fast[c] / exact[c] - 1.0).abs() < 0.03,
                    "({ti},{pi},{to},{po}) c{c}: fast {} exact {}",
                    fast[c],
                    exact[c]
                );
            }
        }
    }
}
