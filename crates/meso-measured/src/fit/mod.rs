//! The fitting framework: a parameterised BRDF model, fitted to samples by Levenberg–Marquardt
//! in a chosen [`Metric`], with linear per-channel amplitudes, bounds, several starts and a
//! coarse-to-fine schedule.
//!
//! # Model structure
//! Every model is written as a sum of *basis lobes* with per-channel non-negative amplitudes:
//!
//! ```text
//! f_c(i, o) = Σ_j A[c][j] · b_j(θ; i, o)        c ∈ {r, g, b}
//! ```
//!
//! where `θ` are the non-linear (shared) parameters — lobe geometry, exponents, roughness —
//! and `A ≥ 0` the linear amplitudes (diffuse albedo, specular colour, ...). This is the "shared
//! lobe geometry, per-channel amplitudes" structure: the amplitudes are initialised by
//! non-negative linear least squares for every start (variable projection) and then refined
//! together with `θ` by LM; the Jacobian in `A` is exact (`b_j`), in `θ` analytic when the model
//! provides [`BrdfModel::basis_gradient`] (both lobe models do) and by forward differences of the
//! basis otherwise.
//!
//! # Schedule ([`fit`])
//! 1. coarse subsample (`coarse_samples`, stratified);
//! 2. every start of [`BrdfModel::initial_guesses`]: amplitudes by NNLS, cost in the metric;
//! 3. the best `refine_starts` starts: a short LM run each (`coarse_iterations / 4`, at least 5)
//!    on the coarse subsample;
//! 4. the best of them: LM continued on the coarse subsample (up to `coarse_iterations` in all);
//! 5. then LM on all samples given (`fine_iterations`).
//!
//! Residual and normal-equation evaluation is parallel (rayon, chunks of samples), with
//! allocation only per chunk; each residual's Jacobian row is compact (`θ` and its own
//! channel's amplitudes).
//!
//! # Where things are
//! * this module — the [`BrdfModel`] trait and [`eval_model`];
//! * `driver` — [`fit`] and [`fit_from`]: the checks of data and model, the bounds, the
//!   schedule above;
//! * `options` — what a fit is asked ([`FitOptions`], [`LobeAxes`]) and what it answers
//!   ([`FitResult`], [`FitError`]);
//! * `score` — [`FitErrors`] of a model or any BRDF on samples, fitted or held out
//!   ([`evaluate`], [`evaluate_samples`], [`evaluate_fn`], [`evaluate_samples_fn`]);
//! * `problem` — the least-squares problem LM solves (residuals, compact Jacobian rows, normal
//!   equations);
//! * `amplitudes` — the amplitudes for fixed `θ` by non-negative least squares
//!   ([`solve_amplitudes`]).

mod amplitudes;
mod driver;
mod options;
mod problem;
mod score;

pub use amplitudes::solve_amplitudes;
pub use driver::{fit, fit_from};
pub use options::{FitError, FitOptions, FitResult, LobeAxes};
pub use score::{evaluate, evaluate_fn, evaluate_samples, evaluate_samples_fn, FitErrors};

#[cfg(doc)]
use crate::metric::Metric;
#[cfg(doc)]
use crate::samples::SampleSet;
use glam::DVec3;

/// A parameterised BRDF model `f_c = Σ_j A[c][j]·b_j(θ; i, o)` (see the module docs).
pub trait BrdfModel: Sync {
    /// A short human-readable name, e.g. `"lobes-2"`, `"ggx"`.
    fn name(&self) -> String;
    /// Names of the non-linear parameters `θ` (their count is the number of parameters).
    fn nonlinear_names(&self) -> Vec<String>;
    /// Names of the basis lobes `b_j` (their count is the number of amplitudes per channel).
    fn basis_names(&self) -> Vec<String>;
    /// Box bounds `(lo, hi)` of each non-linear parameter.
    fn bounds(&self) -> Vec<(f64, f64)>;
    /// Starting values of `θ` to try (at least one; amplitudes are solved for each).
    fn initial_guesses(&self) -> Vec<Vec<f64>>;
    /// Evaluate the basis lobes `b_j(θ; wi, wo)` (1/sr, non-negative) into `out`
    /// (`out.len()` = number of basis lobes). `wi`, `wo` are unit, local frame, upper hemisphere.
    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]);

    /// The basis lobes (as [`BrdfModel::basis`], into `out`) and their derivatives with respect to
    /// the non-linear parameters, `grad[k · n_basis + j] = ∂b_j/∂θ_k` (`grad.len()` =
    /// `n_nonlinear · n_basis`). Returns `false`, leaving the buffers unspecified, when the model
    /// has no analytic derivative (the default): the fit then takes forward differences of
    /// [`BrdfModel::basis`].
    fn basis_gradient(
        &self,
        _theta: &[f64],
        _wi: DVec3,
        _wo: DVec3,
        _out: &mut [f64],
        _grad: &mut [f64],
    ) -> bool {
        false
    }

    /// Bounds `(lo, hi)` of each basis amplitude, the same for the three channels; `lo == hi`
    /// holds the amplitude fixed (e.g. the Fresnel grazing term of a Schlick microfacet model,
    /// whose amplitude is 1). Default: `[0, ∞)` for every basis lobe.
    fn amplitude_bounds(&self) -> Vec<(f64, f64)> {
        vec![(0.0, f64::INFINITY); self.n_basis()]
    }

    /// Limits on sums of basis amplitudes, the same for the three channels: `(basis indices,
    /// limit)` for `Σ_j A[c][j] ≤ limit` (the amplitudes' lower bounds must be 0). The fit
    /// keeps them (projected Levenberg–Marquardt, [`meso_core::lm::SumLimit`]), so the fitted
    /// closed form is the material written: e.g. the mirror models' Schlick amplitudes
    /// `u = s·f0`, `g = s·(1 − f0)` under `s = u + g ≤ 1`. Default: none.
    fn amplitude_sums(&self) -> Vec<(Vec<usize>, f64)> {
        Vec::new()
    }

    /// Indices into `θ` of lobe-axis coordinates whose value 0 puts the lobe axis on the surface
    /// normal (the tangent-plane point `(ax, ay, 1)` of the lobe models). [`LobeAxes::Normal`]
    /// holds them at 0. Default: none.
    fn axis_parameters(&self) -> Vec<usize> {
        Vec::new()
    }

    /// Sharpness parameters: `(index into θ, c)` for each parameter `θ_i = ln η` whose lobe has
    /// the von Mises–Fisher concentration `κ = c·η` (Phong peaks `cos^η(α/2)`: `c = ¼`). With
    /// [`FitOptions::resolution_cap`] their upper bound becomes `ln(κ_max/c)`,
    /// `κ_max = 1/δ²` for the data's angular resolution δ ([`SampleSet::angular_resolution`]):
    /// no lobe narrower than δ (per-axis angular standard deviation `1/√κ`). Default: none.
    fn sharpness_parameters(&self) -> Vec<(usize, f64)> {
        Vec::new()
    }

    /// Number of non-linear parameters.
    fn n_nonlinear(&self) -> usize {
        self.nonlinear_names().len()
    }
    /// Number of basis lobes.
    fn n_basis(&self) -> usize {
        self.basis_names().len()
    }
}

/// Evaluate a model with parameters `theta` and amplitudes `amps[j] = [r, g, b]` (1/sr).
/// `scratch` must hold at least `n_basis` values (kept outside for allocation-free loops).
#[must_use]
pub fn eval_model(
    model: &dyn BrdfModel,
    theta: &[f64],
    amps: &[[f64; 3]],
    wi: DVec3,
    wo: DVec3,
    scratch: &mut [f64],
) -> [f64; 3] {
    let nb = amps.len();
    model.basis(theta, wi, wo, &mut scratch[..nb]);
    let mut f = [0.0; 3];
    for (a, b) in amps.iter().zip(&scratch[..nb]) {
        for c in 0..3 {
            f[c] += a[c] * b;
        }
    }
    f
}
