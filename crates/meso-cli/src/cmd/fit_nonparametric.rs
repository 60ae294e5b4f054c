//! `meso fit DATA --nonparametric [--grid N_Z,N_PHI] --out MATERIAL.toml`: the non-parametric NDF
//! of a MERL table (`meso_measured::nonparametric`, 1-D in θm) or of a sample CSV
//! (`meso_measured::nonparametric_aniso`, 2-D over the grid), printed and written; the CLI only
//! reads, calls and prints.

use super::fit::Args;
use anyhow::{bail, Context, Result};
use meso_measured::job::{fmt3, load};
use meso_measured::nonparametric::{fit, material_toml};
use std::fmt::Write as _;
use std::time::Instant;

/// Run `meso fit --nonparametric`.
pub fn run(a: &Args) -> Result<()> {
    let t0 = Instant::now();
    if a.per_channel_lobes || a.baselines || a.plot.is_some() {
        bail!("--nonparametric fits one NDF for all channels; it takes no --per-channel-lobes, --baselines or --plot");
    }
    crate::util::check_outputs(&[&a.out], &[&a.data])?;
    let data = load(&a.data, a.samples)?;
    let Some(table) = &data.merl else {
        return run_aniso(a, &data, t0);
    };
    if a.grid.is_some() {
        bail!(
            "{}: --grid is the 2-D table of a sample CSV; a MERL table is isotropic and gets the 1-D NDF in θm",
            a.data.display()
        );
    }
    let r = fit(table, &data.samples).with_context(|| a.data.display().to_string())?;
    let mut report = String::new();
    let _ = writeln!(report, "data: {}", data.description);
    let _ = writeln!(
        report,
        "non-parametric NDF: {} back-scattering θh bins (θd = 0) up to {}°, rms angle {:.3}° (kept start: {})",
        r.nodes,
        meso_measured::nonparametric::MAX_THETA_H_DEG,
        r.ndf.rms_theta().to_degrees(),
        r.start.name()
    );
    let comment = format!(
        "meso fit {} --nonparametric --samples {}\nnon-parametric NDF ({} nodes): {}",
        a.data.display(),
        a.samples,
        r.nodes,
        data.description
    );
    let text = material_toml(&r, &comment);
    finish(a, &data.samples, &terms_of!(r), &text, report, t0)
}

/// `--nonparametric` on a sample CSV: the 2-D table over `--grid`.
fn run_aniso(a: &Args, data: &meso_measured::job::Data, t0: Instant) -> Result<()> {
    use meso_measured::nonparametric_aniso::{fit, material_toml, AnisoOptions, MAX_THETA_DEG};
    let opts = a
        .grid
        .map_or_else(AnisoOptions::default, |(n_z, n_phi)| AnisoOptions {
            n_z,
            n_phi,
        });
    let r = fit(&data.samples, &opts).with_context(|| a.data.display().to_string())?;
    let mut report = String::new();
    let _ = writeln!(report, "data: {}", data.description);
    let _ = writeln!(
        report,
        "non-parametric NDF (2-D): {} × {} table, {} back-scattering samples in {} of its {} cells up to {}°",
        opts.n_z, opts.n_phi, r.back_samples, r.cells_covered, r.cells_needed, MAX_THETA_DEG
    );
    let comment = format!(
        "meso fit {} --nonparametric --grid {},{}\nnon-parametric NDF ({} × {} table): {}",
        a.data.display(),
        opts.n_z,
        opts.n_phi,
        opts.n_z,
        opts.n_phi,
        data.description
    );
    let text = material_toml(&r, &comment);
    finish(a, &data.samples, &terms_of!(r), &text, report, t0)
}

/// The [`Terms`] of a fit result `r` (a `NonParametric` or a `NonParametricAniso`, whose fields
/// of these names agree).
macro_rules! terms_of {
    ($r:expr) => {
        Terms {
            f0: $r.f0,
            specular: $r.specular,
            albedo: $r.albedo,
            specular_at_limit: $r.specular_at_limit,
            fitted: &$r.fitted,
            held_out: $r.held_out.as_ref(),
        }
    };
}
use terms_of;

/// What both non-parametric fits report beside their NDF: the mirror's Schlick terms, the
/// Lambert albedo, and the errors on fitted and held-out samples.
struct Terms<'a> {
    f0: [f64; 3],
    specular: [f64; 3],
    albedo: [f64; 3],
    specular_at_limit: bool,
    fitted: &'a meso_measured::fit::FitErrors,
    held_out: Option<&'a meso_measured::fit::FitErrors>,
}

/// The report's common part (the terms, the error table, the engine parameters, also written
/// into the file), the material written atomically to `--out`, and the report printed.
fn finish(
    a: &Args,
    samples: &meso_measured::samples::SampleSet,
    t: &Terms<'_>,
    text: &str,
    mut report: String,
    t0: Instant,
) -> Result<()> {
    let engine = meso_measured::engine::fit_engine(samples, &Default::default())
        .with_context(|| format!("{}: engine parameters", a.data.display()))?;
    let mut text = text.to_owned();
    engine.annotate(&mut text);
    let _ = writeln!(
        report,
        "  transfer mirror, Schlick f0 [{}], specular [{}], Smith masking-shadowing from the NDF",
        fmt3(t.f0, 4),
        fmt3(t.specular, 4)
    );
    let _ = writeln!(report, "  diffuse albedo [{}]", fmt3(t.albedo, 4));
    if t.specular_at_limit {
        let _ = writeln!(
            report,
            "  note: the specular scale is at its limit 1 on some channel (the fit held it there)"
        );
    }
    let _ = writeln!(
        report,
        "\nerrors per channel (r g b)            ngan-l2 (1/sr)             low-log"
    );
    let row = meso_measured::workflow::error_row;
    let _ = writeln!(
        report,
        "{}",
        row(
            &format!("fitted ({} samples)", samples.samples.len()),
            t.fitted
        )
    );
    if let Some(h) = t.held_out {
        let _ = writeln!(
            report,
            "{}",
            row(
                &format!("held out, not fitted ({} samples)", samples.held_out.len()),
                h
            )
        );
    }
    let _ = writeln!(report, "{}", engine.describe());
    meso_core::io::write_atomic(&a.out, text.as_bytes())
        .with_context(|| format!("writing {}", a.out.display()))?;
    let _ = writeln!(report, "\nwrote {}", a.out.display());
    let _ = writeln!(report, "total time {:.2} s", t0.elapsed().as_secs_f64());
    crate::util::print_stdout(&report)
}
