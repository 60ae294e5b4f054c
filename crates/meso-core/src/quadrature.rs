//! Numerical quadrature: Gauss–Legendre nodes and weights, and product rules on the sphere.
//!
//! * [`gauss_legendre`] — the `n`-point Gauss–Legendre rule on `[-1, 1]`, exact for polynomials of
//!   degree `≤ 2n − 1`, computed by Newton iteration on the Legendre polynomial `P_n`.
//! * [`SphereQuadrature`] — Gauss–Legendre in `z = cos θ` × the uniform (trapezoid) rule in φ.
//!   With `n_theta` nodes in `z` and `n_phi` points in φ it integrates exactly every spherical
//!   polynomial of degree `≤ min(2·n_theta − 1, n_phi − 1)`; [`SphereQuadrature::for_band`] picks
//!   the smallest such rule for products of two functions band-limited to `l ≤ lmax`.
//! * [`integrate_sphere`] — the same rule applied once to a closure.
//!
//! The solid-angle element is `dω = dz dφ`, so no Jacobian appears in the weights
//! (conventions in [`crate::frame`]).

use glam::DVec3;
use std::f64::consts::PI;

/// The Legendre polynomial `P_n(x)` and its derivative `P_n'(x)`, by the three-term recurrence
/// `(k+1) P_{k+1} = (2k+1) x P_k − k P_{k−1}`.
///
/// The derivative uses `(x² − 1) P_n' = n (x P_n − P_{n−1})`, which is singular at `x = ±1`; there
/// the exact value `P_n'(±1) = (±1)^{n−1} n(n+1)/2` is returned instead.
#[must_use]
pub fn legendre(n: usize, x: f64) -> (f64, f64) {
    if n == 0 {
        return (1.0, 0.0);
    }
    let (mut p_prev, mut p) = (1.0, x);
    for k in 1..n {
        let kf = k as f64;
        let p_next = ((2.0 * kf + 1.0) * x * p - kf * p_prev) / (kf + 1.0);
        p_prev = p;
        p = p_next;
    }
    let nf = n as f64;
    let denom = x * x - 1.0;
    let dp = if denom.abs() < 1e-300 {
        let s = if x > 0.0 || n % 2 == 1 { 1.0 } else { -1.0 };
        s * nf * (nf + 1.0) / 2.0
    } else {
        nf * (x * p - p_prev) / denom
    };
    (p, dp)
}

/// The `n`-point Gauss–Legendre rule on `[-1, 1]`: `(nodes, weights)`, nodes in ascending order.
///
/// `Σ w_k p(x_k) = ∫_{-1}^{1} p(x) dx` exactly for every polynomial of degree `≤ 2n − 1`.
/// Nodes are the roots of `P_n`, found by Newton iteration from the asymptotic guess
/// `cos(π (k + 3/4) / (n + 1/2))`; weights are `2 / ((1 − x²) P_n'(x)²)`. Symmetry is enforced
/// (`x_{n−1−k} = −x_k`). `n = 0` gives empty vectors.
#[must_use]
pub fn gauss_legendre(n: usize) -> (Vec<f64>, Vec<f64>) {
    let mut nodes = vec![0.0; n];
    let mut weights = vec![0.0; n];
    let nf = n as f64;
    // Roots come in ± pairs; compute the positive half (k < ceil(n/2)), largest root first.
    for k in 0..n.div_ceil(2) {
        let mut x = (PI * (k as f64 + 0.75) / (nf + 0.5)).cos();
        let mut dp = 0.0;
        for _ in 0..100 {
            let (p, d) = legendre(n, x);
            dp = d;
            let dx = p / d;
            x -= dx;
            if dx.abs() <= 1e-16 * x.abs().max(1.0) {
                break;
            }
        }
        // One more derivative evaluation at the converged root for the weight.
        let (_, d) = legendre(n, x);
        if d.is_finite() && d != 0.0 {
            dp = d;
        }
        let w = 2.0 / ((1.0 - x * x) * dp * dp);
        // Ascending order: the k-th largest root goes to index n-1-k, its mirror to index k.
        nodes[n - 1 - k] = x;
        nodes[k] = -x;
        weights[n - 1 - k] = w;
        weights[k] = w;
    }
    if n % 2 == 1 {
        nodes[n / 2] = 0.0;
    }
    (nodes, weights)
}

/// The `n`-point Gauss–Legendre rule mapped to `[a, b]`: `(nodes, weights)`.
#[must_use]
pub fn gauss_legendre_interval(n: usize, a: f64, b: f64) -> (Vec<f64>, Vec<f64>) {
    let (x, w) = gauss_legendre(n);
    let half = 0.5 * (b - a);
    let mid = 0.5 * (a + b);
    (
        x.iter().map(|&x| mid + half * x).collect(),
        w.iter().map(|&w| half * w).collect(),
    )
}

/// A product quadrature on the unit sphere: Gauss–Legendre in `z = cos θ` × uniform φ.
///
/// φ samples are at `φ_j = 2π (j + ½) / n_phi`; every weight is `w_k · 2π / n_phi`, and the
/// weights sum to `4π`. Exact for spherical polynomials of degree `≤ min(2·n_theta − 1, n_phi − 1)`.
#[derive(Clone, Debug)]
pub struct SphereQuadrature {
    /// Number of Gauss–Legendre nodes in `cos θ`.
    pub n_theta: usize,
    /// Number of uniform azimuths.
    pub n_phi: usize,
    /// Unit directions, `n_theta × n_phi` of them, θ-major (`k * n_phi + j`).
    pub points: Vec<DVec3>,
    /// Solid-angle weights (sr), one per point.
    pub weights: Vec<f64>,
}

impl SphereQuadrature {
    /// The product rule with `n_theta` Gauss–Legendre nodes in `cos θ` and `n_phi` azimuths.
    #[must_use]
    pub fn new(n_theta: usize, n_phi: usize) -> SphereQuadrature {
        let (z, wz) = gauss_legendre(n_theta);
        let dphi = 2.0 * PI / n_phi as f64;
        // cos/sin of φ_j by rotation recurrence would drift over many steps; n_phi is small, use
        // sin_cos directly (this is set-up, not a hot path).
        let trig: Vec<(f64, f64)> = (0..n_phi)
            .map(|j| ((j as f64 + 0.5) * dphi).sin_cos())
            .collect();
        let mut points = Vec::with_capacity(n_theta * n_phi);
        let mut weights = Vec::with_capacity(n_theta * n_phi);
        for (&zk, &wk) in z.iter().zip(&wz) {
            let s = (1.0 - zk * zk).max(0.0).sqrt();
            for &(sp, cp) in &trig {
                points.push(DVec3::new(s * cp, s * sp, zk));
                weights.push(wk * dphi);
            }
        }
        SphereQuadrature {
            n_theta,
            n_phi,
            points,
            weights,
        }
    }

    /// The smallest rule of this family that integrates exactly the product of two functions
    /// band-limited to `l ≤ lmax` (a spherical polynomial of degree `2·lmax`):
    /// `n_theta = lmax + 1`, `n_phi = 2·lmax + 1`.
    #[must_use]
    pub fn for_band(lmax: usize) -> SphereQuadrature {
        SphereQuadrature::new(lmax + 1, 2 * lmax + 1)
    }

    /// The highest spherical-polynomial degree this rule integrates exactly.
    #[must_use]
    pub fn exact_degree(&self) -> usize {
        (2 * self.n_theta)
            .saturating_sub(1)
            .min(self.n_phi.saturating_sub(1))
    }

    /// `Σ w_k f(ω_k) ≈ ∫_{S²} f dω`.
    pub fn integrate(&self, mut f: impl FnMut(DVec3) -> f64) -> f64 {
        self.points
            .iter()
            .zip(&self.weights)
            .map(|(&p, &w)| w * f(p))
            .sum()
    }

    /// Number of points.
    #[must_use]
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// `true` when the rule has no points.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }
}

/// `∫_{S²} f(ω) dω` by Gauss–Legendre in `cos θ` (`n_theta` nodes) × uniform φ (`n_phi` points).
///
/// Exact for spherical polynomials of degree `≤ min(2·n_theta − 1, n_phi − 1)`; for functions with
/// a kink or a jump (e.g. a hemisphere's edge at `z = 0`) convergence is only algebraic — split the
/// domain ([`integrate_hemisphere`]) instead of raising the order.
pub fn integrate_sphere(mut f: impl FnMut(DVec3) -> f64, n_theta: usize, n_phi: usize) -> f64 {
    integrate_z_band(&mut f, -1.0, 1.0, n_theta, n_phi)
}

/// `∫_{z>0} f(ω) dω` over the upper hemisphere, Gauss–Legendre in `cos θ ∈ [0, 1]` × uniform φ.
pub fn integrate_hemisphere(mut f: impl FnMut(DVec3) -> f64, n_theta: usize, n_phi: usize) -> f64 {
    integrate_z_band(&mut f, 0.0, 1.0, n_theta, n_phi)
}

/// `∫ f dω` over the zone `z0 ≤ cos θ ≤ z1`, Gauss–Legendre in `z` × uniform φ.
pub fn integrate_z_band(
    f: &mut impl FnMut(DVec3) -> f64,
    z0: f64,
    z1: f64,
    n_theta: usize,
    n_phi: usize,
) -> f64 {
    let (z, wz) = gauss_legendre_interval(n_theta, z0, z1);
    let dphi = 2.0 * PI / n_phi as f64;
    let mut total = 0.0;
    for (&zk, &wk) in z.iter().zip(&wz) {
        let s = (1.0 - zk * zk).max(0.0).sqrt();
        let mut row = 0.0;
        for j in 0..n_phi {
            let (sp, cp) = ((j as f64 + 0.5) * dphi).sin_cos();
            row += f(DVec3::new(s * cp, s * sp, zk));
        }
        total += wk * row;
    }
    total * dphi
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legendre_matches_closed_forms() {
        for &x in &[-1.0f64, -0.7, -0.1, 0.0, 0.3, 0.99, 1.0] {
            let p2 = 0.5 * (3.0 * x * x - 1.0);
            let p3 = 0.5 * (5.0 * x * x * x - 3.0 * x);
            let p4 = (35.0 * x.powi(4) - 30.0 * x * x + 3.0) / 8.0;
            assert!((legendre(2, x).0 - p2).abs() < 1e-15);
            assert!((legendre(3, x).0 - p3).abs() < 1e-15);
            assert!((legendre(4, x).0 - p4).abs() < 1e-15);
            let dp3 = 0.5 * (15.0 * x * x - 3.0);
            assert!((legendre(3, x).1 - dp3).abs() < 1e-12, "x {x}");
            let dp4 = (140.0 * x.powi(3) - 60.0 * x) / 8.0;
            assert!((legendre(4, x).1 - dp4).abs() < 1e-12, "x {x}");
        }
    }

    #[test]
    fn small_rules_match_tables() {
        let (x, w) = gauss_legendre(1);
        assert_eq!(x, vec![0.0]);
        assert!((w[0] - 2.0).abs() < 1e-15);
        let (x, w) = gauss_legendre(2);
        let r = 1.0 / 3f64.sqrt();
        assert!((x[0] + r).abs() < 1e-15 && (x[1] - r).abs() < 1e-15);
        assert!((w[0] - 1.0).abs() < 1e-15 && (w[1] - 1.0).abs() < 1e-15);
        let (x, w) = gauss_legendre(3);
        let r = (0.6f64).sqrt();
        assert!((x[0] + r).abs() < 1e-15 && x[1] == 0.0 && (x[2] - r).abs() < 1e-15);
        assert!((w[0] - 5.0 / 9.0).abs() < 1e-15 && (w[1] - 8.0 / 9.0).abs() < 1e-15);
        // 5-point rule (Abramowitz & Stegun, Table 25.4).
        let (x, w) = gauss_legendre(5);
        assert!((x[4] - 0.906_179_845_938_664).abs() < 1e-15);
        assert!((x[3] - 0.538_469_310_105_683).abs() < 1e-15);
        assert!((w[4] - 0.236_926_885_056_189).abs() < 1e-15);
        assert!((w[3] - 0.478_628_670_499_366).abs() < 1e-15);
        assert!((w[2] - 0.568_888_888_888_889).abs() < 1e-15);
        assert!(gauss_legendre(0).0.is_empty());
    }

    /// ∫_{-1}^{1} x^k dx.
    fn monomial_integral(k: usize) -> f64 {
        if k % 2 == 1 {
            0.0
        } else {
            2.0 / (k as f64 + 1.0)
        }
    }

    #[test]
    fn exact_to_degree_2n_minus_1_and_not_beyond() {
        for n in [1usize, 2, 3, 4, 7, 10, 16, 33, 64, 100] {
            let (x, w) = gauss_legendre(n);
            assert!(x.windows(2).all(|p| p[0] < p[1]), "ascending, n {n}");
            let wsum: f64 = w.iter().sum();
            assert!((wsum - 2.0).abs() < 1e-13, "n {n}: Σw = {wsum}");
            // Monomials up to degree 2n-1 (bounded so that x^k stays well-conditioned).
            for k in 0..=(2 * n - 1).min(60) {
                let q: f64 = x.iter().zip(&w).map(|(&x, &w)| w * x.powi(k as i32)).sum();
                let exact = monomial_integral(k);
                assert!(
                    (q - exact).abs() < 1e-13,
                    "n {n}, degree {k}: {q} vs {exact}"
                );
            }
            // Legendre polynomials P_k, k ≤ 2n−1, are a well-conditioned basis at any degree:
            // ∫ P_k = 2 δ_k0.
            for k in 0..=(2 * n - 1) {
                let q: f64 = x.iter().zip(&w).map(|(&x, &w)| w * legendre(k, x).0).sum();
                let exact = if k == 0 { 2.0 } else { 0.0 };
                assert!((q - exact).abs() < 1e-13, "n {n}, P_{k}: {q}");
            }
            // Degree 2n is not integrated exactly (x^{2n} ≥ 0 and the nodes are roots of P_n:
            // the rule misses ∫ P_n² = 2/(2n+1) entirely).
            let q: f64 = x
                .iter()
                .zip(&w)
                .map(|(&x, &w)| w * legendre(n, x).0.powi(2))
                .sum();
            let exact = 2.0 / (2.0 * n as f64 + 1.0);
            assert!(
                q.abs() < 1e-12 && exact > 1e-3,
                "degree 2n is not exact, n {n}"
            );
        }
    }

    #[test]
    fn interval_rule() {
        let (x, w) = gauss_legendre_interval(4, 0.0, 2.0);
        let q: f64 = x.iter().zip(&w).map(|(&x, &w)| w * x.powi(7)).sum();
        assert!((q - 256.0 / 8.0).abs() < 1e-12);
    }

    #[test]
    fn sphere_rules() {
        // Area, and ∫ z² dω = 4π/3, ∫ x²y² dω = 4π/15.
        let a = integrate_sphere(|_| 1.0, 3, 5);
        assert!((a - 4.0 * PI).abs() < 1e-13);
        let q = integrate_sphere(|w| w.z * w.z, 2, 3);
        assert!((q - 4.0 * PI / 3.0).abs() < 1e-13);
        let q = integrate_sphere(|w| w.x * w.x * w.y * w.y, 3, 5);
        assert!((q - 4.0 * PI / 15.0).abs() < 1e-13, "{q}");
        // Hemisphere: ∫ cos θ dω = π.
        let q = integrate_hemisphere(|w| w.z, 1, 1);
        assert!((q - PI).abs() < 1e-13);
        let sq = SphereQuadrature::for_band(4);
        assert_eq!(sq.exact_degree(), 8);
        let wsum: f64 = sq.weights.iter().sum();
        assert!((wsum - 4.0 * PI).abs() < 1e-12);
        let q = sq.integrate(|w| w.x.powi(4) * w.y.powi(2) * w.z.powi(2));
        // ∫ x^a y^b z^c dω = 2 Γ((a+1)/2) Γ((b+1)/2) Γ((c+1)/2) / Γ((a+b+c+3)/2) (Folland 2001).
        let exact = 2.0 * gamma_half(5) * gamma_half(3) * gamma_half(3) / gamma_half(5 + 3 + 3);
        assert!((q - exact).abs() < 1e-13, "{q} vs {exact}");
    }

    /// Γ(k/2) for small positive integers k.
    fn gamma_half(k: usize) -> f64 {
        match k {
            1 => PI.sqrt(),
            2 => 1.0,
            _ => (k as f64 / 2.0 - 1.0) * gamma_half(k - 2),
        }
    }
}
