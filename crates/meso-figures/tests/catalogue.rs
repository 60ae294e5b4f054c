//! The figures' materials are the catalogue's (`meso_core::catalogue`), and the catalogue's
//! seven normals are what filtering the cylinder bump map gives (Fournier 1992, §4: "the values
//! were obtained from the filtering of a bump-map extracted from a geometric model describing a
//! cylinder").

use meso_core::catalogue;
use meso_figures::{cylinder_map, pyramid, Lobe, MaterialDef};

/// Each figure material's file is the catalogue material's file, byte for byte.
#[test]
fn figure_materials_are_the_catalogues() {
    for m in catalogue::all() {
        let def = MaterialDef::from(&m);
        assert_eq!(def.to_spec().unwrap(), m.spec(), "{}", m.name);
        assert_eq!(def.toml().unwrap(), m.spec().to_toml(), "{}", m.name);
    }
}

/// The top level of the cylinder map's pyramid, fitted with up to 7 lobes from every normal,
/// gives the catalogue's seven normals: the same count, axes within 1e-3°, weights within 1e-5
/// (the catalogue keeps 1e-4° and 1e-6).
#[test]
fn seven_normals_are_the_filtered_cylinder_map() {
    let pyr = pyramid(&cylinder_map().unwrap(), 7).unwrap();
    let fitted: Vec<Lobe> = pyr
        .top()
        .lobes
        .iter()
        .map(|l| Lobe::from_axis(l.axis, l.weight, None))
        .collect();
    let want = catalogue::seven_normals().normals;
    assert_eq!(fitted.len(), want.len(), "{fitted:?}");
    for (f, w) in fitted.iter().zip(&want) {
        // φ = 360° and 0° are the same azimuth (and any φ at θ = 0).
        let dphi = (f.phi_deg - w.phi_deg + 180.0).rem_euclid(360.0) - 180.0;
        assert!(
            (f.theta_deg - w.theta_deg).abs() < 1e-3
                && (w.theta_deg < 1e-3 || dphi.abs() < 1e-3)
                && (f.weight - w.weight).abs() < 1e-5,
            "fitted {f:?}, catalogue {w:?}"
        );
    }
}
