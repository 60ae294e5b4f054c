//! The fit driver: [`fit`] and [`fit_from`] check the data and the model, derive the bounds
//! (axes held on the normal, the sharpness capped by the data's angular resolution) and run the
//! coarse-to-fine schedule of the parent module's docs.

use super::amplitudes::solve_amplitudes;
use super::problem::{pack, Problem};
use super::{evaluate, evaluate_samples, BrdfModel, FitError, FitOptions, FitResult, LobeAxes};
use crate::samples::SampleSet;
use meso_core::lm::{
    minimize_boxed, minimize_limited, LmOptions, LmReport, SumLimit, VectorProblem,
};
use std::time::Instant;

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
    let FitBounds {
        theta: tb,
        all: bounds,
        sums,
        resolution,
    } = fit_bounds(model, data, opts, starts)?;
    let (nt, nb) = (model.n_nonlinear(), model.n_basis());
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
    let (best, mut iterations) = coarse_stage(&pc, &coarse, opts, starts, &tb, &bounds);
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
    let (mut params, r) = minimize_boxed(&pf, &best.0, &bounds, &fine_opts);
    iterations += r.iterations;
    // Amplitude sums over their limits (a mirror brighter than 1): bring them down keeping their
    // proportions (what writing the material did) and continue under the limits, so the result
    // is never worse than that clamped fit.
    if sums.iter().any(|l| !l.holds(&params)) {
        for l in &sums {
            l.scale_into(&mut params);
        }
        let (p, r) = minimize_limited(&pf, &params, &bounds, &sums, &fine_opts);
        params = p;
        iterations += r.iterations;
    }
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

/// The bounds of a fit ([`fit_bounds`]).
struct FitBounds {
    /// Bounds of `θ`: the model's, with the axes held on the normal ([`LobeAxes::Normal`]) and
    /// the sharpness capped by the data's angular resolution.
    theta: Vec<(f64, f64)>,
    /// Bounds of all parameters, `[θ, A_r, A_g, A_b]`.
    all: Vec<(f64, f64)>,
    /// The model's amplitude sum limits ([`BrdfModel::amplitude_sums`]) for each channel, as
    /// indices into all parameters.
    sums: Vec<SumLimit>,
    /// The angular resolution that capped the sharpness ([`FitResult::resolution`]).
    resolution: Option<f64>,
}

/// Check the model's bounds and `starts` against its parameter counts and derive the bounds of
/// the fit.
fn fit_bounds(
    model: &dyn BrdfModel,
    data: &SampleSet,
    opts: &FitOptions,
    starts: &[Vec<f64>],
) -> Result<FitBounds, FitError> {
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
    let mut sums = Vec::new();
    for (basis, limit) in model.amplitude_sums() {
        if basis.iter().any(|&j| j >= nb || ab[j].0 != 0.0) || limit.is_nan() || limit < 0.0 {
            return Err(bad(format!(
                "amplitude sum limit over {basis:?} ≤ {limit}: needs basis lobes with lower bound 0 and a limit ≥ 0"
            )));
        }
        for c in 0..3 {
            sums.push(SumLimit {
                indices: basis.iter().map(|&j| nt + c * nb + j).collect(),
                limit,
            });
        }
    }
    Ok(FitBounds {
        theta: tb,
        all: bounds,
        sums,
        resolution,
    })
}

/// Steps 2–4 of the schedule on the coarse problem `pc` (over `coarse`): rank the starts
/// (clamped into `tb`, amplitudes by NNLS), race the best with short LM runs and continue the
/// winner. Returns its parameters and report, and the LM iterations spent.
fn coarse_stage(
    pc: &Problem<'_>,
    coarse: &SampleSet,
    opts: &FitOptions,
    starts: &[Vec<f64>],
    tb: &[(f64, f64)],
    bounds: &[(f64, f64)],
) -> ((Vec<f64>, LmReport), usize) {
    let model = pc.model;
    let mut ranked: Vec<(f64, Vec<f64>)> = starts
        .iter()
        .map(|s| {
            let s: Vec<f64> = s
                .iter()
                .zip(tb)
                .map(|(x, (lo, hi))| x.clamp(*lo, *hi))
                .collect();
            let amps = solve_amplitudes(model, &s, coarse);
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
        let r = minimize_boxed(pc, p, bounds, &short_opts);
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
        let r = minimize_boxed(pc, &best.0, bounds, &coarse_opts);
        iterations += r.1.iterations;
        if r.1.cost <= best.1.cost {
            best = r;
        }
    }
    (best, iterations)
}
