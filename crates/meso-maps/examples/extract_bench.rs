//! Timing of a 1024 × 1024 extraction at K ≤ 4 (with and without the smoothed refinement of the
//! coarse levels), plus the NDF and BRDF error table of the
//! fixture maps as K goes 1, 2, 4, 7 and for the baselines.
//!
//! ```text
//! CARGO_TARGET_DIR=/work/targets/maps cargo run --release -p meso-maps --example extract_bench
//! ```
use glam::DVec3;
use meso_core::convolution::{effective_brdf_with, Accuracy, Form, Visibility};
use meso_core::frame::spherical_direction_deg as dir;
use meso_core::ndf::{Ndf, PhongPeaks};
use meso_core::transfer::{PhongVariant, Transfer};
use meso_maps::fit::{ndf_bin_mass, ndf_l2_error};
use meso_maps::*;
use std::time::Instant;

/// The core's microfacet form without masking.
fn eval(ndf: &Ndf, facet: &Transfer, i: DVec3, o: DVec3) -> f64 {
    effective_brdf_with(
        ndf,
        facet,
        Form::Microfacet,
        Visibility::None,
        i,
        o,
        Accuracy::default(),
    )[0]
}

fn brdf_error(ndf: &Ndf, exact: &Ndf, facet: &Transfer) -> f64 {
    let mut vals = Vec::new();
    for ti in [0.0, 30.0, 60.0] {
        for to in [0.0, 20.0, 45.0, 60.0] {
            for po in [0.0, 90.0, 180.0] {
                let (i, o) = (dir(ti, 0.0), dir(to, po));
                vals.push((eval(ndf, facet, i, o), eval(exact, facet, i, o)));
            }
        }
    }
    let peak = vals.iter().map(|v| v.1).fold(0.0, f64::max);
    vals.iter()
        .map(|(a, b)| (a - b).abs() / peak)
        .fold(0.0, f64::max)
}

fn main() {
    let maps = [
        (
            "v-grooves",
            fixtures::v_grooves(128, 16, 0.2, 0.05).unwrap(),
        ),
        (
            "cylinders",
            fixtures::half_cylinders(128, 16, 0.05, 1.0).unwrap(),
        ),
        (
            "gaussian",
            fixtures::gaussian(128, 3.0, 0.15, 11, 0.1).unwrap(),
        ),
        ("woven", fixtures::woven(128, 16, 0.1, 0.05).unwrap()),
    ];
    let phong = Transfer::Phong {
        exponent: 20.0,
        specular: [1.0; 3],
        variant: PhongVariant::Half,
    };
    println!("map        method     top-level NDF L2 (rel)  BRDF err (Phong 20, of peak)  lobes");
    for (name, map) in &maps {
        let fnorm = FacetNormals::from_heightmap(map, NormalMode::Triangles);
        let facets = fnorm.normalized();
        let exact = fnorm.to_deltas().unwrap();
        for k in [1, 2, 4, 7] {
            let p = ExtractParams::default().with_max_lobes(k);
            let pyr = extract(Source::Heights(map), &p, &mut |_| {}).unwrap();
            let ndf = Ndf::PhongPeaks(PhongPeaks::new(pyr.top().lobes.iter().collect()).unwrap());
            println!(
                "{name:<10} K={k:<7} {:<23.4} {:<29.4} {}",
                pyr.top().residual.mean,
                brdf_error(&ndf, &exact, &phong),
                pyr.top().lobes.len()
            );
        }
        for b in [
            Baseline::MipNormal,
            Baseline::Toksvig,
            Baseline::Lean,
            Baseline::Vmf,
        ] {
            let ndf = fit_baseline(b, &facets);
            let e = ndf_l2_error(facets.iter().copied(), |g, out| ndf_bin_mass(&ndf, g, out));
            println!(
                "{name:<10} {:<9} {:<23.4} {:<29.4} 1",
                format!("{b:?}"),
                e,
                brdf_error(&ndf, &exact, &phong)
            );
        }
    }
    // Triangles vs central differences on a creased map (V-grooves).
    // Grooves across the triangulation diagonal, so that cells straddle the creases.
    let vg = &HeightMap::from_fn(128, 128, 0.05, Border::Wrap, |x, y| {
        0.2 * (2.0 * ((x + y) / 0.75).rem_euclid(1.0) - 1.0).abs()
    })
    .unwrap();
    let (a, b) = (
        FacetNormals::from_heightmap(vg, NormalMode::Triangles)
            .to_deltas()
            .unwrap(),
        FacetNormals::from_heightmap(vg, NormalMode::CentralDifferences)
            .to_deltas()
            .unwrap(),
    );
    let mut worst: f64 = 0.0;
    for (i, o) in [
        (dir(0.0, 0.0), dir(0.0, 0.0)),
        (dir(30.0, 0.0), dir(30.0, 180.0)),
        (dir(45.0, 0.0), dir(10.0, 0.0)),
    ] {
        let (x, y) = (eval(&a, &phong, i, o), eval(&b, &phong, i, o));
        println!("v-grooves triangles vs central differences: i={i:.3} o={o:.3}: {x:.4} vs {y:.4}");
        worst = worst.max((x - y).abs() / x.max(y));
    }
    println!("largest relative disagreement: {worst:.3}");

    // Timing: 1024 × 1024 Gaussian random surface, K ≤ 4.
    let map = fixtures::gaussian(1024, 4.0, 0.1, 3, 0.01).unwrap();
    let t = Instant::now();
    let pyr = extract(Source::Heights(&map), &ExtractParams::default(), &mut |p| {
        eprintln!(
            "level {}/{} ({} texels)",
            p.levels_done, p.levels, p.texels_done
        )
    })
    .unwrap();
    let dt = t.elapsed().as_secs_f64();
    let texels: usize = pyr.levels.iter().map(|l| l.texels()).sum();
    println!(
        "1024x1024 K<=4: {dt:.2} s on {} threads, {:.0} texels/s\n{}",
        rayon::current_num_threads(),
        texels as f64 / dt,
        pyr.info()
    );
    // The same without the smoothed refinement of the coarse levels (EM fit only), then the
    // default again (the first extraction of the process also pays for page faults).
    let mut em_only = ExtractParams::default();
    em_only.fit.smooth_exponent = 0.0;
    for (name, p) in [
        ("EM only (smooth_exponent = 0)", &em_only),
        ("default, again", &ExtractParams::default()),
    ] {
        let t = Instant::now();
        extract(Source::Heights(&map), p, &mut |_| {}).unwrap();
        println!("1024x1024 K<=4, {name}: {:.2} s", t.elapsed().as_secs_f64());
    }
}
