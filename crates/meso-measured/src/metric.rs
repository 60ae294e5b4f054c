//! Error metrics for BRDF fits.
//!
//! Both are weighted root-mean-square errors over the samples, per channel:
//! `E = sqrt( Σ w·r² / Σ w )`, with `w` the sample weight (for MERL cells, the solid-angle
//! measure of the cell — Ngan et al.'s "solid angle correction") and `θi` the angle of the light
//! direction:
//!
//! * [`Metric::NganL2`] — the cosine-weighted L2 of Ngan, Durand & Matusik, "Experimental Analysis
//!   of BRDF Models" (EGSR 2005): `r = (f_model − f_data)·cos θi`, i.e. the error of the reflected
//!   radiance under unit irradiance from the light direction. Units: 1/sr.
//! * [`Metric::LowLog`] — the log metric of Löw, Kronander, Ynnerman & Unger, "BRDF models for
//!   accurate and efficient rendering of glossy surfaces" (ACM TOG 31(1), 2012):
//!   `r = ln(1 + f_model·cos θi) − ln(1 + f_data·cos θi)`. Dimensionless; it compresses the
//!   dynamic range of specular peaks so that the whole lobe shape counts.
//!
//! Both are restricted, as in the papers, to the samples given (the MERL sampler keeps
//! θi, θo < 80° by default).
//!
//! [`Metric::Both`] minimises the two at once: per sample and channel the squared residual is
//! `r_log²/S_log² + λ·r_L2²/S_L2²`, where `S` is each metric's RMS of the trivial model `f = 0`
//! on the fitted samples (the data's own size in that metric, the mean over r, g, b of the
//! squares), so each term is a relative error and neither unit dominates ([`Objective`]), and
//! `λ` = [`BOTH_L2_WEIGHT`]. A fit that minimises one metric alone can lose in the other
//! (docs/measured.md, "Both metrics").

use crate::samples::Sample;

/// A fitting / scoring metric (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Metric {
    /// Ngan et al. 2005 cosine-weighted L2.
    NganL2,
    /// Löw et al. 2012 log metric (robust to peak heights).
    LowLog,
    /// Both at once, each relative to the trivial model's error ([`Objective`]; the default for
    /// fitting).
    #[default]
    Both,
}

impl Metric {
    /// A short name (`ngan-l2`, `low-log`, `both`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Metric::NganL2 => "ngan-l2",
            Metric::LowLog => "low-log",
            Metric::Both => "both",
        }
    }

    /// The name `meso fit --metric` takes (`ngan`, `log`, `both`).
    #[must_use]
    pub fn cli_name(self) -> &'static str {
        match self {
            Metric::NganL2 => "ngan",
            Metric::LowLog => "log",
            Metric::Both => "both",
        }
    }

    /// Parse a name as given by [`Metric::name`] or [`Metric::cli_name`].
    #[must_use]
    pub fn from_name(s: &str) -> Option<Metric> {
        match s {
            "ngan-l2" | "ngan" | "l2" => Some(Metric::NganL2),
            "low-log" | "log" | "low" => Some(Metric::LowLog),
            "both" | "blend" => Some(Metric::Both),
            _ => None,
        }
    }

    /// The objective this metric minimises on `samples` (the fitted samples): for
    /// [`Metric::Both`] the weights `1/S_log²`, `λ/S_L2²` from the trivial model `f = 0`
    /// (`λ` = [`BOTH_L2_WEIGHT`]);
    /// the single metrics have weight 1 on their own term and 0 on the other.
    #[must_use]
    pub fn objective(self, samples: &[Sample]) -> Objective {
        match self {
            Metric::NganL2 => Objective { log: 0.0, l2: 1.0 },
            Metric::LowLog => Objective { log: 1.0, l2: 0.0 },
            Metric::Both => {
                let (mut sl, mut s2, mut w) = (0.0, 0.0, 0.0);
                for s in samples {
                    let ci = s.wi.z;
                    for &d in &s.rgb {
                        let a = log_residual(0.0, d, ci);
                        let b = l2_residual(0.0, d, ci);
                        sl += s.weight * a * a;
                        s2 += s.weight * b * b;
                    }
                    w += 3.0 * s.weight;
                }
                let w = w.max(f64::MIN_POSITIVE);
                Objective {
                    log: 1.0 / (sl / w).max(1e-300),
                    l2: BOTH_L2_WEIGHT / (s2 / w).max(1e-300),
                }
            }
        }
    }
}

/// `λ`, the weight of the relative L2 term against the relative log term in [`Metric::Both`].
/// Chosen by a sweep on MERL tables (docs/measured.md, "Both metrics"): at 1 the metals and
/// specular phenolics doubled their log error for the L2 peak; at 0.03 they kept most of the
/// log fit's L2 error.
pub const BOTH_L2_WEIGHT: f64 = 0.2;

/// The [`Metric::NganL2`] residual for one channel: model value `f`, data value `d` (1/sr),
/// `cos θi`.
#[inline]
#[must_use]
pub fn l2_residual(f: f64, d: f64, cos_i: f64) -> f64 {
    (f - d) * cos_i
}

/// The [`Metric::LowLog`] residual for one channel (arguments as [`l2_residual`]).
#[inline]
#[must_use]
pub fn log_residual(f: f64, d: f64, cos_i: f64) -> f64 {
    (f * cos_i).max(-0.999_999).ln_1p() - (d * cos_i).ln_1p()
}

/// What a fit minimises: the squared residual of one sample and channel is
/// `log · r_log² + l2 · r_L2²` ([`Metric::objective`]), with `r_log`, `r_L2` the residuals of
/// [`Metric::LowLog`] and [`Metric::NganL2`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Objective {
    /// Weight of the squared log residual.
    pub log: f64,
    /// Weight of the squared L2 residual.
    pub l2: f64,
}

impl Objective {
    /// The residual for one channel: model value `f`, data value `d` (1/sr), `cos θi`. With both
    /// weights positive it is `sign(f − d)·sqrt(log·r_log² + l2·r_L2²)` (both residuals have the
    /// sign of `f − d`, and their ratio is smooth, so this is smooth too).
    #[inline]
    #[must_use]
    pub fn residual(&self, f: f64, d: f64, cos_i: f64) -> f64 {
        if self.l2 == 0.0 {
            return self.log.sqrt() * log_residual(f, d, cos_i);
        }
        if self.log == 0.0 {
            return self.l2.sqrt() * l2_residual(f, d, cos_i);
        }
        let a = log_residual(f, d, cos_i);
        let b = l2_residual(f, d, cos_i);
        (self.log * a * a + self.l2 * b * b).sqrt().copysign(b)
    }

    /// `∂residual/∂f`.
    #[inline]
    #[must_use]
    pub fn d_residual(&self, f: f64, d: f64, cos_i: f64) -> f64 {
        let da = cos_i / (1.0 + (f * cos_i).max(-0.999_999));
        if self.l2 == 0.0 {
            return self.log.sqrt() * da;
        }
        if self.log == 0.0 {
            return self.l2.sqrt() * cos_i;
        }
        let a = log_residual(f, d, cos_i);
        let b = l2_residual(f, d, cos_i);
        let r = (self.log * a * a + self.l2 * b * b).sqrt();
        if r > 1e-150 {
            (self.log * a * da + self.l2 * b * cos_i) / r.copysign(b)
        } else {
            // f = d: r_log ≈ r_L2/(1 + d cos θi) to first order.
            (self.log * da * da + self.l2 * cos_i * cos_i).sqrt()
        }
    }

    /// The error per channel that this objective's fit minimises, from errors in both metrics:
    /// `sqrt(log·E_log² + l2·E_L2²)` (the metric's own RMS for a single metric).
    #[must_use]
    pub fn error(&self, e: &crate::fit::FitErrors) -> [f64; 3] {
        [0, 1, 2].map(|c| {
            (self.log * e.low_log[c] * e.low_log[c] + self.l2 * e.ngan_l2[c] * e.ngan_l2[c]).sqrt()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A few samples with peaks and dark cells, as a MERL table has.
    fn samples() -> Vec<Sample> {
        (0..40)
            .map(|k| {
                let t = 0.02 + 1.3 * f64::from(k) / 40.0;
                let wi = DVec3::new(t.sin(), 0.0, t.cos());
                let peak = 200.0 * (-(t * t) / 0.01).exp();
                Sample {
                    wi,
                    wo: DVec3::new(-wi.x, 0.0, wi.z),
                    rgb: [0.05 + peak, 0.1 + 0.5 * peak, 0.2 + 0.1 * peak],
                    weight: 1.0 + 0.1 * f64::from(k % 3),
                }
            })
            .collect()
    }

    #[test]
    fn both_squares_to_the_weighted_sum_of_the_two_metrics() {
        let o = Objective { log: 3.0, l2: 0.7 };
        for &(f, d, c) in &[(0.3, 0.1, 0.9), (0.01, 5.0, 0.5), (120.0, 80.0, 0.99)] {
            let r = o.residual(f, d, c);
            let a = (1.0 + f * c).ln() - (1.0 + d * c).ln();
            let b = (f - d) * c;
            assert!((r * r - (3.0 * a * a + 0.7 * b * b)).abs() <= 1e-12 * r * r);
            assert_eq!(r.signum(), (f - d).signum());
        }
        // The single metrics are their own residuals.
        let l = Metric::LowLog.objective(&[]);
        let n = Metric::NganL2.objective(&[]);
        assert_eq!(l.residual(2.0, 1.0, 0.5), 2f64.ln() - 1.5f64.ln());
        assert_eq!(n.residual(2.0, 1.0, 0.5), 0.5);
    }

    #[test]
    fn both_derivative_matches_central_differences() {
        let o = Objective { log: 2.0, l2: 0.3 };
        for &(f, d, c) in &[
            (0.3, 0.1, 0.9),
            (0.01, 5.0, 0.5),
            (120.0, 80.0, 0.99),
            (1.0, 1.0, 0.7),
        ] {
            let h = 1e-6 * (1.0 + f);
            let num = (o.residual(f + h, d, c) - o.residual(f - h, d, c)) / (2.0 * h);
            let got = o.d_residual(f, d, c);
            assert!(
                (got - num).abs() <= 1e-6 * num.abs(),
                "{f} {d}: {got} vs {num}"
            );
        }
    }

    #[test]
    fn both_weights_make_the_trivial_model_score_one_and_lambda() {
        let s = samples();
        let o = Metric::Both.objective(&s);
        // The trivial model f = 0, scored independently by the fit's evaluator.
        let e = crate::fit::evaluate_samples_fn(&s, |_, _| [0.0; 3]);
        let mean_sq = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>() / 3.0;
        assert!((o.log * mean_sq(e.low_log) - 1.0).abs() < 1e-12);
        assert!((o.l2 * mean_sq(e.ngan_l2) - BOTH_L2_WEIGHT).abs() < 1e-12);
        let err = o.error(&e);
        assert!(
            (mean_sq(err) - (1.0 + BOTH_L2_WEIGHT)).abs() < 1e-12,
            "{err:?}"
        );
    }
}
