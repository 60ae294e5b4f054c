//! Benchmark table: fit lobe sums (K = 1, 2, 3; Phong and microfacet transfer, GGX lobe mixtures)
//! and every baseline to MERL binaries and print per-channel errors in both metrics and fit times
//! as a Markdown table.
//!
//! ```text
//! cargo run --release -p meso-measured --example merl_table -- [--metric low-log|ngan-l2] \
//!     [--target N] [--axes normal|free] [--no-cap] \
//!     [--models phong,microfacet,ggx-lobes,ggx-lobes-t,baselines,ggx-baseline] \
//!     A.binary [B.binary ...]
//! ```
//!
//! Fits use a stratified subsample of `N` cells (default 30 000, θi, θo < 80°); the errors are
//! reported on *all* valid cells with θi, θo < 80°, and (Löw log and Ngan L2) on the 30 000
//! held-out cells (valid cells not fitted). `ggx-baseline` fits only the GGX baseline of
//! `baselines`; `ggx-lobes-t` fits the GGX lobe mixtures with a Student-t candidate too
//! (`GGX_BECKMANN_OR_STUDENT_T`, γ fitted). `--axes` and `--no-cap` set
//! [`FitOptions::axes`] and [`FitOptions::resolution_cap`] (defaults: the library's).
//! Each lobe fit's sharpest lobe (η, tilt) is printed too.

use meso_measured::fit::{evaluate, fit, BrdfModel, FitOptions, FitResult, LobeAxes};
use meso_measured::merl::MerlTable;
use meso_measured::metric::Metric;
use meso_measured::model::{self, TransferExponent};
use meso_measured::samples::{MerlSampling, SampleSet};
use std::path::Path;

fn row(
    material: &str,
    m: &dyn BrdfModel,
    r: &FitResult,
    all: &SampleSet,
    lobes: &[meso_core::ndf::PhongLobe],
    other: &str,
) {
    let e = evaluate(m, &r.theta, &r.amps, all);
    let f = |v: [f64; 3]| format!("{:.4} {:.4} {:.4}", v[0], v[1], v[2]);
    let sharpest = lobes
        .iter()
        .max_by(|a, b| a.exponent.total_cmp(&b.exponent))
        .map(|l| {
            format!(
                "{:.0} at {:.1}° (w {:.2})",
                l.exponent,
                l.axis.z.clamp(-1.0, 1.0).acos().to_degrees(),
                l.weight
            )
        })
        .unwrap_or_else(|| other.to_owned());
    println!(
        "| {material} | {} | {} | {} | {} | {} | {} | {:.2} | {} |",
        r.model,
        f(e.ngan_l2),
        f(e.low_log),
        r.held_out.map(|h| f(h.low_log)).unwrap_or_default(),
        r.held_out.map(|h| f(h.ngan_l2)).unwrap_or_default(),
        sharpest,
        r.seconds,
        r.iterations
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut metric = Metric::LowLog;
    let mut target = 30_000;
    let mut paths = Vec::new();
    let mut opts = FitOptions::default();
    let mut models = "phong,microfacet,baselines".to_string();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--metric" => {
                let v = args.next().ok_or("--metric needs a value")?;
                metric = Metric::from_name(&v).ok_or(format!("unknown metric {v}"))?;
            }
            "--target" => target = args.next().ok_or("--target needs a value")?.parse()?,
            "--axes" => {
                let v = args.next().ok_or("--axes needs a value")?;
                opts.axes = LobeAxes::from_name(&v).ok_or(format!("unknown axes {v}"))?;
            }
            "--no-cap" => opts.resolution_cap = false,
            "--models" => models = args.next().ok_or("--models needs a value")?,
            "-h" | "--help" => {
                println!(
                    "usage: merl_table [--metric low-log|ngan-l2] [--target N] [--axes normal|free] [--no-cap] [--models phong,microfacet,ggx-lobes,ggx-lobes-t,baselines,ggx-baseline] FILE.binary..."
                );
                return Ok(());
            }
            _ => paths.push(a),
        }
    }
    if paths.is_empty() {
        return Err("no MERL files given (see --help)".into());
    }
    opts.metric = metric;
    println!(
        "fitted in metric {}, lobe axes {}, resolution cap {}; errors on all valid cells with θ < 80° and on the held-out cells",
        metric.name(),
        opts.axes.name(),
        if opts.resolution_cap { "on" } else { "off" }
    );
    println!();
    println!("| material | model | Ngan L2 (r g b, 1/sr) | Löw log (r g b) | held-out Löw log (r g b) | held-out Ngan L2 (r g b) | sharpest lobe η (GGX lobes: α) | fit time (s) | LM iterations |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let has = |m: &str| models.split(',').any(|x| x == m);
    for p in &paths {
        let name = Path::new(p)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| p.clone());
        let table = MerlTable::read(Path::new(p))?;
        let (data, stats) = SampleSet::from_merl(
            &table,
            &MerlSampling {
                target,
                ..MerlSampling::default()
            },
        );
        let (all, _) = SampleSet::from_merl(
            &table,
            &MerlSampling {
                target: 0,
                ..MerlSampling::default()
            },
        );
        eprintln!(
            "{name}: {stats:?}, angular resolution {:.3}°",
            data.angular_resolution().to_degrees()
        );
        if has("phong") {
            let fits = model::fit_lobes_progressive(3, TransferExponent::Free, &data, &opts)?;
            for (m, r) in &fits {
                let p = m.params(r);
                row(&name, m, r, &all, &p.lobes, "");
                eprintln!("{}", p.to_material_toml(&format!("{name} {}", r.model)));
            }
        }
        if has("microfacet") {
            let fits = model::fit_microfacet_lobes_progressive(3, &data, &opts)?;
            for (m, r) in &fits {
                let p = m.params(r);
                row(&name, m, r, &all, &p.lobes, "");
                eprintln!("{}", p.to_material_toml(&format!("{name} {}", r.model)));
            }
        }
        for (key, candidates) in [
            ("ggx-lobes", &model::lobes_ggx::GGX_OR_BECKMANN[..]),
            (
                "ggx-lobes-t",
                &model::lobes_ggx::GGX_BECKMANN_OR_STUDENT_T[..],
            ),
        ] {
            if !has(key) {
                continue;
            }
            let fits = model::fit_ggx_lobes_progressive(3, candidates, &data, &opts)?;
            for (m, r) in &fits {
                let p = m.params(r);
                let sharpest = p
                    .lobes
                    .iter()
                    .zip(p.eq1_weights())
                    .min_by(|a, b| a.0.alpha.total_cmp(&b.0.alpha))
                    .map(|(l, w)| format!("α {:.4} {:?} (w {w:.2})", l.alpha, l.distribution))
                    .unwrap_or_default();
                row(&name, m, r, &all, &[], &sharpest);
                eprintln!("{}", p.to_material_toml(&format!("{name} {}", r.model)));
            }
        }
        if has("ggx-baseline") {
            let m = model::Microfacet::GGX;
            let r = fit(&m, &data, &opts)?;
            row(
                &name,
                &m,
                &r,
                &all,
                &[],
                &format!("α {:.4}", r.theta[0].exp()),
            );
        }
        if has("baselines") {
            for m in model::baselines() {
                let r = fit(m.as_ref(), &data, &opts)?;
                row(&name, m.as_ref(), &r, &all, &[], "");
                eprintln!("{}: θ = {:?}, amplitudes = {:?}", r.model, r.theta, r.amps);
            }
        }
    }
    Ok(())
}
