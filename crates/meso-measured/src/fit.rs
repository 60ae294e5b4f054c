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

use crate::metric::{Metric, Objective};
use crate::samples::{Sample, SampleSet};
use glam::DVec3;
use meso_core::linalg::cholesky_solve;
use meso_core::lm::{minimize_boxed, LmOptions, LmReport, VectorProblem};
use rayon::prelude::*;
use std::time::Instant;

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

/// Errors of a model against samples, per channel (r, g, b), in both metrics.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FitErrors {
    /// [`Metric::NganL2`] RMS, 1/sr.
    pub ngan_l2: [f64; 3],
    /// [`Metric::LowLog`] RMS, dimensionless.
    pub low_log: [f64; 3],
}

/// Score `theta`/`amps` of `model` on `data` in both metrics (weighted RMS per channel).
#[must_use]
pub fn evaluate(
    model: &dyn BrdfModel,
    theta: &[f64],
    amps: &[[f64; 3]],
    data: &SampleSet,
) -> FitErrors {
    evaluate_samples(model, theta, amps, &data.samples)
}

/// [`evaluate`] on a slice of samples (e.g. [`SampleSet::held_out`]).
#[must_use]
pub fn evaluate_samples(
    model: &dyn BrdfModel,
    theta: &[f64],
    amps: &[[f64; 3]],
    samples: &[Sample],
) -> FitErrors {
    evaluate_samples_fn(samples, |wi, wo| {
        let mut scratch = [0.0; 16];
        if amps.len() <= 16 {
            eval_model(model, theta, amps, wi, wo, &mut scratch)
        } else {
            eval_model(model, theta, amps, wi, wo, &mut vec![0.0; amps.len()])
        }
    })
}

/// Score any BRDF `f(wi, wo) → [r, g, b]` (1/sr) on `data` in both metrics (weighted RMS per
/// channel); `f` is evaluated once per sample, in parallel.
#[must_use]
pub fn evaluate_fn(data: &SampleSet, f: impl Fn(DVec3, DVec3) -> [f64; 3] + Sync) -> FitErrors {
    evaluate_samples_fn(&data.samples, f)
}

/// [`evaluate_fn`] on a slice of samples (e.g. [`SampleSet::held_out`]).
#[must_use]
pub fn evaluate_samples_fn(
    samples: &[Sample],
    f: impl Fn(DVec3, DVec3) -> [f64; 3] + Sync,
) -> FitErrors {
    let sums = samples
        .par_chunks(256)
        .map(|chunk| {
            let mut acc = [0.0f64; 7];
            for s in chunk {
                let f = f(s.wi, s.wo);
                let ci = s.wi.z;
                for (c, (&fc, &dc)) in f.iter().zip(&s.rgb).enumerate() {
                    let a = crate::metric::l2_residual(fc, dc, ci);
                    let b = crate::metric::log_residual(fc, dc, ci);
                    acc[c] += s.weight * a * a;
                    acc[3 + c] += s.weight * b * b;
                }
                acc[6] += s.weight;
            }
            acc
        })
        .reduce(
            || [0.0; 7],
            |mut a, b| {
                for k in 0..7 {
                    a[k] += b[k];
                }
                a
            },
        );
    let w = sums[6].max(f64::MIN_POSITIVE);
    FitErrors {
        ngan_l2: [0, 1, 2].map(|c| (sums[c] / w).sqrt()),
        low_log: [0, 1, 2].map(|c| (sums[3 + c] / w).sqrt()),
    }
}

/// Where the lobe axes of a lobe model may go ([`BrdfModel::axis_parameters`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LobeAxes {
    /// Every lobe axis on the surface normal: an isotropic NDF without off-specular peaks
    /// (the right model for isotropic data such as MERL tables).
    Normal,
    /// Axes anywhere within the model's bounds (off-specular and anisotropic placements).
    Free,
}

impl LobeAxes {
    /// Parse `"normal"` or `"free"`.
    #[must_use]
    pub fn from_name(s: &str) -> Option<LobeAxes> {
        match s {
            "normal" => Some(LobeAxes::Normal),
            "free" => Some(LobeAxes::Free),
            _ => None,
        }
    }

    /// `"normal"` or `"free"`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            LobeAxes::Normal => "normal",
            LobeAxes::Free => "free",
        }
    }
}

/// Options of [`fit`].
#[derive(Clone, Copy, Debug)]
pub struct FitOptions {
    /// The metric minimised.
    pub metric: Metric,
    /// Size of the coarse subsample used to rank starts and for the first LM run.
    pub coarse_samples: usize,
    /// How many of the best starts get a short LM run on the coarse subsample (the best of them
    /// is continued).
    pub refine_starts: usize,
    /// LM iterations on the coarse subsample (short runs: a quarter of this, at least 5).
    pub coarse_iterations: usize,
    /// LM iterations on the full sample set.
    pub fine_iterations: usize,
    /// Where lobe axes may go (models with [`BrdfModel::axis_parameters`]; others ignore it).
    /// Default [`LobeAxes::Normal`]: on the six MERL materials of docs/benchmarks.md free axes
    /// fitted "sink" lobes on red-fabric (false glints: log error 0.020 on all cells against
    /// 0.0048 on the normal), and were better only with broad tilted lobes on beige-fabric and
    /// black-oxidized-steel (K = 3: 0.0046 / 0.0038 against 0.0059 / 0.0042); use
    /// [`LobeAxes::Free`] for anisotropic or off-specular data.
    pub axes: LobeAxes,
    /// Cap the lobe sharpness by the data's angular resolution
    /// ([`BrdfModel::sharpness_parameters`]): a lobe narrower than the spacing of the samples can
    /// hide between them and be fitted as a "sink" of facet area that shows as a false glint
    /// elsewhere. The resolution is [`SampleSet::angular_resolution`] with free axes and
    /// [`SampleSet::angular_resolution_at_normal`] with the axes on the normal (where MERL
    /// tables are much finer than 1°). On by default.
    pub resolution_cap: bool,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            metric: Metric::LowLog,
            coarse_samples: 4000,
            refine_starts: 3,
            coarse_iterations: 60,
            fine_iterations: 40,
            axes: LobeAxes::Normal,
            resolution_cap: true,
        }
    }
}

/// Errors of [`fit`].
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    /// No samples with positive weight.
    #[error("no samples to fit (after filtering)")]
    NoData,
    /// A sample is not usable.
    #[error("sample {index}: {what}")]
    BadSample {
        /// Index in the sample set.
        index: usize,
        /// What is wrong.
        what: String,
    },
    /// The model's starting points or bounds are inconsistent.
    #[error("model {model}: {what}")]
    BadModel {
        /// Model name.
        model: String,
        /// What is wrong.
        what: String,
    },
}

/// The outcome of [`fit`].
#[derive(Clone, Debug)]
pub struct FitResult {
    /// Model name.
    pub model: String,
    /// Metric minimised.
    pub metric: Metric,
    /// Non-linear parameters (names: [`BrdfModel::nonlinear_names`]).
    pub theta: Vec<f64>,
    /// Amplitudes per basis lobe, `[r, g, b]` (names: [`BrdfModel::basis_names`]).
    pub amps: Vec<[f64; 3]>,
    /// Errors on the fitted samples, both metrics, per channel.
    pub errors: FitErrors,
    /// Errors on the held-out samples ([`SampleSet::held_out`]; never fitted), `None` when the
    /// data have none. Much larger than `errors` means an over-fit (e.g. a lobe between samples).
    pub held_out: Option<FitErrors>,
    /// Number of held-out samples scored.
    pub held_out_count: usize,
    /// The angular resolution δ (radians) that capped the lobe sharpness (`κ ≤ 1/δ²`; the
    /// model's own bound applies when that is tighter, e.g. δ = 0), `None`
    /// when [`FitOptions::resolution_cap`] is off or the model has no sharpness parameters.
    pub resolution: Option<f64>,
    /// Where the lobe axes were allowed to go.
    pub axes: LobeAxes,
    /// Total LM iterations (all starts, both stages).
    pub iterations: usize,
    /// Number of starts tried.
    pub starts: usize,
    /// Wall-clock time, seconds.
    pub seconds: f64,
}

struct Problem<'a> {
    model: &'a dyn BrdfModel,
    data: &'a [Sample],
    objective: Objective,
    nt: usize,
    nb: usize,
}

impl Problem<'_> {
    fn split<'p>(&self, p: &'p [f64]) -> (&'p [f64], Vec<[f64; 3]>) {
        let (t, a) = p.split_at(self.nt);
        let amps = (0..self.nb)
            .map(|j| [a[j], a[self.nb + j], a[2 * self.nb + j]])
            .collect();
        (t, amps)
    }
}

impl VectorProblem for Problem<'_> {
    fn n_params(&self) -> usize {
        self.nt + 3 * self.nb
    }

    fn cost(&self, p: &[f64]) -> f64 {
        let (theta, amps) = self.split(p);
        let nb = self.nb;
        self.data
            .par_chunks(1024)
            .map(|chunk| {
                let mut scratch = vec![0.0; nb];
                let mut acc = 0.0;
                for s in chunk {
                    let f = eval_model(self.model, theta, &amps, s.wi, s.wo, &mut scratch);
                    for (&fc, &dc) in f.iter().zip(&s.rgb) {
                        let r = self.objective.residual(fc, dc, s.wi.z);
                        acc += s.weight * r * r;
                    }
                }
                acc
            })
            .sum::<f64>()
            * 0.5
    }

    fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
        let (theta, amps) = self.split(p);
        let (nt, nb) = (self.nt, self.nb);
        let n = nt + 3 * nb;
        // One residual depends on θ and on the amplitudes of its own channel only: a compact row
        // of `nt + nb` entries, scattered through `index[c]`.
        let m = nt + nb;
        let index: Vec<Vec<usize>> = (0..3)
            .map(|c| {
                (0..m)
                    .map(|x| if x < nt { x } else { nt + c * nb + (x - nt) })
                    .collect()
            })
            .collect();
        // Forward-difference steps, for models without an analytic derivative.
        let bounds = self.model.bounds();
        let steps: Vec<f64> = (0..nt)
            .map(|k| {
                let h = 1e-6 * (1.0 + theta[k].abs());
                if theta[k] + h > bounds[k].1 {
                    -h
                } else {
                    h
                }
            })
            .collect();
        let thetas: Vec<Vec<f64>> = (0..nt)
            .map(|k| {
                let mut t = theta.to_vec();
                t[k] += steps[k];
                t
            })
            .collect();
        let (a, g, cost) = self
            .data
            .par_chunks(512)
            .map(|chunk| {
                let mut a = vec![0.0; n * n];
                let mut g = vec![0.0; n];
                let mut cost = 0.0;
                let mut b0 = vec![0.0; nb];
                let mut db = vec![0.0; nt * nb];
                let mut bk = vec![0.0; nb];
                let mut row = vec![0.0; m];
                for s in chunk {
                    if !self
                        .model
                        .basis_gradient(theta, s.wi, s.wo, &mut b0, &mut db)
                    {
                        self.model.basis(theta, s.wi, s.wo, &mut b0);
                        for k in 0..nt {
                            self.model.basis(&thetas[k], s.wi, s.wo, &mut bk);
                            for j in 0..nb {
                                db[k * nb + j] = (bk[j] - b0[j]) / steps[k];
                            }
                        }
                    }
                    let sw = s.weight.sqrt();
                    for (c, idx) in index.iter().enumerate() {
                        let f: f64 = (0..nb).map(|j| amps[j][c] * b0[j]).sum();
                        let r = sw * self.objective.residual(f, s.rgb[c], s.wi.z);
                        let dr = sw * self.objective.d_residual(f, s.rgb[c], s.wi.z);
                        cost += r * r;
                        for k in 0..nt {
                            let d = &db[k * nb..(k + 1) * nb];
                            let df: f64 = (0..nb).map(|j| amps[j][c] * d[j]).sum();
                            row[k] = dr * df;
                        }
                        for j in 0..nb {
                            row[nt + j] = dr * b0[j];
                        }
                        for x in 0..m {
                            let rx = row[x];
                            if rx == 0.0 {
                                continue;
                            }
                            let ix = idx[x];
                            g[ix] += rx * r;
                            let ax = &mut a[ix * n..(ix + 1) * n];
                            for y in x..m {
                                ax[idx[y]] += rx * row[y];
                            }
                        }
                    }
                }
                (a, g, cost)
            })
            .reduce(
                || (vec![0.0; n * n], vec![0.0; n], 0.0),
                |(mut a, mut g, c), (a2, g2, c2)| {
                    a.iter_mut().zip(&a2).for_each(|(x, y)| *x += y);
                    g.iter_mut().zip(&g2).for_each(|(x, y)| *x += y);
                    (a, g, c + c2)
                },
            );
        for x in 0..n {
            jtr[x] = g[x];
            for y in x..n {
                jtj[x * n + y] = a[x * n + y];
                jtj[y * n + x] = a[x * n + y];
            }
        }
        0.5 * cost
    }
}

/// Non-negative least squares for one channel's amplitudes from the normal equations
/// (`m` row-major `nb×nb`, `v` right-hand side), by an active set that drops negative entries.
fn nnls_small(m: &[f64], v: &[f64], nb: usize) -> Vec<f64> {
    let mut free = vec![true; nb];
    for _ in 0..=nb {
        let idx: Vec<usize> = (0..nb).filter(|&j| free[j]).collect();
        let k = idx.len();
        let mut x = vec![0.0; nb];
        if k == 0 {
            return x;
        }
        let mut a = vec![0.0; k * k];
        let mut b = vec![0.0; k];
        let scale = idx
            .iter()
            .map(|&j| m[j * nb + j])
            .fold(0.0f64, f64::max)
            .max(1e-300);
        for (p, &i) in idx.iter().enumerate() {
            b[p] = v[i];
            for (q, &j) in idx.iter().enumerate() {
                a[p * k + q] = m[i * nb + j];
            }
            a[p * k + p] += 1e-12 * scale;
        }
        if !cholesky_solve(&mut a, &mut b, k) {
            return x;
        }
        let mut all_pos = true;
        for (p, &i) in idx.iter().enumerate() {
            if b[p] < 0.0 {
                free[i] = false;
                all_pos = false;
            } else {
                x[i] = b[p];
            }
        }
        if all_pos {
            return x;
        }
    }
    vec![0.0; nb]
}

/// Amplitudes for fixed `theta` by non-negative weighted least squares in the cosine-weighted L2
/// sense (a good start for either metric). Amplitudes held fixed by
/// [`BrdfModel::amplitude_bounds`] keep their value; the others are solved for and clamped to
/// their bounds.
#[must_use]
pub fn solve_amplitudes(model: &dyn BrdfModel, theta: &[f64], data: &SampleSet) -> Vec<[f64; 3]> {
    let nb = model.n_basis();
    let ab = model.amplitude_bounds();
    let (m, v) = data
        .samples
        .par_chunks(1024)
        .map(|chunk| {
            let mut m = vec![0.0; nb * nb];
            let mut v = vec![0.0; 3 * nb];
            let mut b = vec![0.0; nb];
            for s in chunk {
                model.basis(theta, s.wi, s.wo, &mut b);
                let w = s.weight * s.wi.z * s.wi.z;
                for x in 0..nb {
                    for y in 0..nb {
                        m[x * nb + y] += w * b[x] * b[y];
                    }
                    for c in 0..3 {
                        v[c * nb + x] += w * b[x] * s.rgb[c];
                    }
                }
            }
            (m, v)
        })
        .reduce(
            || (vec![0.0; nb * nb], vec![0.0; 3 * nb]),
            |(mut m, mut v), (m2, v2)| {
                m.iter_mut().zip(&m2).for_each(|(x, y)| *x += y);
                v.iter_mut().zip(&v2).for_each(|(x, y)| *x += y);
                (m, v)
            },
        );
    // Fixed amplitudes move to the right-hand side; NNLS on the free ones.
    let free: Vec<usize> = (0..nb).filter(|&j| ab[j].0 < ab[j].1).collect();
    let nf = free.len();
    let mut mf = vec![0.0; nf * nf];
    for (p, &x) in free.iter().enumerate() {
        for (q, &y) in free.iter().enumerate() {
            mf[p * nf + q] = m[x * nb + y];
        }
    }
    let per_c: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            let vf: Vec<f64> = free
                .iter()
                .map(|&x| {
                    let fixed: f64 = (0..nb)
                        .filter(|&j| ab[j].0 >= ab[j].1)
                        .map(|j| m[x * nb + j] * ab[j].0)
                        .sum();
                    v[c * nb + x] - fixed
                })
                .collect();
            let xf = nnls_small(&mf, &vf, nf);
            let mut out: Vec<f64> = ab.iter().map(|b| b.0).collect();
            for (p, &x) in free.iter().enumerate() {
                out[x] = xf[p].clamp(ab[x].0.max(0.0), ab[x].1);
            }
            out
        })
        .collect();
    (0..nb)
        .map(|j| [per_c[0][j], per_c[1][j], per_c[2][j]])
        .collect()
}

fn check_data(data: &SampleSet) -> Result<(), FitError> {
    if data.samples.iter().all(|s| s.weight <= 0.0) {
        return Err(FitError::NoData);
    }
    for (index, s) in data.samples.iter().enumerate() {
        let ok = s.wi.is_finite()
            && s.wo.is_finite()
            && s.weight.is_finite()
            && s.weight >= 0.0
            && s.rgb.iter().all(|v| v.is_finite() && *v >= 0.0);
        if !ok {
            return Err(FitError::BadSample {
                index,
                what: "non-finite or negative value, weight or direction".into(),
            });
        }
        if s.wi.z <= 0.0 || s.wo.z <= 0.0 {
            return Err(FitError::BadSample {
                index,
                what: "direction below the horizon".into(),
            });
        }
    }
    Ok(())
}

fn pack(theta: &[f64], amps: &[[f64; 3]]) -> Vec<f64> {
    let nb = amps.len();
    let mut p = theta.to_vec();
    for c in 0..3 {
        for a in amps.iter().take(nb) {
            p.push(a[c]);
        }
    }
    p
}

/// Fit `model` to `data` (see the module docs for the schedule); errors are reported on `data`.
pub fn fit(
    model: &dyn BrdfModel,
    data: &SampleSet,
    opts: &FitOptions,
) -> Result<FitResult, FitError> {
    fit_from(model, data, opts, &model.initial_guesses())
}

/// [`fit`] from the given starting values of `θ` instead of the model's own.
pub fn fit_from(
    model: &dyn BrdfModel,
    data: &SampleSet,
    opts: &FitOptions,
    starts: &[Vec<f64>],
) -> Result<FitResult, FitError> {
    let t0 = Instant::now();
    check_data(data)?;
    let nt = model.n_nonlinear();
    let nb = model.n_basis();
    let tb = model.bounds();
    let bad = |what: String| FitError::BadModel {
        model: model.name(),
        what,
    };
    if tb.len() != nt {
        return Err(bad(format!("{} bounds for {nt} parameters", tb.len())));
    }
    if starts.is_empty() || starts.iter().any(|s| s.len() != nt) {
        return Err(bad("starting points missing or of the wrong length".into()));
    }
    let mut tb = tb;
    if opts.axes == LobeAxes::Normal {
        for i in model.axis_parameters() {
            if i < nt {
                tb[i] = (0.0, 0.0);
            }
        }
    }
    let sharp = model.sharpness_parameters();
    // Lobes anywhere: the resolution of the whole set; lobes on the normal: the resolution there.
    let resolution = (opts.resolution_cap && !sharp.is_empty()).then(|| match opts.axes {
        LobeAxes::Free => data.angular_resolution(),
        LobeAxes::Normal => data.angular_resolution_at_normal(),
    });
    if let Some(delta) = resolution {
        let kappa_max = 1.0 / (delta * delta);
        for (i, c) in sharp {
            if i < nt && c > 0.0 {
                let hi = (kappa_max / c).ln();
                // Data too sparse for the model's broadest lobe: the cap stops at the lower bound.
                tb[i].1 = tb[i].1.min(hi).max(tb[i].0);
            }
        }
    }
    let ab = model.amplitude_bounds();
    if ab.len() != nb
        || ab
            .iter()
            .any(|(lo, hi)| lo.is_nan() || hi.is_nan() || lo > hi || *lo < 0.0)
    {
        return Err(bad(format!(
            "{} amplitude bounds for {nb} basis lobes",
            ab.len()
        )));
    }
    let mut bounds = tb.clone();
    for _ in 0..3 {
        bounds.extend(ab.iter().copied());
    }
    let coarse = data.stratified(opts.coarse_samples);
    // One objective for both stages: its weights come from all the fitted samples.
    let objective = opts.metric.objective(&data.samples);
    let pc = Problem {
        model,
        data: &coarse.samples,
        objective,
        nt,
        nb,
    };
    let mut ranked: Vec<(f64, Vec<f64>)> = starts
        .iter()
        .map(|s| {
            let s: Vec<f64> = s
                .iter()
                .zip(&tb)
                .map(|(x, (lo, hi))| x.clamp(*lo, *hi))
                .collect();
            let amps = solve_amplitudes(model, &s, &coarse);
            let p = pack(&s, &amps);
            (pc.cost(&p), p)
        })
        .collect();
    ranked.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut iterations = 0;
    // Racing: the best `refine_starts` starts get a short LM run each; the best of them is
    // continued to convergence on the coarse subsample.
    let n_short = (opts.coarse_iterations / 4)
        .max(5)
        .min(opts.coarse_iterations);
    let short_opts = LmOptions {
        max_iterations: n_short,
        rel_tolerance: 1e-7,
        ..LmOptions::default()
    };
    let mut best: Option<(Vec<f64>, LmReport)> = None;
    for (_, p) in ranked.iter().take(opts.refine_starts.max(1)) {
        let r = minimize_boxed(&pc, p, &bounds, &short_opts);
        iterations += r.1.iterations;
        if best.as_ref().is_none_or(|b| r.1.cost < b.1.cost) {
            best = Some(r);
        }
    }
    let mut best = best.expect("at least one start");
    if best.1.iterations >= n_short && opts.coarse_iterations > n_short {
        let coarse_opts = LmOptions {
            max_iterations: opts.coarse_iterations - n_short,
            rel_tolerance: 1e-7,
            ..LmOptions::default()
        };
        let r = minimize_boxed(&pc, &best.0, &bounds, &coarse_opts);
        iterations += r.1.iterations;
        if r.1.cost <= best.1.cost {
            best = r;
        }
    }
    let pf = Problem {
        model,
        data: &data.samples,
        objective,
        nt,
        nb,
    };
    let fine_opts = LmOptions {
        max_iterations: opts.fine_iterations,
        rel_tolerance: 1e-10,
        ..LmOptions::default()
    };
    let (params, r) = minimize_boxed(&pf, &best.0, &bounds, &fine_opts);
    iterations += r.iterations;
    let (theta, amps) = pf.split(&params);
    let theta = theta.to_vec();
    let errors = evaluate(model, &theta, &amps, data);
    let held_out =
        (!data.held_out.is_empty()).then(|| evaluate_samples(model, &theta, &amps, &data.held_out));
    Ok(FitResult {
        model: model.name(),
        metric: opts.metric,
        theta,
        amps,
        errors,
        held_out,
        held_out_count: data.held_out.len(),
        resolution,
        axes: opts.axes,
        iterations,
        starts: starts.len(),
        seconds: t0.elapsed().as_secs_f64(),
    })
}
