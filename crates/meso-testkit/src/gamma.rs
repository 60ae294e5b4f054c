//! The log-gamma function, the regularised incomplete gamma functions and chi-square tail
//! probabilities — written here so that the harness needs no statistics crate.
//!
//! * [`ln_gamma`] — meso-core's [`meso_core::special::ln_gamma`] (libm's `lgamma`), re-exported:
//!   the workspace keeps one `ln Γ`.
//! * [`gamma_p`] / [`gamma_q`] — `P(a, x) = γ(a, x)/Γ(a)` and `Q(a, x) = 1 − P(a, x)`, by the power
//!   series for `x < a + 1` and by the continued fraction (modified Lentz) otherwise, as in
//!   Numerical Recipes §6.2. The one not computed directly is `1 −` the other, so the small tail
//!   is always the one evaluated accurately.
//! * [`chi_square_sf`] — `Pr[χ²_k ≥ x] = Q(k/2, x/2)`, the p-value of a chi-square statistic.

pub use meso_core::special::ln_gamma;

const EPS: f64 = 1e-16;
const FPMIN: f64 = f64::MIN_POSITIVE / EPS;
/// Iteration cap; both expansions converge in O(√a) steps near `x ≈ a`, far less elsewhere.
const MAX_ITER: usize = 1_000_000;

/// `e^{−x} x^a / Γ(a)`, the common prefactor.
fn prefactor(a: f64, x: f64) -> f64 {
    (-x + a * x.ln() - ln_gamma(a)).exp()
}

/// `P(a, x)` by its series `e^{−x} x^a / Γ(a) · Σ xⁿ / (a (a+1) … (a+n))`; for `x < a + 1`.
fn p_series(a: f64, x: f64) -> f64 {
    let mut ap = a;
    let mut del = 1.0 / a;
    let mut sum = del;
    for _ in 0..MAX_ITER {
        ap += 1.0;
        del *= x / ap;
        sum += del;
        if del.abs() < sum.abs() * EPS {
            break;
        }
    }
    sum * prefactor(a, x)
}

/// `Q(a, x)` by its continued fraction (modified Lentz); for `x ≥ a + 1`.
fn q_continued_fraction(a: f64, x: f64) -> f64 {
    let mut b = x + 1.0 - a;
    let mut c = 1.0 / FPMIN;
    let mut d = 1.0 / b;
    let mut h = d;
    for i in 1..MAX_ITER {
        let an = -(i as f64) * (i as f64 - a);
        b += 2.0;
        d = an * d + b;
        if d.abs() < FPMIN {
            d = FPMIN;
        }
        c = b + an / c;
        if c.abs() < FPMIN {
            c = FPMIN;
        }
        d = 1.0 / d;
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < EPS {
            break;
        }
    }
    prefactor(a, x) * h
}

/// The regularised lower incomplete gamma function `P(a, x) = γ(a, x) / Γ(a)`, `a > 0`, `x ≥ 0`.
///
/// # Panics
/// When `a ≤ 0` or `x < 0` (or either is NaN).
#[must_use]
pub fn gamma_p(a: f64, x: f64) -> f64 {
    assert!(
        a > 0.0 && x >= 0.0,
        "gamma_p: need a > 0, x ≥ 0 (a = {a}, x = {x})"
    );
    if x == 0.0 {
        0.0
    } else if x.is_infinite() {
        1.0
    } else if x < a + 1.0 {
        p_series(a, x)
    } else {
        1.0 - q_continued_fraction(a, x)
    }
}

/// The regularised upper incomplete gamma function `Q(a, x) = Γ(a, x) / Γ(a) = 1 − P(a, x)`,
/// `a > 0`, `x ≥ 0`.
///
/// # Panics
/// When `a ≤ 0` or `x < 0` (or either is NaN).
#[must_use]
pub fn gamma_q(a: f64, x: f64) -> f64 {
    assert!(
        a > 0.0 && x >= 0.0,
        "gamma_q: need a > 0, x ≥ 0 (a = {a}, x = {x})"
    );
    if x == 0.0 {
        1.0
    } else if x.is_infinite() {
        0.0
    } else if x < a + 1.0 {
        1.0 - p_series(a, x)
    } else {
        q_continued_fraction(a, x)
    }
}

/// The chi-square survival function `Pr[χ²_dof ≥ statistic] = Q(dof/2, statistic/2)`: the p-value
/// of a chi-square statistic with `dof` degrees of freedom.
///
/// # Panics
/// When `dof == 0` or `statistic < 0`.
#[must_use]
pub fn chi_square_sf(statistic: f64, dof: usize) -> f64 {
    assert!(dof > 0, "chi_square_sf: dof must be positive");
    gamma_q(0.5 * dof as f64, 0.5 * statistic)
}

/// The chi-square CDF `Pr[χ²_dof ≤ statistic] = P(dof/2, statistic/2)`.
///
/// # Panics
/// When `dof == 0` or `statistic < 0`.
#[must_use]
pub fn chi_square_cdf(statistic: f64, dof: usize) -> f64 {
    assert!(dof > 0, "chi_square_cdf: dof must be positive");
    gamma_p(0.5 * dof as f64, 0.5 * statistic)
}

#[cfg(test)]
#[allow(clippy::excessive_precision)] // reference values are quoted in full
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn rel(a: f64, b: f64) -> f64 {
        (a - b).abs() / b.abs().max(f64::MIN_POSITIVE)
    }

    #[test]
    fn ln_gamma_known_values() {
        // Integers: Γ(n) = (n−1)!
        let mut fact = 1.0f64;
        for n in 1..=30u32 {
            if n > 1 {
                fact *= (n - 1) as f64;
            }
            assert!((ln_gamma(n as f64) - fact.ln()).abs() < 1e-13, "n {n}");
        }
        // Half-integers: Γ(½) = √π, Γ(n+½) = (2n−1)!!/2ⁿ √π.
        assert!((ln_gamma(0.5) - PI.sqrt().ln()).abs() < 1e-14);
        assert!((ln_gamma(2.5) - (0.75 * PI.sqrt()).ln()).abs() < 1e-14);
        // Large argument vs Stirling's series (3 terms, error < 1e-13 at x = 1000).
        let x = 1000.0f64;
        let stirling = (x - 0.5) * x.ln() - x + 0.5 * (2.0 * PI).ln() + 1.0 / (12.0 * x)
            - 1.0 / (360.0 * x.powi(3));
        assert!(
            rel(ln_gamma(x), stirling) < 1e-14,
            "{} vs {stirling}",
            ln_gamma(x)
        );
        // Reflection: Γ(−½) = −2√π.
        assert!((ln_gamma(-0.5) - (2.0 * PI.sqrt()).ln()).abs() < 1e-14);
        assert!(ln_gamma(0.0).is_infinite());
    }

    #[test]
    fn q_of_a_one_is_exp() {
        for &x in &[
            0.0, 1e-8, 0.1, 0.5, 1.0, 1.999, 2.0, 2.001, 5.0, 30.0, 200.0,
        ] {
            let q = gamma_q(1.0, x);
            assert!(rel(q, (-x).exp()) < 1e-13, "x {x}: {q}");
            assert!((gamma_p(1.0, x) + q - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn q_of_integer_a_matches_poisson_sum() {
        // Q(n, x) = e^{−x} Σ_{k<n} x^k / k!
        for n in 1..=40usize {
            for &x in &[0.3, 1.0, 4.0, 9.5, 20.0, 35.0, 60.0] {
                let mut term = 1.0f64;
                let mut sum = 0.0;
                for k in 0..n {
                    if k > 0 {
                        term *= x / k as f64;
                    }
                    sum += term;
                }
                let expect = (-x).exp() * sum;
                let q = gamma_q(n as f64, x);
                // Relative where Q is the small tail, absolute where it is close to 1.
                assert!(
                    (q - expect).abs() < 1e-12 * expect.min(1.0 - expect).max(1e-300) + 1e-15,
                    "n {n}, x {x}: {q} vs {expect}"
                );
            }
        }
    }

    /// Reference values computed with mpmath (40 digits), `gammainc(a, x, inf, regularized=True)`.
    const Q_TABLE: [(f64, f64, f64); 14] = [
        (0.5, 0.1, 0.654_720_846_018_577_020_44),
        (0.5, 2.0, 0.045_500_263_896_358_414_401),
        (1.5, 3.0, 0.111_610_225_094_712_559_98),
        (2.5, 0.5, 0.962_565_773_247_296_368_96),
        (5.0, 2.5, 0.891_178_018_914_151_242_35),
        (10.5, 12.0, 0.293_058_531_258_574_875_06),
        (50.0, 40.0, 0.929_664_933_340_605_045_56),
        (50.0, 60.0, 0.084_406_681_093_691_829_623),
        (500.0, 480.0, 0.813_718_026_809_675_399_34),
        (6399.5, 6500.0, 0.104_931_246_583_637_731_01),
        (3.0, 30.0, 4.501_016_648_012_123_985e-11),
        (0.5, 50.0, 1.523_970_604_832_105_213_2e-23),
        (100.0, 1.0, 1.0),
        (0.001, 0.001, 0.006_312_353_291_139_709_903_8),
    ];

    #[test]
    fn q_matches_reference_values() {
        for &(a, x, q) in &Q_TABLE {
            let got = gamma_q(a, x);
            assert!(rel(got, q) < 1e-10, "Q({a}, {x}) = {got}, expected {q}");
            let p = gamma_p(a, x);
            assert!((p - (1.0 - q)).abs() < 1e-10, "P({a}, {x}) = {p}");
        }
    }

    #[test]
    fn chi_square_table_critical_values() {
        // (dof, critical value, upper-tail probability), critical values from the chi-square
        // table (scipy.stats.chi2.isf), tails re-evaluated with mpmath.
        let table = [
            (1, 3.841_458_820_694_124, 0.05),
            (1, 6.634_896_601_021_214, 0.01),
            (2, 5.991_464_547_107_979, 0.05),
            (10, 18.307_038_053_275_146, 0.05),
            (10, 23.209_251_158_954_356, 0.01),
            (100, 124.342_113_404_004_07, 0.05),
        ];
        for &(k, x, p) in &table {
            let got = chi_square_sf(x, k);
            assert!((got - p).abs() < 1e-8 * p, "dof {k}, χ² {x}: {got} vs {p}");
            assert!((chi_square_cdf(x, k) - (1.0 - p)).abs() < 1e-12);
        }
        // The size of the default harness: 80 × 160 cells → about 12 799 dof.
        let got = chi_square_sf(13_172.0, 12_799);
        assert!(rel(got, 0.010_355_055_864_190_934_769) < 1e-8, "{got}");
        // χ²₂ is exponential with mean 2.
        for &x in &[0.5, 3.0, 17.0] {
            assert!(rel(chi_square_sf(x, 2), (-0.5 * x).exp()) < 1e-13);
        }
    }
}
