//! Benchmark table: fit lobe sums (K = 1, 2, 3; Phong and microfacet transfer) and every baseline to MERL binaries and print
//! per-channel errors in both metrics and fit times as a Markdown table.
//!
//! ```text
//! cargo run --release -p meso-measured --example merl_table -- [--metric low-log|ngan-l2] \
//!     [--target N] A.binary [B.binary ...]
//! ```
//!
//! Fits use a stratified subsample of `N` cells (default 30 000, θi, θo < 80°); the errors are
//! reported on *all* valid cells with θi, θo < 80°.

use meso_measured::fit::{evaluate, fit, BrdfModel, FitOptions, FitResult};
use meso_measured::merl::MerlTable;
use meso_measured::metric::Metric;
use meso_measured::model::{self, TransferExponent};
use meso_measured::samples::{MerlSampling, SampleSet};
use std::path::Path;

fn row(material: &str, m: &dyn BrdfModel, r: &FitResult, all: &SampleSet) {
    let e = evaluate(m, &r.theta, &r.amps, all);
    let f = |v: [f64; 3]| format!("{:.4} {:.4} {:.4}", v[0], v[1], v[2]);
    println!(
        "| {material} | {} | {} | {} | {:.2} | {} |",
        r.model,
        f(e.ngan_l2),
        f(e.low_log),
        r.seconds,
        r.iterations
    );
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut metric = Metric::LowLog;
    let mut target = 30_000;
    let mut paths = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--metric" => {
                let v = args.next().ok_or("--metric needs a value")?;
                metric = Metric::from_name(&v).ok_or(format!("unknown metric {v}"))?;
            }
            "--target" => target = args.next().ok_or("--target needs a value")?.parse()?,
            "-h" | "--help" => {
                println!(
                    "usage: merl_table [--metric low-log|ngan-l2] [--target N] FILE.binary..."
                );
                return Ok(());
            }
            _ => paths.push(a),
        }
    }
    if paths.is_empty() {
        return Err("no MERL files given (see --help)".into());
    }
    let opts = FitOptions {
        metric,
        ..FitOptions::default()
    };
    println!(
        "fitted in metric {}; errors on all valid cells with θ < 80°",
        metric.name()
    );
    println!();
    println!("| material | model | Ngan L2 (r g b, 1/sr) | Löw log (r g b) | fit time (s) | LM iterations |");
    println!("|---|---|---|---|---|---|");
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
        eprintln!("{name}: {stats:?}");
        let fits = model::fit_lobes_progressive(3, TransferExponent::Free, &data, &opts)?;
        for (m, r) in &fits {
            row(&name, m, r, &all);
            eprintln!(
                "{}",
                m.params(r).to_material_toml(&format!("{name} {}", r.model))
            );
        }
        let fits = model::fit_microfacet_lobes_progressive(3, &data, &opts)?;
        for (m, r) in &fits {
            row(&name, m, r, &all);
            eprintln!(
                "{}",
                m.params(r).to_material_toml(&format!("{name} {}", r.model))
            );
        }
        for m in model::baselines() {
            let r = fit(m.as_ref(), &data, &opts)?;
            row(&name, m.as_ref(), &r, &all);
            eprintln!("{}: θ = {:?}, amplitudes = {:?}", r.model, r.theta, r.amps);
        }
    }
    Ok(())
}
