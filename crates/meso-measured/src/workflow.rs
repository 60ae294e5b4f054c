//! The whole `meso fit` workflow as one library call: the lobe fits (shared by r, g, b or one per
//! channel, each family of [`FitRequest::candidates`] tried and the best kept on held-out cells),
//! the written material(s) parsed back by meso-core, that material evaluated exactly on a
//! subsample beside the closed form, the baselines, and the engine parameters — returned as a
//! [`FitReport`] value. `meso fit` prints [`FitReport::summary`] and writes
//! [`FitReport::texts`]; Python turns the same value into a dict.
//!
//! Nothing here reads or writes files: the caller loads the [`Data`] ([`crate::job::load`]) and
//! writes what it wants.

use crate::engine::{fit_engine, EngineParams};
use crate::fit::{self, FitError, FitErrors, FitOptions, FitResult, LobeAxes};
use crate::job::{
    fit_best, fmt3, material_comment, Data, FitSettings, Fits, Lobes, Transfer, Tried,
    AUTO_LOBES_FLOOR, AUTO_LOBES_GAIN,
};
use crate::metric::Metric;
use crate::samples::{Sample, SampleSet};
use glam::DVec3;
use meso_core::material::Material;
use rayon::prelude::*;
use std::fmt::Write as _;

/// A held-out Löw-log error above this multiple of the fitted one is reported as an over-fit.
pub const OVERFIT_RATIO: f64 = 2.0;

/// Channel names, in order.
const CHANNELS: [&str; 3] = ["red", "green", "blue"];

/// What to fit, as `meso fit`'s options say it.
#[derive(Clone, Copy, Debug)]
pub struct FitRequest<'a> {
    /// The data as named on the command line (written into the material's comment, which
    /// re-runs the fit as written).
    pub data_name: &'a str,
    /// The number of lobes, or with `auto_lobes` the most lobes tried.
    pub lobes: usize,
    /// Choose the number of lobes on held-out cells ([`crate::job::auto_lobes`]).
    pub auto_lobes: bool,
    /// The families tried ([`Transfer::ALL`] for `--transfer auto`); the best on held-out cells
    /// is kept ([`fit_best`]).
    pub candidates: &'a [Transfer],
    /// The metric minimised.
    pub metric: Metric,
    /// Where the lobe axes may go; `None`: on the normal for MERL tables, free for samples.
    pub axes: Option<LobeAxes>,
    /// Fit each channel with its own lobes (three grey materials).
    pub per_channel: bool,
    /// Also fit every baseline model ([`crate::model::baselines()`]).
    pub baselines: bool,
    /// Number of cells on which the written material is evaluated exactly (meso-core's
    /// quadrature); 0 skips that check.
    pub exact_cells: usize,
}

/// One step of the workflow, for a progress display: `done` of `total` steps are finished and
/// `message` says what runs now.
#[derive(Clone, Debug)]
pub struct Step {
    /// What runs now.
    pub message: String,
    /// Steps finished.
    pub done: u64,
    /// Steps in all.
    pub total: u64,
}

/// The fit of one pass: all channels (shared lobes) or one channel (per-channel lobes).
#[derive(Clone, Debug)]
pub struct ChannelFit {
    /// The family kept.
    pub transfer: Transfer,
    /// Every family tried, with its selection error.
    pub tried: Vec<Tried>,
    /// The progressive fits of the family kept (1, 2, …, K lobes); the last is the result.
    pub fits: Fits,
    /// The material file written for it (grey for a per-channel pass).
    pub text: String,
    /// That file, parsed back by meso-core.
    pub material: Material,
}

impl ChannelFit {
    /// The last (kept) fit: its lobes and fit result.
    #[must_use]
    pub fn last(&self) -> &(Lobes, FitResult) {
        self.fits.last().expect("a pass has at least one lobe fit")
    }
}

/// The written material evaluated exactly on a stratified subsample, beside the closed form.
#[derive(Clone, Copy, Debug)]
pub struct ExactCheck {
    /// Cells of the subsample.
    pub cells: usize,
    /// Errors of the written material (meso-core quadrature) there.
    pub exact: FitErrors,
    /// Errors of the fitted closed form on the same cells.
    pub closed_form: FitErrors,
    /// Relative cosine-weighted RMS difference between the two (a fraction).
    pub relative_difference: f64,
}

/// Everything a fit produced.
#[derive(Clone, Debug)]
pub struct FitReport {
    /// The data as named in the request.
    pub data_name: String,
    /// The data's description (format, cells, subsample).
    pub description: String,
    /// The metric minimised.
    pub metric: Metric,
    /// Where the axes went.
    pub axes: LobeAxes,
    /// The requested number of lobes (the most tried with `auto_lobes`).
    pub lobes: usize,
    /// Whether the number of lobes was chosen on held-out cells.
    pub auto_lobes: bool,
    /// Whether more than one family was tried.
    pub several_families: bool,
    /// Whether each channel has its own lobes.
    pub per_channel: bool,
    /// One pass (shared lobes) or three (per channel).
    pub channels: Vec<ChannelFit>,
    /// Errors of the fitted closed form on the fitted cells.
    pub fitted: FitErrors,
    /// Number of fitted cells.
    pub fitted_count: usize,
    /// Errors on held-out cells (`None` when too few cells were held out).
    pub held_out: Option<FitErrors>,
    /// Number of held-out cells.
    pub held_out_count: usize,
    /// The exact check of the written material (`None` when `exact_cells` was 0).
    pub exact: Option<ExactCheck>,
    /// The baseline fits, when asked for.
    pub baselines: Vec<FitResult>,
    /// The best single GGX + Lambert as glTF metallic–roughness parameters.
    pub engine: EngineParams,
}

/// Run the fit workflow on `data` (see the module docs). `progress` is called before each step.
///
/// # Errors
/// The first fit that fails; a written material that meso-core cannot parse (an internal error,
/// reported as [`FitError::BadModel`]).
pub fn run(
    data: &Data,
    req: &FitRequest<'_>,
    progress: &mut dyn FnMut(&Step),
) -> Result<FitReport, FitError> {
    let opts = FitOptions {
        metric: req.metric,
        axes: req.axes.unwrap_or(if data.merl.is_some() {
            LobeAxes::Normal
        } else {
            LobeAxes::Free
        }),
        ..FitOptions::default()
    };
    let baselines = if req.baselines {
        crate::model::baselines()
    } else {
        Vec::new()
    };
    let passes = if req.per_channel { 3 } else { 1 };
    let total = (passes * req.candidates.len() + baselines.len() + 2) as u64;
    let mut done = 0u64;
    let mut step = |message: String, done: u64| {
        progress(&Step {
            message,
            done,
            total,
        });
    };

    let mut channels = Vec::with_capacity(passes);
    for j in 0..passes {
        let channel = req.per_channel.then_some(j);
        let mono;
        let set = match channel {
            Some(c) => {
                step(format!("lobes, {} channel", CHANNELS[c]), done);
                mono = grey_set(&data.samples, c);
                &mono
            }
            None => {
                let names: Vec<&str> = req.candidates.iter().map(|t| t.name()).collect();
                step(
                    format!("{} lobe(s), {} transfer", req.lobes, names.join(" and ")),
                    done,
                );
                &data.samples
            }
        };
        let (transfer, fits, tried) =
            fit_best(req.lobes, req.auto_lobes, req.candidates, set, &opts)?;
        done += req.candidates.len() as u64;
        let (lobes, r) = fits.last().expect("at least one lobe fit");
        let settings = FitSettings {
            data: req.data_name,
            k: fits.len(),
            metric: req.metric,
            transfer,
            axes: opts.axes,
            channel,
            samples: data.merl_target,
        };
        let comment = material_comment(&settings, &data.description, r);
        let text = match channel {
            Some(c) => lobes.grey(c).to_toml(&comment),
            None => lobes.to_toml(&comment),
        };
        let material = Material::from_toml_str(&text).map_err(|e| FitError::BadModel {
            model: r.model.clone(),
            what: format!(
                "internal error: the fitted material does not parse: {}",
                e.0
            ),
        })?;
        channels.push(ChannelFit {
            transfer,
            tried,
            fits,
            text,
            material,
        });
    }
    let model_eval = |wi: DVec3, wo: DVec3| pick(&channels, |ch| ch.last().0.eval(wi, wo));
    let fitted = fit::evaluate_fn(&data.samples, model_eval);
    let held = &data.samples.held_out;
    let held_out = (!held.is_empty()).then(|| fit::evaluate_samples_fn(held, model_eval));

    step("exact evaluation of the written material".into(), done);
    let exact = (req.exact_cells > 0)
        .then(|| exact_check(&channels, &data.samples.stratified(req.exact_cells)));
    done += 1;

    let mut baseline_fits = Vec::with_capacity(baselines.len());
    for b in &baselines {
        step(format!("baseline {}", b.name()), done);
        baseline_fits.push(fit::fit(b.as_ref(), &data.samples, &opts)?);
        done += 1;
    }
    step("engine parameters (GGX + Lambert)".into(), done);
    let engine = fit_engine(&data.samples, &opts)?;
    done += 1;
    // The engine parameters go into each written file too (the report prints the same line).
    for ch in &mut channels {
        engine.annotate(&mut ch.text);
    }
    step("done".into(), done);
    Ok(FitReport {
        data_name: req.data_name.to_string(),
        description: data.description.clone(),
        metric: req.metric,
        axes: opts.axes,
        lobes: req.lobes,
        auto_lobes: req.auto_lobes,
        several_families: req.candidates.len() > 1,
        per_channel: req.per_channel,
        channels,
        fitted,
        fitted_count: data.samples.len(),
        held_out,
        held_out_count: held.len(),
        exact,
        baselines: baseline_fits,
        engine,
    })
}

/// `f` of the one pass, or channel c of `f` of pass c.
fn pick(channels: &[ChannelFit], f: impl Fn(&ChannelFit) -> [f64; 3]) -> [f64; 3] {
    if let [one] = channels {
        f(one)
    } else {
        [0, 1, 2].map(|c| f(&channels[c])[c])
    }
}

/// The samples with channel `c` copied into all three (a grey data set for a per-channel pass).
fn grey_set(s: &SampleSet, c: usize) -> SampleSet {
    let grey = |v: &[Sample]| {
        v.iter()
            .map(|s| Sample {
                rgb: [s.rgb[c]; 3],
                ..*s
            })
            .collect()
    };
    SampleSet {
        samples: grey(&s.samples),
        held_out: grey(&s.held_out),
        cell_size: s.cell_size,
    }
}

/// The written material evaluated exactly on `sub`, beside the closed form there.
fn exact_check(channels: &[ChannelFit], sub: &SampleSet) -> ExactCheck {
    let model_eval = |wi: DVec3, wo: DVec3| pick(channels, |ch| ch.last().0.eval(wi, wo));
    let exact_values: Vec<[f64; 3]> = sub
        .samples
        .par_iter()
        .map(|s| pick(channels, |ch| ch.material.brdf(s.wi, s.wo)))
        .collect();
    let key = |wi: DVec3, wo: DVec3| [wi.x, wi.y, wi.z, wo.x, wo.y, wo.z].map(f64::to_bits);
    let lookup: std::collections::HashMap<[u64; 6], [f64; 3]> = sub
        .samples
        .iter()
        .zip(&exact_values)
        .map(|(s, v)| (key(s.wi, s.wo), *v))
        .collect();
    let exact = fit::evaluate_fn(sub, |wi, wo| lookup[&key(wi, wo)]);
    let closed_form = fit::evaluate_fn(sub, model_eval);
    let (mut num, mut den) = (0.0, 0.0);
    for (s, e) in sub.samples.iter().zip(&exact_values) {
        let m = model_eval(s.wi, s.wo);
        for c in 0..3 {
            num += s.weight * ((e[c] - m[c]) * s.wi.z).powi(2);
            den += s.weight * (m[c] * s.wi.z).powi(2);
        }
    }
    ExactCheck {
        cells: sub.len(),
        exact,
        closed_form,
        relative_difference: (num / den.max(1e-300)).sqrt(),
    }
}

/// One row of an error table: a label, then r g b in both metrics.
#[must_use]
pub fn error_row(label: &str, e: &FitErrors) -> String {
    format!(
        "  {:<34} {:<26} {}",
        label,
        fmt3(e.ngan_l2, 5),
        fmt3(e.low_log, 5)
    )
}

impl FitReport {
    /// The fitted closed form (1/sr, RGB): the shared lobes, or channel c of pass c.
    #[must_use]
    pub fn model_eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        pick(&self.channels, |ch| ch.last().0.eval(wi, wo))
    }

    /// The written material(s) evaluated exactly by meso-core (1/sr, RGB).
    #[must_use]
    pub fn material_eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        pick(&self.channels, |ch| ch.material.brdf(wi, wo))
    }

    /// The material file(s): one, or red, green, blue.
    #[must_use]
    pub fn texts(&self) -> Vec<&str> {
        self.channels.iter().map(|c| c.text.as_str()).collect()
    }

    /// The report `meso fit` prints (several lines, ending with a newline): the data, the
    /// choices made, the engine parameters, the families tried, the lobes, the error table and
    /// the baselines.
    #[must_use]
    pub fn summary(&self) -> String {
        let mut rep = String::new();
        let _ = writeln!(rep, "data: {} — {}", self.data_name, self.description);
        self.write_choices(&mut rep);
        let _ = writeln!(rep, "{}", self.engine.describe());
        self.write_tried(&mut rep);
        self.write_cap(&mut rep);
        self.write_lobes(&mut rep);
        self.write_errors(&mut rep);
        if !self.baselines.is_empty() {
            self.write_baselines(&mut rep);
        }
        rep
    }

    fn write_choices(&self, rep: &mut String) {
        let ks: Vec<String> = self
            .channels
            .iter()
            .map(|c| c.fits.len().to_string())
            .collect();
        let auto = if self.auto_lobes {
            format!(
                " (auto: one more lobe gains < {:.0} % or < {:e} held-out)",
                AUTO_LOBES_GAIN * 100.0,
                AUTO_LOBES_FLOOR
            )
        } else {
            String::new()
        };
        let names: Vec<&str> = self.channels.iter().map(|c| c.transfer.name()).collect();
        let _ = writeln!(
            rep,
            "metric minimised: {}; transfer: {}; lobes: {}{auto}{}; axes: {}",
            self.metric.name(),
            names.join(", "),
            ks.join(", "),
            if self.per_channel {
                " per channel"
            } else {
                " shared by r, g, b"
            },
            self.axes.name()
        );
    }

    fn write_tried(&self, rep: &mut String) {
        if !self.several_families {
            return;
        }
        for (j, ch) in self.channels.iter().enumerate() {
            let row: Vec<String> = ch
                .tried
                .iter()
                .map(|t| {
                    format!(
                        "{} {:.5}{}",
                        t.transfer.name(),
                        t.error,
                        if t.held_out { "" } else { " (fitted samples)" }
                    )
                })
                .collect();
            let _ = writeln!(
                rep,
                "transfer families tried{} ({} mean of r, g, b, held-out): {} -> {}",
                if self.channels.len() > 1 {
                    format!(", {} channel", CHANNELS[j])
                } else {
                    String::new()
                },
                self.metric.name(),
                row.join(", "),
                ch.transfer.name()
            );
        }
    }

    fn write_cap(&self, rep: &mut String) {
        let Some(delta) = self.channels[0].last().1.resolution else {
            return;
        };
        let cap = 4.0 / (delta * delta);
        if cap < 1e6 {
            let _ = writeln!(
                rep,
                "lobe sharpness cap: exponent <= {cap:.0} (lobes no narrower than the data's angular resolution {:.2} deg)",
                delta.to_degrees()
            );
        } else if delta.to_degrees() >= 1e-3 {
            let _ = writeln!(
                rep,
                "lobe sharpness cap: none below the model's bound (angular resolution {:.4} deg)",
                delta.to_degrees()
            );
        } else {
            // MERL's θh cells reach the normal exactly: no resolution limit to print.
            let _ = writeln!(
                rep,
                "lobe sharpness cap: none below the model's bound (the samples reach the lobe axes)"
            );
        }
    }

    fn write_lobes(&self, rep: &mut String) {
        for (j, ch) in self.channels.iter().enumerate() {
            if self.per_channel {
                let _ = writeln!(rep, "\n{} channel:", CHANNELS[j]);
            } else {
                let _ = writeln!(rep);
            }
            let (lobes, r) = ch.last();
            let _ = writeln!(
                rep,
                "{}: {:.2} s, {} LM iterations, {} starts (all sizes 1..{}: {:.2} s)",
                r.model,
                r.seconds,
                r.iterations,
                r.starts,
                self.lobes,
                ch.fits.iter().map(|(_, r)| r.seconds).sum::<f64>()
            );
            let _ = writeln!(rep, "{}", lobes.describe());
        }
    }

    fn write_errors(&self, rep: &mut String) {
        let _ = writeln!(
            rep,
            "\nerrors per channel (r g b)           {:<26} low-log",
            "ngan-l2 (1/sr)"
        );
        let row = |rep: &mut String, label: String, e: &FitErrors| {
            let _ = writeln!(rep, "{}", error_row(&label, e));
        };
        row(
            rep,
            format!("fitted closed form ({} samples)", self.fitted_count),
            &self.fitted,
        );
        match &self.held_out {
            Some(h) => row(
                rep,
                format!("held out, not fitted ({} samples)", self.held_out_count),
                h,
            ),
            None => {
                let _ = writeln!(rep, "  held out, not fitted: none (too few samples)");
            }
        }
        if let Some(x) = &self.exact {
            row(
                rep,
                format!("fitted closed form ({} samples)", x.cells),
                &x.closed_form,
            );
            row(
                rep,
                format!("written material, exact ({})", x.cells),
                &x.exact,
            );
            let _ = writeln!(
                rep,
                "  written material vs fitted closed form: relative cos-weighted RMS difference {:.2} %",
                100.0 * x.relative_difference
            );
        }
        if let Some(h) = &self.held_out {
            let ratio = (0..3)
                .map(|c| h.low_log[c] / self.fitted.low_log[c].max(1e-12))
                .fold(0.0, f64::max);
            if ratio > OVERFIT_RATIO {
                let _ = writeln!(
                    rep,
                    "  warning: the held-out low-log error is {ratio:.1} times the fitted one: over-fit (a lobe between the samples?)"
                );
            }
        }
    }

    fn write_baselines(&self, rep: &mut String) {
        let _ = writeln!(
            rep,
            "\n{:<26} {:>8} {:>6}   {:<26} {:<26} held-out low-log r g b",
            "model (same machinery)", "time(s)", "iters", "ngan-l2 r g b", "low-log r g b"
        );
        let mut rows: Vec<&FitResult> = Vec::new();
        if !self.per_channel {
            rows.extend(self.channels[0].fits.iter().map(|(_, r)| r));
        }
        rows.extend(&self.baselines);
        for r in rows {
            let _ = writeln!(
                rep,
                "{:<26} {:>8.2} {:>6}   {:<26} {:<26} {}",
                r.model,
                r.seconds,
                r.iterations,
                fmt3(r.errors.ngan_l2, 5),
                fmt3(r.errors.low_log, 5),
                r.held_out
                    .map_or_else(|| "-".to_string(), |h| fmt3(h.low_log, 5))
            );
        }
    }
}
