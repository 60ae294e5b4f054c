//! The convolution of Eq. 2/8 against independent truth: brute-force quadrature on a fine
//! Gauss–Legendre × uniform grid, the exact sum of Eq. 4, reciprocity and the white furnace.

use glam::DVec3;
use meso_core::convolution::{
    effective_brdf, integrate, isotropic_projected_area, phong_closed_form, Accuracy, Form,
    SmithMasking,
};
use meso_core::frame::{half_vector, spherical_direction_deg, Frame};
use meso_core::material::Material;
use meso_core::ndf::{
    DeltaSum, Distribution, Microfacet, Ndf, PhongLobe, PhongPeaks, VonMisesFisher, WeightedNormal,
};
use meso_core::quadrature::{integrate_hemisphere, integrate_sphere};
use meso_core::transfer::{Fresnel, PhongVariant, Transfer};

const ISSUE_EXAMPLE: &str = r#"
[ndf]
kind = "phong-peaks"            # Eq. 12; weights are normalised to sum to 1
lobes = [
  { axis = [0.0, 0.0],  weight = 0.6, exponent = 40.0 },    # axis = [theta_deg, phi_deg]
  { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },
]
[transfer]
kind = "phong"
exponent = 50.0
specular = [1.0, 0.8, 0.6]
"#;

fn pairs() -> Vec<(DVec3, DVec3)> {
    [
        (0.0, 0.0, 0.0, 0.0),
        (30.0, 0.0, 30.0, 180.0),
        (45.0, 90.0, 20.0, 250.0),
        (60.0, 10.0, 60.0, 190.0),
        (20.0, 270.0, 50.0, 90.0),
        (75.0, 45.0, 30.0, 225.0),
        (10.0, 0.0, 80.0, 120.0),
    ]
    .iter()
    .map(|&(a, b, c, d)| (spherical_direction_deg(a, b), spherical_direction_deg(c, d)))
    .collect()
}

/// Eq. 2 in the multiple-surface form by brute force: a 1600 × 3200 product rule over the sphere,
/// written from the definition with no shared code but the transfer function itself.
fn brute_force_multiple_surface(ndf: &Ndf, t: &Transfer, i: DVec3, o: DVec3) -> [f64; 3] {
    let mut out = [0.0; 3];
    // The transfer functions used here are grey up to a constant RGB factor: integrate channel 0
    // and scale by the channel ratios at the peak.
    let r = integrate_sphere(
        |m| {
            let cmi = m.dot(i);
            if cmi <= 0.0 {
                return 0.0;
            }
            let f = Frame::from_normal_tangent(m, DVec3::X);
            ndf.eval(m) * t.eval(f.to_local(i), f.to_local(o))[0] * cmi
        },
        1000,
        2000,
    ) / i.z;
    let probe = t.eval(DVec3::Z, DVec3::Z);
    for c in 0..3 {
        out[c] = r * probe[c] / probe[0];
    }
    out
}

#[test]
fn issue_example_matches_brute_force_quadrature_within_1_percent() {
    let m = Material::from_toml_str(ISSUE_EXAMPLE).unwrap();
    for (i, o) in pairs() {
        let got = m.brdf(i, o);
        let want = brute_force_multiple_surface(&m.ndf, &m.transfer, i, o);
        for c in 0..3 {
            let rel = (got[c] - want[c]).abs() / want[c].abs().max(1e-6);
            assert!(
                rel < 0.01,
                "i={i:?} o={o:?} c={c}: {} vs {}",
                got[c],
                want[c]
            );
        }
    }
}

#[test]
fn quadrature_converges_with_accuracy() {
    let m = Material::from_toml_str(ISSUE_EXAMPLE).unwrap();
    let (i, o) = (
        spherical_direction_deg(45.0, 90.0),
        spherical_direction_deg(20.0, 250.0),
    );
    let reference = brute_force_multiple_surface(&m.ndf, &m.transfer, i, o)[0];
    let err = |a: Accuracy| {
        (effective_brdf(&m.ndf, &m.transfer, Form::MultipleSurface, i, o, a)[0] / reference - 1.0)
            .abs()
    };
    let (e_fast, e_fine) = (err(Accuracy::fast()), err(Accuracy::fine()));
    assert!(e_fine < 1e-4, "fine: {e_fine}");
    assert!(e_fast < 1e-2, "fast: {e_fast}");
}

#[test]
fn eq4_delta_sum_equals_the_limit_of_sharp_peaks() {
    // A delta sum is the η → ∞ limit of Phong peaks: the exact sum of Eq. 4 must match the
    // quadrature of very sharp peaks at the same normals.
    let normals = [
        (spherical_direction_deg(0.0, 0.0), 0.5),
        (spherical_direction_deg(25.0, 30.0), 0.3),
        (spherical_direction_deg(40.0, 200.0), 0.2),
    ];
    let deltas = Ndf::Deltas(
        DeltaSum::new(
            normals
                .iter()
                .map(|&(n, w)| WeightedNormal {
                    normal: n,
                    weight: w,
                })
                .collect(),
        )
        .unwrap(),
    );
    let sharp = Ndf::PhongPeaks(
        PhongPeaks::new(
            normals
                .iter()
                .map(|&(n, w)| PhongLobe::new(n, w, 1e6))
                .collect(),
        )
        .unwrap(),
    );
    for t in [
        Transfer::Phong {
            exponent: 20.0,
            specular: [1.0; 3],
            variant: PhongVariant::Half,
        },
        Transfer::Lambert { albedo: [0.7; 3] },
    ] {
        for (i, o) in pairs() {
            let exact = effective_brdf(
                &deltas,
                &t,
                Form::MultipleSurface,
                i,
                o,
                Accuracy::default(),
            );
            // Eq. 4 written out by hand.
            let mut by_hand = 0.0;
            for &(n, w) in &normals {
                let f = Frame::from_normal_tangent(n, DVec3::X);
                by_hand += w * t.eval(f.to_local(i), f.to_local(o))[0] * n.dot(i).max(0.0) / i.z;
            }
            assert!((exact[0] - by_hand).abs() <= 1e-12 * by_hand.abs().max(1.0));
            let quad = effective_brdf(&sharp, &t, Form::MultipleSurface, i, o, Accuracy::fine());
            let tol = 2e-3 * exact[0].abs() + 1e-9;
            assert!(
                (quad[0] - exact[0]).abs() < tol,
                "{i:?} {o:?}: {} vs {}",
                quad[0],
                exact[0]
            );
        }
    }
}

fn continuous_ndfs() -> Vec<(&'static str, Ndf)> {
    vec![
        (
            "phong-peaks",
            Ndf::PhongPeaks(
                PhongPeaks::new(vec![
                    PhongLobe::new(DVec3::Z, 0.7, 60.0),
                    PhongLobe::new(spherical_direction_deg(35.0, 90.0), 0.3, 150.0),
                ])
                .unwrap(),
            ),
        ),
        (
            "beckmann",
            Ndf::Microfacet(Microfacet::new(Distribution::Beckmann, 0.3, 0.15).unwrap()),
        ),
        (
            "ggx",
            Ndf::Microfacet(Microfacet::isotropic(Distribution::Ggx, 0.25).unwrap()),
        ),
        (
            "vmf",
            Ndf::VonMisesFisher(VonMisesFisher::new(DVec3::new(0.1, 0.0, 1.0), 30.0).unwrap()),
        ),
        (
            "mixture",
            Ndf::Mixture(
                meso_core::ndf::Mixture::isotropic(&[
                    (Distribution::Ggx, 0.25, 0.6),
                    (Distribution::Beckmann, 0.4, 0.4),
                ])
                .unwrap(),
            ),
        ),
    ]
}

#[test]
fn microfacet_form_with_mirror_facets_is_reciprocal() {
    let t = Transfer::Mirror {
        fresnel: Fresnel::None,
        specular: [1.0; 3],
    };
    for (name, ndf) in continuous_ndfs() {
        for (i, o) in pairs() {
            let a = effective_brdf(&ndf, &t, Form::Microfacet, i, o, Accuracy::default())[0];
            let b = effective_brdf(&ndf, &t, Form::Microfacet, o, i, Accuracy::default())[0];
            assert!(
                (a - b).abs() <= 1e-3 * a.abs().max(1e-9),
                "{name} {i:?} {o:?}: {a} vs {b}"
            );
        }
    }
}

#[test]
fn microfacet_form_matches_closed_form_beckmann_ggx() {
    // With the Beckmann/GGX NDF and a mirror facet, the numerical D and Smith Λ must reproduce the
    // closed-form Cook–Torrance/Walter BRDF D(h) G₂ / (4 cos θi cos θo).
    for dist in [Distribution::Beckmann, Distribution::Ggx] {
        let mf = Microfacet::new(dist, 0.35, 0.2).unwrap();
        let ndf = Ndf::Microfacet(mf);
        let t = Transfer::Mirror {
            fresnel: Fresnel::None,
            specular: [1.0; 3],
        };
        for (i, o) in pairs() {
            let h = half_vector(i, o).unwrap();
            let closed = mf.d(h) / (1.0 + mf.lambda(i) + mf.lambda(o)) / (4.0 * i.z * o.z);
            let got = effective_brdf(&ndf, &t, Form::Microfacet, i, o, Accuracy::fine())[0];
            assert!(
                (got / closed - 1.0).abs() < 5e-3,
                "{dist:?} {i:?} {o:?}: {got} vs {closed}"
            );
        }
    }
}

#[test]
fn microfacet_form_gains_no_energy_under_a_white_furnace() {
    // The microfacet form with a mirror facet is D(h) G₂ / (4 cos θi cos θo) with D and Λ computed
    // numerically from the NDF; one masking object per NDF and Λ(i) once per incidence keep this
    // affordable. The value is checked against effective_brdf at a few directions first.
    let t = Transfer::Mirror {
        fresnel: Fresnel::None,
        specular: [1.0; 3],
    };
    for (name, ndf) in continuous_ndfs() {
        let acc = Accuracy::fast();
        let sm = SmithMasking::new(&ndf, acc);
        for theta in [0.0, 30.0, 60.0, 80.0] {
            let i = spherical_direction_deg(theta, 15.0);
            let li = sm.lambda(i);
            let f = |o: DVec3| {
                let h = half_vector(i, o).unwrap();
                if h.z <= 0.0 {
                    return 0.0;
                }
                ndf.eval(h) / sm.projected_area / (1.0 + li + sm.lambda(o)) / (4.0 * i.z * o.z)
            };
            let o = spherical_direction_deg(35.0, 200.0);
            let direct = effective_brdf(&ndf, &t, Form::Microfacet, i, o, acc)[0];
            assert!((f(o) / direct - 1.0).abs() < 1e-9, "{name}");
            let albedo = integrate_hemisphere(|o| f(o) * o.z, 48, 48);
            assert!(albedo <= 1.01, "{name} θi={theta}: albedo {albedo}");
            assert!(
                albedo > 0.5,
                "{name} θi={theta}: albedo {albedo} implausibly low"
            );
        }
    }
}

#[test]
fn smith_lambda_of_tabulated_beckmann_matches_closed_form() {
    let mf = Microfacet::isotropic(Distribution::Beckmann, 0.4).unwrap();
    let ndf = Ndf::Microfacet(mf);
    let sm = SmithMasking::numerical(&ndf, Accuracy::fine());
    // ∫_{z>0} n (m·z) = 1/A.
    assert!((sm.projected_area * mf.area_ratio() - 1.0).abs() < 1e-4);
    for theta in [20.0, 50.0, 70.0, 85.0] {
        let w = spherical_direction_deg(theta, 0.0);
        let (num, exact) = (sm.lambda(w), mf.lambda(w));
        assert!(
            (num - exact).abs() < 2e-3 * (1.0 + exact),
            "θ={theta}: {num} vs {exact}"
        );
    }
}

/// The 1-D projected area of isotropic NDFs (the Smith Λ of fitted lobe sums) against the
/// closed-form Λ of Beckmann and GGX up to 89.9°, and against the 2-D quadrature for Phong peaks
/// from broad to very sharp.
#[test]
fn isotropic_projected_area_matches_closed_forms_and_the_2d_quadrature() {
    for (dist, alpha) in [
        (Distribution::Beckmann, 0.05),
        (Distribution::Beckmann, 0.5),
        (Distribution::Ggx, 0.08),
        (Distribution::Ggx, 0.6),
    ] {
        let mf = Microfacet::isotropic(dist, alpha).unwrap();
        let ndf = Ndf::Microfacet(mf);
        let p = isotropic_projected_area(&ndf, 1.0);
        assert!(
            (p * mf.area_ratio() - 1.0).abs() < 1e-9,
            "{dist:?} {alpha}: P = {p}"
        );
        for theta in [0.0, 30.0, 60.0, 80.0, 85.0, 89.0, 89.9] {
            let w = spherical_direction_deg(theta, 0.0);
            let lambda = isotropic_projected_area(&ndf, w.z) / (p * w.z) - 1.0;
            let exact = mf.lambda(w);
            assert!(
                (lambda - exact).abs() < 1e-7 * (1.0 + exact),
                "{dist:?} α {alpha} θ {theta}: {lambda} vs {exact}"
            );
        }
    }
    for eta in [1.0, 40.0, 1e3, 1e5] {
        let ndf =
            Ndf::PhongPeaks(PhongPeaks::new(vec![PhongLobe::new(DVec3::Z, 1.0, eta)]).unwrap());
        for theta in [0.0, 45.0, 75.0, 88.0] {
            let w = spherical_direction_deg(theta, 0.0);
            // Broad lobes: brute force on the hemisphere (the warped rule loses accuracy at
            // the horizon they cross); sharp ones: the lobe-warped rule.
            let q = if eta < 100.0 {
                integrate_hemisphere(|m| ndf.eval(m) * w.dot(m).max(0.0), 600, 600)
            } else {
                integrate(&ndf, Accuracy::fine(), None, |m| {
                    [if m.z > 0.0 { w.dot(m).max(0.0) } else { 0.0 }]
                })[0]
            };
            let p = isotropic_projected_area(&ndf, w.z);
            assert!(
                (p - q).abs() < 3e-4 * q.max(1e-3),
                "η {eta} θ {theta}: 1-D {p} vs 2-D {q}"
            );
        }
        // Towards the normal, in closed form (a = η/2):
        // P↑ = (η+2)/2 · [2(1 − 2^−(a+2))/(a+2) − (1 − 2^−(a+1))/(a+1)].
        let a = 0.5 * eta;
        let closed = 0.5
            * (eta + 2.0)
            * (2.0 * (1.0 - 2f64.powf(-(a + 2.0))) / (a + 2.0)
                - (1.0 - 2f64.powf(-(a + 1.0))) / (a + 1.0));
        let p = isotropic_projected_area(&ndf, 1.0);
        assert!(
            (p - closed).abs() < 1e-9 * closed,
            "η {eta}: {p} vs closed form {closed}"
        );
    }
}

#[test]
fn multiple_surface_form_is_neither_reciprocal_nor_energy_conserving() {
    // The default form's known defects, measured (docs/ndf-conventions.md quotes these bounds).
    let m = Material::from_toml_str(ISSUE_EXAMPLE).unwrap();
    let (i, o) = (
        spherical_direction_deg(60.0, 10.0),
        spherical_direction_deg(20.0, 190.0),
    );
    let a = m.brdf(i, o)[0];
    let b = m.brdf(o, i)[0];
    let asym = (a - b).abs() / a.max(b);
    assert!(
        asym > 0.05,
        "expected a visible reciprocity defect, got {asym}"
    );
    // A Lambert facet on a spread NDF at grazing light: facets tilted towards the light see more
    // than cos θi, so the directional albedo exceeds the facet albedo.
    let ndf = continuous_ndfs().remove(0).1;
    let t = Transfer::Lambert { albedo: [1.0; 3] };
    let i = spherical_direction_deg(80.0, 0.0);
    let albedo = integrate_hemisphere(
        |o| effective_brdf(&ndf, &t, Form::MultipleSurface, i, o, Accuracy::fast())[0] * o.z,
        64,
        64,
    );
    println!(
        "multiple-surface form: reciprocity defect {asym:.3}, grazing Lambert albedo {albedo:.4}"
    );
    assert!(albedo > 1.005, "grazing Lambert albedo {albedo}");
}

#[test]
fn closed_form_error_against_quadrature_is_bounded() {
    let m = Material::from_toml_str(ISSUE_EXAMPLE).unwrap();
    let Ndf::PhongPeaks(p) = &m.ndf else { panic!() };
    let mut worst: f64 = 0.0;
    for (i, o) in pairs() {
        let exact = m.brdf(i, o)[0];
        let approx = phong_closed_form(p.lobes(), 50.0, [1.0, 0.8, 0.6], i, o)[0];
        if exact > 1e-3 {
            worst = worst.max((approx / exact - 1.0).abs());
        }
    }
    // Measured 2026-11: see docs/benchmarks.md.
    assert!(worst < 0.1, "closed-form worst relative error {worst}");
}

#[test]
fn every_representation_integrates_to_one() {
    let mut all = continuous_ndfs();
    all.push(("sphere", Ndf::Sphere(meso_core::ndf::Sphere)));
    for (name, ndf) in &all {
        let i = integrate_sphere(|m| ndf.eval(m), 1200, 1200);
        assert!((i - 1.0).abs() < 1e-3, "{name}: {i}");
        let [q] = integrate(ndf, Accuracy::default(), None, |_| [1.0]);
        assert!((q - 1.0).abs() < 1e-3, "{name} (lobe quadrature): {q}");
    }
}
