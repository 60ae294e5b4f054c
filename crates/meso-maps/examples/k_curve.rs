//! Issue #11 item 4: the top level's fit as `max_lobes` goes 1, 2, 4, 8, with the K chain and
//! without it (the single fit at `max_lobes`, `FitParams::k_chain = false`): its own objective
//! (`fit::fit_objective`), the binned NDF residual and the shading error (% of peak); then the
//! time of a 1024 × 1024 extraction at K ≤ 4 with and without the chain, alternated.
//!
//! ```text
//! cargo run --release -p meso-maps --example k_curve [--no-timing | --timing-only]
//! ```
use meso_maps::fit::{fit_objective, merge_entries, Entry};
use meso_maps::*;
use std::time::Instant;

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
    println!("map; chain; K; top lobes; top objective; top NDF residual; top shading error (% of peak); level-5 shading mean/max (%)");
    for (name, map) in maps.iter().filter(|_| table) {
        let facets = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        let singles: Vec<Entry> = facets
            .footprint(0, facets.rows, 0, facets.cols)
            .map(|(n, w)| Entry::new(n, w))
            .collect();
        let mut all = Vec::new();
        merge_entries(&[&singles], &mut all);
        for chain in [false, true] {
            for k in [1, 2, 4, 8] {
                let mut p = ExtractParams::default();
                p.fit.max_lobes = k;
                p.fit.k_chain = chain;
                let pyr = extract(Source::Heights(map), &p, &mut |_| {}).unwrap();
                let top = pyr.top();
                let lobes = top.texel_lobes(0, 0).unwrap();
                let o = fit_objective(&all, &p.fit, p.fit.max_em_points, true, &lobes);
                let l5 = &pyr.levels[5.min(pyr.levels.len() - 1)].residual;
                println!(
                    "{name}; {chain}; {k}; {}; {o:.6e}; {:.4}; {:.2}; {:.2}/{:.2}",
                    lobes.len(),
                    top.residual.mean,
                    100.0 * top.residual.shading_mean.unwrap_or(f64::NAN),
                    100.0 * l5.shading_mean.unwrap_or(f64::NAN),
                    100.0 * l5.shading_max.unwrap_or(f64::NAN),
                );
            }
        }
    }
    if !timing {
        return;
    }
    let map = fixtures::gaussian(1024, 4.0, 0.1, 3, 0.01).unwrap();
    for round in 0..2 {
        for chain in [false, true] {
            let mut p = ExtractParams::default();
            p.fit.k_chain = chain;
            let t = Instant::now();
            extract(Source::Heights(&map), &p, &mut |_| {}).unwrap();
            println!(
                "round {round}: 1024x1024 K<=4, chain {chain}: {:.2} s",
                t.elapsed().as_secs_f64()
            );
        }
    }
}
