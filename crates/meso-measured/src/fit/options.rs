//! What a fit is asked and what it answers: [`FitOptions`] (metric, schedule, where lobe axes may
//! go as [`LobeAxes`], the resolution cap), [`FitResult`] and [`FitError`].

use super::FitErrors;
#[cfg(doc)]
use super::{fit, BrdfModel};
use crate::metric::Metric;
#[cfg(doc)]
use crate::samples::SampleSet;

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
