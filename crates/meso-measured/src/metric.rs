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

/// A fitting / scoring metric (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Metric {
    /// Ngan et al. 2005 cosine-weighted L2.
    NganL2,
    /// Löw et al. 2012 log metric (the default for fitting: robust to peak heights).
    #[default]
    LowLog,
}

impl Metric {
    /// The residual for one channel: model value `f`, data value `d` (1/sr), `cos θi`.
    #[inline]
    #[must_use]
    pub fn residual(self, f: f64, d: f64, cos_i: f64) -> f64 {
        match self {
            Metric::NganL2 => (f - d) * cos_i,
            Metric::LowLog => (f * cos_i).max(-0.999_999).ln_1p() - (d * cos_i).ln_1p(),
        }
    }

    /// `∂residual/∂f`.
    #[inline]
    #[must_use]
    pub fn d_residual(self, f: f64, cos_i: f64) -> f64 {
        match self {
            Metric::NganL2 => cos_i,
            Metric::LowLog => cos_i / (1.0 + (f * cos_i).max(-0.999_999)),
        }
    }

    /// A short name (`ngan-l2`, `low-log`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Metric::NganL2 => "ngan-l2",
            Metric::LowLog => "low-log",
        }
    }

    /// Parse a name as given by [`Metric::name`].
    #[must_use]
    pub fn from_name(s: &str) -> Option<Metric> {
        match s {
            "ngan-l2" | "ngan" | "l2" => Some(Metric::NganL2),
            "low-log" | "log" | "low" => Some(Metric::LowLog),
            _ => None,
        }
    }
}
