//! The material sampler of `meso_core::importance` (used by the Mitsuba 3 plugin of the Python
//! package): its draws follow the density it claims (chi-square), and `f cos / pdf` averages to the
//! directional albedo computed independently by quadrature.

use glam::DVec3;
use meso_core::frame::spherical_direction_deg;
use meso_core::importance::{sample_incident, sample_pdf};
use meso_core::material::Material;
use meso_testkit::ChiSquareTest;
use rand::RngExt;

fn materials() -> Vec<(&'static str, Material)> {
    let m = |t: &str| Material::from_toml_str(t).unwrap();
    vec![
        (
            "glossy beckmann 0.05 (microfacet form)",
            m("form = \"microfacet\"\n[ndf]\nkind = \"beckmann\"\nalpha = 0.05\n[transfer]\nkind = \"mirror\"\n"),
        ),
        (
            "ggx 0.3 + diffuse",
            m("form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = 0.3\n[transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.04, 0.04, 0.04]\n[diffuse]\nalbedo = [0.5, 0.4, 0.3]\n"),
        ),
        (
            "phong peaks, phong transfer",
            m("[ndf]\nkind = \"phong-peaks\"\nlobes = [{ axis = [0.0, 0.0], weight = 1.0, exponent = 40.0 }, { axis = [25.0, 90.0], weight = 0.5, exponent = 200.0 }]\n[transfer]\nkind = \"phong\"\nexponent = 50.0\n"),
        ),
        (
            "deltas (singular: cosine only)",
            m("[ndf]\nkind = \"deltas\"\nlobes = [{ axis = [0, 0], weight = 1 }, { axis = [30, 0], weight = 1 }]\n[transfer]\nkind = \"microfacet\"\ndistribution = \"ggx\"\nalpha = 0.3\n"),
        ),
    ]
}

#[test]
fn draws_follow_the_claimed_density() {
    let all = materials();
    for (name, mat) in &all {
        for o in [
            spherical_direction_deg(10.0, 30.0),
            spherical_direction_deg(70.0, 200.0),
        ] {
            let test = ChiSquareTest {
                samples: 300_000,
                tests_run: all.len() * 2,
                normalization_tolerance: None,
                cell_subdivisions: 6,
                ..ChiSquareTest::default()
            };
            test.run(
                |r| sample_incident(mat, o, [r.random(), r.random(), r.random()]),
                |i| sample_pdf(mat, o, i),
            )
            .unwrap_or_else(|e| panic!("{name}, o = {o}: {e}"));
        }
    }
}

#[test]
fn a_wrong_density_is_rejected() {
    // The harness must be able to fail: claim the density of α = 0.06 for draws at α = 0.05.
    let mats = materials();
    let (_, glossy) = &mats[0];
    let wrong = Material::from_toml_str(
        "form = \"microfacet\"\n[ndf]\nkind = \"beckmann\"\nalpha = 0.06\n[transfer]\nkind = \"mirror\"\n",
    )
    .unwrap();
    let o = spherical_direction_deg(10.0, 30.0);
    let test = ChiSquareTest {
        samples: 300_000,
        normalization_tolerance: None,
        cell_subdivisions: 6,
        ..ChiSquareTest::default()
    };
    assert!(test
        .run(
            |r| sample_incident(glossy, o, [r.random(), r.random(), r.random()]),
            |i| sample_pdf(&wrong, o, i),
        )
        .is_err());
}

/// `∫ f(i,o) cos θᵢ dωᵢ` by a midpoint rule in (cos θ, φ), refined near the mirror direction.
fn albedo_quadrature(mat: &Material, o: DVec3) -> f64 {
    let (nz, nphi) = (160, 160);
    let mut sum = 0.0;
    for a in 0..nz {
        let z = (a as f64 + 0.5) / nz as f64;
        let s = (1.0 - z * z).sqrt();
        for b in 0..nphi {
            let phi = (b as f64 + 0.5) / nphi as f64 * std::f64::consts::TAU;
            let i = DVec3::new(s * phi.cos(), s * phi.sin(), z);
            sum += mat.brdf(i, o)[1] * z;
        }
    }
    sum * std::f64::consts::TAU / (nz * nphi) as f64
}

#[test]
fn weighted_draws_average_to_the_albedo() {
    let all = materials();
    // A rough one with a diffuse term: the quadrature is exact enough for it.
    {
        let (name, mat) = &all[1];
        let o = spherical_direction_deg(40.0, 60.0);
        let truth = albedo_quadrature(mat, o);
        let mut rng = meso_testkit::rng(11);
        let n = 20_000;
        let (mut s, mut s2) = (0.0, 0.0);
        for _ in 0..n {
            if let Some(i) = sample_incident(mat, o, [rng.random(), rng.random(), rng.random()]) {
                let w = mat.brdf(i, o)[1] * i.z / sample_pdf(mat, o, i);
                s += w;
                s2 += w * w;
            }
        }
        let mean = s / n as f64;
        let se = ((s2 / n as f64 - mean * mean) / n as f64).sqrt();
        assert!(
            (mean - truth).abs() < 4.0 * se + 2e-3 * truth,
            "{name}: Monte Carlo {mean} ± {se}, quadrature {truth}"
        );
    }
}
