//! Issue #11 item 4: the top level's fit as `max_lobes` goes 1, 2, 4, 8, for each way of
//! choosing K (`Fit`: the single fit at `max_lobes`, `FitParams::k_chain = false`; the K chain's
//! end; the chain with K per texel by the shading error, `KChoice::Shading`, at two
//! tolerances and two facet kernels): its own objective (`fit::fit_objective`), the binned NDF
//! residual and the shading error (% of peak); the mean lobes per texel and mean shading error
//! of every level; then the time of a 1024 × 1024 extraction at K ≤ 4 for each, alternated.
//!
//! ```text
//! cargo run --release -p meso-maps --example k_curve [--no-timing | --timing-only]
//! ```
use meso_maps::fit::{fit_objective, merge_entries, Entry, KChoice};
use meso_maps::*;
use std::time::Instant;

/// A way of choosing K: its name, `k_chain`, the choice and the facet kernel's exponent (0:
/// not known, the default λ = 40).
const FITS: [(&str, bool, KChoice, f64); 5] = [
    ("single", false, KChoice::Objective, 0.0),
    ("chain", true, KChoice::Objective, 0.0),
    (
        "shading tol 0",
        true,
        KChoice::Shading { tolerance: 0.0 },
        0.0,
    ),
    (
        "shading tol 0.2%",
        true,
        KChoice::Shading { tolerance: 0.002 },
        0.0,
    ),
    (
        "shading tol 0.2% λ=20",
        true,
        KChoice::Shading { tolerance: 0.002 },
        20.0,
    ),
];

/// The extraction parameters of a way of choosing K (`FITS`) at `max_lobes` K.
fn params(fit: &(&str, bool, KChoice, f64), k: usize) -> ExtractParams {
    let mut p = ExtractParams::default().with_max_lobes(k);
    p.fit.k_chain = fit.1;
    p.fit.k_choice = fit.2;
    p.fit.facet_exponent = fit.3;
    p
}

fn main() {
    let timing = !std::env::args().any(|a| a == "--no-timing");
    let table = !std::env::args().any(|a| a == "--timing-only");
    let maps = [
        (
            "steep gaussian (rms 1.5, corr 1.5)",
            fixtures::gaussian(128, 1.5, 1.5, 4, 1.0).unwrap(),
        ),
        (
            "gaussian (rms 0.15, corr 3)",
            fixtures::gaussian(128, 3.0, 0.15, 11, 0.1).unwrap(),
        ),
        ("woven", fixtures::woven(128, 16, 0.1, 0.05).unwrap()),
    ];
    println!("map; fit; K; top lobes; top objective; top NDF residual; top shading error (% of peak); per level from 0: mean lobes per texel / mean shading error (%)");
    for (name, map) in maps.iter().filter(|_| table) {
        let facets = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        let singles: Vec<Entry> = facets
            .footprint(0, facets.rows, 0, facets.cols)
            .map(|(n, w)| Entry::new(n, w))
            .collect();
        let mut all = Vec::new();
        merge_entries(&[&singles], &mut all);
        for fit in &FITS {
            for k in [1, 2, 4, 8] {
                let p = params(fit, k);
                let pyr = extract(Source::Heights(map), &p, &mut |_| {}).unwrap();
                let top = pyr.top();
                let lobes = top.texel_lobes(0, 0).unwrap();
                let o = fit_objective(&all, &p.fit, p.fit.max_em_points, true, &lobes);
                let levels: Vec<String> = pyr
                    .levels
                    .iter()
                    .map(|l| {
                        format!(
                            "{:.2}/{:.2}",
                            l.lobes.len() as f64 / (l.cols * l.rows) as f64,
                            100.0 * l.residual.shading_mean.unwrap_or(f64::NAN)
                        )
                    })
                    .collect();
                println!(
                    "{name}; {}; {k}; {}; {o:.6e}; {:.4}; {:.2}; {}",
                    fit.0,
                    lobes.len(),
                    top.residual.mean,
                    100.0 * top.residual.shading_mean.unwrap_or(f64::NAN),
                    levels.join(" "),
                );
            }
        }
    }
    if !timing {
        return;
    }
    let map = fixtures::gaussian(1024, 4.0, 0.1, 3, 0.01).unwrap();
    for round in 0..2 {
        for fit in FITS.iter().take(4) {
            let p = params(fit, 4);
            let t = Instant::now();
            let pyr = extract(Source::Heights(&map), &p, &mut |_| {}).unwrap();
            let lobes: usize = pyr.levels.iter().map(|l| l.lobes.len()).sum();
            let texels: usize = pyr.levels.iter().map(|l| l.cols * l.rows).sum();
            println!(
                "round {round}: 1024x1024 K<=4, {}: {:.2} s, {:.3} lobes per texel",
                fit.0,
                t.elapsed().as_secs_f64(),
                lobes as f64 / texels as f64
            );
        }
    }
}
