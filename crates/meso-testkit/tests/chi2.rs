//! Tests of the chi-square harness itself: correct samplers pass, wrong ones are rejected.

use glam::DVec3;
use meso_core::ndf::PhongLobe;
use meso_testkit::{reference, uniform2, ChiSquareTest};
use std::f64::consts::PI;

fn default_test() -> ChiSquareTest {
    ChiSquareTest::default()
}

#[test]
fn uniform_sphere_passes() {
    let r = default_test()
        .run(
            |rng| Some(reference::uniform_sphere(uniform2(rng))),
            reference::uniform_sphere_pdf,
        )
        .unwrap();
    eprintln!("uniform sphere: {r}");
    assert!((r.pdf_integral - 1.0).abs() < 1e-12);
    // Only the ring of cells at each pole expects fewer than 5 samples (≈ 2.4).
    assert_eq!(r.pooled_cells, 2 * 160);
    assert_eq!(r.dof, 78 * 160, "78 rows of cells and the pool, minus 1");
}

#[test]
fn cosine_hemisphere_passes() {
    let r = default_test()
        .run(
            |rng| Some(reference::cosine_hemisphere(uniform2(rng))),
            reference::cosine_hemisphere_pdf,
        )
        .unwrap();
    eprintln!("cosine hemisphere: {r}");
    assert!((r.pdf_integral - 1.0).abs() < 1e-12);
    // The lower hemisphere is empty (no category); every upper cell expects ≥ 5 samples.
    assert_eq!(r.dof, 40 * 160 - 1);
}

#[test]
fn phong_lobes_pass() {
    for (axis, eta) in [
        (DVec3::new(0.3, -0.2, 0.9), 10.0),
        (DVec3::Z, 100.0),
        (DVec3::new(-0.5, 0.4, 0.2), 2000.0),
    ] {
        let lobe = PhongLobe::new(axis, 1.0, eta);
        let r = default_test()
            .run(
                |rng| Some(lobe.sample(uniform2(rng))),
                |d| lobe.unit_density(d),
            )
            .unwrap_or_else(|e| panic!("η = {eta}: {e}"));
        eprintln!("Phong η = {eta}: {r}");
        assert!((r.pdf_integral - 1.0).abs() < 1e-6);
    }
}

#[test]
fn cosine_samples_against_uniform_hemisphere_pdf_are_rejected() {
    let r = default_test().run_report(
        |rng| Some(reference::cosine_hemisphere(uniform2(rng))),
        reference::uniform_hemisphere_pdf,
    );
    eprintln!("cosine vs uniform hemisphere: {r}");
    assert!(!r.passed());
    assert!(r.p_value < 1e-100, "gross mismatch: p = {}", r.p_value);
    assert!(
        (r.pdf_integral - 1.0).abs() < 1e-12,
        "the pdf itself is fine"
    );
}

#[test]
fn phong_exponent_mismatch_is_rejected() {
    let axis = DVec3::new(0.3, -0.2, 0.9);
    let sampled = PhongLobe::new(axis, 1.0, 10.0);
    let claimed = PhongLobe::new(axis, 1.0, 12.0);
    let r = default_test().run_report(
        |rng| Some(sampled.sample(uniform2(rng))),
        |d| claimed.unit_density(d),
    );
    eprintln!("Phong 10 vs 12: {r}");
    assert!(!r.passed());
    assert!(r.failure.as_deref().unwrap().contains("p-value"));
    // A subtler mismatch (5 % in the exponent) is still rejected at 10⁶ samples.
    let claimed = PhongLobe::new(axis, 1.0, 10.5);
    let r = default_test().run_report(
        |rng| Some(sampled.sample(uniform2(rng))),
        |d| claimed.unit_density(d),
    );
    eprintln!("Phong 10 vs 10.5: {r}");
    assert!(!r.passed());
}

#[test]
fn mismatched_axis_is_rejected() {
    // The sampler's frame is rotated by 1° about +z relative to the pdf's.
    let lobe = PhongLobe::new(DVec3::new(0.6, 0.0, 0.8), 1.0, 200.0);
    let rot = glam::DQuat::from_rotation_z(1f64.to_radians());
    let r = default_test().run_report(
        |rng| Some(rot * lobe.sample(uniform2(rng))),
        |d| lobe.unit_density(d),
    );
    eprintln!("Phong rotated 1°: {r}");
    assert!(!r.passed());
}

#[test]
fn samples_where_the_pdf_is_zero_fail_at_once() {
    let r = default_test().run_report(
        |rng| Some(reference::uniform_sphere(uniform2(rng))),
        reference::uniform_hemisphere_pdf,
    );
    let why = r.failure.unwrap();
    assert!(why.contains("integrates to 0"), "{why}");
}

#[test]
fn unnormalised_pdf_fails_and_reports_its_integral() {
    let r = default_test().run_report(
        |rng| Some(reference::uniform_sphere(uniform2(rng))),
        |_| 0.5 / PI,
    );
    assert!((r.pdf_integral - 2.0).abs() < 1e-12);
    assert!(r.failure.unwrap().contains("integrates to 2.0"));
}

#[test]
fn non_unit_samples_fail() {
    let r = default_test().run_report(
        |_| Some(DVec3::new(1.0, 1.0, 0.0)),
        reference::uniform_sphere_pdf,
    );
    assert!(r.failure.unwrap().contains("not a unit vector"));
}

#[test]
fn defective_samplers() {
    // Uniform sphere with the lower half absorbed: the pdf is 1/(4π) on z > 0 only (mass ½).
    let sample = |rng: &mut meso_testkit::Rng| {
        let d = reference::uniform_sphere(uniform2(rng));
        (d.z > 0.0).then_some(d)
    };
    let half = |d: DVec3| if d.z > 0.0 { 0.25 / PI } else { 0.0 };
    let test = ChiSquareTest {
        normalization_tolerance: None,
        ..default_test()
    };
    let r = test.run(sample, half).unwrap();
    assert!((r.pdf_integral - 0.5).abs() < 1e-12);
    assert!((r.none_samples as f64 / r.samples as f64 - 0.5).abs() < 0.01);
    // Claiming mass 0.6 on the upper half does not match the 50 % `None` rate.
    let r = test.run_report(sample, |d| half(d) * 1.2);
    assert!(!r.passed(), "{r}");
    // A sampler that loses samples while its pdf claims all the mass.
    let r = test.run_report(sample, |d| 2.0 * half(d));
    assert!(r.failure.unwrap().contains("returned None 50"));
}

#[test]
fn p_values_are_calibrated_under_the_null() {
    // 60 independent runs of a correct sampler on a coarse grid: the p-values should look
    // uniform on [0, 1] (a wrong dof or a biased statistic skews them).
    let mut p = Vec::new();
    for seed in 0..60 {
        let test = ChiSquareTest {
            n_theta: 10,
            n_phi: 20,
            samples: 20_000,
            seed,
            ..default_test()
        };
        let r = test.run_report(
            |rng| Some(reference::cosine_hemisphere(uniform2(rng))),
            reference::cosine_hemisphere_pdf,
        );
        p.push(r.p_value);
    }
    let mean = p.iter().sum::<f64>() / p.len() as f64;
    let below_01 = p.iter().filter(|&&v| v < 0.1).count();
    eprintln!("null p-values: mean {mean:.3}, {below_01} of 60 below 0.1");
    assert!((0.38..0.62).contains(&mean), "mean p {mean}");
    assert!(below_01 <= 14, "{below_01} of 60 below 0.1");
    // Kolmogorov–Smirnov distance to U(0, 1); the 1 % critical value for n = 60 is 0.21.
    p.sort_by(f64::total_cmp);
    let ks = p
        .iter()
        .enumerate()
        .map(|(k, &v)| ((k + 1) as f64 / 60.0 - v).max(v - k as f64 / 60.0))
        .fold(0.0, f64::max);
    assert!(ks < 0.21, "KS distance {ks}");
}

#[test]
fn sidak_threshold() {
    let t = ChiSquareTest {
        tests_run: 10,
        ..default_test()
    };
    let expect = 1.0 - 0.99f64.powf(0.1);
    assert!((t.threshold() - expect).abs() < 1e-15);
    assert!((default_test().threshold() - 0.01).abs() < 1e-15);
}
