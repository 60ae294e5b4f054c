//! The paper's model (Fournier 1992, §3.3): an NDF that is a sum of K Phong peaks (Eq. 12) with
//! a Phong transfer function (Eq. 10), convolved as in Eq. 2 in its default "multiple-surface"
//! form, plus a Lambertian diffuse term:
//!
//! ```text
//! f_c(i, o) = albedo_c/π + specular_c · S(i, o)
//! S(i, o)   = ∫ n(m) · max(0, m·H)^η_t · max(0, m·i) dω_m / cos θi
//! n(m)      = Σ_k w_k (η_k+2)/(8π) · cos^η_k(α_k/2),     Σ w_k = 1
//! ```
//!
//! # Closed form (von Mises–Fisher)
//! `S` is evaluated in closed form by replacing both Phong shapes with spherical Gaussians
//! ([`meso_core::sg`], whose module docs name every Phong ↔ SG mapping and its user). Two
//! mappings are used here, both chosen to keep an integral:
//! * each NDF peak by the *normalised* vMF `C(κ_k) exp(κ_k (cos α − 1))`,
//!   `C(κ) = κ/(2π(1 − e^(−2κ)))`, with `κ_k = (η_k + 2)/4`
//!   ([`meso_core::sg::kappa_same_integral`]: the peak's integral `8π/(η_k+2)` equals the
//!   Gaussian's `2π/κ_k`, so the normalised heights agree), **not** `κ = η/4` (the second-order
//!   match at the peak, [`meso_core::sg::kappa_same_curvature`]), which this closed form does not
//!   use;
//! * the transfer `(m·H)^η_t` by `exp(κ_t (m·H − 1))` with `κ_t = η_t + 1`
//!   ([`meso_core::sg::kappa_transfer`]: the same integral `2π/(η_t+1)`), **not** `κ_t = η_t`.
//!
//! The product of the two is one lobe with `v = κ_k N_k + κ_t H`, `κ₃ = |v|`, `μ₃ = v/κ₃` and
//! scale `e^(κ₃ − κ_k − κ_t)` ([`meso_core::sg::product`]), whose integral is
//! `2π (1 − e^(−2κ₃))/κ₃`. The cosine `max(0, m·i)` is not taken at one point: its expectation
//! `E(κ₃, μ₃·i) = E[max(0, m·i)]` under the product's vMF is read from meso-core's table over
//! `(ln κ, c)` ([`meso_core::convolution::clamped_cosine_mean_grad`]). Hence
//!
//! ```text
//! S ≈ Σ_k w_k C(κ_k) · 2π (1 − e^(−2κ₃))/κ₃ · e^(κ₃ − κ_k − κ_t) · E(κ₃, μ₃·i) / cos θi.
//! ```
//!
//! This is meso-core's [`meso_core::convolution::phong_closed_form`] — one implementation, so
//! the fitted closed form and `meso brdf`'s closed form are the same function. The written
//! material is evaluated by `meso brdf` with the exact quadrature of Eq. 2
//! ([`meso_core::material::Material::brdf`]); the approximation is good for sharp lobes
//! (η_k, η_t ≳ 10) and degrades for broad ones, so `meso fit` reports the exact error of the
//! written file too.
//!
//! # Parameters (non-linear θ, per lobe k, then shared)
//! * `ax_k, ay_k`: the lobe axis as the point `(ax, ay, 1)` of the tangent plane at the normal
//!   (axis = normalize(ax, ay, 1)) — no singularity at the normal, off-specular and anisotropic
//!   placements allowed; bounded to `|ax|, |ay| ≤ 2.75` (θ ≲ 75°);
//! * `ln η_k`, `η_k ∈ [1, 10⁶]`;
//! * `logit_k` for k ≥ 1 (k = 0 fixed at 0): weights `w = softmax(logits)`, bounded to ±10;
//! * `ln η_t` when the transfer exponent is free.
//!
//! Linear amplitudes: `albedo` (basis 1/π) and `specular` (basis `S`), per channel.
//!
//! **Identifiability:** near the peak only the combination `κ_k κ_t/(κ_k + κ_t)` and the peak
//! height are strongly determined; the split between lobe exponents and the transfer exponent rests
//! on the weaker `μ₃·i/cos θi` factor. Fix the transfer exponent ([`TransferExponent::Fixed`])
//! to pin the lobe exponents exactly.

use crate::fit::{eval_model, fit_from, BrdfModel, FitError, FitOptions, FitResult};
use crate::samples::SampleSet;
use glam::DVec3;
use meso_core::convolution::Accuracy;
use meso_core::frame::{rad_to_deg, spherical_angles, spherical_direction_deg};
use meso_core::material::{MaterialSpec, NdfSpec};
use meso_core::ndf::{Ndf, PhongLobe, PhongPeaks};
use meso_core::transfer::{PhongVariant, Transfer};
use meso_core::NdfError;
use std::f64::consts::PI;

/// Largest number of lobes supported by [`LobeModel`].
pub const MAX_LOBES: usize = 6;
const AXIS_BOUND: f64 = 2.75;
const LN_ETA: (f64, f64) = (0.0, 13.815_510_557_964_274); // ln 1 .. ln 1e6
const LOGIT: (f64, f64) = (-10.0, 10.0);

/// `S(i, o)` of the module docs (1/sr per unit specular): the closed-form vMF approximation of
/// the Eq. 2 convolution of a Phong-peak NDF with the Phong transfer `max(0, m·H)^η_t`, with each
/// facet lit by its own cosine, divided by `cos θi`. Zero if either direction is below the horizon.
/// Lobe weights are used as given (callers normalise them).
#[must_use]
pub fn lobe_sum_closed_form(
    lobes: &[PhongLobe],
    transfer_exponent: f64,
    wi: DVec3,
    wo: DVec3,
) -> f64 {
    meso_core::convolution::phong_closed_form(lobes, transfer_exponent, [1.0; 3], wi, wo)[0]
}

/// Whether the transfer exponent η_t is fitted or fixed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TransferExponent {
    /// Fitted (one shared non-linear parameter).
    Free,
    /// Fixed at this value.
    Fixed(f64),
}

/// The lobe-sum model with `k` lobes (1 ≤ k ≤ [`MAX_LOBES`]); see the module docs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobeModel {
    /// Number of Phong peaks.
    pub k: usize,
    /// The transfer exponent: fitted or fixed.
    pub transfer: TransferExponent,
}

/// A concrete lobe-sum material: the fitted (or generating) parameters in physical terms.
#[derive(Clone, Debug, PartialEq)]
pub struct LobeParams {
    /// The Phong peaks (unit axes, weights summing to 1, exponents on cos(α/2)).
    pub lobes: Vec<PhongLobe>,
    /// Transfer exponent η_t of `max(0, m·H)^η_t`.
    pub transfer_exponent: f64,
    /// Specular colour (the transfer's `specular`), per channel.
    pub specular: [f64; 3],
    /// Lambertian albedo per channel (`f = albedo/π`).
    pub albedo: [f64; 3],
}

impl LobeParams {
    /// The BRDF (1/sr) per channel at `wi`, `wo` (unit, local frame).
    #[must_use]
    pub fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        let s = lobe_sum_closed_form(&self.lobes, self.transfer_exponent, wi, wo);
        [0, 1, 2].map(|c| self.albedo[c] / PI + self.specular[c] * s)
    }

    /// The material: the `phong-peaks` NDF (axes snapped to the degrees the file holds), the `phong` transfer and a
    /// `[diffuse]` albedo, in the multiple-surface form.
    ///
    /// # Errors
    /// Lobes that make no NDF (non-finite or negative weights or exponents).
    pub fn to_spec(&self) -> Result<MaterialSpec, NdfError> {
        Ok(MaterialSpec {
            name: None,
            ndf: NdfSpec::Inline(Ndf::PhongPeaks(file_phong_peaks(&self.lobes)?)),
            transfer: Transfer::Phong {
                exponent: self.transfer_exponent,
                specular: self.specular,
                variant: PhongVariant::Half,
            },
            diffuse: self.albedo,
            form: None,
            shadowing: None,
            accuracy: Accuracy::default(),
        })
    }

    /// The material as meso TOML ([`LobeParams::to_spec`] written by
    /// [`MaterialSpec::to_toml_with_comment`]; axes as `[theta_deg, phi_deg]`). `comment` lines
    /// (e.g. the fit report) are prepended as `#` comments.
    #[must_use]
    pub fn to_material_toml(&self, comment: &str) -> String {
        super::material_file(self.to_spec(), comment)
    }
}

/// Decode the first `k` lobes of `θ` (per lobe `ax, ay, ln η`, then `k − 1` logits), weights
/// normalised by a softmax; the lobes past `k` are empty (on the normal, weight and exponent 0).
pub(crate) fn decode_lobes(k: usize, theta: &[f64]) -> [PhongLobe; MAX_LOBES] {
    let mut out = [PhongLobe::new(DVec3::Z, 0.0, 0.0); MAX_LOBES];
    let logit = |j: usize| if j == 0 { 0.0 } else { theta[3 * k + j - 1] };
    let mx = (0..k).map(logit).fold(f64::NEG_INFINITY, f64::max);
    let mut total = 0.0;
    for (j, l) in out.iter_mut().enumerate().take(k) {
        let w = (logit(j) - mx).exp();
        total += w;
        *l = PhongLobe {
            axis: DVec3::new(theta[3 * j], theta[3 * j + 1], 1.0).normalize(),
            weight: w,
            exponent: theta[3 * j + 2].exp(),
        };
    }
    for l in out.iter_mut().take(k) {
        l.weight /= total;
    }
    out
}

/// `θ` entries of lobes (inverse of [`decode_lobes`], axes in the upper hemisphere).
pub(crate) fn encode_lobes(lobes: &[PhongLobe]) -> Vec<f64> {
    let mut t = Vec::with_capacity(4 * lobes.len());
    for l in lobes {
        let a = l.axis / l.axis.z.max(1e-9);
        t.extend([a.x, a.y, l.exponent.max(1e-300).ln()]);
    }
    let w0 = lobes[0].weight.max(1e-300);
    for l in &lobes[1..] {
        t.push((l.weight.max(1e-300) / w0).ln());
    }
    t
}

/// The names of the `θ` entries [`decode_lobes`] reads for `k` lobes: `ax_j, ay_j, ln_eta_j` per
/// lobe, then `logit_j` for `j` in `1..k`.
pub(crate) fn peak_parameter_names(k: usize) -> Vec<String> {
    let mut v = Vec::new();
    for j in 0..k {
        v.extend([format!("ax{j}"), format!("ay{j}"), format!("ln_eta{j}")]);
    }
    for j in 1..k {
        v.push(format!("logit{j}"));
    }
    v
}

/// The bounds of the `θ` entries [`decode_lobes`] reads for `k` lobes: the axis slopes in
/// `±AXIS_BOUND`, `ln η` in `ln_eta`, the logits in `LOGIT`.
pub(crate) fn peak_bounds(k: usize, ln_eta: (f64, f64)) -> Vec<(f64, f64)> {
    let mut v = Vec::new();
    for _ in 0..k {
        v.extend([(-AXIS_BOUND, AXIS_BOUND), (-AXIS_BOUND, AXIS_BOUND), ln_eta]);
    }
    v.extend(std::iter::repeat_n(LOGIT, k - 1));
    v
}

/// [`BrdfModel::axis_parameters`] of `k` Phong peaks: `ax_j, ay_j` of every lobe.
pub(crate) fn peak_axis_parameters(k: usize) -> Vec<usize> {
    (0..k).flat_map(|j| [3 * j, 3 * j + 1]).collect()
}

/// [`BrdfModel::sharpness_parameters`] of `k` Phong peaks: `ln η_j` of every lobe, `κ = η/4`.
/// (The BRDF lobe is never sharper than its NDF peak, so capping the peaks caps every lobe of
/// the fitted BRDF.)
pub(crate) fn peak_sharpness_parameters(k: usize) -> Vec<(usize, f64)> {
    (0..k).map(|j| (3 * j + 2, 0.25)).collect()
}

/// The Phong peaks as a material file holds them: each axis at the `[theta_deg, phi_deg]` it is
/// written with (φ = 0 on the normal), so that the file reads back to exactly this NDF.
///
/// # Errors
/// As [`PhongPeaks::new`].
pub(crate) fn file_phong_peaks(lobes: &[PhongLobe]) -> Result<PhongPeaks, NdfError> {
    PhongPeaks::new(
        lobes
            .iter()
            .map(|l| {
                let (t, p) = spherical_angles(l.axis);
                let (t, mut p) = (rad_to_deg(t), rad_to_deg(p));
                if t < 1e-9 {
                    p = 0.0;
                }
                PhongLobe::new(spherical_direction_deg(t, p), l.weight, l.exponent)
            })
            .collect(),
    )
}

impl LobeModel {
    /// A model with `k` lobes and a fitted transfer exponent. `k` is clamped to `1..=MAX_LOBES`.
    #[must_use]
    pub fn new(k: usize) -> LobeModel {
        LobeModel {
            k: k.clamp(1, MAX_LOBES),
            transfer: TransferExponent::Free,
        }
    }

    /// The same model with the transfer exponent fixed at `eta_t`.
    #[must_use]
    pub fn with_fixed_transfer(self, eta_t: f64) -> LobeModel {
        LobeModel {
            transfer: TransferExponent::Fixed(eta_t),
            ..self
        }
    }

    /// The lobes ([`decode_lobes`]) and the transfer exponent of `θ`.
    fn decode(&self, theta: &[f64]) -> ([PhongLobe; MAX_LOBES], f64) {
        let eta_t = match self.transfer {
            TransferExponent::Free => theta[4 * self.k - 1].exp(),
            TransferExponent::Fixed(e) => e,
        };
        (decode_lobes(self.k, theta), eta_t)
    }

    /// Physical parameters from a fit of this model.
    #[must_use]
    pub fn params(&self, fit: &FitResult) -> LobeParams {
        self.params_from(&fit.theta, &fit.amps)
    }

    /// Physical parameters from `θ` and amplitudes (`[albedo, specular]`).
    #[must_use]
    pub fn params_from(&self, theta: &[f64], amps: &[[f64; 3]]) -> LobeParams {
        let (lobes, eta_t) = self.decode(theta);
        LobeParams {
            lobes: lobes[..self.k].to_vec(),
            transfer_exponent: eta_t,
            specular: amps[1],
            albedo: amps[0],
        }
    }

    /// `θ` encoding `p` (lobe axes must lie in the upper hemisphere; weights are renormalised;
    /// values are not clamped to the bounds). `p.lobes.len()` must equal `k`.
    #[must_use]
    pub fn theta_of(&self, p: &LobeParams) -> Vec<f64> {
        let mut t = encode_lobes(&p.lobes);
        if self.transfer == TransferExponent::Free {
            t.push(p.transfer_exponent.ln());
        }
        t
    }
}

impl BrdfModel for LobeModel {
    fn name(&self) -> String {
        match self.transfer {
            TransferExponent::Free => format!("lobes-{}", self.k),
            TransferExponent::Fixed(e) => format!("lobes-{} (eta_t = {e})", self.k),
        }
    }

    fn nonlinear_names(&self) -> Vec<String> {
        let mut v = peak_parameter_names(self.k);
        if self.transfer == TransferExponent::Free {
            v.push("ln_eta_t".into());
        }
        v
    }

    fn basis_names(&self) -> Vec<String> {
        vec!["diffuse".into(), "specular".into()]
    }

    fn axis_parameters(&self) -> Vec<usize> {
        peak_axis_parameters(self.k)
    }

    fn sharpness_parameters(&self) -> Vec<(usize, f64)> {
        peak_sharpness_parameters(self.k)
    }

    fn amplitude_bounds(&self) -> Vec<(f64, f64)> {
        // The material format's ranges: albedo in [0, 1], specular in [0, 1e6].
        vec![(0.0, 1.0), (0.0, 1e6)]
    }

    fn bounds(&self) -> Vec<(f64, f64)> {
        let mut v = peak_bounds(self.k, LN_ETA);
        if self.transfer == TransferExponent::Free {
            v.push(LN_ETA);
        }
        v
    }

    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        // Starts described by the Blinn-equivalent sharpness e_j of each lobe convolved with the
        // transfer: κ_eff = κ_j κ_t/(κ_j + κ_t). Lobes on the normal, equal weights.
        let grid = start_sharpness_grid(self.k);
        grid.iter()
            .map(|es| {
                let emax = es.iter().copied().fold(0.0, f64::max);
                let kt = match self.transfer {
                    TransferExponent::Free => 2.0 * emax,
                    TransferExponent::Fixed(e) => e,
                };
                let mut t = Vec::new();
                for j in 0..self.k {
                    let e = es[j.min(es.len() - 1)] * (1.0 + 0.1 * (j / es.len()) as f64);
                    let e = e.min(0.9 * kt);
                    let kk = e * kt / (kt - e);
                    t.extend([0.0, 0.0, (4.0 * kk).clamp(1.0, 1e6).ln()]);
                }
                t.extend(std::iter::repeat_n(0.0, self.k - 1));
                if self.transfer == TransferExponent::Free {
                    t.push(kt.clamp(1.0, 1e6).ln());
                }
                t
            })
            .collect()
    }

    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let (lobes, eta_t) = self.decode(theta);
        out[0] = 1.0 / PI;
        out[1] = lobe_sum_closed_form(&lobes[..self.k], eta_t, wi, wo);
    }

    /// Analytic derivatives of the closed form (see [`super::vmf`]).
    fn basis_gradient(
        &self,
        theta: &[f64],
        wi: DVec3,
        wo: DVec3,
        out: &mut [f64],
        grad: &mut [f64],
    ) -> bool {
        let k = self.k;
        let nt = match self.transfer {
            TransferExponent::Free => 4 * k,
            TransferExponent::Fixed(_) => 4 * k - 1,
        };
        grad[..2 * nt].fill(0.0);
        out[0] = 1.0 / PI;
        out[1] = 0.0;
        let Some(h) = super::upper_half_vector(wi, wo) else {
            return true;
        };
        let (lobes, eta_t) = self.decode(theta);
        let k2 = meso_core::sg::kappa_transfer(eta_t);
        let inv = 1.0 / wi.z;
        let mut terms = [0.0; MAX_LOBES];
        let mut s = 0.0;
        let mut d_k2 = 0.0;
        for (j, l) in lobes.iter().enumerate().take(k) {
            let k1 = meso_core::sg::kappa_same_integral(l.exponent);
            let (t, dk1, dk2, dv) = super::vmf::lobe_term_grad(l.axis, k1, k2, h, wi);
            terms[j] = t;
            s += l.weight * t;
            d_k2 += l.weight * (dk2 + dv.dot(h));
            let w = l.weight * inv;
            // ln η: dκ₁ = η/4 and v moves along the axis.
            grad[2 * (3 * j + 2) + 1] = w * 0.25 * l.exponent * (dk1 + dv.dot(l.axis));
            // Axis (ax, ay, 1)/r: ∂a/∂ax = (e_x − a a_x)/r, v moves by κ₁ ∂a.
            let r = DVec3::new(theta[3 * j], theta[3 * j + 1], 1.0).length();
            let da = dv.dot(l.axis);
            grad[2 * (3 * j) + 1] = w * k1 / r * (dv.x - da * l.axis.x);
            grad[2 * (3 * j + 1) + 1] = w * k1 / r * (dv.y - da * l.axis.y);
        }
        out[1] = s * inv;
        // Softmax weights: ∂w_j/∂logit_m = w_j (δ_jm − w_m).
        for m in 1..k {
            grad[2 * (3 * k + m - 1) + 1] = lobes[m].weight * (terms[m] - s) * inv;
        }
        if self.transfer == TransferExponent::Free {
            grad[2 * (4 * k - 1) + 1] = eta_t * d_k2 * inv;
        }
        true
    }
}

/// Half vectors of the samples where the data most exceed the current model (log residual,
/// channels averaged), at least 5° apart: seeds for new lobe axes. `current` is `None` for an
/// empty model.
pub(crate) fn peak_seeds(
    data: &SampleSet,
    current: Option<(&dyn BrdfModel, &FitResult)>,
    n: usize,
) -> Vec<DVec3> {
    let mut scored: Vec<(f64, DVec3)> = data
        .samples
        .iter()
        .filter_map(|s| {
            let f = match current {
                Some((m, r)) => eval_model(m, &r.theta, &r.amps, s.wi, s.wo, &mut [0.0; 8]),
                None => [0.0; 3],
            };
            let ci = s.wi.z;
            let e: f64 = (0..3)
                .map(|c| (s.rgb[c] * ci).ln_1p() - (f[c] * ci).ln_1p())
                .sum();
            meso_core::frame::half_vector(s.wi, s.wo).map(|h| (e, h))
        })
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    let cos_sep = 5f64.to_radians().cos();
    let mut out: Vec<DVec3> = Vec::new();
    for (_, h) in scored {
        if out.len() >= n {
            break;
        }
        if h.z > 0.2 && out.iter().all(|o| o.dot(h) < cos_sep) {
            out.push(h);
        }
    }
    out
}

/// Lobe exponent η giving the Blinn-equivalent sharpness `e` once convolved with a transfer of
/// exponent `eta_t` (κ_eff = κ κ_t/(κ + κ_t), κ = η/4, κ_t = η_t).
fn eta_for(e: f64, eta_t: f64) -> f64 {
    let e = e.min(0.9 * eta_t);
    (4.0 * e * eta_t / (eta_t - e)).clamp(1.0, 1e6)
}

/// Fit lobe sums with 1, 2, …, `k` lobes progressively (coarse to fine in model size): each fit
/// starts from the model's own start grid, plus starts that keep the previous fit and add a
/// lobe at the half vector where the data most exceed it (several exponents). Returns every
/// model fitted, with its result.
pub fn fit_lobes_progressive(
    k: usize,
    transfer: TransferExponent,
    data: &SampleSet,
    opts: &FitOptions,
) -> Result<Vec<(LobeModel, FitResult)>, FitError> {
    fit_peaks_progressive(
        k,
        data,
        opts,
        |j| LobeModel { k: j, transfer },
        |m, prev, h, e, [keep, w]| {
            let p = match prev {
                Some((pm, r)) => {
                    let mut p = pm.params(r);
                    let eta = eta_for(e, p.transfer_exponent);
                    p.lobes.iter_mut().for_each(|l| l.weight *= keep);
                    p.lobes.push(PhongLobe::new(h, w, eta));
                    p
                }
                None => {
                    let eta_t = match transfer {
                        TransferExponent::Free => 2.0 * e,
                        TransferExponent::Fixed(t) => t,
                    };
                    LobeParams {
                        lobes: vec![PhongLobe::new(h, 1.0, eta_for(e, eta_t))],
                        transfer_exponent: eta_t,
                        specular: [0.0; 3],
                        albedo: [0.0; 3],
                    }
                }
            };
            m.theta_of(&p)
        },
    )
}

/// The progressive schedule of both Phong-peak models ([`fit_lobes_progressive`],
/// [`super::fit_microfacet_lobes_progressive`]): for `K = 1, …, k` lobes, the model `model(K)`
/// starts from its own grid, then from `grow(m, prev, h, e, [keep, w])` — the previous fit
/// `prev` with its weights scaled by `keep` and one more lobe of weight `w` at the half vector
/// `h` with the Blinn-equivalent sharpness `e` (for `K = 1`, `prev` is `None`: one lobe at
/// `h`), as `θ` of `m`: first a negligible new lobe at the first seed (`e = 100`, weights
/// `[0.99, 0.01]`; a start as good as the previous fit, so that adding a lobe does not make the
/// fit worse), then a lobe of weight 0.25 at each of three seeds ([`peak_seeds`]) and each `e`
/// in 10, 100, 1000, 10000.
pub(crate) fn fit_peaks_progressive<M: BrdfModel>(
    k: usize,
    data: &SampleSet,
    opts: &FitOptions,
    model: impl Fn(usize) -> M,
    grow: impl Fn(&M, Option<(&M, &FitResult)>, DVec3, f64, [f64; 2]) -> Vec<f64>,
) -> Result<Vec<(M, FitResult)>, FitError> {
    let mut out: Vec<(M, FitResult)> = Vec::new();
    for j in 1..=k.clamp(1, MAX_LOBES) {
        let m = model(j);
        let mut starts = m.initial_guesses();
        let prev = out.last().map(|(pm, r)| (pm, r));
        let seeds = peak_seeds(data, prev.map(|(pm, r)| (pm as &dyn BrdfModel, r)), 3);
        if let (Some(prev), Some(&h)) = (prev, seeds.first()) {
            starts.push(grow(&m, Some(prev), h, 100.0, [0.99, 0.01]));
        }
        for h in seeds {
            for e in [10.0, 100.0, 1000.0, 10000.0] {
                starts.push(grow(&m, prev, h, e, [0.75, 0.25]));
            }
        }
        let r = fit_from(&m, data, opts, &starts)?;
        out.push((m, r));
    }
    Ok(out)
}

/// The multi-start grid of both lobe models: for K = 1, 2, ≥ 3 lobes, sets of Blinn-equivalent
/// sharpnesses (one per lobe, repeated when K exceeds the set) from which the fits start.
pub(crate) fn start_sharpness_grid(k: usize) -> &'static [&'static [f64]] {
    match k {
        1 => &[
            &[3.0],
            &[10.0],
            &[30.0],
            &[100.0],
            &[300.0],
            &[1e3],
            &[3e3],
            &[1e4],
            &[3e4],
        ],
        2 => &[
            &[3.0, 30.0],
            &[3.0, 300.0],
            &[10.0, 100.0],
            &[10.0, 1e3],
            &[30.0, 300.0],
            &[30.0, 3e3],
            &[100.0, 1e3],
            &[100.0, 1e4],
            &[300.0, 3e3],
            &[1e3, 1e4],
        ],
        _ => &[
            &[3.0, 30.0, 300.0],
            &[3.0, 100.0, 3e3],
            &[10.0, 100.0, 1e3],
            &[10.0, 300.0, 1e4],
            &[30.0, 300.0, 3e3],
            &[30.0, 1e3, 3e4],
            &[100.0, 1e3, 1e4],
            &[3.0, 10.0, 30.0],
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::spherical_direction_deg;

    /// Independent truth: the vMF-shaped integrand of the module docs integrated numerically over
    /// the sphere (θ, φ midpoint rule), where the product formula is exact but the cosine is not
    /// taken at the mean.
    fn quadrature_vmf(l: &PhongLobe, kt: f64, wi: DVec3, wo: DVec3, exact_phong: bool) -> f64 {
        let h = (wi + wo).normalize();
        let (nt, np) = (1200, 1200);
        let mut s = 0.0;
        for a in 0..nt {
            let t = PI * (a as f64 + 0.5) / nt as f64;
            for b in 0..np {
                let p = 2.0 * PI * (b as f64 + 0.5) / np as f64;
                let m = meso_core::frame::spherical_direction(t, p);
                let (nd, tr) = if exact_phong {
                    (l.unit_density(m), m.dot(h).max(0.0).powf(kt))
                } else {
                    // The core's vMF shapes: κ₁ = (η+2)/4 normalised, κ₂ = η_t + 1.
                    let k1 = meso_core::sg::kappa_same_integral(l.exponent);
                    let k2 = meso_core::sg::kappa_transfer(kt);
                    (
                        meso_core::sg::Sg::normalised(l.axis, k1).eval(m),
                        (k2 * (m.dot(h) - 1.0)).exp(),
                    )
                };
                s += nd * tr * m.dot(wi).max(0.0) * t.sin();
            }
        }
        s * (PI / nt as f64) * (2.0 * PI / np as f64) / wi.z
    }

    #[test]
    fn closed_form_matches_quadrature() {
        let l = PhongLobe::new(spherical_direction_deg(10.0, 30.0), 1.0, 200.0);
        for (ti, pi, to, po) in [
            (20.0, 180.0, 25.0, 10.0),
            (40.0, 200.0, 30.0, 40.0),
            (60.0, 0.0, 50.0, 150.0),
        ] {
            let wi = spherical_direction_deg(ti, pi);
            let wo = spherical_direction_deg(to, po);
            let cf = lobe_sum_closed_form(&[l], 100.0, wi, wo);
            let q = quadrature_vmf(&l, 100.0, wi, wo, false);
            assert!(
                (cf / q - 1.0).abs() < 0.01,
                "vMF shapes: closed {cf} vs quadrature {q}"
            );
            let qp = quadrature_vmf(&l, 100.0, wi, wo, true);
            assert!(
                (cf / qp - 1.0).abs() < 0.05,
                "Phong shapes: closed {cf} vs quadrature {qp}"
            );
        }
    }

    #[test]
    fn theta_round_trip_and_toml() {
        let m = LobeModel::new(2);
        let p = LobeParams {
            lobes: vec![
                PhongLobe::new(spherical_direction_deg(0.0, 0.0), 0.25, 50.0),
                PhongLobe::new(spherical_direction_deg(30.0, 90.0), 0.75, 400.0),
            ],
            transfer_exponent: 80.0,
            specular: [1.0, 0.8, 0.6],
            albedo: [0.1, 0.2, 0.3],
        };
        let t = m.theta_of(&p);
        let back = m.params_from(&t, &[p.albedo, p.specular]);
        for (a, b) in back.lobes.iter().zip(&p.lobes) {
            assert!((a.axis - b.axis).length() < 1e-12);
            assert!((a.weight - b.weight).abs() < 1e-12 && (a.exponent - b.exponent).abs() < 1e-9);
        }
        let text = back.to_material_toml("fit report\nline 2");
        assert!(text.starts_with("# fit report\n# line 2\n[ndf]\n"));
        let v: toml::Value = toml::from_str(&text).expect("valid TOML");
        assert_eq!(v["ndf"]["kind"].as_str(), Some("phong-peaks"));
        let lobes = v["ndf"]["lobes"].as_array().unwrap();
        let num = |x: &toml::Value| x.as_float().unwrap();
        let expect = [(0.0, 0.0, 0.25, 50.0), (30.0, 90.0, 0.75, 400.0)];
        for (l, e) in lobes.iter().zip(expect) {
            let ax = l["axis"].as_array().unwrap();
            assert!((num(&ax[0]) - e.0).abs() < 1e-9 && (num(&ax[1]) - e.1).abs() < 1e-9);
            assert!((num(&l["weight"]) - e.2).abs() < 1e-12);
            assert!((num(&l["exponent"]) - e.3).abs() < 1e-9);
        }
        assert_eq!(v["transfer"]["kind"].as_str(), Some("phong"));
        assert!((num(&v["transfer"]["exponent"]) - 80.0).abs() < 1e-9);
        let spec = v["transfer"]["specular"].as_array().unwrap();
        assert!((num(&spec[1]) - 0.8).abs() < 1e-15);
        let alb = v["diffuse"]["albedo"].as_array().unwrap();
        assert!((num(&alb[2]) - 0.3).abs() < 1e-15);
    }
}
