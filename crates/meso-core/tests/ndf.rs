//! Every NDF representation: normalisation (Eq. 1) by independent quadrature, and its sampler
//! against its own pdf by a chi-square test (as Mitsuba 3 tests its BSDFs).

use glam::DVec3;
use meso_core::frame::spherical_direction_deg;
use meso_core::grid::EqualAreaGrid;
use meso_core::ndf::*;
use meso_core::quadrature::{integrate_sphere, SphereQuadrature};
use meso_testkit::{uniform2, ChiSquareTest};

fn peaks() -> Ndf {
    Ndf::PhongPeaks(
        PhongPeaks::new(vec![
            PhongLobe::new(DVec3::Z, 0.6, 40.0),
            PhongLobe::new(spherical_direction_deg(30.0, 90.0), 0.4, 100.0),
        ])
        .unwrap(),
    )
}

fn continuous() -> Vec<(&'static str, Ndf)> {
    let p = peaks();
    vec![
        ("phong-peaks", p.clone()),
        ("sphere", Ndf::Sphere(Sphere)),
        (
            "vmf",
            Ndf::VonMisesFisher(
                VonMisesFisher::new(spherical_direction_deg(20.0, 45.0), 25.0).unwrap(),
            ),
        ),
        (
            "beckmann",
            Ndf::Microfacet(Microfacet::new(Distribution::Beckmann, 0.4, 0.2).unwrap()),
        ),
        (
            "ggx",
            Ndf::Microfacet(Microfacet::new(Distribution::Ggx, 0.3, 0.5).unwrap()),
        ),
        (
            "student-t",
            Ndf::Microfacet(
                Microfacet::new(Distribution::StudentT { gamma: 3.0 }, 0.35, 0.2).unwrap(),
            ),
        ),
        (
            "mixture",
            Ndf::Mixture(
                Mixture::isotropic(&[
                    (Distribution::Ggx, 0.1, 0.6),
                    (Distribution::Beckmann, 0.45, 0.4),
                    (Distribution::StudentT { gamma: 1.8 }, 0.25, 0.2),
                ])
                .unwrap(),
            ),
        ),
        (
            "tabulated",
            Ndf::Tabulated(
                Tabulated::from_fn(EqualAreaGrid::new(64, 128), 3, |m| p.eval(m)).unwrap(),
            ),
        ),
        (
            "harmonics",
            Ndf::Harmonics(Harmonics::project(16, 4, |m| p.eval(m)).unwrap()),
        ),
        ("radial", radial()),
    ]
}

/// A radial table on MERL's half-angle nodes `θ = (k/90)² · 90°`: a GGX-like core of α = 0.2
/// plus a broad tail.
fn radial() -> Ndf {
    let theta: Vec<f64> = (0..=90)
        .map(|k| (f64::from(k) / 90.0).powi(2) * std::f64::consts::FRAC_PI_2)
        .collect();
    let density = theta
        .iter()
        .map(|&t| {
            let (a2, c2) = (0.04, t.cos().powi(2));
            let ggx = a2 / (std::f64::consts::PI * (c2 * (a2 - 1.0) + 1.0).powi(2));
            ggx + 0.05 * t.cos()
        })
        .collect();
    Ndf::Radial(Radial::new(theta, density).unwrap())
}

#[test]
fn every_continuous_representation_integrates_to_one() {
    for (name, ndf) in continuous() {
        let i = if name == "tabulated" {
            // Piecewise constant: the midpoint rule on a grid that refines the table's is exact.
            EqualAreaGrid::new(64 * 3, 128 * 3).integrate(|m| ndf.eval(m))
        } else {
            integrate_sphere(|m| ndf.eval(m), 1000, 2000)
        };
        assert!((i - 1.0).abs() < 1e-3, "{name}: ∫ n dω = {i}");
    }
}

#[test]
fn singular_representations_carry_unit_mass() {
    let d = DeltaSum::new(vec![
        WeightedNormal {
            normal: DVec3::Z,
            weight: 2.0,
        },
        WeightedNormal {
            normal: DVec3::X,
            weight: 6.0,
        },
    ])
    .unwrap();
    let s: f64 = d.normals().iter().map(|n| n.weight).sum();
    assert!((s - 1.0).abs() < 1e-15);
    assert!((d.normals()[1].weight - 0.75).abs() < 1e-15);
    // Cylinder: the NDF's integral against 1 is 1, and its second moments are those of a circle.
    for half in [false, true] {
        let c = Ndf::Cylinder(Cylinder::new(DVec3::X, half).unwrap());
        let st = c.stats();
        assert!((st.integral - 1.0).abs() < 1e-12, "{half}");
        // All normals ⊥ x: ⟨m_x²⟩ = 0.
        assert!(st.covariance.x_axis.x.abs() < 1e-12);
        if half {
            // Mean of cos ψ over [−π/2, π/2] is 2/π.
            assert!((st.mean_normal.z - 2.0 / std::f64::consts::PI).abs() < 1e-9);
        } else {
            assert!(st.mean_normal.length() < 1e-9);
        }
    }
}

#[test]
fn phong_peak_mean_and_stats_match_quadrature() {
    let p = peaks();
    let st = p.stats();
    assert!((st.integral - 1.0).abs() < 1e-5, "{}", st.integral);
    let mz = integrate_sphere(|m| p.eval(m) * m.z, 800, 1600);
    let my = integrate_sphere(|m| p.eval(m) * m.y, 800, 1600);
    assert!((st.mean_normal.z - mz).abs() < 1e-5 && (st.mean_normal.y - my).abs() < 1e-5);
}

#[test]
fn every_sampler_passes_chi_square_against_its_own_pdf() {
    let all = continuous();
    let n = all.len() + 2;
    for (name, ndf) in all
        .iter()
        .filter(|(n, _)| !["tabulated", "harmonics"].contains(n))
    {
        let test = ChiSquareTest {
            samples: 400_000,
            tests_run: n,
            ..ChiSquareTest::default()
        };
        test.run(|r| Some(ndf.sample(uniform2(r))), |m| ndf.pdf(m))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
    // Piecewise-constant samplers (tabulated, and harmonics through its table) are tested on their
    // own grid, where the cell probabilities are exact: counts per cell by χ².
    for (name, ndf) in all
        .iter()
        .filter(|(n, _)| ["tabulated", "harmonics"].contains(n))
    {
        let grid = match ndf {
            Ndf::Tabulated(t) => t.grid(),
            Ndf::Harmonics(h) => h.sampling_table().grid(),
            _ => unreachable!(),
        };
        let fine = EqualAreaGrid::new(grid.n_z * 4, grid.n_phi * 4);
        let mut p = vec![0.0; grid.len()];
        for c in 0..fine.len() {
            let w = fine.cell_center(c);
            p[grid.cell_of(w)] += ndf.pdf(w) * fine.cell_solid_angle();
        }
        let mut rng = meso_testkit::rng(3);
        let ns = 400_000;
        let mut counts = vec![0.0; grid.len()];
        for _ in 0..ns {
            counts[grid.cell_of(ndf.sample(uniform2(&mut rng)))] += 1.0;
        }
        let expected: Vec<f64> = p.iter().map(|p| p * ns as f64).collect();
        let r = meso_testkit::chi2::pearson(&counts, &expected, 5.0)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert!(r.p_value > 0.001 / n as f64, "{name}: {r:?}");
    }
    // The exact samplers' pdf is the NDF itself.
    for (name, ndf) in &all[..3] {
        for k in 0..50 {
            let m = spherical_direction_deg(3.6 * k as f64, 7.3 * k as f64);
            assert_eq!(ndf.pdf(m), ndf.eval(m), "{name}");
        }
    }
}

#[test]
fn a_wrong_sampler_is_rejected() {
    // The harness must be able to fail: sample η = 40 but claim η = 44.
    let a = PhongLobe::new(DVec3::Z, 1.0, 40.0);
    let b = PhongLobe::new(DVec3::Z, 1.0, 44.0);
    let r = ChiSquareTest {
        samples: 400_000,
        ..ChiSquareTest::default()
    }
    .run(|r| Some(a.sample(uniform2(r))), |m| b.unit_density(m));
    assert!(r.is_err());
}

#[test]
fn delta_and_cylinder_samplers_follow_their_weights() {
    let d = DeltaSum::new(vec![
        WeightedNormal {
            normal: DVec3::Z,
            weight: 0.2,
        },
        WeightedNormal {
            normal: DVec3::X,
            weight: 0.5,
        },
        WeightedNormal {
            normal: DVec3::Y,
            weight: 0.3,
        },
    ])
    .unwrap();
    let mut rng = meso_testkit::rng(7);
    let n = 200_000;
    let mut counts = [0usize; 3];
    for _ in 0..n {
        let m = d.sample(uniform2(&mut rng)[0]);
        let k = d.normals().iter().position(|w| w.normal == m).unwrap();
        counts[k] += 1;
    }
    let chi2: f64 = counts
        .iter()
        .zip([0.2, 0.5, 0.3])
        .map(|(&c, p)| (c as f64 - n as f64 * p).powi(2) / (n as f64 * p))
        .sum();
    assert!(
        meso_testkit::gamma::chi_square_sf(chi2, 2) > 0.001,
        "χ² = {chi2}"
    );
    // Cylinder: the angle along the circle is uniform (20-bin χ²) and every sample is ⊥ axis.
    let c = Cylinder::new(spherical_direction_deg(90.0, 30.0), true).unwrap();
    let (e1, e2) = c.circle_basis();
    let mut bins = [0usize; 20];
    for _ in 0..n {
        let m = c.sample(uniform2(&mut rng)[0]);
        assert!(m.dot(c.axis).abs() < 1e-12 && m.z >= -1e-12);
        let psi = m.dot(e2).atan2(m.dot(e1));
        let b = (((psi + 0.5 * std::f64::consts::PI) / std::f64::consts::PI) * 20.0) as usize;
        bins[b.min(19)] += 1;
    }
    let e = n as f64 / 20.0;
    let chi2: f64 = bins.iter().map(|&c| (c as f64 - e).powi(2) / e).sum();
    assert!(
        meso_testkit::gamma::chi_square_sf(chi2, 19) > 0.001,
        "χ² = {chi2}"
    );
}

#[test]
fn sh_truncation_error_falls_with_the_band_for_a_sharp_mixture() {
    // A two-lobe NDF whose second lobe is sharp (η = 400): the SH L2 error must fall with the band.
    let p = peaks();
    let quad = SphereQuadrature::for_band(120);
    let mut last = f64::INFINITY;
    for band in [2, 4, 8, 16, 24] {
        let h = Harmonics::project(band, 4, |m| p.eval(m)).unwrap();
        let e = h.l2_error(|m| p.eval(m), &quad);
        assert!(e < last, "band {band}: {e} ≥ {last}");
        last = e;
    }
    assert!(last < 0.02, "band 24 error {last}");
}

#[test]
fn sampling_is_consistent_with_histogram_tabulation() {
    // Round trip: a histogram of 1e6 samples of the NDF, as a tabulated NDF, approaches the NDF.
    let p = peaks();
    let mut rng = meso_testkit::rng(11);
    let grid = EqualAreaGrid::new(32, 64);
    let t = Tabulated::from_samples(
        grid,
        (0..4_000_000).map(|_| (p.sample(uniform2(&mut rng)), 1.0)),
    )
    .unwrap();
    let exact = Tabulated::from_fn(grid, 4, |m| p.eval(m)).unwrap();
    let l1: f64 = t
        .values()
        .iter()
        .zip(exact.values())
        .map(|(a, b)| (a - b).abs())
        .sum::<f64>()
        * grid.cell_solid_angle();
    // Sampling noise alone gives an L1 distance of about Σ √(2 p_c/(π N)) ≈ 0.009 here.
    assert!(l1 < 0.012, "L1 distance {l1}");
}
