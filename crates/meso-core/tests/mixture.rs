//! Mixtures of Beckmann / GGX lobes (`kind = "mixture"`): Eq. 1 normalisation, the sampler by
//! χ², the closed-form Smith Λ and projected area against the quadratures, and the material's
//! BRDF (closed form against the explicit formula, reciprocity, white furnace, `FastBrdf`).

mod common;

use glam::DVec3;
use meso_core::convolution::{isotropic_projected_area, Accuracy, SmithMasking};
use meso_core::frame::{half_vector, spherical_direction_deg};
use meso_core::material::Material;
use meso_core::ndf::{Distribution, Mixture, Ndf};
use meso_core::quadrature::{integrate_hemisphere, integrate_sphere};
use meso_core::shading::{FastBrdf, Policy, CLOSED_MICROFACET_PATH};
use meso_testkit::{uniform2, ChiSquareTest};

fn mixtures() -> Vec<(&'static str, Mixture)> {
    vec![
        (
            "ggx+ggx",
            Mixture::isotropic(&[
                (Distribution::Ggx, 0.06, 0.6),
                (Distribution::Ggx, 0.35, 0.4),
            ])
            .unwrap(),
        ),
        (
            "ggx+beckmann",
            Mixture::isotropic(&[
                (Distribution::Ggx, 0.08, 0.7),
                (Distribution::Beckmann, 0.4, 0.3),
            ])
            .unwrap(),
        ),
        (
            "three",
            Mixture::isotropic(&[
                (Distribution::Beckmann, 0.05, 0.2),
                (Distribution::Ggx, 0.2, 0.5),
                (Distribution::Ggx, 1.2, 0.3),
            ])
            .unwrap(),
        ),
    ]
}

/// The material of the closed-form test: a GGX and a Beckmann lobe.
fn material_toml() -> String {
    common::mirror_mixture_toml(&[
        "{ kind = \"ggx\", alpha = 0.08, weight = 0.7 }",
        "{ kind = \"beckmann\", alpha = 0.4, weight = 0.3 }",
    ])
}

#[test]
fn a_mixture_integrates_to_one_and_its_d_is_normalised_by_projected_area() {
    for (name, mx) in mixtures() {
        let ndf = Ndf::Mixture(mx.clone());
        assert!(ndf.is_isotropic(), "{name}");
        assert_eq!(ndf.kind(), "mixture");
        // Eq. 1 by an independent quadrature (GGX tails are long: a fine grid).
        let i = integrate_sphere(|m| ndf.eval(m), 2000, 64);
        assert!((i - 1.0).abs() < 1e-3, "{name}: ∫ n dω = {i}");
        let st = ndf.stats();
        assert!((st.integral - 1.0).abs() < 1e-3, "{name}: {}", st.integral);
        assert!(st.mean_normal.x.abs() < 1e-9 && st.mean_normal.y.abs() < 1e-9);
        // ∫ D (m·z) dω = 1.
        let p = integrate_sphere(|m| mx.d(m) * m.z.max(0.0), 2000, 64);
        assert!((p - 1.0).abs() < 1e-3, "{name}: ∫ D cos = {p}");
        // n = Σ w_k n_k.
        let m = spherical_direction_deg(25.0, 40.0);
        let direct: f64 = mx
            .lobes()
            .iter()
            .map(|l| l.weight * l.microfacet.eval(m))
            .sum();
        assert!((ndf.eval(m) / direct - 1.0).abs() < 1e-12, "{name}");
        assert!(
            (mx.d_isotropic(m.z) / mx.d(m) - 1.0).abs() < 1e-12,
            "{name}"
        );
    }
}

#[test]
fn the_mixture_sampler_passes_chi_square_and_a_wrong_one_fails() {
    let all = mixtures();
    for (name, mx) in &all {
        let ndf = Ndf::Mixture(mx.clone());
        ChiSquareTest {
            samples: 400_000,
            tests_run: all.len() + 1,
            ..ChiSquareTest::default()
        }
        .run(|r| Some(ndf.sample(uniform2(r))), |m| ndf.pdf(m))
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    // Choosing the lobes by their Eq. 1 weights instead of their projected-area shares c_k is a
    // different density: the test must see it.
    let mx = &all[2].1;
    let by_weight = |u: [f64; 2]| {
        let mut lo = 0.0;
        for l in mx.lobes() {
            if u[0] < lo + l.weight {
                return l.microfacet.sample([(u[0] - lo) / l.weight, u[1]]);
            }
            lo += l.weight;
        }
        mx.lobes().last().unwrap().microfacet.sample(u)
    };
    let r = ChiSquareTest {
        samples: 400_000,
        ..ChiSquareTest::default()
    }
    .run(|r| Some(by_weight(uniform2(r))), |m| mx.pdf(m));
    assert!(r.is_err(), "a lobe choice by Eq. 1 weight passed");
}

#[test]
fn closed_form_smith_of_a_mixture_matches_the_quadratures() {
    for (name, mx) in mixtures() {
        let ndf = Ndf::Mixture(mx.clone());
        let closed = SmithMasking::new(&ndf, Accuracy::fine());
        let numerical = SmithMasking::numerical(&ndf, Accuracy::fine());
        let p1 = isotropic_projected_area(&ndf, 1.0);
        assert!(
            (closed.projected_area / p1 - 1.0).abs() < 1e-9,
            "{name}: P {} vs 1-D {p1}",
            closed.projected_area
        );
        assert!((numerical.projected_area / p1 - 1.0).abs() < 1e-12);
        for theta in [0.0, 20.0, 45.0, 70.0, 80.0, 85.0, 89.0, 89.9] {
            let w = spherical_direction_deg(theta, 33.0);
            let (a, b) = (closed.lambda(w), numerical.lambda(w));
            assert!(
                (a - b).abs() < 1e-6 * (1.0 + b),
                "{name} θ {theta}: closed {a} vs quadrature {b}"
            );
            assert!((mx.lambda_isotropic(w.z) - a).abs() < 1e-12 * (1.0 + a));
        }
    }
    // A wrong mixing rule (Λ weighted by the Eq. 1 weights w_k instead of c_k) is visibly off.
    let mx = &mixtures()[2].1;
    let ndf = Ndf::Mixture(mx.clone());
    let numerical = SmithMasking::numerical(&ndf, Accuracy::fine());
    let w = spherical_direction_deg(80.0, 0.0);
    let wrong: f64 = mx
        .lobes()
        .iter()
        .map(|l| l.weight * l.microfacet.lambda(w))
        .sum();
    assert!((wrong - numerical.lambda(w)).abs() > 1e-3 * (1.0 + wrong));
}

#[test]
fn the_mixture_material_is_the_closed_form_microfacet_brdf() {
    let m = Material::from_toml_str(&material_toml()).unwrap();
    let Ndf::Mixture(mx) = &m.ndf else {
        panic!("not a mixture")
    };
    assert!((mx.lobes()[0].weight - 0.7).abs() < 1e-15);
    let fast = FastBrdf::with_policy(&m, Policy::Accurate);
    assert_eq!(fast.path(), CLOSED_MICROFACET_PATH);
    for (ti, pi, to, po) in [
        (10.0, 0.0, 12.0, 180.0),
        (30.0, 20.0, 25.0, 190.0),
        (60.0, 0.0, 55.0, 180.0),
        (75.0, 90.0, 40.0, 200.0),
        (85.0, 0.0, 85.0, 180.0),
    ] {
        let i = spherical_direction_deg(ti, pi);
        let o = spherical_direction_deg(to, po);
        let want = common::closed_form_brdf(mx, i, o);
        let exact = m.brdf(i, o);
        let fa = fast.eval(i, o);
        let back = fast.eval(o, i);
        for k in 0..3 {
            assert!(
                (exact[k] / want[k] - 1.0).abs() < 1e-9,
                "({ti},{pi},{to},{po}) c{k}: material {} vs formula {}",
                exact[k],
                want[k]
            );
            assert!((fa[k] / want[k] - 1.0).abs() < 1e-9);
            // Reciprocity.
            assert!((back[k] / fa[k] - 1.0).abs() < 1e-9);
        }
    }
}

#[test]
fn the_mixture_gains_no_energy_under_a_white_furnace() {
    for (name, mx) in mixtures() {
        let ndf = Ndf::Mixture(mx.clone());
        for theta in [0.0, 40.0, 70.0, 85.0] {
            let i = spherical_direction_deg(theta, 15.0);
            let li = mx.lambda(i);
            let f = |o: DVec3| {
                let Some(h) = half_vector(i, o) else {
                    return 0.0;
                };
                ndf.eval(h) / mx.projected_area() / (1.0 + li + mx.lambda(o)) / (4.0 * i.z * o.z)
            };
            let albedo = integrate_hemisphere(|o| f(o) * o.z, 400, 800);
            assert!(albedo <= 1.0 + 2e-3, "{name} θi={theta}: albedo {albedo}");
            assert!(albedo > 0.5, "{name} θi={theta}: albedo {albedo} too low");
        }
    }
}

#[test]
fn mixture_toml_errors_are_clear() {
    let with = |lobes: &str| {
        Material::from_toml_str(&format!(
            "form = \"microfacet\"\n[ndf]\nkind = \"mixture\"\nlobes = [{lobes}]\n[transfer]\nkind = \"mirror\"\n"
        ))
    };
    assert!(with("{ kind = \"ggx\", alpha = 0.1, weight = 1 }").is_ok());
    for (lobes, needle) in [
        ("", "empty"),
        (
            "{ kind = \"phong\", alpha = 0.1, weight = 1 }",
            "unknown lobe kind \"phong\"",
        ),
        ("{ kind = \"ggx\", alpha = 0.0, weight = 1 }", "alpha"),
        ("{ kind = \"ggx\", alpha = -0.2, weight = 1 }", "alpha"),
        ("{ kind = \"ggx\", alpha = nan, weight = 1 }", "alpha"),
        ("{ kind = \"ggx\", alpha = inf, weight = 1 }", "alpha"),
        ("{ kind = \"ggx\", alpha = 0.1, weight = -1 }", "weight"),
        ("{ kind = \"ggx\", alpha = 0.1, weight = 0 }", "sum to zero"),
        ("{ kind = \"ggx\", weight = 1 }", "alpha"),
        ("{ alpha = 0.1, weight = 1 }", "missing `kind`"),
        ("{ kind = \"ggx\", alpha = 0.1 }", "weight"),
        (
            "{ kind = \"ggx\", alpha = 0.1, weight = 1, exponent = 3 }",
            "exponent",
        ),
    ] {
        let e = with(lobes).unwrap_err().0;
        assert!(e.contains(needle), "{lobes}: {e}");
    }
    let e = Material::from_toml_str("[ndf]\nkind = \"mixture\"\n[transfer]\nkind = \"mirror\"\n")
        .unwrap_err()
        .0;
    assert!(e.contains("lobes"), "{e}");
}
