//! `meso fit DATA --lobes K [--metric ngan|log] [--transfer auto|phong|microfacet|ggx-lobes] [--axes auto|normal|free]
//! [--per-channel-lobes] [--baselines] [--plot DIR] --out MATERIAL.toml` — fit a measured BRDF with
//! a sum of Phong peaks (Fournier 1992, §3.3) and write it as a meso material.

use anyhow::{bail, Context, Result};
use glam::DVec3;
use indicatif::{ProgressBar, ProgressStyle};
use meso_core::material::Material;
use meso_measured::fit::{self, FitErrors, FitOptions, FitResult, LobeAxes};
use meso_measured::job::{fit_best, fmt3, load, Data, FitSettings, Lobes, Transfer, Tried};
use meso_measured::metric::Metric;
use meso_measured::model;
use meso_measured::samples::SampleSet;
use meso_plot::{Canvas, LineStyle, PolarPlot, PolarSeries, Sheet};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Number of data cells on which the written material is evaluated exactly.
const EXACT_CELLS: usize = 500;

/// The metric minimised.
#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum MetricArg {
    /// Cosine-weighted L2 of Ngan, Durand & Matusik 2005.
    Ngan,
    /// Log metric of Löw et al. 2012, `ln(1 + f cos θi)`.
    Log,
}

/// The facet transfer function of the lobe model.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum TransferArg {
    /// Fit every family (microfacet, phong, ggx-lobes) and keep the one with the lowest held-out
    /// error in the metric minimised (the fitted error when nothing is held out); the report
    /// lists them all.
    Auto,
    /// Phong facets `max(0, m·H)^η_t`, multiple-surface form (Eq. 2, 10).
    Phong,
    /// Mirror facets with Schlick Fresnel and Smith masking–shadowing, microfacet form.
    Microfacet,
    /// Mirror facets as `microfacet`, under a mixture of GGX lobes on the normal (long tails)
    /// instead of Phong peaks: `[ndf] kind = "mixture"`; K = 1 is GGX + Lambert.
    GgxLobes,
}

/// Where the lobe axes may go.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum AxesArg {
    /// `normal` for MERL tables (isotropic by construction), `free` for sample CSVs.
    Auto,
    /// Every lobe on the surface normal (isotropic, no off-specular peaks).
    Normal,
    /// Axes free (off-specular and anisotropic lobes allowed).
    Free,
}

/// A held-out Löw-log error above this multiple of the fitted one is reported as an over-fit.
const OVERFIT_RATIO: f64 = 2.0;

/// Fit a measured BRDF with K Phong peaks and write a meso material.
///
/// DATA is a MERL binary (detected by its header or size) or a CSV of samples with the header
/// `theta_i,phi_i,theta_o,phi_o,r,g,b` (degrees, BRDF in 1/sr). The report (stdout) gives the
/// lobes, the per-channel errors in both metrics of the fitted closed form and of the written
/// material evaluated exactly (meso-core quadrature) on a subsample, the time and iterations.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Measured data: MERL binary or sample CSV.
    pub data: PathBuf,
    /// Number of lobes (1–6), or `auto`: up to 6, stopping when one more lobe lowers the
    /// held-out error by less than 1 % or 1e-4.
    #[arg(long, value_parser = parse_lobes, required_unless_present = "nonparametric")]
    pub lobes: Option<LobeCount>,
    /// Fit the non-parametric NDF instead of lobes: the NDF tabulated in θm from the
    /// back-scattering cells of a MERL table (power iteration, Dupuy et al. 2015), Smith masking
    /// derived from it, Schlick Fresnel, specular scale and Lambert fitted alongside
    /// (docs/measured.md "Non-parametric NDF").
    #[arg(long, conflicts_with_all = ["lobes", "transfer", "axes"])]
    pub nonparametric: bool,
    /// Metric minimised.
    #[arg(long, value_enum, default_value = "log")]
    pub metric: MetricArg,
    /// Facet transfer function and lobe family: `auto` (the default) fits all three and keeps
    /// the best on held-out data.
    #[arg(long, value_enum, default_value = "auto")]
    pub transfer: TransferArg,
    /// Where the lobe axes may go: on the surface normal (isotropic) or free (off-specular,
    /// anisotropic); `auto`: on the normal for MERL tables, free for sample CSVs.
    #[arg(long, value_enum, default_value = "auto")]
    pub axes: AxesArg,
    /// Fit each channel with its own lobes: writes OUT's stem + `.red.toml`, `.green.toml`,
    /// `.blue.toml` (channel c of the BRDF is channel c of file c; the files are grey).
    #[arg(long)]
    pub per_channel_lobes: bool,
    /// Also fit every baseline model by the same machinery and print the table.
    #[arg(long)]
    pub baselines: bool,
    /// Write polar slices and rendered spheres (data against model) as PNGs into this directory.
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// Number of MERL cells fitted (stratified subsample; 0 = all valid cells).
    #[arg(long, default_value_t = 30_000)]
    pub samples: usize,
    /// Output material file (TOML).
    #[arg(long, short)]
    pub out: PathBuf,
}

pub(super) fn error_row(label: &str, e: &FitErrors) -> String {
    format!(
        "  {:<34} {:<26} {}",
        label,
        fmt3(e.ngan_l2, 5),
        fmt3(e.low_log, 5)
    )
}

fn bar(len: u64) -> ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template("     fit [{bar:30}] {pos}/{len} {msg} ({elapsed})")
            .expect("static template")
            .progress_chars("=> "),
    );
    b.enable_steady_tick(std::time::Duration::from_millis(200));
    b
}

/// The output paths: one file, or three per-channel files.
fn out_paths(out: &Path, per_channel: bool) -> Vec<PathBuf> {
    if !per_channel {
        return vec![out.to_path_buf()];
    }
    let stem = out
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("material");
    ["red", "green", "blue"]
        .iter()
        .map(|c| out.with_file_name(format!("{stem}.{c}.toml")))
        .collect()
}

/// `--lobes`: a number of lobes or `auto`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LobeCount {
    /// Exactly this many (1–6).
    Fixed(u32),
    /// Chosen on held-out data (`meso_measured::job::auto_lobes`).
    Auto,
}

/// `--lobes`'s value parser.
fn parse_lobes(s: &str) -> Result<LobeCount, String> {
    if s == "auto" {
        return Ok(LobeCount::Auto);
    }
    match s.parse::<u32>() {
        Ok(k) if (1..=6).contains(&k) => Ok(LobeCount::Fixed(k)),
        _ => Err(format!(
            "{s}: expected a number of lobes from 1 to 6, or auto"
        )),
    }
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    let t0 = Instant::now();
    let (k, auto_k) = match a.lobes {
        Some(LobeCount::Fixed(k)) => (k as usize, false),
        Some(LobeCount::Auto) => (meso_measured::job::AUTO_LOBES_MAX, true),
        None => bail!("--lobes is needed (a number or `auto`), or --nonparametric"),
    };
    let paths = out_paths(&a.out, a.per_channel_lobes);
    {
        let mut outs: Vec<PathBuf> = paths.clone();
        if let Some(dir) = &a.plot {
            if dir.exists() && !dir.is_dir() {
                bail!("{}: --plot needs a directory", dir.display());
            }
            outs.extend(PLOT_FILES.iter().map(|f| dir.join(f)));
        }
        let outs: Vec<&Path> = outs.iter().map(PathBuf::as_path).collect();
        // A missing plot directory is created at the end.
        let checked: Vec<&Path> = outs
            .iter()
            .copied()
            .filter(|p| {
                a.plot
                    .as_deref()
                    .is_none_or(|d| !p.starts_with(d) || d.is_dir())
            })
            .collect();
        crate::util::check_outputs(&checked, &[&a.data])?;
    }
    let data = load(&a.data, a.samples)?;
    let candidates: &[Transfer] = match a.transfer {
        TransferArg::Auto => &Transfer::ALL,
        TransferArg::Phong => &[Transfer::Phong],
        TransferArg::Microfacet => &[Transfer::Microfacet],
        TransferArg::GgxLobes => &[Transfer::GgxLobes],
    };
    let metric = match a.metric {
        MetricArg::Ngan => Metric::NganL2,
        MetricArg::Log => Metric::LowLog,
    };
    let opts = FitOptions {
        metric,
        axes: match (a.axes, data.merl.is_some()) {
            (AxesArg::Normal, _) | (AxesArg::Auto, true) => LobeAxes::Normal,
            (AxesArg::Free, _) | (AxesArg::Auto, false) => LobeAxes::Free,
        },
        ..FitOptions::default()
    };
    let baselines = if a.baselines {
        model::baselines()
    } else {
        Vec::new()
    };
    let fits_per_pass = if a.per_channel_lobes { 3 } else { 1 } * candidates.len();
    let progress = bar((fits_per_pass + baselines.len() + 2) as u64);

    // The lobe fits: shared geometry, or one mono fit per channel.
    let mut channel_fits: Vec<Vec<(Lobes, FitResult)>> = Vec::new();
    // The family kept per pass, and every family's selection error.
    let mut chosen: Vec<Transfer> = Vec::new();
    let mut tried: Vec<Vec<Tried>> = Vec::new();
    if a.per_channel_lobes {
        for (c, name) in ["red", "green", "blue"].iter().enumerate() {
            progress.set_message(format!("lobes, {name} channel"));
            let grey = |v: &[meso_measured::samples::Sample]| {
                v.iter()
                    .map(|s| meso_measured::samples::Sample {
                        rgb: [s.rgb[c]; 3],
                        ..*s
                    })
                    .collect()
            };
            let mono = SampleSet {
                samples: grey(&data.samples.samples),
                held_out: grey(&data.samples.held_out),
                cell_size: data.samples.cell_size,
            };
            let (t, fits, scores) = fit_best(k, auto_k, candidates, &mono, &opts)?;
            channel_fits.push(fits);
            chosen.push(t);
            tried.push(scores);
            progress.inc(candidates.len() as u64);
        }
    } else {
        let names: Vec<&str> = candidates.iter().map(|t| t.name()).collect();
        progress.set_message(format!("{k} lobe(s), {} transfer", names.join(" and ")));
        let (t, fits, scores) = fit_best(k, auto_k, candidates, &data.samples, &opts)?;
        channel_fits.push(fits);
        chosen.push(t);
        tried.push(scores);
        progress.inc(candidates.len() as u64);
    }
    let finals: Vec<(Lobes, FitResult)> = channel_fits
        .iter()
        .map(|v| v.last().expect("at least one lobe fit").clone())
        .collect();
    let pick = |wi: DVec3, wo: DVec3, f: &dyn Fn(usize, DVec3, DVec3) -> [f64; 3]| -> [f64; 3] {
        if finals.len() == 1 {
            f(0, wi, wo)
        } else {
            [0, 1, 2].map(|c| f(c, wi, wo)[c])
        }
    };
    let model_eval = |wi: DVec3, wo: DVec3| pick(wi, wo, &|j, wi, wo| finals[j].0.eval(wi, wo));
    let fitted_errors = fit::evaluate_fn(&data.samples, model_eval);
    let held_out = &data.samples.held_out;
    let held_out_errors =
        (!held_out.is_empty()).then(|| fit::evaluate_samples_fn(held_out, model_eval));

    // The written material(s), parsed back by meso-core before anything is written.
    let mut texts = Vec::new();
    let mut materials = Vec::new();
    for (j, (lobes, r)) in finals.iter().enumerate() {
        let data_name = a.data.display().to_string();
        let settings = FitSettings {
            data: &data_name,
            k: channel_fits[j].len(),
            metric,
            transfer: chosen[j],
            axes: opts.axes,
            channel: a.per_channel_lobes.then_some(j),
        };
        let comment = meso_measured::job::material_comment(&settings, &data.description, r);
        let lobes = if a.per_channel_lobes {
            lobes.grey(j)
        } else {
            lobes.clone()
        };
        let text = lobes.to_toml(&comment);
        let material = Material::from_toml_str(&text).map_err(|e| {
            anyhow::anyhow!(
                "internal error: the fitted material does not parse: {}",
                e.0
            )
        })?;
        texts.push(text);
        materials.push(material);
    }

    // The written material evaluated exactly on a subsample, next to the closed form there.
    progress.set_message("exact evaluation of the written material");
    let sub = data.samples.stratified(EXACT_CELLS);
    let exact_values: Vec<[f64; 3]> = sub
        .samples
        .par_iter()
        .map(|s| {
            if materials.len() == 1 {
                materials[0].brdf(s.wi, s.wo)
            } else {
                [0, 1, 2].map(|c| materials[c].brdf(s.wi, s.wo)[c])
            }
        })
        .collect();
    let lookup: std::collections::HashMap<[u64; 6], [f64; 3]> = sub
        .samples
        .iter()
        .zip(&exact_values)
        .map(|(s, v)| (key(s.wi, s.wo), *v))
        .collect();
    let exact_errors = fit::evaluate_fn(&sub, |wi, wo| lookup[&key(wi, wo)]);
    let sub_fitted_errors = fit::evaluate_fn(&sub, model_eval);
    let rel_diff = {
        let (mut num, mut den) = (0.0, 0.0);
        for (s, e) in sub.samples.iter().zip(&exact_values) {
            let m = model_eval(s.wi, s.wo);
            for c in 0..3 {
                num += s.weight * ((e[c] - m[c]) * s.wi.z).powi(2);
                den += s.weight * (m[c] * s.wi.z).powi(2);
            }
        }
        (num / den.max(1e-300)).sqrt()
    };
    progress.inc(1);

    // Baselines.
    let mut baseline_rows = Vec::new();
    for b in &baselines {
        progress.set_message(format!("baseline {}", b.name()));
        let r = fit::fit(b.as_ref(), &data.samples, &opts)?;
        baseline_rows.push(r);
        progress.inc(1);
    }
    // Engine parameters: the best single GGX lobe + Lambert, as glTF metallic-roughness.
    progress.set_message("engine parameters (GGX + Lambert)");
    let engine = meso_measured::engine::fit_engine(&data.samples, &opts)?;
    progress.inc(1);
    progress.finish_and_clear();

    // The plots, in memory.
    let plots = match &a.plot {
        Some(dir) => plot_files(dir, &data, &model_eval, &|wi, wo| {
            if materials.len() == 1 {
                materials[0].brdf(wi, wo)
            } else {
                [0, 1, 2].map(|c| materials[c].brdf(wi, wo)[c])
            }
        })?,
        None => Vec::new(),
    };

    // Write the material(s) and plots only once everything succeeded, all or none.
    let mut files: Vec<(PathBuf, &[u8])> = paths
        .iter()
        .zip(&texts)
        .map(|(p, t)| (p.clone(), t.as_bytes()))
        .collect();
    files.extend(plots.iter().map(|(p, b)| (p.clone(), b.as_slice())));
    write_all_or_none(a.plot.as_deref(), &files)?;

    // Report.
    let mut rep = String::new();
    let _ = writeln!(rep, "data: {} — {}", a.data.display(), data.description);
    let _ = writeln!(
        rep,
        "metric minimised: {}; transfer: {}; lobes: {}{}; axes: {}",
        metric.name(),
        chosen
            .iter()
            .map(|t| t.name())
            .collect::<Vec<_>>()
            .join(", "),
        {
            let ks: Vec<String> = channel_fits.iter().map(|f| f.len().to_string()).collect();
            let auto = if auto_k {
                format!(
                    " (auto: one more lobe gains < {:.0} % or < {:e} held-out)",
                    meso_measured::job::AUTO_LOBES_GAIN * 100.0,
                    meso_measured::job::AUTO_LOBES_FLOOR
                )
            } else {
                String::new()
            };
            format!("{}{auto}", ks.join(", "))
        },
        if a.per_channel_lobes {
            " per channel"
        } else {
            " shared by r, g, b"
        },
        opts.axes.name()
    );
    let _ = writeln!(rep, "{}", engine.describe());
    if candidates.len() > 1 {
        for (j, scores) in tried.iter().enumerate() {
            let row: Vec<String> = scores
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
                if tried.len() > 1 {
                    format!(", {} channel", ["red", "green", "blue"][j])
                } else {
                    String::new()
                },
                metric.name(),
                row.join(", "),
                chosen[j].name()
            );
        }
    }
    if let Some(delta) = finals[0].1.resolution {
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
    for (j, (lobes, r)) in finals.iter().enumerate() {
        if a.per_channel_lobes {
            let _ = writeln!(rep, "\n{} channel:", ["red", "green", "blue"][j]);
        } else {
            let _ = writeln!(rep);
        }
        let _ = writeln!(
            rep,
            "{}: {:.2} s, {} LM iterations, {} starts (all sizes 1..{k}: {:.2} s)",
            r.model,
            r.seconds,
            r.iterations,
            r.starts,
            channel_fits[j].iter().map(|(_, r)| r.seconds).sum::<f64>()
        );
        let _ = writeln!(rep, "{}", lobes.describe());
    }
    let _ = writeln!(
        rep,
        "\nerrors per channel (r g b)           {:<26} low-log",
        "ngan-l2 (1/sr)"
    );
    let _ = writeln!(
        rep,
        "{}",
        error_row(
            &format!("fitted closed form ({} samples)", data.samples.len()),
            &fitted_errors
        )
    );
    match &held_out_errors {
        Some(h) => {
            let _ = writeln!(
                rep,
                "{}",
                error_row(
                    &format!("held out, not fitted ({} samples)", held_out.len()),
                    h
                )
            );
        }
        None => {
            let _ = writeln!(rep, "  held out, not fitted: none (too few samples)");
        }
    }
    let _ = writeln!(
        rep,
        "{}",
        error_row(
            &format!("fitted closed form ({} samples)", sub.len()),
            &sub_fitted_errors
        )
    );
    let _ = writeln!(
        rep,
        "{}",
        error_row(
            &format!("written material, exact ({})", sub.len()),
            &exact_errors
        )
    );
    let _ = writeln!(
        rep,
        "  written material vs fitted closed form: relative cos-weighted RMS difference {:.2} %",
        100.0 * rel_diff
    );
    if let Some(h) = &held_out_errors {
        let ratio = (0..3)
            .map(|c| h.low_log[c] / fitted_errors.low_log[c].max(1e-12))
            .fold(0.0, f64::max);
        if ratio > OVERFIT_RATIO {
            let _ = writeln!(
                rep,
                "  warning: the held-out low-log error is {ratio:.1} times the fitted one: over-fit (a lobe between the samples?)"
            );
        }
    }
    if a.baselines {
        let _ = writeln!(
            rep,
            "\n{:<26} {:>8} {:>6}   {:<26} {:<26} held-out low-log r g b",
            "model (same machinery)", "time(s)", "iters", "ngan-l2 r g b", "low-log r g b"
        );
        let mut rows: Vec<&FitResult> = Vec::new();
        if !a.per_channel_lobes {
            rows.extend(channel_fits[0].iter().map(|(_, r)| r));
        }
        rows.extend(&baseline_rows);
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
    for p in &paths {
        let _ = writeln!(rep, "\nwrote {}", p.display());
    }

    for (f, _) in &plots {
        let _ = writeln!(rep, "wrote {}", f.display());
    }
    let _ = write!(rep, "total time {:.2} s", t0.elapsed().as_secs_f64());
    rep.push('\n');
    crate::util::print_stdout(&rep)
}

fn key(wi: DVec3, wo: DVec3) -> [u64; 6] {
    [wi.x, wi.y, wi.z, wo.x, wo.y, wo.z].map(f64::to_bits)
}

/// Rec. 709 luminance.
fn luminance(v: [f64; 3]) -> f64 {
    0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2]
}

/// The in-plane pair for signed outgoing θo: light at `(θi, φ = 180°)`, viewer at `(|θo|, 0°)`
/// for θo ≥ 0 and `(|θo|, 180°)` otherwise.
fn in_plane(theta_i: f64, theta_o: f64) -> (DVec3, DVec3) {
    let wi = meso_core::frame::spherical_direction(theta_i, std::f64::consts::PI);
    let po = if theta_o >= 0.0 {
        0.0
    } else {
        std::f64::consts::PI
    };
    (wi, meso_core::frame::spherical_direction(theta_o.abs(), po))
}

type Brdf<'a> = &'a (dyn Fn(DVec3, DVec3) -> [f64; 3] + Sync);

/// The names of the PNGs `--plot DIR` writes into DIR.
const PLOT_FILES: [&str; 2] = ["slices.png", "spheres.png"];

/// Write `files` (path, content) all or none: each to a temporary file first, then all renamed
/// into place ([`meso_core::io::commit_all`]). `plot_dir` is created if missing, and removed
/// again if nothing could be written into it.
fn write_all_or_none(plot_dir: Option<&Path>, files: &[(PathBuf, &[u8])]) -> Result<()> {
    let created_dir = match plot_dir {
        Some(dir) if !dir.exists() => {
            std::fs::create_dir_all(dir)
                .with_context(|| format!("{}: cannot create the directory", dir.display()))?;
            Some(dir)
        }
        _ => None,
    };
    let result = (|| -> Result<()> {
        let mut staged = Vec::new();
        for (p, bytes) in files {
            staged.push(
                meso_core::io::stage_with(p, |w| w.write_all(bytes))
                    .with_context(|| format!("{}: cannot write", p.display()))?,
            );
        }
        meso_core::io::commit_all(staged)?;
        Ok(())
    })();
    if result.is_err() {
        if let Some(dir) = created_dir {
            // Only succeeds when empty: nothing else is removed.
            let _ = std::fs::remove_dir(dir);
        }
    }
    result
}

/// Polar slices (in-plane, θi = 0°, 30°, 60°) of `ln(1 + Y cos θi)` for the data, the fitted
/// closed form and the written material (exact), and rendered spheres of data and model, as
/// PNG files in memory (paths in `dir`, [`PLOT_FILES`]).
fn plot_files(
    dir: &Path,
    data: &Data,
    model: Brdf<'_>,
    exact: Brdf<'_>,
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    let mut written = Vec::new();
    let save = |c: &Canvas, name: &str, written: &mut Vec<(PathBuf, Vec<u8>)>| -> Result<()> {
        let bytes = c.to_png_bytes().map_err(|e| anyhow::anyhow!("{e}"))?;
        written.push((dir.join(name), bytes));
        Ok(())
    };
    let lm = |f: [f64; 3], ci: f64| (luminance(f) * ci).max(0.0).ln_1p();
    let mut sheet = Sheet::new(
        "in-plane slices: ln(1 + Y·cos θi), Y = luminance of the BRDF",
        3,
        420,
        420,
    );
    for ti_deg in [0.0f64, 30.0, 60.0] {
        let ti = ti_deg.to_radians();
        let ci = ti.cos();
        let thetas: Vec<f64> = (-89..=89).map(|d| f64::from(d).to_radians()).collect();
        let mut plot = PolarPlot::new(format!("θi = {ti_deg}°"));
        plot.incident = Some(-ti);
        plot.incident_label = "light".into();
        plot.r_label = "ln(1 + Y cos θi)".into();
        // Data.
        let data_pts: Vec<[f64; 2]> = match &data.merl {
            Some(t) => thetas
                .iter()
                .step_by(2)
                .filter_map(|&to| {
                    let (wi, wo) = in_plane(ti, to);
                    t.lookup(wi, wo).map(|f| [to, lm(f, ci)])
                })
                .collect(),
            None => data
                .samples
                .samples
                .iter()
                .filter_map(|s| {
                    let (th_i, ph_i) = meso_core::frame::spherical_angles(s.wi);
                    let (th_o, ph_o) = meso_core::frame::spherical_angles(s.wo);
                    let dphi = (ph_o - ph_i).rem_euclid(2.0 * std::f64::consts::PI);
                    let in_plane =
                        (dphi - std::f64::consts::PI).abs() < 0.05 || th_i < 0.02 || th_o < 0.02;
                    if (th_i - ti).abs() < 0.05 && in_plane {
                        let sign = if dphi.cos() < 0.0 { 1.0 } else { -1.0 };
                        Some([sign * th_o, lm(s.rgb, ci)])
                    } else {
                        None
                    }
                })
                .collect(),
        };
        plot.add(
            PolarSeries::new("data", data_pts)
                .with_color(meso_plot::color::hex(0x222222))
                .with_style(LineStyle::Solid)
                .with_markers(true),
        );
        let mpts = thetas
            .iter()
            .map(|&to| {
                let (wi, wo) = in_plane(ti, to);
                [to, lm(model(wi, wo), ci)]
            })
            .collect();
        plot.add(
            PolarSeries::new("fitted model", mpts).with_color(meso_plot::color::hex(0xD62728)),
        );
        let epts: Vec<[f64; 2]> = thetas
            .par_iter()
            .step_by(3)
            .map(|&to| {
                let (wi, wo) = in_plane(ti, to);
                [to, lm(exact(wi, wo), ci)]
            })
            .collect();
        plot.add(
            PolarSeries::new("written material (exact)", epts)
                .with_color(meso_plot::color::hex(0x1F77B4))
                .with_style(LineStyle::Dashed),
        );
        let c = plot
            .render(420, 420)
            .map_err(|e| anyhow::anyhow!("polar plot: {e}"))?;
        sheet.add(c, format!("θi = {ti_deg}°, in the plane of incidence"));
    }
    let slices = sheet.render().map_err(|e| anyhow::anyhow!("{e}"))?;
    save(&slices, PLOT_FILES[0], &mut written)?;

    // Spheres under the same directional light, same exposure.
    let light = DVec3::new(-0.5, 0.55, 0.67).normalize();
    let size = 320usize;
    let render = |f: &(dyn Fn(DVec3, DVec3) -> Option<[f64; 3]> + Sync)| -> Vec<Option<[f64; 3]>> {
        (0..size * size)
            .into_par_iter()
            .map(|p| {
                let (px, py) = (p % size, p / size);
                let x = (px as f64 + 0.5) / size as f64 * 2.0 - 1.0;
                let y = 1.0 - (py as f64 + 0.5) / size as f64 * 2.0;
                let r2 = x * x + y * y;
                if r2 >= 1.0 {
                    return None;
                }
                let n = DVec3::new(x, y, (1.0 - r2).sqrt());
                let t = if x * x + y * y > 1e-12 {
                    DVec3::new(-y, x, 0.0).normalize()
                } else {
                    DVec3::X
                };
                let b = n.cross(t);
                let to_local = |w: DVec3| DVec3::new(w.dot(t), w.dot(b), w.dot(n));
                let (wi, wo) = (to_local(light), to_local(DVec3::Z));
                if wi.z <= 0.0 || wo.z <= 0.0 {
                    return Some([0.0; 3]);
                }
                f(wi, wo).map(|v| v.map(|c| c * wi.z))
            })
            .collect()
    };
    let model_img = render(&|wi, wo| Some(model(wi, wo)));
    let data_img = data
        .merl
        .as_ref()
        .map(|t| render(&|wi, wo| t.lookup(wi, wo)));
    // Exposure: the 90th percentile of the reference image's luminance maps to 0.6 (before the
    // tone curve), highlights roll off with x/(1+x).
    let reference = data_img.as_ref().unwrap_or(&model_img);
    let mut lum: Vec<f64> = reference
        .iter()
        .flatten()
        .map(|v| luminance(*v))
        .filter(|l| *l > 0.0)
        .collect();
    lum.sort_by(f64::total_cmp);
    let p90 = lum
        .get(lum.len() * 9 / 10)
        .copied()
        .unwrap_or(1.0)
        .max(1e-12);
    let exposure = 1.5 / p90;
    let to_canvas = |img: &[Option<[f64; 3]>]| -> Result<Canvas> {
        let mut v = Vec::with_capacity(size * size * 3);
        for p in img {
            match p {
                None => v.extend([0.25f32, 0.25, 0.27]),
                Some(c) => v.extend(c.map(|x| {
                    let e = x * exposure;
                    let t = e / (1.0 + e);
                    srgb(t) as f32
                })),
            }
        }
        Canvas::from_rgb_f32(size as u32, size as u32, &v).map_err(|e| anyhow::anyhow!("{e}"))
    };
    let mut sheet = Sheet::new(
        "sphere under a directional light (same light, same exposure)",
        2,
        size as u32,
        size as u32,
    );
    match &data_img {
        Some(d) => {
            sheet.add(to_canvas(d)?, "data (MERL, nearest cell)");
        }
        None => {
            let mut c = Canvas::new(size as u32, size as u32, [0.25, 0.25, 0.27]);
            meso_plot::draw_text(
                &mut c,
                20,
                (size / 2) as i32,
                "CSV data: no image",
                2,
                [1.0; 3],
            );
            sheet.add(c, "data (scattered samples)");
        }
    }
    sheet.add(to_canvas(&model_img)?, "fitted model");
    let spheres = sheet.render().map_err(|e| anyhow::anyhow!("{e}"))?;
    save(&spheres, PLOT_FILES[1], &mut written)?;
    Ok(written)
}

/// Linear → sRGB transfer.
fn srgb(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}
