//! `meso fit DATA --lobes K [--metric both|ngan|log] [--transfer auto|phong|microfacet|ggx-lobes] [--axes auto|normal|free]
//! [--per-channel-lobes] [--baselines] [--plot DIR] --out MATERIAL.toml` — fit a measured BRDF with
//! a sum of Phong peaks (Fournier 1992, §3.3) and write it as a meso material.

use anyhow::{bail, Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use meso_measured::fit::LobeAxes;
use meso_measured::job::{load, Transfer};
use meso_measured::metric::Metric;
use meso_measured::plots;
use meso_measured::workflow::{self, FitRequest};
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
    /// Both at once, each relative to the error of the trivial model `f = 0` (the default:
    /// the fit that wins in both metrics, docs/measured.md "Both metrics").
    Both,
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
    /// instead of Phong peaks: `[ndf] kind = "mixture"`, each lobe GGX or Beckmann, whichever
    /// fits the data better (K = 1: one such lobe + Lambert; on sparse data the two can be
    /// close and either may be chosen).
    GgxLobes,
    /// As `ggx-lobes`, each lobe GGX, Beckmann or Student-t with its tail exponent γ fitted
    /// (tails heavier than GGX's to Beckmann's); several times the cost of `ggx-lobes`, not
    /// tried by `auto` (docs/measured.md, "Student-t lobes").
    StudentTLobes,
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

/// Fit a measured BRDF with a sum of K lobes (Phong peaks, or GGX / Beckmann / Student-t lobes;
/// by default every family is fitted and the best on held-out data kept) or with a
/// non-parametric NDF (`--nonparametric`), and write a meso material.
///
/// DATA is a MERL binary (detected by its header or size) or a CSV of samples with the header
/// `theta_i,phi_i,theta_o,phi_o,r,g,b` (degrees, BRDF in 1/sr). The report (stdout) gives the
/// lobes, the per-channel errors in both metrics of the fitted closed form and of the written
/// material evaluated exactly (meso-core quadrature) on a subsample, the time and iterations.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Measured data: MERL binary or sample CSV.
    pub data: PathBuf,
    /// Number of lobes (1–6), or `auto` (the default when not given): up to 6, stopping when
    /// one more lobe lowers the held-out error by less than 1 % or 1e-4.
    #[arg(long, value_parser = parse_lobes)]
    pub lobes: Option<LobeCount>,
    /// Fit the non-parametric NDF instead of lobes: the NDF tabulated in θm from the
    /// back-scattering cells of a MERL table, or over (θm, φm) from the back-scattering samples
    /// of a sample CSV (anisotropic data; `[ndf] kind = "tabulated"` on the --grid), by power
    /// iteration (Dupuy et al. 2015), Smith masking derived from it, Schlick Fresnel, specular
    /// scale and Lambert fitted alongside (docs/measured.md "Non-parametric NDF").
    #[arg(long, conflicts_with_all = ["lobes", "transfer", "axes"])]
    pub nonparametric: bool,
    /// The 2-D table of `--nonparametric` on a sample CSV: `N_Z,N_PHI`, bands of equal height in
    /// cos θ over the sphere (even; half above the horizon) and sectors in φ. The CSV needs
    /// back-scattering samples (i and o within 0.5°) in 90 % of the upper cells up to 85°.
    /// Default 512,64.
    #[arg(long, value_parser = parse_grid, requires = "nonparametric")]
    pub grid: Option<(usize, usize)>,
    /// Metric minimised.
    #[arg(long, value_enum, default_value = "both")]
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

fn bar() -> ProgressBar {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(1);
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

/// `--grid`'s value parser: `N_Z,N_PHI`.
fn parse_grid(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("{s}: expected N_Z,N_PHI (two whole numbers, e.g. 512,64)");
    let (a, b) = s.split_once(',').ok_or_else(bad)?;
    let a = a.trim().parse::<usize>().map_err(|_| bad())?;
    let b = b.trim().parse::<usize>().map_err(|_| bad())?;
    Ok((a, b))
}

/// Run the command.
pub fn run(a: Args) -> Result<()> {
    let t0 = Instant::now();
    let (k, auto_k) = match a.lobes {
        Some(LobeCount::Fixed(k)) => (k as usize, false),
        Some(LobeCount::Auto) | None => (meso_measured::job::AUTO_LOBES_MAX, true),
    };
    let paths = out_paths(&a.out, a.per_channel_lobes);
    check_outputs(&a, &paths)?;
    let data = load(&a.data, a.samples)?;
    let data_name = a.data.display().to_string();
    let request = FitRequest {
        data_name: &data_name,
        lobes: k,
        auto_lobes: auto_k,
        candidates: match a.transfer {
            TransferArg::Auto => &Transfer::ALL,
            TransferArg::Phong => &[Transfer::Phong],
            TransferArg::Microfacet => &[Transfer::Microfacet],
            TransferArg::GgxLobes => &[Transfer::GgxLobes],
            TransferArg::StudentTLobes => &[Transfer::StudentTLobes],
        },
        metric: match a.metric {
            MetricArg::Ngan => Metric::NganL2,
            MetricArg::Log => Metric::LowLog,
            MetricArg::Both => Metric::Both,
        },
        axes: match a.axes {
            AxesArg::Auto => None,
            AxesArg::Normal => Some(LobeAxes::Normal),
            AxesArg::Free => Some(LobeAxes::Free),
        },
        per_channel: a.per_channel_lobes,
        baselines: a.baselines,
        exact_cells: EXACT_CELLS,
    };
    let progress = bar();
    let report = workflow::run(&data, &request, &mut |s| {
        progress.set_length(s.total);
        progress.set_position(s.done);
        progress.set_message(s.message.clone());
    })?;
    progress.finish_and_clear();

    // The plots, in memory; then the material(s) and plots written all or none.
    let plots = match &a.plot {
        Some(dir) => {
            let [slices, spheres] =
                plots::plot_files(&data, &|wi, wo| report.model_eval(wi, wo), &|wi, wo| {
                    report.material_eval(wi, wo)
                })?;
            vec![
                (dir.join(plots::PLOT_FILES[0]), slices),
                (dir.join(plots::PLOT_FILES[1]), spheres),
            ]
        }
        None => Vec::new(),
    };
    let mut files: Vec<(PathBuf, &[u8])> = paths
        .iter()
        .zip(report.texts())
        .map(|(p, t)| (p.clone(), t.as_bytes()))
        .collect();
    files.extend(plots.iter().map(|(p, b)| (p.clone(), b.as_slice())));
    write_all_or_none(a.plot.as_deref(), &files)?;

    let mut rep = report.summary();
    for p in &paths {
        let _ = writeln!(rep, "\nwrote {}", p.display());
    }
    for (f, _) in &plots {
        let _ = writeln!(rep, "wrote {}", f.display());
    }
    let _ = writeln!(rep, "total time {:.2} s", t0.elapsed().as_secs_f64());
    crate::util::print_stdout(&rep)
}

/// Refuse outputs that would overwrite the data or cannot be written, before any work.
fn check_outputs(a: &Args, paths: &[PathBuf]) -> Result<()> {
    let mut outs: Vec<PathBuf> = paths.to_vec();
    if let Some(dir) = &a.plot {
        if dir.exists() && !dir.is_dir() {
            bail!("{}: --plot needs a directory", dir.display());
        }
        outs.extend(plots::PLOT_FILES.iter().map(|f| dir.join(f)));
    }
    // A missing plot directory is created at the end.
    let checked: Vec<&Path> = outs
        .iter()
        .map(PathBuf::as_path)
        .filter(|p| {
            a.plot
                .as_deref()
                .is_none_or(|d| !p.starts_with(d) || d.is_dir())
        })
        .collect();
    crate::util::check_outputs(&checked, &[&a.data])
}

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
