//! Scoring a fit: [`FitErrors`], the weighted RMS error per channel in both metrics
//! ([`Metric::NganL2`] and [`Metric::LowLog`]), of a model's parameters or of any BRDF, on a
//! sample set or a slice of it (the held-out samples).
//!
//! # Conventions
//! * BRDF values are in 1/sr, `[r, g, b]`; each sample counts with its weight.
//! * Evaluation is parallel (rayon, chunks of 256 samples).

use super::{eval_model, BrdfModel};
#[cfg(doc)]
use crate::metric::Metric;
use crate::samples::{Sample, SampleSet};
use glam::DVec3;
use rayon::prelude::*;

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
