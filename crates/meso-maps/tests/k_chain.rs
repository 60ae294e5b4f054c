//! Issue #11 item 4, "lobe fits that cannot go wrong", as a property over random maps: the lobe
//! fit's own objective (`meso_maps::fit::fit_objective`) never rises as `max_lobes` goes
//! 1, 2, …, 8, on every fitting path (thorough or cheap EM, with or without the smoothed
//! refinement), and no lobe's axis lies below `AXIS_MIN_Z`.

use glam::DVec3;
use meso_maps::fit::{fit_lobes_with, fit_objective, merge_entries, Entry, FitParams};
use meso_maps::limits::{AXIS_MIN_Z, ETA_MAX, ETA_MIN, MAX_LOBES};
use meso_maps::{fixtures, FacetNormals, NormalMap, NormalMode};
use rand::{RngExt, SeedableRng};

/// The merged entries of the footprint `[r0, r1) × [c0, c1)` of `facets`.
fn entries(facets: &FacetNormals, r0: usize, r1: usize, c0: usize, c1: usize) -> Vec<Entry> {
    let singles: Vec<Entry> = facets
        .footprint(r0, r1, c0, c1)
        .map(|(n, w)| Entry::new(n, w))
        .collect();
    let mut out = Vec::new();
    merge_entries(&[&singles], &mut out);
    out
}

#[test]
fn objective_never_rises_with_k_and_no_lobe_below_the_horizon() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
    let mut footprints: Vec<(String, Vec<Entry>)> = Vec::new();
    // Gentle to steep Gaussian surfaces (RMS slope ≈ 0.1 to ≈ 2).
    for seed in 0..5u64 {
        let rms = [0.03, 0.15, 0.4, 0.8, 1.5][seed as usize];
        let corr = 1.5 + (seed % 3) as f64;
        let map = fixtures::gaussian(32, corr, rms, seed, 1.0).unwrap();
        let f = FacetNormals::from_heightmap(&map, NormalMode::Triangles);
        for (r0, r1, c0, c1) in [
            (0, 32, 0, 32),
            (0, 8, 0, 8),
            (8, 12, 20, 24),
            (16, 32, 0, 16),
        ] {
            footprints.push((
                format!("gaussian rms {rms} [{r0},{r1})x[{c0},{c1})"),
                entries(&f, r0, r1, c0, c1),
            ));
        }
    }
    // Random normal maps, some texels below the horizon (clamped by the reader).
    for seed in 0..2 {
        let normals: Vec<DVec3> = (0..16 * 16)
            .map(|_| {
                let z = rng.random::<f64>() * 1.2 - 0.3 + 0.3 * seed as f64;
                DVec3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, z)
            })
            .map(|v| if v.length() < 1e-3 { DVec3::Z } else { v })
            .collect();
        let nm = NormalMap::from_normals(16, 16, normals).unwrap();
        let f = FacetNormals::from_normal_map(&nm);
        for (r0, r1, c0, c1) in [(0, 16, 0, 16), (0, 4, 0, 4)] {
            footprints.push((
                format!("normal map {seed} [{r0},{r1})x[{c0},{c1})"),
                entries(&f, r0, r1, c0, c1),
            ));
        }
    }
    let mut checked = 0;
    let mut pts = Vec::new();
    let mut lobes = Vec::new();
    for (name, e) in &footprints {
        // (max points, thorough, smooth): the thorough smoothed path of the coarse levels, the
        // thorough EM-only path, and the cheap path of the fine levels on few points.
        for (max_points, thorough, smooth) in
            [(512, true, true), (512, true, false), (64, false, false)]
        {
            let mut prev = f64::INFINITY;
            for k in 1..=MAX_LOBES {
                let params = FitParams {
                    max_lobes: k,
                    k_chain: true,
                    ..FitParams::default()
                };
                fit_lobes_with(
                    e, &params, max_points, thorough, smooth, &mut pts, &mut lobes,
                );
                assert!(
                    !lobes.is_empty() && lobes.len() <= k,
                    "{name}: {} lobes",
                    lobes.len()
                );
                let w: f64 = lobes.iter().map(|l| l.weight).sum();
                assert!((w - 1.0).abs() < 1e-9, "{name}: weights {w}");
                for l in &lobes {
                    assert!(l.axis.z >= AXIS_MIN_Z - 1e-12, "{name}: axis {:?}", l.axis);
                    assert!(l.exponent >= ETA_MIN && l.exponent <= ETA_MAX);
                }
                let o = fit_objective(e, &params, max_points, smooth, &lobes);
                assert!(
                    o <= prev,
                    "{name} ({max_points}, {thorough}, {smooth}): objective {o} at K = {k} above {prev} at K − 1"
                );
                prev = o;
                checked += 1;
            }
        }
    }
    assert!(checked >= 8 * 3 * 20, "{checked}");
}
