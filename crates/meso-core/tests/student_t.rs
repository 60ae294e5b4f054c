//! Student-t lobes (STD, `kind = "student-t"`, `Distribution::StudentT`): Eq. 1 normalisation and
//! `∫ D cos θ dω = 1` by an independent 1-D quadrature in θ, γ = 2 against GGX, large γ against
//! Beckmann, the closed-form Smith Λ against the numerical projected area, the sampler by χ²
//! (alone and in a mixture), the mixture's closed plan, and the material file's errors.

mod common;

use glam::DVec3;
use meso_core::convolution::{isotropic_projected_area, Accuracy, SmithMasking};
use meso_core::frame::spherical_direction_deg;
use meso_core::material::Material;
use meso_core::ndf::{Distribution, Microfacet, Mixture, Ndf};
use meso_core::quadrature::{gauss_legendre, integrate_sphere};
use meso_core::shading::{FastBrdf, Policy, CLOSED_MICROFACET_PATH};
use meso_testkit::{uniform2, ChiSquareTest};
use std::f64::consts::{FRAC_PI_2, PI};

fn st(gamma: f64) -> Distribution {
    Distribution::StudentT { gamma }
}

/// `2π ∫₀^{π/2} f(m) sin θ dθ` for an isotropic `f` of the normal `m = (sin θ, 0, cos θ)`, with
/// `ε = π/2 − θ = (π/2) v^q` (`q = 1/(2γ−3)` makes the horizon's `cos^(2γ−4) θ` tail of `D`
/// smooth in `v`; `cos θ = sin ε` without rounding) and 4000 × 8 Gauss–Legendre nodes in `v`
/// split at `v_kink` (a kink of `f`): independent of the slope-space quadrature of the area ratio.
fn hemisphere_1d(f: impl Fn(DVec3) -> f64, gamma: f64, theta_kink: Option<f64>) -> f64 {
    let q = (1.0 / (2.0 * gamma - 3.0)).max(1.0);
    let (xs, ws) = gauss_legendre(8);
    let n = 4000;
    let kink = theta_kink.map(|t| ((FRAC_PI_2 - t) / FRAC_PI_2).powf(1.0 / q));
    let mut ends: Vec<f64> = (0..=n).map(|i| i as f64 / n as f64).collect();
    if let Some(k) = kink {
        ends.push(k);
        ends.sort_by(f64::total_cmp);
    }
    let mut s = 0.0;
    for ab in ends.windows(2) {
        let (a, b) = (ab[0], ab[1]);
        for (x, w) in xs.iter().zip(&ws) {
            let v = 0.5 * (a + b) + 0.5 * (b - a) * x;
            let eps = FRAC_PI_2 * v.powf(q);
            let (sin_t, cos_t) = (eps.cos(), eps.sin());
            let d_eps = FRAC_PI_2 * q * v.powf(q - 1.0);
            s += 0.5 * (b - a) * w * f(DVec3::new(sin_t, 0.0, cos_t)) * sin_t * d_eps;
        }
    }
    2.0 * PI * s
}

/// `∫ n(m)(ω·m)⁺ dω_m` for an isotropic `n` and `ω` at polar angle θ: the azimuthal integral of
/// the clamped cosine in closed form (`2(A acos(−A/B) + √(B² − A²))`, `A = cos θ cos θ_m`,
/// `B = sin θ sin θ_m`; `2πA` where `A ≥ B`), θ_m by [`hemisphere_1d`] split at the kink.
fn projected_area_1d(n: impl Fn(DVec3) -> f64, theta: f64, gamma: f64) -> f64 {
    let (ct, stt) = (theta.cos(), theta.sin());
    hemisphere_1d(
        |m| {
            let (a, b) = (ct * m.z, stt * m.x);
            let az = if a >= b {
                2.0 * PI * a
            } else {
                2.0 * (a * (-a / b).acos() + (b * b - a * a).sqrt())
            };
            n(m) * az / (2.0 * PI)
        },
        gamma,
        Some(FRAC_PI_2 - theta),
    )
}

const GAMMAS: [f64; 6] = [1.6, 2.0, 2.5, 4.0, 10.0, 50.0];
const ALPHAS: [f64; 4] = [0.05, 0.2, 0.6, 1.5];

#[test]
fn student_t_is_normalised_eq1_and_by_projected_area() {
    let mut worst: (f64, f64) = (0.0, 0.0);
    for gamma in GAMMAS {
        for alpha in ALPHAS {
            let m = Microfacet::isotropic(st(gamma), alpha).unwrap();
            let proj = hemisphere_1d(|w| m.d(w) * w.z, gamma, None);
            let eq1 = hemisphere_1d(|w| m.eval(w), gamma, None);
            assert!(
                (proj - 1.0).abs() < 1e-8,
                "γ={gamma} α={alpha}: ∫ D cos = {proj}"
            );
            assert!(
                (eq1 - 1.0).abs() < 1e-6,
                "γ={gamma} α={alpha}: ∫ n dω = {eq1} (A = {})",
                m.area_ratio()
            );
            worst = (
                worst.0.max((proj - 1.0).abs()),
                worst.1.max((eq1 - 1.0).abs()),
            );
        }
    }
    eprintln!(
        "worst |∫D cos − 1| = {:.1e}, |∫n − 1| = {:.1e}",
        worst.0, worst.1
    );
    // Anisotropic, by the 2-D sphere rule.
    for gamma in [1.8, 3.0, 20.0] {
        let m = Microfacet::new(st(gamma), 0.2, 0.6).unwrap();
        let ndf = Ndf::Microfacet(m);
        assert_eq!(ndf.kind(), "student-t");
        let i = integrate_sphere(|w| ndf.eval(w), 2000, 256);
        let p = integrate_sphere(|w| m.d(w) * w.z.max(0.0), 2000, 256);
        assert!(
            (i - 1.0).abs() < 2e-3 && (p - 1.0).abs() < 2e-3,
            "γ={gamma}: {i} {p}"
        );
    }
}

#[test]
fn gamma_two_is_ggx() {
    let mut worst = [0.0f64; 5];
    for (ax, ay) in [(0.05, 0.05), (0.3, 0.3), (0.2, 0.7), (1.5, 0.4)] {
        let t = Microfacet::new(st(2.0), ax, ay).unwrap();
        let g = Microfacet::new(Distribution::Ggx, ax, ay).unwrap();
        for k in 0..200 {
            let w = spherical_direction_deg(0.449 * k as f64, 7.3 * k as f64);
            let r = |a: f64, b: f64| if a == b { 0.0 } else { (a / b - 1.0).abs() };
            worst[0] = worst[0].max(r(t.d(w), g.d(w)));
            // GGX's Λ = (√(1 + x) − 1)/2 without its cancellation near the normal.
            let x = (w.x * w.x * ax * ax + w.y * w.y * ay * ay) / (w.z * w.z);
            worst[1] = worst[1].max(r(t.lambda(w), 0.5 * x / (1.0 + (1.0 + x).sqrt())));
            worst[2] = worst[2].max(r(t.eval(w), g.eval(w)));
            let u = [
                (k as f64 + 0.5) / 200.0,
                (k as f64 * 0.618_033_988_7).fract(),
            ];
            worst[3] = worst[3].max((t.sample(u) - g.sample(u)).length());
        }
        worst[4] = worst[4].max((t.area_ratio() / g.area_ratio() - 1.0).abs());
    }
    eprintln!(
        "γ = 2 vs GGX: D {:.1e}, Λ {:.1e}, n {:.1e}, samples {:.1e}, A {:.1e}",
        worst[0], worst[1], worst[2], worst[3], worst[4]
    );
    // Λ through the incomplete beta function: 1.2e-12 measured.
    assert!(worst[0] < 1e-12 && worst[1] < 5e-12, "{worst:?}");
    assert!(worst[3] < 1e-12, "{worst:?}");
    assert!(worst[4] < 1e-10 && worst[2] < 1e-10, "{worst:?}");
}

#[test]
fn large_gamma_approaches_beckmann() {
    let alpha = 0.3;
    let b = Microfacet::isotropic(Distribution::Beckmann, alpha).unwrap();
    let mut prev = f64::INFINITY;
    for gamma in [10.0, 100.0, 1000.0] {
        let t = Microfacet::isotropic(st(gamma), alpha).unwrap();
        // Within the core (tan θ ≤ 2α, D ≥ e⁻⁴ of its peak) D, Λ and A differ by O(1/γ).
        let mut worst: f64 = 0.0;
        for k in 0..=40 {
            let theta = (2.0 * alpha * k as f64 / 40.0).atan();
            let w = DVec3::new(theta.sin(), 0.0, theta.cos());
            worst = worst.max((t.d(w) / b.d(w) - 1.0).abs());
        }
        for theta_deg in [30.0, 60.0, 80.0, 89.0] {
            let w = spherical_direction_deg(theta_deg, 0.0);
            worst = worst.max((t.lambda(w) - b.lambda(w)).abs() / (1e-3 + b.lambda(w)));
        }
        worst = worst.max((t.area_ratio() / b.area_ratio() - 1.0).abs());
        eprintln!("γ = {gamma}: worst relative difference to Beckmann {worst:.2e}");
        assert!(worst < 30.0 / gamma, "γ={gamma}: {worst}");
        assert!(worst < 0.2 * prev, "γ={gamma}: {worst} vs {prev}");
        prev = worst;
    }
}

#[test]
fn closed_form_smith_matches_the_numerical_projected_area() {
    let mut worst: f64 = 0.0;
    let mut worst_lib: f64 = 0.0;
    for gamma in [1.6, 1.8, 2.0, 2.5, 4.0, 10.0, 50.0] {
        for alpha in [0.05, 0.2, 0.6, 1.5] {
            let m = Microfacet::isotropic(st(gamma), alpha).unwrap();
            let ndf = Ndf::Microfacet(m);
            for theta in [10.0, 30.0, 50.0, 70.0, 80.0, 85.0, 89.0] {
                let w = spherical_direction_deg(theta, 0.0);
                // ∫ D (ω·m)⁺ dω = (1 + Λ) cos θ.
                let p = projected_area_1d(|m| ndf.eval(m), theta.to_radians(), gamma);
                let numerical = p * m.area_ratio() / w.z - 1.0;
                // meso-core's own 1-D rule (geometric intervals; the horizon's integrable
                // singularity `cos^(2γ−4)` of γ < 2 is beyond it).
                if gamma >= 2.0 {
                    let lib = isotropic_projected_area(&ndf, w.z) * m.area_ratio() / w.z - 1.0;
                    let e = (m.lambda(w) - lib).abs() / (1.0 + lib);
                    worst_lib = worst_lib.max(e);
                    assert!(
                        e < 1e-6,
                        "γ={gamma} α={alpha} θ={theta}: {} vs {lib}",
                        m.lambda(w)
                    );
                }
                let closed = m.lambda(w);
                let e = (closed - numerical).abs() / (1.0 + closed);
                worst = worst.max(e);
                assert!(
                    e < 1e-6,
                    "γ={gamma} α={alpha} θ={theta}: closed {closed} vs numerical {numerical}"
                );
            }
        }
    }
    eprintln!(
        "worst |ΔΛ|/(1+Λ) against the 1-D projected area: {worst:.1e} (meso-core's rule, γ ≥ 2: \
         {worst_lib:.1e})"
    );
    // Anisotropic: against the 2-D quadrature of the masking.
    let m = Microfacet::new(st(3.0), 0.15, 0.5).unwrap();
    let ndf = Ndf::Microfacet(m);
    let closed = SmithMasking::new(&ndf, Accuracy::fine());
    let numerical = SmithMasking::numerical(&ndf, Accuracy::fine());
    let mut worst2: f64 = 0.0;
    for (theta, phi) in [
        (20.0, 10.0),
        (60.0, 45.0),
        (80.0, 100.0),
        (85.0, 0.0),
        (88.0, 0.0),
    ] {
        let w = spherical_direction_deg(theta, phi);
        let (a, b) = (closed.lambda(w), numerical.lambda(w));
        let e = (a - b).abs() / (1.0 + b);
        worst2 = worst2.max(e);
        // The 2-D rule's own error grows towards grazing (5e-4 at 88°).
        assert!(
            e < if theta < 86.0 { 1e-4 } else { 1e-3 },
            "θ {theta} φ {phi}: {a} vs {b}"
        );
    }
    eprintln!("anisotropic γ = 3: worst against the 2-D quadrature {worst2:.1e}");
}

#[test]
fn smith_lambda_is_fast() {
    let m = Microfacet::isotropic(st(3.7), 0.2).unwrap();
    let g = Microfacet::isotropic(Distribution::Ggx, 0.2).unwrap();
    let n = 200_000;
    let time = |m: &Microfacet| {
        let t0 = std::time::Instant::now();
        let mut s = 0.0;
        for k in 0..n {
            s += m.lambda_isotropic(0.02 + 0.98 * (k as f64 + 0.5) / n as f64);
        }
        (t0.elapsed().as_secs_f64() * 1e9 / n as f64, s)
    };
    let (ts, s) = time(&m);
    let (tg, _) = time(&g);
    eprintln!("Λ: student-t {ts:.0} ns, GGX {tg:.0} ns per call ({s})");
    // Generous (shared machines, debug builds): the closed form is not a quadrature.
    assert!(ts < 20_000.0, "{ts} ns");
}

fn sampled() -> Vec<(&'static str, Ndf)> {
    vec![
        (
            "γ 1.6",
            Ndf::Microfacet(Microfacet::new(st(1.6), 0.2, 0.2).unwrap()),
        ),
        (
            "γ 2.5 aniso",
            Ndf::Microfacet(Microfacet::new(st(2.5), 0.1, 0.4).unwrap()),
        ),
        (
            "γ 12",
            Ndf::Microfacet(Microfacet::new(st(12.0), 0.5, 0.5).unwrap()),
        ),
        (
            "mixture",
            Ndf::Mixture(
                Mixture::isotropic(&[
                    (st(3.0), 0.06, 0.5),
                    (Distribution::Ggx, 0.3, 0.3),
                    (Distribution::Beckmann, 0.8, 0.2),
                ])
                .unwrap(),
            ),
        ),
    ]
}

#[test]
fn the_sampler_passes_chi_square_and_a_wrong_gamma_fails() {
    let all = sampled();
    for (name, ndf) in &all {
        ChiSquareTest {
            samples: 400_000,
            tests_run: all.len() + 1,
            ..ChiSquareTest::default()
        }
        .run(|r| Some(ndf.sample(uniform2(r))), |m| ndf.pdf(m))
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    // Samples of γ = 2.2 against the pdf of γ = 2.5: the test must see it.
    let a = Microfacet::new(st(2.2), 0.1, 0.4).unwrap();
    let b = Microfacet::new(st(2.5), 0.1, 0.4).unwrap();
    let r = ChiSquareTest {
        samples: 400_000,
        ..ChiSquareTest::default()
    }
    .run(|r| Some(a.sample(uniform2(r))), |m| b.pdf(m));
    assert!(r.is_err(), "a wrong γ passed");
}

/// The material of the closed-plan test: a Student-t and a GGX lobe.
fn material_toml() -> String {
    common::mirror_mixture_toml(&[
        "{ kind = \"student-t\", gamma = 3.5, alpha = 0.08, weight = 0.6 }",
        "{ kind = \"ggx\", alpha = 0.4, weight = 0.4 }",
    ])
}

#[test]
fn a_student_t_mixture_takes_the_closed_plan() {
    let m = Material::from_toml_str(&material_toml()).unwrap();
    let Ndf::Mixture(mx) = &m.ndf else {
        panic!("not a mixture")
    };
    assert_eq!(mx.lobes()[0].microfacet.distribution, st(3.5));
    let fast = FastBrdf::with_policy(&m, Policy::Accurate);
    assert_eq!(fast.path(), CLOSED_MICROFACET_PATH);
    let ndf = m.ndf.clone();
    let numerical = SmithMasking::numerical(&ndf, Accuracy::fine());
    for (ti, pi, to, po) in [
        (10.0, 0.0, 12.0, 180.0),
        (30.0, 20.0, 25.0, 190.0),
        (60.0, 0.0, 55.0, 180.0),
        (85.0, 0.0, 85.0, 180.0),
    ] {
        let i = spherical_direction_deg(ti, pi);
        let o = spherical_direction_deg(to, po);
        for w in [i, o] {
            let (a, b) = (mx.lambda(w), numerical.lambda(w));
            assert!((a - b).abs() < 1e-6 * (1.0 + b), "{a} vs {b}");
        }
        let want = common::closed_form_brdf(mx, i, o);
        let exact = m.brdf(i, o);
        let fa = fast.eval(i, o);
        for k in 0..3 {
            assert!(
                (exact[k] / want[k] - 1.0).abs() < 1e-9,
                "{exact:?} vs {want:?}"
            );
            assert!((fa[k] / want[k] - 1.0).abs() < 1e-9);
        }
    }
    // The file round-trips with its γ.
    let text =
        meso_core::material::MaterialSpec::parse(&material_toml(), std::path::Path::new("."))
            .unwrap()
            .to_toml();
    assert!(
        text.contains("kind = \"student-t\", gamma = 3.5, alpha = 0.08"),
        "{text}"
    );
    let back = Material::from_toml_str(&text).unwrap();
    assert_eq!(back.ndf, m.ndf);
}

#[test]
fn student_t_toml_errors_are_clear() {
    let ndf = |body: &str| {
        Material::from_toml_str(&format!(
            "form = \"microfacet\"\n[ndf]\n{body}\n[transfer]\nkind = \"mirror\"\n"
        ))
    };
    assert!(ndf("kind = \"student-t\"\ngamma = 2.5\nalpha = 0.1").is_ok());
    assert!(ndf("kind = \"mixture\"\nlobes = [{ kind = \"student-t\", gamma = 1.51, alpha = 0.1, weight = 1 }]").is_ok());
    for (body, needle) in [
        ("kind = \"student-t\"\nalpha = 0.1", "needs `gamma = …` in [1.51, 1000]"),
        ("kind = \"student-t\"\ngamma = 1.5\nalpha = 0.1", "gamma: must be a finite number in [1.51, 1000]"),
        ("kind = \"student-t\"\ngamma = 2000\nalpha = 0.1", "diverges as gamma → 1.5"),
        ("kind = \"student-t\"\ngamma = \"big\"\nalpha = 0.1", "gamma"),
        (
            "kind = \"mixture\"\nlobes = [{ kind = \"student-t\", alpha = 0.1, weight = 1 }]",
            "lobes[1]: a student-t distribution needs `gamma",
        ),
        (
            "kind = \"mixture\"\nlobes = [{ kind = \"student-t\", gamma = 0.9, alpha = 0.1, weight = 1 }]",
            "lobes[1] gamma",
        ),
        (
            "kind = \"mixture\"\nlobes = [{ kind = \"ggx\", gamma = 3, alpha = 0.1, weight = 1 }]",
            "gamma",
        ),
    ] {
        let e = ndf(body).unwrap_err().to_string();
        assert!(e.contains(needle), "{body}: {e}");
    }
    // The microfacet transfer.
    let t = |extra: &str| {
        Material::from_toml_str(&format!(
            "[ndf]\nkind = \"sphere\"\n[transfer]\nkind = \"microfacet\"\ndistribution = \"student-t\"\nalpha = 0.2\n{extra}"
        ))
    };
    assert!(t("gamma = 4").is_ok());
    let e = t("").unwrap_err().to_string();
    assert!(
        e.contains("[transfer]: a student-t distribution needs `gamma"),
        "{e}"
    );
    // The constructor refuses too.
    assert!(Microfacet::isotropic(st(1.5), 0.1).is_err());
    assert!(Microfacet::isotropic(st(f64::NAN), 0.1).is_err());
    let e = Microfacet::isotropic(st(1.2), 0.1).unwrap_err().to_string();
    assert!(e.contains("gamma must be in [1.51, 1000]"), "{e}");
}
