//! How noisy the traced light between glossy facets is (docs/heightmaps.md, "Light between
//! glossy facets"): the part of the BRDF beyond the single bounce (`first_bounce = 2`, 8
//! events) over the 16 far-field pairs, traced with three seeds at 128², 256² and 512² paths;
//! prints the relative RMSE between the seeds, its size against the single bounce, and the
//! time per pair.
//!
//! `cargo run --release -p meso-maps --example glossy_noise -- [cyl|grv|weave|vgrooves] [alpha]`
//! (Beckmann facets without Fresnel loss; the lobe share of the continuation is
//! `gonio::LOBE_SHARE`, changed there for the sweep the docs quote).

use meso_core::ndf::{Distribution, Microfacet};
use meso_core::transfer::{Fresnel, Transfer};
use meso_maps::{fixtures, Gonio, GonioParams};

fn main() {
    let s = 1.0 / 64.0;
    let which = std::env::args().nth(1).unwrap_or_else(|| "cyl".into());
    let alpha: f64 = std::env::args()
        .nth(2)
        .map_or(0.1, |a| a.parse().expect("alpha: a number"));
    let map = match which.as_str() {
        "cyl" => fixtures::half_cylinders(64, 16, s, 1.0),
        "grv" => fixtures::half_cylinders(64, 16, s, -1.0),
        "weave" => fixtures::woven(64, 16, 0.06, s),
        _ => fixtures::v_grooves(64, 16, 0.25, s),
    }
    .expect("fixture");
    let g = Gonio::new(&map).expect("a wrapped map");
    let t = Transfer::Microfacet {
        distribution: Microfacet::new(Distribution::Beckmann, alpha, alpha).expect("alpha"),
        fresnel: Fresnel::None,
    };
    let pairs = fixtures::farfield_pairs();
    for side in [128usize, 256, 512] {
        let t0 = std::time::Instant::now();
        let runs: Vec<Vec<f64>> = (1..=3u64)
            .map(|seed| {
                let p = GonioParams {
                    rays_per_side: side,
                    bounces: 8,
                    first_bounce: 2,
                    seed,
                    ..GonioParams::default()
                };
                pairs
                    .iter()
                    .map(|&(i, o)| g.measure(&t, i, o, &p)[0])
                    .collect()
            })
            .collect();
        let per_pair = t0.elapsed().as_secs_f64() / 3.0 / pairs.len() as f64;
        let mean: Vec<f64> = (0..pairs.len())
            .map(|k| runs.iter().map(|r| r[k]).sum::<f64>() / 3.0)
            .collect();
        let power: f64 = mean.iter().map(|m| m * m).sum();
        let var: f64 = runs
            .iter()
            .map(|r| {
                r.iter()
                    .zip(&mean)
                    .map(|(a, b)| (a - b) * (a - b))
                    .sum::<f64>()
            })
            .sum::<f64>()
            / 2.0;
        let p1 = GonioParams {
            rays_per_side: side,
            ..GonioParams::default()
        };
        let single: f64 = pairs
            .iter()
            .map(|&(i, o)| g.measure(&t, i, o, &p1)[0].powi(2))
            .sum();
        println!(
            "{which} α = {alpha}, {side}² paths: noise {:.1} % of the light beyond the single \
             bounce, which is {:.2}× the single bounce (RMS); {:.1} ms a pair",
            100.0 * (var / power).sqrt(),
            (power / single).sqrt(),
            1e3 * per_pair
        );
    }
}
