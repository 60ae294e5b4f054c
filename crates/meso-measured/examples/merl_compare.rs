//! Per-material comparison on MERL tables: `meso fit`'s default pipeline against a fresh
//! GGX + Lambert fit and Ngan et al.'s published Cook–Torrance fit, on held-out cells, in the
//! Löw log metric and in Ngan's L2 (issue 13, item 4).
//!
//! ```text
//! cargo run --release -p meso-measured --example merl_compare -- \
//!     --ngan ngan_cooktorrance.fit [--samples N] [--metric both|log|ngan] [--ggx-same-metric] \
//!     [--student-t] \
//!     A.binary [B.binary ...]
//! ```
//!
//! For each MERL binary (the material's name is the file stem):
//!
//! * **meso** — what `meso fit DATA --lobes auto` does with its defaults: [`job::load`] with
//!   `--samples 30000` fitted cells, both metrics at once ([`Metric::Both`]; `--metric log|ngan`:
//!   one metric, as `meso fit --metric log|ngan`), lobe axes on the normal (MERL data), every
//!   transfer family of `--transfer auto` fitted with up to [`job::AUTO_LOBES_MAX`] lobes and cut by
//!   [`job::auto_lobes`], the family with the lowest held-out error kept ([`job::fit_best`]);
//! * **GGX + Lambert** — the `ggx` baseline ([`model::Microfacet::GGX`]) fitted by the same
//!   machinery to the same cells, twice: in the Löw log metric alone (scored in log) and in Ngan's
//!   L2 alone (scored in L2), so that each column holds the GGX fit best in that metric. It is also
//!   fitted in meso's metric and scored in both (the column "GGX+L in meso's metric", and a
//!   summary row), with its largest specular amplitude `k_s` (unbounded in the baseline).
//!   `--ggx-same-metric`: the main columns use that fit, as before (the only one
//!   when meso fitted one metric); `--student-t`: `student-t-lobes` joins the families tried
//!   (an experiment: `meso fit --transfer auto` does not try it);
//! * **GGX + Lambert as a meso material** — the same model held to what a meso material can
//!   write: the GGX-lobe family at K = 1 with one GGX lobe ([`model::LobeGgxModel::ggx`]), whose
//!   mirror `specular` is at most 1 (docs/material-format.md) and whose `f0` is per channel, fitted
//!   in meso's metric and scored as written. It is the special case that `ggx-lobes` contains;
//!   the baseline above is not when its `k_s` exceeds 1;
//! * **Ngan CT** — the published fit of Ngan, Durand & Matusik 2005 as distributed by
//!   bsdfbenchmark/bbm (`fits/ngan_cooktorrance.fit`), evaluated as bbm's `NganCookTorrance`
//!   (include/bsdfmodel/ngan.h) plus its Lambertian: see [`NganCt::eval`].
//!
//! The held-out cells (valid cells with θi, θo < 80° that no fit saw) are split alternately in
//! two: the first half is what `fit_best` sees as held-out cells (it picks the family and K on
//! them, as `meso fit` does on all of them); the second half, seen by no fit and no choice, is
//! where the three models are scored. Errors are the mean over r, g, b of the per-channel RMS
//! ([`meso_measured::metric`]). The table is Markdown; the summary counts wins (strictly lower
//! error) per metric against each baseline.

use glam::DVec3;
use meso_measured::fit::{eval_model, evaluate_samples_fn, FitErrors, FitOptions, LobeAxes};
use meso_measured::job::{self, Transfer};
use meso_measured::metric::Metric;
use meso_measured::model;
use meso_measured::samples::SampleSet;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The families `meso fit --transfer auto` tries (crates/meso-cli/src/cmd/fit.rs). The match is
/// exhaustive on purpose: a family added to [`Transfer`] stops this example from compiling until
/// it is listed here, so the comparison always runs what `fit_best` is given by the CLI.
fn auto_candidates() -> Vec<Transfer> {
    let all = Transfer::ALL;
    for t in all {
        match t {
            Transfer::Microfacet | Transfer::Phong | Transfer::GgxLobes => {}
            // Not in `Transfer::ALL`; `--student-t` adds it to the candidates.
            Transfer::StudentTLobes => unreachable!("not an auto family"),
        }
    }
    all.to_vec()
}

/// Ngan's Cook–Torrance fit of one material, with a Lambertian term (bbm's
/// `Aggregate(Lambertian(albedo), NganCookTorrance(albedo, eta, roughness))`).
#[derive(Clone, Copy, Debug)]
struct NganCt {
    diffuse: [f64; 3],
    specular: [f64; 3],
    /// Schlick's reflectance at normal incidence (bbm's `eta`, an `ior::reflectance`).
    f0: f64,
    /// Beckmann roughness α (RMS slope).
    alpha: f64,
}

/// The published colours use the MERL scale 1/1500 on all three channels; a MERL reader (and
/// meso's) applies 1/1500, 1.15/1500, 1.66/1500 (README of the ngan-fits directory).
const NGAN_CHANNEL: [f64; 3] = [1.0, 1.15, 1.66];

impl NganCt {
    /// bbm: `scaledmodel<microfacet<beckmann<Isotropic, Normalize = true>, vgroove, schlick,
    /// microfacet_n::Cook>>` plus `Lambertian`:
    /// `f = kd/π + ks · D·G·F / (π cos θi cos θo)` with
    /// `D = exp(−tan²θh/α²) / (π α² cos⁴θh)`,
    /// `G = min(1, 2 cos θh cos θi / (i·h), 2 cos θh cos θo / (o·h))` (V-groove),
    /// `F = F0 + (1 − F0)(1 − c)⁵`, `c = (i·h + o·h)/2`; then × [`NGAN_CHANNEL`].
    fn eval(&self, wi: DVec3, wo: DVec3) -> [f64; 3] {
        let (ci, co) = (wi.z, wo.z);
        if ci <= 0.0 || co <= 0.0 {
            return [0.0; 3];
        }
        let spec = match (wi + wo).try_normalize() {
            Some(h) if h.z > 0.0 => {
                let c = h.z;
                let c2 = c * c;
                let a2 = self.alpha * self.alpha;
                let d = (-(1.0 - c2) / (c2 * a2)).exp() / (PI * a2 * c2 * c2);
                let (ih, oh) = (wi.dot(h), wo.dot(h));
                let g = if ih > 0.0 && oh > 0.0 {
                    (2.0 * c * ci / ih).min(2.0 * c * co / oh).min(1.0)
                } else {
                    0.0
                };
                let x = 1.0 - 0.5 * (ih + oh);
                let f = self.f0 + (1.0 - self.f0) * x.powi(5);
                d * g * f / (PI * ci * co)
            }
            _ => 0.0,
        };
        [0, 1, 2].map(|k| (self.diffuse[k] / PI + self.specular[k] * spec) * NGAN_CHANNEL[k])
    }
}

/// `[a, b, c]` after `key` in `s`.
fn triple_after(s: &str, key: &str) -> Option<[f64; 3]> {
    let rest = &s[s.find(key)? + key.len()..];
    let rest = &rest[rest.find('[')? + 1..];
    let v: Vec<f64> = rest[..rest.find(']')?]
        .split(',')
        .map(|t| t.trim().parse().ok())
        .collect::<Option<_>>()?;
    v.try_into().ok()
}

/// The number after `key` (up to `,` or `)`) in `s`.
fn number_after(s: &str, key: &str) -> Option<f64> {
    let rest = &s[s.find(key)? + key.len()..];
    rest[..rest.find([',', ')'])?].trim().parse().ok()
}

/// Parse bbm's `ngan_cooktorrance.fit`: `name = Aggregate(Lambertian(albedo = [r, g, b]),
/// NganCookTorrance(albedo = [r, g, b], eta = x, roughness = y))` per line, `#` comments.
fn read_ngan(path: &Path) -> Result<Vec<(String, NganCt)>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let bad = || {
            format!(
                "{}: line {}: not a NganCookTorrance fit",
                path.display(),
                n + 1
            )
        };
        let (name, rest) = line.split_once('=').ok_or_else(bad)?;
        let lam = rest.find("Lambertian(").ok_or_else(bad)?;
        let ct = rest.find("NganCookTorrance(").ok_or_else(bad)?;
        let (lam, ct) = (&rest[lam..ct], &rest[ct..]);
        out.push((
            name.trim().to_string(),
            NganCt {
                diffuse: triple_after(lam, "albedo").ok_or_else(bad)?,
                specular: triple_after(ct, "albedo").ok_or_else(bad)?,
                f0: number_after(ct, "eta =").ok_or_else(bad)?,
                alpha: number_after(ct, "roughness =").ok_or_else(bad)?,
            },
        ));
    }
    Ok(out)
}

fn mean(v: [f64; 3]) -> f64 {
    (v[0] + v[1] + v[2]) / 3.0
}

/// Both metrics, channel mean: (Löw log, Ngan L2).
fn score(e: &FitErrors) -> (f64, f64) {
    (mean(e.low_log), mean(e.ngan_l2))
}

struct Row {
    material: String,
    meso: (f64, f64),
    ggx: (f64, f64),
    /// GGX + Lambert fitted in meso's metric, scored in both.
    ggx_same: (f64, f64),
    /// The same held to a meso material's limits (K = 1 of `ggx-lobes`), scored in both.
    ggx_material: (f64, f64),
    ngan: Option<(f64, f64)>,
}

fn mark(a: f64, b: f64) -> &'static str {
    if a < b {
        "win"
    } else {
        "**lose**"
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut ngan_path: Option<PathBuf> = None;
    let mut target = 30_000usize;
    let mut metric = Metric::Both;
    let mut ggx_own_metric = true;
    let mut student_t = false;
    let mut files = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--ngan" => ngan_path = Some(args.next().ok_or("--ngan needs a file")?.into()),
            "--samples" => target = args.next().ok_or("--samples needs N")?.parse()?,
            "--metric" => {
                let m = args.next().ok_or("--metric needs both, log or ngan")?;
                metric = Metric::from_name(&m).ok_or(format!("--metric {m}: both, log or ngan"))?;
            }
            "--ggx-same-metric" => ggx_own_metric = false,
            "--student-t" => student_t = true,
            "-h" | "--help" => {
                println!(
                    "merl_compare --ngan ngan_cooktorrance.fit [--samples N] [--metric both|log|ngan] [--ggx-same-metric] [--student-t] A.binary [B.binary ...]"
                );
                return Ok(());
            }
            _ => files.push(PathBuf::from(a)),
        }
    }
    let ngan = match &ngan_path {
        Some(p) => read_ngan(p)?,
        None => Vec::new(),
    };
    if files.is_empty() {
        return Err("no MERL file given (merl_compare --help)".into());
    }
    let mut candidates = auto_candidates();
    if student_t {
        candidates.push(Transfer::StudentTLobes);
    }
    let names: Vec<&str> = candidates.iter().map(|t| t.name()).collect();
    println!(
        "meso: `meso fit DATA --lobes auto --metric {}` (families tried: {}; {} fitted cells; {} \
         minimised by meso; GGX + Lambert fitted {}). Errors: mean over r, g, b on held-out cells \
         no fit and no choice saw.",
        metric.cli_name(),
        names.join(", "),
        target,
        metric.name(),
        if ggx_own_metric {
            "twice, in each metric alone, each scored in its own metric".to_string()
        } else {
            format!("in {}", metric.name())
        }
    );
    println!();
    println!(
        "| material | meso family, K | log: meso | log: GGX+L | log: Ngan CT | L2: meso | L2: GGX+L | L2: Ngan CT | log vs GGX / Ngan | L2 vs GGX / Ngan | GGX+L in meso's metric: log, L2 | its k_s max | GGX+L as a meso material: log, L2 | meso vs it: log / L2 | cells scored | time (s) |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
    let mut rows = Vec::new();
    let mut failed: Vec<String> = Vec::new();
    for path in &files {
        let t0 = Instant::now();
        let material = path
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or("?")
            .to_string();
        let data = match job::load(path, target) {
            Ok(d) if d.merl.is_some() => d,
            Ok(_) => {
                println!("| {material} | not a MERL binary: {} |", path.display());
                failed.push(material);
                continue;
            }
            Err(e) => {
                println!("| {material} | not scored: {e} |");
                failed.push(material);
                continue;
            }
        };
        // Held-out cells split alternately: selection (what fit_best sees) and scoring.
        let (mut select, mut scored) = (Vec::new(), Vec::new());
        for (k, s) in data.samples.held_out.iter().enumerate() {
            if k % 2 == 0 {
                select.push(*s);
            } else {
                scored.push(*s);
            }
        }
        let fitset = SampleSet {
            samples: data.samples.samples.clone(),
            cell_size: data.samples.cell_size,
            held_out: select,
        };
        let opts = FitOptions {
            metric,
            axes: LobeAxes::Normal,
            ..FitOptions::default()
        };
        let (family, fits, _tried) =
            job::fit_best(job::AUTO_LOBES_MAX, true, &candidates, &fitset, &opts)?;
        let (lobes, _) = fits.last().ok_or("no lobe fit")?;
        let meso = score(&evaluate_samples_fn(&scored, |wi, wo| lobes.eval(wi, wo)));
        // GGX + Lambert fitted twice, in each metric alone, and scored in the metric it
        // minimised: the strongest fair baseline in each column.
        let ggx_model = model::Microfacet::GGX;
        // Returns the scores and the largest specular amplitude k_s.
        let ggx_in = |m: Metric| -> Result<((f64, f64), f64), Box<dyn std::error::Error>> {
            let o = FitOptions { metric: m, ..opts };
            let g = meso_measured::fit::fit(&ggx_model, &fitset, &o)?;
            let s = score(&evaluate_samples_fn(&scored, |wi, wo| {
                let mut scratch = [0.0; 4];
                eval_model(&ggx_model, &g.theta, &g.amps, wi, wo, &mut scratch)
            }));
            Ok((s, g.amps[1].iter().copied().fold(0.0, f64::max)))
        };
        let (ggx_same, ks_max) = ggx_in(metric)?;
        let ggx = if ggx_own_metric {
            (ggx_in(Metric::LowLog)?.0 .0, ggx_in(Metric::NganL2)?.0 .1)
        } else {
            ggx_same
        };
        // GGX + Lambert as a meso material: K = 1 of the GGX-lobe family, one GGX lobe.
        let one = model::LobeGgxModel::ggx(1);
        let p = one.params(&meso_measured::fit::fit(&one, &fitset, &opts)?);
        let ggx_material = score(&evaluate_samples_fn(&scored, |wi, wo| p.eval(wi, wo)));
        let ngan_fit = ngan.iter().find(|(n, _)| *n == material).map(|(_, p)| *p);
        let ngan_score =
            ngan_fit.map(|p| score(&evaluate_samples_fn(&scored, |wi, wo| p.eval(wi, wo))));
        let f = |x: f64| format!("{x:.5}");
        let (nl, n2, ml, m2) = match ngan_score {
            Some((l, l2)) => (f(l), f(l2), mark(meso.0, l), mark(meso.1, l2)),
            None => ("—".into(), "—".into(), "—", "—"),
        };
        println!(
            "| {material} | {} {} | {} | {} | {} | {} | {} | {} | {} / {} | {} / {} | {}, {} | {:.3} | {}, {} | {} / {} | {} | {:.1} |",
            family.name(),
            fits.len(),
            f(meso.0),
            f(ggx.0),
            nl,
            f(meso.1),
            f(ggx.1),
            n2,
            mark(meso.0, ggx.0),
            ml,
            mark(meso.1, ggx.1),
            m2,
            f(ggx_same.0),
            f(ggx_same.1),
            ks_max,
            f(ggx_material.0),
            f(ggx_material.1),
            mark(meso.0, ggx_material.0),
            mark(meso.1, ggx_material.1),
            scored.len(),
            t0.elapsed().as_secs_f64()
        );
        rows.push(Row {
            material,
            meso,
            ggx,
            ggx_same,
            ggx_material,
            ngan: ngan_score,
        });
    }
    // Summary.
    let n = rows.len();
    let pct = |k: usize, n: usize| {
        if n == 0 {
            0.0
        } else {
            100.0 * k as f64 / n as f64
        }
    };
    let with_ngan: Vec<&Row> = rows.iter().filter(|r| r.ngan.is_some()).collect();
    let nn = with_ngan.len();
    let count = |f: &dyn Fn(&Row) -> bool, v: &[&Row]| v.iter().filter(|r| f(r)).count();
    let all: Vec<&Row> = rows.iter().collect();
    let g_log = count(&|r| r.meso.0 < r.ggx.0, &all);
    let g_l2 = count(&|r| r.meso.1 < r.ggx.1, &all);
    let n_log = count(&|r| r.meso.0 < r.ngan.unwrap().0, &with_ngan);
    let n_l2 = count(&|r| r.meso.1 < r.ngan.unwrap().1, &with_ngan);
    println!();
    println!("| meso wins against | Löw log | Ngan L2 |");
    println!("|---|---|---|");
    println!(
        "| Ngan's Cook–Torrance | {n_log} of {nn} ({:.0} %) | {n_l2} of {nn} ({:.0} %) |",
        pct(n_log, nn),
        pct(n_l2, nn)
    );
    println!(
        "| fresh GGX + Lambert{} | {g_log} of {n} ({:.0} %) | {g_l2} of {n} ({:.0} %) |",
        if ggx_own_metric {
            ", fitted in each metric alone"
        } else {
            ""
        },
        pct(g_log, n),
        pct(g_l2, n)
    );
    if ggx_own_metric {
        let s_log = count(&|r| r.meso.0 < r.ggx_same.0, &all);
        let s_l2 = count(&|r| r.meso.1 < r.ggx_same.1, &all);
        println!(
            "| fresh GGX + Lambert, fitted in {} as meso | {s_log} of {n} ({:.0} %) | {s_l2} of {n} ({:.0} %) |",
            metric.name(),
            pct(s_log, n),
            pct(s_l2, n)
        );
    }
    let m_log = count(&|r| r.meso.0 < r.ggx_material.0, &all);
    let m_l2 = count(&|r| r.meso.1 < r.ggx_material.1, &all);
    println!(
        "| GGX + Lambert as a meso material (specular ≤ 1), fitted in {} as meso | {m_log} of {n} ({:.0} %) | {m_l2} of {n} ({:.0} %) |",
        metric.name(),
        pct(m_log, n),
        pct(m_l2, n)
    );
    let lost: Vec<String> = rows
        .iter()
        .filter(|r| {
            r.meso.0 >= r.ggx.0
                || r.meso.1 >= r.ggx.1
                || r.ngan.is_some_and(|g| r.meso.0 >= g.0 || r.meso.1 >= g.1)
        })
        .map(|r| r.material.clone())
        .collect();
    println!();
    println!(
        "Materials where meso loses at least one comparison: {}",
        if lost.is_empty() {
            "none".to_string()
        } else {
            lost.join(", ")
        }
    );
    let missing: Vec<&str> = rows
        .iter()
        .filter(|r| r.ngan.is_none())
        .map(|r| r.material.as_str())
        .collect();
    if !missing.is_empty() {
        println!("No Ngan fit for: {}", missing.join(", "));
    }
    if !failed.is_empty() {
        println!("Not scored (file refused): {}", failed.join(", "));
    }
    Ok(())
}
