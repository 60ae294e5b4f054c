//! Real spherical harmonics: evaluation, projection and reconstruction.
//!
//! # Definition
//! The orthonormal real basis `Y_lm`, `l ≥ 0`, `−l ≤ m ≤ l`, with `∫_{S²} Y_lm Y_l'm' dω = δ_ll' δ_mm'`:
//!
//! ```text
//! Y_lm = √2 K_l|m| P_l^|m|(cos θ) cos(mφ)      m > 0
//! Y_l0 =    K_l0   P_l(cos θ)
//! Y_lm = √2 K_l|m| P_l^|m|(cos θ) sin(|m|φ)    m < 0
//! K_lm = √((2l+1)/(4π) · (l−m)!/(l+m)!)
//! ```
//!
//! with **no Condon–Shortley phase**, so that band 1 is `√(3/4π)·(y, z, x)` for `m = −1, 0, 1`
//! (the convention of Sloan's "Stupid SH tricks" up to sign, and of most graphics code). Angles
//! follow [`crate::frame`]: θ from +z, φ from +x towards +y.
//!
//! Coefficients are stored flat at index `l² + l + m` ([`sh_index`]); a band-limited expansion up to
//! `lmax` has [`sh_count`]`(lmax) = (lmax+1)²` coefficients.
//!
//! # Evaluation
//! [`sh_eval`] never calls a trigonometric function: `sin^m θ cos mφ` and `sin^m θ sin mφ` are the
//! real and imaginary parts of `(x + iy)^m`, built by complex multiplication, and the remaining
//! factor `K_lm P_l^m(z) / sin^m θ` (a polynomial in `z`) comes from the fully normalised
//! associated-Legendre recurrences
//!
//! ```text
//! Q_mm     = √((2m+1)/(2m)) · Q_{m−1,m−1},            Q_00 = 1/√(4π)
//! Q_{m+1,m} = √(2m+3) · z · Q_mm
//! Q_lm     = a_lm (z Q_{l−1,m} − b_lm Q_{l−2,m}),     a_lm = √((4l²−1)/(l²−m²)),
//!                                                   b_lm = √(((l−1)²−m²)/(4(l−1)²−1))
//! ```
//!
//! which are stable in `z ∈ [−1, 1]` and never form a factorial. Any `lmax` works; the tests check
//! orthonormality to `1e-10` up to `lmax = 32` and the addition theorem up to `l = 64`.
//!
//! # Projection
//! [`sh_project`] integrates `f · Y_lm` with a [`SphereQuadrature`] (Gauss–Legendre in `cos θ` ×
//! uniform φ), which is exact when `f` is itself band-limited and the rule is fine enough.
//!
//! ```
//! use meso_core::sh::{sh_project, sh_reconstruct};
//! use glam::DVec3;
//! // A band-2 function is recovered exactly from its band-2 projection.
//! let f = |w: DVec3| 1.0 + w.x * w.y - 0.5 * w.z;
//! let c = sh_project(2, f, 2);
//! let d = DVec3::new(0.3, -0.4, 0.5).normalize();
//! assert!((sh_reconstruct(&c, 2, d) - f(d)).abs() < 1e-12);
//! ```

use crate::quadrature::SphereQuadrature;
use glam::DVec3;

/// The number of coefficients of an expansion up to band `lmax` inclusive: `(lmax + 1)²`.
#[inline]
#[must_use]
pub const fn sh_count(lmax: usize) -> usize {
    (lmax + 1) * (lmax + 1)
}

/// The flat index `l² + l + m` of `Y_lm`.
///
/// # Panics
/// In debug builds, when `|m| > l`.
#[inline]
#[must_use]
pub fn sh_index(l: usize, m: i64) -> usize {
    debug_assert!(m.unsigned_abs() as usize <= l, "|m| > l");
    (l * l + l).wrapping_add_signed(m as isize)
}

/// The band `l` and order `m` of the flat index `i` (inverse of [`sh_index`]).
#[must_use]
pub fn sh_lm(i: usize) -> (usize, i64) {
    let mut l = (i as f64).sqrt() as usize;
    // Guard against rounding of the square root.
    while l * l > i {
        l -= 1;
    }
    while (l + 1) * (l + 1) <= i {
        l += 1;
    }
    (l, i as i64 - (l * l + l) as i64)
}

/// Evaluate every `Y_lm(dir)`, `l ≤ lmax`, into `out[sh_index(l, m)]`. No allocation.
///
/// `dir` must be a unit vector (it is not normalised here; a non-unit vector evaluates the
/// homogeneous polynomials `r^l Y_lm`, which is occasionally useful but rarely intended).
///
/// # Panics
/// When `out.len() < sh_count(lmax)`.
pub fn sh_eval(lmax: usize, dir: DVec3, out: &mut [f64]) {
    assert!(
        out.len() >= sh_count(lmax),
        "sh_eval: output has {} slots, band {lmax} needs {}",
        out.len(),
        sh_count(lmax)
    );
    sh_visit(lmax, dir, |i, y| out[i] = y);
}

/// Call `sink(sh_index(l, m), Y_lm(dir))` for every `l ≤ lmax` (in an unspecified order).
/// The allocation-free kernel behind [`sh_eval`] and [`sh_reconstruct`].
#[inline]
pub fn sh_visit(lmax: usize, dir: DVec3, mut sink: impl FnMut(usize, f64)) {
    let (x, y, z) = (dir.x, dir.y, dir.z);
    const INV_SQRT_4PI: f64 = 0.282_094_791_773_878_14; // 1/√(4π)
    const SQRT2: f64 = std::f64::consts::SQRT_2;

    // c + i s = (x + i y)^m = sin^m θ · e^{imφ}
    let (mut c, mut s) = (1.0f64, 0.0f64);
    // Q_mm (diagonal of the normalised Legendre table, sin^m θ factored out).
    let mut q_mm = INV_SQRT_4PI;
    for m in 0..=lmax {
        if m > 0 {
            let c_next = x * c - y * s;
            s = x * s + y * c;
            c = c_next;
            let mf = m as f64;
            q_mm *= ((2.0 * mf + 1.0) / (2.0 * mf)).sqrt();
        }
        let (cm, sm) = (SQRT2 * c, SQRT2 * s);
        let mut put = |l: usize, q: f64| {
            let base = l * l + l;
            if m == 0 {
                sink(base, q);
            } else {
                sink(base + m, q * cm);
                sink(base - m, q * sm);
            }
        };
        put(m, q_mm);
        if m == lmax {
            break;
        }
        let mf = m as f64;
        let mut q_prev = q_mm; // Q_{l-2,m}
        let mut q = (2.0 * mf + 3.0).sqrt() * z * q_mm; // Q_{m+1,m}
        put(m + 1, q);
        for l in (m + 2)..=lmax {
            let lf = l as f64;
            let l1 = lf - 1.0;
            let a = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
            let b = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt();
            let q_next = a * (z * q - b * q_prev);
            q_prev = q;
            q = q_next;
            put(l, q);
        }
    }
}

/// `Σ_{l ≤ lmax} Σ_m c_lm Y_lm(dir)`: the value of an expansion at the unit direction `dir`.
/// No allocation.
///
/// # Panics
/// When `coeffs.len() < sh_count(lmax)`.
#[must_use]
pub fn sh_reconstruct(coeffs: &[f64], lmax: usize, dir: DVec3) -> f64 {
    assert!(
        coeffs.len() >= sh_count(lmax),
        "sh_reconstruct: {} coefficients, band {lmax} needs {}",
        coeffs.len(),
        sh_count(lmax)
    );
    let mut acc = 0.0;
    sh_visit(lmax, dir, |i, y| acc += coeffs[i] * y);
    acc
}

/// The coefficients `c_lm = ∫ f Y_lm dω`, `l ≤ lmax`, by the product quadrature
/// [`SphereQuadrature::for_band`]`(max(quad_order, lmax))`, i.e. `quad_order + 1` Gauss–Legendre
/// nodes in `cos θ` × `2·quad_order + 1` azimuths.
///
/// The result is exact when `f` is band-limited to `L` and `L + lmax ≤ 2·quad_order`. For other
/// functions raise `quad_order` until the coefficients stop changing; the evaluation count is
/// about `2·quad_order²`.
#[must_use]
pub fn sh_project(lmax: usize, f: impl Fn(DVec3) -> f64, quad_order: usize) -> Vec<f64> {
    let quad = SphereQuadrature::for_band(quad_order.max(lmax));
    sh_project_with(lmax, f, &quad)
}

/// Like [`sh_project`], with a caller-supplied quadrature (reuse it across many projections).
#[must_use]
pub fn sh_project_with(lmax: usize, f: impl Fn(DVec3) -> f64, quad: &SphereQuadrature) -> Vec<f64> {
    let n = sh_count(lmax);
    let mut coeffs = vec![0.0; n];
    let mut basis = vec![0.0; n];
    for (&p, &w) in quad.points.iter().zip(&quad.weights) {
        let fw = f(p) * w;
        if fw == 0.0 {
            continue;
        }
        sh_eval(lmax, p, &mut basis);
        for (c, y) in coeffs.iter_mut().zip(&basis) {
            *c += fw * y;
        }
    }
    coeffs
}

/// The energy of each band, `E_l = Σ_m c_lm²` (rotation invariant), `l ≤ lmax`.
///
/// # Panics
/// When `coeffs.len() < sh_count(lmax)`.
#[must_use]
pub fn sh_band_energy(coeffs: &[f64], lmax: usize) -> Vec<f64> {
    assert!(coeffs.len() >= sh_count(lmax));
    (0..=lmax)
        .map(|l| coeffs[l * l..(l + 1) * (l + 1)].iter().map(|c| c * c).sum())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadrature::legendre;
    use std::f64::consts::PI;

    /// Deterministic quasi-random unit directions (golden-ratio spiral, jittered off the axes).
    fn directions(n: usize) -> Vec<DVec3> {
        let ga = PI * (3.0 - 5f64.sqrt());
        (0..n)
            .map(|k| {
                let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
                let r = (1.0 - z * z).sqrt();
                let phi = ga * k as f64 + 0.1;
                DVec3::new(r * phi.cos(), r * phi.sin(), z)
            })
            .collect()
    }

    #[test]
    fn indexing_round_trips() {
        assert_eq!(sh_count(0), 1);
        assert_eq!(sh_count(32), 1089);
        for l in 0..40usize {
            for m in -(l as i64)..=(l as i64) {
                let i = sh_index(l, m);
                assert_eq!(sh_lm(i), (l, m));
            }
        }
        assert_eq!(sh_index(1, -1), 1);
        assert_eq!(sh_index(1, 1), 3);
    }

    fn gram_error(lmax: usize) -> f64 {
        let quad = SphereQuadrature::for_band(lmax);
        let n = sh_count(lmax);
        let mut gram = vec![0.0; n * n];
        let mut y = vec![0.0; n];
        for (&p, &w) in quad.points.iter().zip(&quad.weights) {
            sh_eval(lmax, p, &mut y);
            for a in 0..n {
                let wa = w * y[a];
                let row = &mut gram[a * n..(a + 1) * n];
                for b in a..n {
                    row[b] += wa * y[b];
                }
            }
        }
        let mut worst = 0.0f64;
        for a in 0..n {
            for b in a..n {
                let target = if a == b { 1.0 } else { 0.0 };
                worst = worst.max((gram[a * n + b] - target).abs());
            }
        }
        worst
    }

    #[test]
    fn orthonormal_by_exact_quadrature() {
        for lmax in [0, 1, 2, 5, 16] {
            let e = gram_error(lmax);
            assert!(e < 1e-10, "lmax {lmax}: Gram matrix off identity by {e}");
        }
    }

    #[test]
    fn orthonormal_at_band_32() {
        let e = gram_error(32);
        assert!(e < 1e-10, "lmax 32: Gram matrix off identity by {e}");
    }

    #[test]
    fn quadrature_too_coarse_is_detected() {
        // Guard for the test above: a rule one node short in θ must break orthonormality of
        // the top band (∫ Y_l0² has degree 2l).
        let lmax = 8;
        let quad = SphereQuadrature::new(lmax, 2 * lmax + 1);
        let mut y = vec![0.0; sh_count(lmax)];
        let i = sh_index(lmax, 0);
        let q: f64 = quad
            .points
            .iter()
            .zip(&quad.weights)
            .map(|(&p, &w)| {
                sh_eval(lmax, p, &mut y);
                w * y[i] * y[i]
            })
            .sum();
        assert!((q - 1.0).abs() > 1e-3, "{q}");
    }

    #[test]
    fn first_bands_match_closed_forms() {
        let k0 = 0.5 / PI.sqrt();
        let k1 = (3.0 / (4.0 * PI)).sqrt();
        let k2a = 0.5 * (15.0 / PI).sqrt();
        let k2b = 0.25 * (5.0 / PI).sqrt();
        let k2c = 0.25 * (15.0 / PI).sqrt();
        let mut y = vec![0.0; sh_count(2)];
        for d in directions(200)
            .into_iter()
            .chain([DVec3::Z, -DVec3::Z, DVec3::X, DVec3::Y])
        {
            sh_eval(2, d, &mut y);
            let (x, yy, z) = (d.x, d.y, d.z);
            let expect = [
                k0,
                k1 * yy,
                k1 * z,
                k1 * x,
                k2a * x * yy,
                k2a * yy * z,
                k2b * (3.0 * z * z - 1.0),
                k2a * x * z,
                k2c * (x * x - yy * yy),
            ];
            for (i, (&a, &b)) in y.iter().zip(&expect).enumerate() {
                assert!((a - b).abs() < 1e-14, "index {i} at {d}: {a} vs {b}");
            }
        }
    }

    #[test]
    fn band_3_matches_closed_forms() {
        // Real SH, band 3 (no Condon–Shortley phase), from the Cartesian table.
        let mut y = vec![0.0; sh_count(3)];
        for d in directions(50) {
            sh_eval(3, d, &mut y);
            let (x, yy, z) = (d.x, d.y, d.z);
            let expect = [
                0.25 * (35.0 / (2.0 * PI)).sqrt() * yy * (3.0 * x * x - yy * yy),
                0.5 * (105.0 / PI).sqrt() * x * yy * z,
                0.25 * (21.0 / (2.0 * PI)).sqrt() * yy * (5.0 * z * z - 1.0),
                0.25 * (7.0 / PI).sqrt() * z * (5.0 * z * z - 3.0),
                0.25 * (21.0 / (2.0 * PI)).sqrt() * x * (5.0 * z * z - 1.0),
                0.25 * (105.0 / PI).sqrt() * z * (x * x - yy * yy),
                0.25 * (35.0 / (2.0 * PI)).sqrt() * x * (x * x - 3.0 * yy * yy),
            ];
            for (m, &e) in expect.iter().enumerate() {
                let a = y[9 + m];
                assert!(
                    (a - e).abs() < 1e-13,
                    "Y_3,{} at {d}: {a} vs {e}",
                    m as i64 - 3
                );
            }
        }
    }

    #[test]
    fn addition_theorem() {
        // Σ_m Y_lm(a) Y_lm(b) = (2l+1)/(4π) P_l(a·b).
        let lmax = 64;
        let dirs = directions(40);
        let mut ya = vec![0.0; sh_count(lmax)];
        let mut yb = vec![0.0; sh_count(lmax)];
        for (k, &a) in dirs.iter().enumerate() {
            let b = dirs[(k * 7 + 3) % dirs.len()];
            sh_eval(lmax, a, &mut ya);
            sh_eval(lmax, b, &mut yb);
            for l in 0..=lmax {
                let r = l * l..(l + 1) * (l + 1);
                let s: f64 = ya[r.clone()].iter().zip(&yb[r]).map(|(p, q)| p * q).sum();
                let expect = (2 * l + 1) as f64 / (4.0 * PI) * legendre(l, a.dot(b)).0;
                let scale = (2 * l + 1) as f64 / (4.0 * PI);
                assert!(
                    (s - expect).abs() < 1e-12 * scale,
                    "l {l}: {s} vs {expect} (a·b = {})",
                    a.dot(b)
                );
            }
        }
        // a = b: Σ_m Y_lm² = (2l+1)/(4π) — including the poles, where sin θ = 0.
        for d in [DVec3::Z, -DVec3::Z, DVec3::X] {
            sh_eval(lmax, d, &mut ya);
            for l in 0..=lmax {
                let s: f64 = ya[l * l..(l + 1) * (l + 1)].iter().map(|v| v * v).sum();
                let expect = (2 * l + 1) as f64 / (4.0 * PI);
                assert!((s / expect - 1.0).abs() < 1e-12, "l {l} at {d}");
            }
        }
    }

    #[test]
    fn band_limited_projection_is_exact() {
        // Pseudo-random coefficients up to band 8; project at bands 8 and 12.
        let lf = 8;
        let truth: Vec<f64> = (0..sh_count(lf))
            .map(|i| ((i as f64 * 12.9898).sin() * 43758.5453).fract() - 0.5)
            .collect();
        let f = |d: DVec3| sh_reconstruct(&truth, lf, d);
        let c = sh_project(lf, f, lf);
        for (i, (a, b)) in c.iter().zip(&truth).enumerate() {
            assert!((a - b).abs() < 1e-12, "coefficient {i}: {a} vs {b}");
        }
        // Higher bands of a band-8 function vanish (the quadrature must cover 8 + 12 = 20).
        let c = sh_project(12, f, 10);
        for (i, v) in c.iter().enumerate() {
            let expect = truth.get(i).copied().unwrap_or(0.0);
            assert!(
                (v - expect).abs() < 1e-12,
                "coefficient {i}: {v} vs {expect}"
            );
        }
        for d in directions(100) {
            assert!((sh_reconstruct(&c, 12, d) - f(d)).abs() < 1e-12);
        }
    }

    /// The normalised Phong peak of Eq. 12: `(η+2)/(8π) ((1 + a·ω)/2)^(η/2)`.
    fn phong(axis: DVec3, eta: f64) -> impl Fn(DVec3) -> f64 {
        move |w: DVec3| {
            (eta + 2.0) / (8.0 * PI) * (0.5 * (1.0 + axis.dot(w))).max(0.0).powf(0.5 * eta)
        }
    }

    /// `∫ f² dω` of the normalised Phong peak: `(η+2)² / (16π (η+1))`.
    fn phong_norm2(eta: f64) -> f64 {
        (eta + 2.0) * (eta + 2.0) / (16.0 * PI * (eta + 1.0))
    }

    /// Relative L2 truncation error `‖f − f_L‖ / ‖f‖` of the band-`lmax` projection, with the
    /// coefficients and the residual both integrated by a rule exact to degree 128.
    fn truncation_error(f: &impl Fn(DVec3) -> f64, lmax: usize) -> f64 {
        let quad = SphereQuadrature::for_band(64);
        let c = sh_project_with(lmax, f, &quad);
        let resid = quad.integrate(|w| (f(w) - sh_reconstruct(&c, lmax, w)).powi(2));
        let norm = quad.integrate(|w| f(w).powi(2));
        (resid / norm).sqrt()
    }

    #[test]
    fn peaked_functions_truncation_error_falls_with_band() {
        let axis = DVec3::new(0.3, -0.5, 0.8).normalize();
        let kappa = 20.0f64;
        let lobe = crate::sg::Sg::normalised(axis, kappa);
        let vmf = move |w: DVec3| lobe.eval(w);
        let bands = [2, 4, 8, 16];
        // (name, f, bound on the band-16 error). Measured band-2/4/8/16 relative L2 errors:
        //   Phong η=20:   4.2e-1, 8.4e-2, 1.1e-4, 2e-15  (((1+u)/2)^10 is a degree-10 polynomial)
        //   Phong η=21.5: 4.5e-1, 1.0e-1, 2.6e-4, 1.5e-13 (C^10 at the antipode, fast decay)
        //   vMF κ=20:     7.9e-1, 5.3e-1, 1.3e-1, 9.1e-4 (analytic but sharper)
        type Lobe = Box<dyn Fn(DVec3) -> f64>;
        let cases: [(&str, Lobe, f64); 3] = [
            ("phong 20", Box::new(phong(axis, 20.0)), 1e-12),
            ("phong 21.5", Box::new(phong(axis, 21.5)), 1e-11),
            ("vMF 20", Box::new(vmf), 1.5e-3),
        ];
        for (name, f, bound) in &cases {
            let errs: Vec<f64> = bands.iter().map(|&l| truncation_error(f, l)).collect();
            for w in errs.windows(2) {
                assert!(
                    w[1] < 0.75 * w[0],
                    "{name}: error must fall with the band: {errs:?}"
                );
            }
            assert!(
                errs[0] > 0.3,
                "{name}: band 2 cannot represent a peak: {errs:?}"
            );
            assert!(errs[3] < *bound, "{name}: band-16 error {errs:?}");
        }
        // η = 20 is band-limited to exactly l = 10.
        let f = phong(axis, 20.0);
        assert!(truncation_error(&f, 9) > 1e-6);
        assert!(truncation_error(&f, 10) < 1e-12);
        // The quadrature reproduces ‖f‖² of the Phong peak in closed form.
        let quad = SphereQuadrature::for_band(64);
        let n2 = quad.integrate(|w| phong(axis, 21.5)(w).powi(2));
        assert!((n2 / phong_norm2(21.5) - 1.0).abs() < 1e-12);
        // The DC term is exactly 1/(2√π) for any normalised density (∫ f Y_00 = Y_00).
        let c = sh_project(0, phong(axis, 20.0), 64);
        assert!((c[0] - 0.5 / PI.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn band_energy_is_rotation_invariant() {
        // Axis on +z: only m = 0 survives (zonal); a tilted axis spreads each band over all m
        // but keeps the band energy.
        let eta = 20.0;
        let lmax = 16;
        let cz = sh_project(lmax, phong(DVec3::Z, eta), 48);
        for l in 0..=lmax {
            for m in -(l as i64)..=(l as i64) {
                if m != 0 {
                    assert!(cz[sh_index(l, m)].abs() < 1e-13);
                }
            }
        }
        let axis = DVec3::new(-0.6, 0.2, 0.3).normalize();
        let ct = sh_project(lmax, phong(axis, eta), 48);
        let ez = sh_band_energy(&cz, lmax);
        let et = sh_band_energy(&ct, lmax);
        for l in 0..=lmax {
            assert!(
                (ez[l] - et[l]).abs() < 1e-12 * ez[0].max(1.0),
                "band {l}: {} vs {}",
                ez[l],
                et[l]
            );
        }
        // Zonal coefficients: c_l0 = √((2l+1)/(4π)) · 2π ∫ f(u) P_l(u) du.
        let (u, w) = crate::quadrature::gauss_legendre(64);
        for l in 0..=lmax {
            let g: f64 = u
                .iter()
                .zip(&w)
                .map(|(&u, &w)| {
                    w * phong(DVec3::Z, eta)(DVec3::new((1.0 - u * u).sqrt(), 0.0, u))
                        * legendre(l, u).0
                })
                .sum();
            let expect = ((2 * l + 1) as f64 / (4.0 * PI)).sqrt() * 2.0 * PI * g;
            assert!((cz[sh_index(l, 0)] - expect).abs() < 1e-12, "l {l}");
        }
    }
}
