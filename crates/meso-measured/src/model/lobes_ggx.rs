//! NDFs with tails: K GGX (or Beckmann) lobes on the normal as the simple NDFs of Eq. 7, mixed in
//! one sum, under the **microfacet transfer** (mirror facets, Schlick Fresnel, Smith masking from
//! the fitted NDF), plus a Lambertian term — the material
//!
//! ```toml
//! form = "microfacet"
//! [ndf]
//! kind = "mixture"
//! lobes = [ { kind = "ggx", alpha = …, weight = … }, … ]
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
//! which meso-core evaluates in closed form ([`meso_core::ndf::mixture`]):
//! `f = albedo/π + s F(i·h) D(h) G₂ / (4 cos θi cos θo)` with `D = Σ c_k D_k`,
//! `G₂ = 1/(1 + Λ(i) + Λ(o))`, `Λ = Σ c_k Λ_k`, `c_k` the lobes' shares of the projected area.
//! The fit works with exactly that form (no approximation): its parameters are `ln(1/α_k²)` per
//! lobe (the von Mises–Fisher concentration of the lobe core is `κ = 2/α²` for Beckmann and
//! `4/α²` for GGX, which is what the data's resolution caps, [`BrdfModel::sharpness_parameters`])
//! and the softmax logits of the `c_k` (lobe 0's logit is 0); the written Eq. 1 weights are
//! `w_k ∝ c_k A_k` (`A_k` the lobe's area ratio), which meso-core turns back into the same `c_k`.
//! The Fresnel and specular scale are the linear amplitudes `u = s f0` and `g = s (1 − f0)` of the
//! basis lobes `X` and `X (1 − i·h)⁵`, `X = D G₂ / (4 cos θi cos θo)`, each in `[0, 1]`, as in
//! [`super::lobes_microfacet`]. `α ∈ [0.001, 1.5]`, the GGX baseline's bounds (MERL tables
//! resolve sharp lobes near the normal: brass and blue-acrylic fits reached a bound of 0.005).
//! With K = 1 the model is GGX + Lambert
//! (Schlick, height-correlated Smith).
//!
//! **Student-t lobes** ([`Distribution::StudentT`], STD: Ribardière et al. 2017) add their shape
//! γ as one more parameter each, `ln(γ − 3/2)`, after the logits, with γ in
//! [[`GAMMA_MIN`], [`GAMMA_MAX`]] (γ = 2 is GGX, large γ Beckmann): the tails are fitted
//! rather than chosen. Their `D` and `∂ ln D/∂γ` are closed forms, their Smith `Λ` meso-core's
//! closed form ([`meso_core::ndf::student_t`]) with `∂Λ/∂γ` by central differences. In a model's
//! `distributions` the γ of a Student-t lobe is only its starting value.
//!
//! The lobes stay on the normal whatever [`crate::fit::LobeAxes`] says (the model is isotropic).

use crate::fit::{fit_from, BrdfModel, FitError, FitOptions, FitResult};
use crate::samples::SampleSet;
use glam::DVec3;
use meso_core::material::MaterialSpec;
use meso_core::ndf::student_t::StudentT;
use meso_core::ndf::{Distribution, Microfacet, Mixture, Ndf};
use meso_core::NdfError;
use std::f64::consts::PI;

/// Most lobes of the model.
pub const MAX_GGX_LOBES: usize = super::lobes::MAX_LOBES;
/// Smallest roughness fitted.
pub const ALPHA_MIN: f64 = 0.001;
/// Largest roughness fitted.
pub const ALPHA_MAX: f64 = 1.5;
const LOGIT: (f64, f64) = (-12.0, 12.0);
/// Smallest Student-t γ fitted.
pub const GAMMA_MIN: f64 = 1.55;
/// Largest Student-t γ fitted (the lobe is then within a few % of Beckmann's).
pub const GAMMA_MAX: f64 = 50.0;
/// γ is fitted as `ln(γ − GAMMA_SHIFT)`.
const GAMMA_SHIFT: f64 = 1.5;

/// The lobe distributions `meso fit --transfer ggx-lobes` tries for each new lobe
/// ([`fit_ggx_lobes_progressive`]): GGX, and Beckmann where it fits better.
pub const GGX_OR_BECKMANN: [Distribution; 2] = [Distribution::Ggx, Distribution::Beckmann];

/// [`GGX_OR_BECKMANN`] and a Student-t lobe (γ fitted, starting from 3 and the values of
/// [`fit_ggx_lobes_progressive`]).
pub const GGX_BECKMANN_OR_STUDENT_T: [Distribution; 3] = [
    Distribution::Ggx,
    Distribution::Beckmann,
    Distribution::StudentT { gamma: 3.0 },
];

/// One fitted lobe.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GgxLobe {
    /// Beckmann, GGX or Student-t (with its γ).
    pub distribution: Distribution,
    /// Roughness α.
    pub alpha: f64,
    /// Weight in the microfacet `D` (`c_k`, the lobe's share of the projected area; the weights
    /// of a material sum to 1).
    pub d_weight: f64,
}

/// `D(cos θh)` of an isotropic lobe (1/sr, `∫ D (m·z) dω = 1`) and `∂ ln D / ∂ ln α`.
#[inline]
fn lobe_d(dist: Distribution, alpha: f64, cos2: f64, tan2: f64) -> (f64, f64) {
    let a2 = alpha * alpha;
    match dist {
        Distribution::Ggx => {
            let s = a2 + tan2;
            (a2 / (PI * cos2 * cos2 * s * s), 2.0 - 4.0 * a2 / s)
        }
        Distribution::Beckmann => {
            let e = tan2 / a2;
            ((-e).exp() / (PI * a2 * cos2 * cos2), 2.0 * e - 2.0)
        }
        Distribution::StudentT { gamma } => {
            let e = tan2 / a2;
            let g1 = gamma - 1.0;
            (
                (-gamma * (e / g1).ln_1p()).exp() / (PI * a2 * cos2 * cos2),
                2.0 * gamma * e / (g1 + e) - 2.0,
            )
        }
    }
}

/// Smith `Λ` of an isotropic lobe for a direction with `tan² θ = tan2`, and `∂Λ/∂ ln α` —
/// the formulas of [`meso_core::ndf::Microfacet::lambda_isotropic`] (`t`: the constants of a
/// Student-t lobe's γ, made here when not given).
#[inline]
fn lobe_lambda(dist: Distribution, alpha: f64, tan2: f64, t: Option<&StudentT>) -> (f64, f64) {
    if tan2 <= 0.0 {
        return (0.0, 0.0);
    }
    let a2 = alpha * alpha;
    match dist {
        Distribution::Ggx => {
            let r = (1.0 + a2 * tan2).sqrt();
            // ½(r − 1) as ½x/(1 + r): no cancellation near the normal.
            (0.5 * a2 * tan2 / (1.0 + r), 0.5 * a2 * tan2 / r)
        }
        Distribution::Beckmann => {
            let nu = 1.0 / (a2 * tan2).sqrt();
            if nu > 6.0 {
                return (0.0, 0.0);
            }
            let e = (-nu * nu).exp();
            let sp = PI.sqrt();
            (0.5 * (e / (nu * sp) - libm::erfc(nu)), 0.5 * e / (sp * nu))
        }
        Distribution::StudentT { gamma } => {
            let a = 1.0 / (a2 * tan2).sqrt();
            match t {
                Some(t) => t.lambda_and_dlnalpha(a),
                None => StudentT::new(gamma).lambda_and_dlnalpha(a),
            }
        }
    }
}

/// The parameter of γ, `ln(γ − 3/2)` (γ clamped to the fitted range).
fn gamma_theta(gamma: f64) -> f64 {
    (gamma.clamp(GAMMA_MIN, GAMMA_MAX) - GAMMA_SHIFT).ln()
}

#[inline]
fn tan2_of(c: f64) -> f64 {
    let c2 = c * c;
    (1.0 - c2).max(0.0) / c2
}

/// The specular basis `X = D(h) G₂ / (4 cos θi cos θo)` of a mixture (weights `d_weight`
/// summing to 1) and `c = i·h`; `None` below the horizon. What meso-core evaluates for the
/// written material.
#[must_use]
pub fn mixture_specular(lobes: &[GgxLobe], wi: DVec3, wo: DVec3) -> Option<(f64, f64)> {
    let h = super::upper_half_vector(wi, wo)?;
    let (ch2, th2) = (h.z * h.z, tan2_of(h.z));
    let (ti2, to2) = (tan2_of(wi.z), tan2_of(wo.z));
    let (mut d, mut li, mut lo) = (0.0, 0.0, 0.0);
    for l in lobes {
        d += l.d_weight * lobe_d(l.distribution, l.alpha, ch2, th2).0;
        let t = l.distribution.gamma().map(StudentT::new);
        li += l.d_weight * lobe_lambda(l.distribution, l.alpha, ti2, t.as_ref()).0;
        lo += l.d_weight * lobe_lambda(l.distribution, l.alpha, to2, t.as_ref()).0;
    }
    Some((d / ((1.0 + li + lo) * 4.0 * wi.z * wo.z), wi.dot(h)))
}

/// K Beckmann / GGX lobes on the normal with the microfacet mirror transfer (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct LobeGgxModel {
    /// The distribution of each lobe (their count is K).
    pub distributions: Vec<Distribution>,
}

/// A concrete lobe-mixture material (fitted or generating parameters).
#[derive(Clone, Debug, PartialEq)]
pub struct LobeGgxParams {
    /// The lobes (`d_weight`s summing to 1).
    pub lobes: Vec<GgxLobe>,
    /// Schlick's reflectance at normal incidence per channel, in [0, 1].
    pub f0: [f64; 3],
    /// The mirror's per-channel specular scale in [0, 1].
    pub specular: [f64; 3],
    /// Lambertian albedo per channel.
    pub albedo: [f64; 3],
}

impl LobeGgxParams {
    /// The BRDF (1/sr) per channel: the fitted closed form, which is also meso-core's evaluation
    /// of [`LobeGgxParams::to_material_toml`].
    #[must_use]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let s = mixture_specular(&self.lobes, wi, wo);
        super::mirror_brdf(s, self.f0, self.specular, self.albedo)
    }

    /// The Eq. 1 weights of the lobes, `w_k ∝ c_k A_k` (sum 1).
    #[must_use]
    pub fn eq1_weights(&self) -> Vec<f64> {
        let w: Vec<f64> = self
            .lobes
            .iter()
            .map(|l| {
                let a = meso_core::ndf::Microfacet::isotropic(l.distribution, l.alpha)
                    .map_or(1.0, |m| m.area_ratio());
                l.d_weight.max(0.0) * a
            })
            .collect();
        let t: f64 = w.iter().sum::<f64>().max(1e-300);
        w.iter().map(|x| x / t).collect()
    }

    /// The material (module docs): the lobes as a `mixture` NDF with the Eq. 1 weights
    /// ([`LobeGgxParams::eq1_weights`]) under [`super::mirror_material`].
    ///
    /// # Errors
    /// Lobes that make no NDF (an α outside `[1e-4, 10]`, non-finite weights).
    pub fn to_spec(&self) -> Result<MaterialSpec, NdfError> {
        let lobes = self
            .lobes
            .iter()
            .zip(self.eq1_weights())
            .map(|(l, w)| Microfacet::isotropic(l.distribution, l.alpha).map(|m| (m, w)))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(super::mirror_material(
            Ndf::Mixture(Mixture::new(lobes)?),
            self.f0,
            self.specular,
            self.albedo,
        ))
    }

    /// The material as meso TOML ([`LobeGgxParams::to_spec`], module docs); `comment` lines are
    /// prepended as `#` comments.
    #[must_use]
    pub fn to_material_toml(&self, comment: &str) -> String {
        super::material_file(self.to_spec(), comment)
    }
}

impl LobeGgxModel {
    /// `k` GGX lobes (clamped to `1..=MAX_GGX_LOBES`).
    #[must_use]
    pub fn ggx(k: usize) -> LobeGgxModel {
        LobeGgxModel {
            distributions: vec![Distribution::Ggx; k.clamp(1, MAX_GGX_LOBES)],
        }
    }

    /// `k` lobes of one distribution.
    #[must_use]
    pub fn uniform(distribution: Distribution, k: usize) -> LobeGgxModel {
        LobeGgxModel {
            distributions: vec![distribution; k.clamp(1, MAX_GGX_LOBES)],
        }
    }

    /// Number of lobes.
    #[must_use]
    pub fn k(&self) -> usize {
        self.distributions.len()
    }

    /// The Student-t lobes' indices (their γ parameters follow the logits in this order).
    fn student_lobes(&self) -> impl Iterator<Item = usize> + '_ {
        self.distributions
            .iter()
            .enumerate()
            .filter(|(_, d)| d.gamma().is_some())
            .map(|(j, _)| j)
    }

    /// Number of Student-t lobes.
    fn n_student(&self) -> usize {
        self.student_lobes().count()
    }

    fn decode(&self, theta: &[f64]) -> Vec<GgxLobe> {
        let k = self.k();
        let mut c: Vec<f64> = (0..k)
            .map(|j| if j == 0 { 0.0 } else { theta[k + j - 1] })
            .collect();
        let mx = c.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        c.iter_mut().for_each(|x| *x = (*x - mx).exp());
        let t: f64 = c.iter().sum();
        let mut q = 2 * k - 1;
        (0..k)
            .map(|j| GgxLobe {
                distribution: match self.distributions[j] {
                    Distribution::StudentT { .. } => {
                        q += 1;
                        Distribution::StudentT {
                            gamma: GAMMA_SHIFT + theta[q - 1].exp(),
                        }
                    }
                    d => d,
                },
                alpha: (-0.5 * theta[j]).exp(),
                d_weight: c[j] / t,
            })
            .collect()
    }

    /// `θ` encoding `p` (its lobes' distributions are this model's).
    #[must_use]
    pub fn theta_of(&self, p: &LobeGgxParams) -> Vec<f64> {
        let k = self.k();
        let mut t: Vec<f64> = p
            .lobes
            .iter()
            .map(|l| -2.0 * l.alpha.clamp(ALPHA_MIN, ALPHA_MAX).ln())
            .collect();
        let w0 = p.lobes[0].d_weight.max(1e-9);
        for l in &p.lobes[1..k] {
            t.push((l.d_weight.max(1e-9) / w0).ln().clamp(LOGIT.0, LOGIT.1));
        }
        for j in self.student_lobes() {
            let g = p.lobes[j]
                .distribution
                .gamma()
                .or(self.distributions[j].gamma())
                .unwrap_or(2.0);
            t.push(gamma_theta(g));
        }
        t
    }

    /// Physical parameters from a fit (as [`super::LobeMicrofacetModel::params`]).
    #[must_use]
    pub fn params(&self, fit: &FitResult) -> LobeGgxParams {
        self.params_from(&fit.theta, &fit.amps)
    }

    /// Physical parameters from `θ` and amplitudes `[albedo, u, g]`.
    #[must_use]
    pub fn params_from(&self, theta: &[f64], amps: &[[f64; 3]]) -> LobeGgxParams {
        let (f0, specular) = super::mirror_from_amplitudes(amps);
        LobeGgxParams {
            lobes: self.decode(theta),
            f0,
            specular,
            albedo: amps[0],
        }
    }

    /// The basis and, when `grad` is given, `∂/∂θ` into `grad[q·3 + j]`.
    fn eval_basis(
        &self,
        theta: &[f64],
        wi: DVec3,
        wo: DVec3,
        out: &mut [f64],
        grad: Option<&mut [f64]>,
    ) {
        let k = self.k();
        let nt = 2 * k - 1 + self.n_student();
        out[0] = 1.0 / PI;
        out[1] = 0.0;
        out[2] = 0.0;
        let mut grad = grad;
        if let Some(g) = grad.as_deref_mut() {
            g[..3 * nt].fill(0.0);
        }
        let Some(h) = super::upper_half_vector(wi, wo) else {
            return;
        };
        let lobes = self.decode(theta);
        let (ch2, th2) = (h.z * h.z, tan2_of(h.z));
        let (ti2, to2) = (tan2_of(wi.z), tan2_of(wo.z));
        let mut per = [[0.0f64; 6]; MAX_GGX_LOBES]; // D, dlnD, Λi, dΛi, Λo, dΛo
                                                    // Student-t lobes: ∂ ln D/∂γ, ∂Λi/∂γ, ∂Λo/∂γ.
        let mut per_t = [[0.0f64; 3]; MAX_GGX_LOBES];
        let want_grad = grad.is_some();
        let (mut d, mut li, mut lo) = (0.0, 0.0, 0.0);
        for (j, l) in lobes.iter().enumerate() {
            let t = l.distribution.gamma().map(StudentT::new);
            let (dj, dd) = lobe_d(l.distribution, l.alpha, ch2, th2);
            let (lij, dli) = lobe_lambda(l.distribution, l.alpha, ti2, t.as_ref());
            let (loj, dlo) = lobe_lambda(l.distribution, l.alpha, to2, t.as_ref());
            per[j] = [dj, dd, lij, dli, loj, dlo];
            if let (Some(g), true) = (l.distribution.gamma(), want_grad) {
                let (g1, e) = (g - 1.0, th2 / (l.alpha * l.alpha));
                let dlnd = -(e / g1).ln_1p() + g * e / (g1 * (g1 + e));
                let h = 1e-5 * g;
                let (tp, tm) = (StudentT::new(g + h), StudentT::new(g - h));
                let dl = |tan2: f64| {
                    let lp = lobe_lambda(l.distribution, l.alpha, tan2, Some(&tp)).0;
                    let lm = lobe_lambda(l.distribution, l.alpha, tan2, Some(&tm)).0;
                    (lp - lm) / (2.0 * h)
                };
                per_t[j] = [dlnd, dl(ti2), dl(to2)];
            }
            d += l.d_weight * dj;
            li += l.d_weight * lij;
            lo += l.d_weight * loj;
        }
        let kk = 1.0 / (4.0 * wi.z * wo.z);
        let g2 = 1.0 / (1.0 + li + lo);
        let x = d * g2 * kk;
        let m5 = super::schlick_m5(wi.dot(h));
        super::split_schlick(out, x, m5);
        let Some(grad) = grad else {
            return;
        };
        // dX from (dD, dΛi + dΛo).
        let dx = |dd: f64, dl: f64| kk * (dd * g2 - d * g2 * g2 * dl);
        let mut put = |q: usize, v: f64| super::split_schlick(&mut grad[3 * q..], v, m5);
        for (j, l) in lobes.iter().enumerate() {
            let p = per[j];
            // θ_j = ln(1/α²): ∂/∂θ = −½ ∂/∂ln α.
            let c = l.d_weight;
            put(j, -0.5 * dx(c * p[0] * p[1], c * (p[3] + p[5])));
        }
        for i in 1..k {
            let c = lobes[i].d_weight;
            let p = per[i];
            put(k + i - 1, dx(c * (p[0] - d), c * (p[2] - li + p[4] - lo)));
        }
        // θ = ln(γ − 3/2): ∂/∂θ = (γ − 3/2) ∂/∂γ.
        for (n, j) in self.student_lobes().enumerate() {
            let l = lobes[j];
            let s = l.distribution.gamma().unwrap_or(2.0) - GAMMA_SHIFT;
            let (p, pt) = (per[j], per_t[j]);
            let c = l.d_weight * s;
            put(2 * k - 1 + n, dx(c * p[0] * pt[0], c * (pt[1] + pt[2])));
        }
    }
}

impl BrdfModel for LobeGgxModel {
    fn name(&self) -> String {
        let first = self.distributions[0];
        let fam = if self.distributions.iter().all(|d| d.same_family(first)) {
            first.name()
        } else {
            "mixed"
        };
        format!("lobes-{}-{fam}", self.k())
    }

    fn nonlinear_names(&self) -> Vec<String> {
        let k = self.k();
        let mut v: Vec<String> = (0..k).map(|j| format!("ln_inv_alpha2_{j}")).collect();
        v.extend((1..k).map(|j| format!("logit{j}")));
        v.extend(
            self.student_lobes()
                .map(|j| format!("ln_gamma_minus_1.5_{j}")),
        );
        v
    }

    fn basis_names(&self) -> Vec<String> {
        super::mirror_basis_names()
    }

    fn sharpness_parameters(&self) -> Vec<(usize, f64)> {
        self.distributions
            .iter()
            .enumerate()
            .map(|(j, d)| {
                (
                    j,
                    match d {
                        Distribution::Ggx => 4.0,
                        Distribution::Beckmann => 2.0,
                        // The core `(1 + e/(γ−1))^(−γ) ≈ e^(−γe/(γ−1))`.
                        Distribution::StudentT { gamma } => 2.0 * gamma / (gamma - 1.0),
                    },
                )
            })
            .collect()
    }

    fn amplitude_bounds(&self) -> Vec<(f64, f64)> {
        super::mirror_amplitude_bounds()
    }

    fn amplitude_sums(&self) -> Vec<(Vec<usize>, f64)> {
        super::mirror_amplitude_sums()
    }

    fn bounds(&self) -> Vec<(f64, f64)> {
        let k = self.k();
        let s = (-2.0 * ALPHA_MAX.ln(), -2.0 * ALPHA_MIN.ln());
        let mut v = vec![s; k];
        v.extend(std::iter::repeat_n(LOGIT, k - 1));
        v.extend(std::iter::repeat_n(
            (gamma_theta(GAMMA_MIN), gamma_theta(GAMMA_MAX)),
            self.n_student(),
        ));
        v
    }

    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        let k = self.k();
        let grid: &[f64] = &[0.01, 0.03, 0.08, 0.2, 0.5];
        // Student-t lobes: their own starting γ, and light and heavy tails.
        let gammas: &[Option<f64>] = if self.n_student() > 0 {
            &[None, Some(2.0), Some(10.0)]
        } else {
            &[None]
        };
        let mut out = Vec::new();
        for &g in gammas {
            for (s, &a0) in grid.iter().enumerate() {
                let mut t: Vec<f64> = (0..k)
                    .map(|j| {
                        let a = (a0 * 3f64.powi(j as i32)).clamp(ALPHA_MIN, ALPHA_MAX);
                        -2.0 * a.ln()
                    })
                    .collect();
                t.extend(std::iter::repeat_n(-1.0 + 0.1 * s as f64, k - 1));
                for j in self.student_lobes() {
                    t.push(gamma_theta(
                        g.or(self.distributions[j].gamma()).unwrap_or(2.0),
                    ));
                }
                out.push(t);
            }
        }
        out
    }

    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        self.eval_basis(theta, wi, wo, out, None);
    }

    fn basis_gradient(
        &self,
        theta: &[f64],
        wi: DVec3,
        wo: DVec3,
        out: &mut [f64],
        grad: &mut [f64],
    ) -> bool {
        self.eval_basis(theta, wi, wo, out, Some(grad));
        true
    }
}

/// Fit lobe mixtures with 1, 2, …, `k` lobes progressively. Each new lobe is tried with every
/// distribution in `candidates` (`[Ggx]`: GGX lobes only; `[Ggx, Beckmann]`: each lobe is the
/// one that fits better, by the error of the metric minimised on the fitted samples; a
/// Student-t candidate, [`GGX_BECKMANN_OR_STUDENT_T`], fits its γ too, the new lobe starting
/// from the candidate's γ, 2 and 10); each size
/// starts from the model's grid and from the previous fit with one more lobe at each of several
/// roughnesses (with a small and a moderate weight), so that adding a lobe does not make the fit
/// worse. Returns every model fitted with its result.
///
/// # Errors
/// [`FitError`] from the fitting driver.
pub fn fit_ggx_lobes_progressive(
    k: usize,
    candidates: &[Distribution],
    data: &SampleSet,
    opts: &FitOptions,
) -> Result<Vec<(LobeGgxModel, FitResult)>, FitError> {
    let candidates = if candidates.is_empty() {
        &[Distribution::Ggx][..]
    } else {
        candidates
    };
    let objective = opts.metric.objective(&data.samples);
    let score = |r: &FitResult| {
        let v = objective.error(&r.errors);
        v[0] + v[1] + v[2]
    };
    let mut out: Vec<(LobeGgxModel, FitResult)> = Vec::new();
    for _ in 1..=k.clamp(1, MAX_GGX_LOBES) {
        let mut best: Option<(LobeGgxModel, FitResult)> = None;
        for &distribution in candidates {
            let mut distributions = out
                .last()
                .map_or_else(Vec::new, |(pm, _)| pm.distributions.clone());
            distributions.push(distribution);
            let m = LobeGgxModel { distributions };
            let mut starts = m.initial_guesses();
            if let Some((pm, r)) = out.last() {
                let prev = pm.params(r);
                let news: Vec<Distribution> = match distribution {
                    Distribution::StudentT { gamma } => [gamma, 2.0, 10.0]
                        .iter()
                        .map(|&gamma| Distribution::StudentT { gamma })
                        .collect(),
                    d => vec![d],
                };
                for a in [0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.4, 0.8, 1.5] {
                    for w in [0.01, 0.2] {
                        for &distribution in &news {
                            let mut p = prev.clone();
                            p.lobes.iter_mut().for_each(|l| l.d_weight *= 1.0 - w);
                            p.lobes.push(GgxLobe {
                                distribution,
                                alpha: a,
                                d_weight: w,
                            });
                            starts.push(m.theta_of(&p));
                        }
                    }
                }
            }
            let r = fit_from(&m, data, opts, &starts)?;
            if best.as_ref().is_none_or(|(_, b)| score(&r) < score(b)) {
                best = Some((m, r));
            }
        }
        out.push(best.expect("at least one candidate distribution"));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::spherical_direction_deg;
    use meso_core::material::Material;

    fn params() -> LobeGgxParams {
        LobeGgxParams {
            lobes: vec![
                GgxLobe {
                    distribution: Distribution::Ggx,
                    alpha: 0.06,
                    d_weight: 0.6,
                },
                GgxLobe {
                    distribution: Distribution::Beckmann,
                    alpha: 0.35,
                    d_weight: 0.3,
                },
                GgxLobe {
                    distribution: Distribution::StudentT { gamma: 2.7 },
                    alpha: 0.15,
                    d_weight: 0.1,
                },
            ],
            f0: [0.9, 0.6, 0.3],
            specular: [0.8, 0.7, 1.0],
            albedo: [0.05, 0.1, 0.2],
        }
    }

    /// The fitted closed form is meso-core's evaluation of the written material.
    #[test]
    fn closed_form_is_the_written_material() {
        let p = params();
        let m = Material::from_toml_str(&p.to_material_toml("test")).expect("valid material");
        let fast =
            meso_core::shading::FastBrdf::with_policy(&m, meso_core::shading::Policy::Accurate);
        for (ti, pi, to, po) in [
            (10.0, 0.0, 10.0, 180.0),
            (30.0, 20.0, 25.0, 190.0),
            (60.0, 0.0, 55.0, 180.0),
            (70.0, 90.0, 20.0, 300.0),
            (85.0, 0.0, 80.0, 180.0),
        ] {
            let wi = spherical_direction_deg(ti, pi);
            let wo = spherical_direction_deg(to, po);
            let exact = m.brdf(wi, wo);
            let f = fast.eval(wi, wo);
            let ours = p.eval(wi, wo);
            for c in 0..3 {
                assert!(
                    (ours[c] / exact[c] - 1.0).abs() < 1e-8,
                    "({ti},{pi},{to},{po}) c{c}: {} vs {}",
                    ours[c],
                    exact[c]
                );
                assert!((f[c] / exact[c] - 1.0).abs() < 1e-9);
            }
        }
    }

    /// The analytic Jacobian against central differences.
    #[test]
    fn gradient_matches_finite_differences() {
        let m = LobeGgxModel {
            distributions: vec![
                Distribution::Ggx,
                Distribution::StudentT { gamma: 3.0 },
                Distribution::Beckmann,
                Distribution::StudentT { gamma: 3.0 },
            ],
        };
        let theta = vec![
            -2.0 * 0.05f64.ln(),
            -2.0 * 0.12f64.ln(),
            -2.0 * 0.3f64.ln(),
            -2.0 * 0.9f64.ln(),
            0.3,
            -0.2,
            -0.7,
            gamma_theta(1.8),
            gamma_theta(6.0),
        ];
        let nt = theta.len();
        for (ti, pi, to, po) in [
            (20.0, 0.0, 25.0, 175.0),
            (60.0, 10.0, 70.0, 200.0),
            (5.0, 0.0, 80.0, 90.0),
        ] {
            let wi = spherical_direction_deg(ti, pi);
            let wo = spherical_direction_deg(to, po);
            let mut out = [0.0; 3];
            let mut grad = vec![0.0; 3 * nt];
            assert!(m.basis_gradient(&theta, wi, wo, &mut out, &mut grad));
            for q in 0..nt {
                let h = 1e-6;
                let (mut tp, mut tm) = (theta.clone(), theta.clone());
                tp[q] += h;
                tm[q] -= h;
                let (mut op, mut om) = ([0.0; 3], [0.0; 3]);
                m.basis(&tp, wi, wo, &mut op);
                m.basis(&tm, wi, wo, &mut om);
                for j in 1..3 {
                    let fd = (op[j] - om[j]) / (2.0 * h);
                    let an = grad[3 * q + j];
                    assert!(
                        (fd - an).abs() <= 1e-5 * (fd.abs() + out[j].abs()) + 1e-12,
                        "θ{q} basis {j} at ({ti},{to}): analytic {an} vs fd {fd}"
                    );
                }
            }
        }
    }
}
