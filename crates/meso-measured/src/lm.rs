//! A compact dense Levenberg–Marquardt solver with box constraints (projection + active set).
//!
//! The problem supplies the Gauss–Newton normal equations `JᵀJ`, `Jᵀr` and the cost `½‖r‖²`
//! (the fitting code accumulates them in parallel without storing `J`). Each step solves
//! `(JᵀJ + λ·diag(JᵀJ)) δ = −Jᵀr` by Cholesky, with the parameters that sit on a bound and
//! whose gradient pushes outwards held fixed, then projects `p + δ` onto the box. Parameter counts
//! are small (≲ 30), so dense linear algebra is the right tool.

/// A least-squares problem for [`minimize`].
pub trait LeastSquares: Sync {
    /// Number of parameters.
    fn n_params(&self) -> usize;
    /// `½‖r(p)‖²`.
    fn cost(&self, p: &[f64]) -> f64;
    /// Fill `jtj` (row-major `n×n`) and `jtr` (`n`) at `p`; return the cost `½‖r(p)‖²`.
    fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64;
}

/// Options of [`minimize`].
#[derive(Clone, Copy, Debug)]
pub struct LmOptions {
    /// Maximum number of outer iterations (Jacobian evaluations).
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this fraction.
    pub rel_tolerance: f64,
    /// Initial damping λ.
    pub initial_lambda: f64,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iterations: 100,
            rel_tolerance: 1e-10,
            initial_lambda: 1e-3,
        }
    }
}

/// The outcome of [`minimize`].
#[derive(Clone, Debug)]
pub struct LmResult {
    /// The parameters found (inside the bounds).
    pub params: Vec<f64>,
    /// `½‖r‖²` at `params`.
    pub cost: f64,
    /// Outer iterations (Jacobian evaluations).
    pub iterations: usize,
    /// Cost evaluations (trial steps).
    pub evaluations: usize,
}

pub use meso_core::linalg::cholesky_solve;

/// Minimise `½‖r(p)‖²` subject to `lo ≤ p ≤ hi` from `p0` (projected onto the box first).
pub fn minimize<P: LeastSquares>(
    problem: &P,
    p0: &[f64],
    bounds: &[(f64, f64)],
    opts: &LmOptions,
) -> LmResult {
    let n = problem.n_params();
    assert_eq!(p0.len(), n);
    assert_eq!(bounds.len(), n);
    let project = |p: &mut [f64]| {
        for (x, &(lo, hi)) in p.iter_mut().zip(bounds) {
            *x = x.clamp(lo, hi);
        }
    };
    let mut p = p0.to_vec();
    project(&mut p);
    let mut jtj = vec![0.0; n * n];
    let mut jtr = vec![0.0; n];
    let mut m = vec![0.0; n * n];
    let mut delta = vec![0.0; n];
    let mut trial = vec![0.0; n];
    let mut lambda = opts.initial_lambda;
    let mut cost = f64::INFINITY;
    let mut iterations = 0;
    let mut evaluations = 0;
    let mut small_steps = 0;
    'outer: while iterations < opts.max_iterations {
        iterations += 1;
        cost = problem.normal_equations(&p, &mut jtj, &mut jtr);
        evaluations += 1;
        if cost == 0.0 {
            break;
        }
        // Active set: on a bound with the descent direction −g pointing outwards.
        let active: Vec<bool> = (0..n)
            .map(|j| {
                let (lo, hi) = bounds[j];
                (p[j] <= lo && jtr[j] > 0.0) || (p[j] >= hi && jtr[j] < 0.0)
            })
            .collect();
        let max_diag = (0..n).map(|j| jtj[j * n + j]).fold(0.0f64, f64::max);
        let floor = 1e-12 * max_diag.max(1e-300);
        loop {
            m.copy_from_slice(&jtj);
            for j in 0..n {
                delta[j] = -jtr[j];
                let d = jtj[j * n + j].max(floor);
                m[j * n + j] = d * (1.0 + lambda);
                if active[j] {
                    for k in 0..n {
                        m[j * n + k] = 0.0;
                        m[k * n + j] = 0.0;
                    }
                    m[j * n + j] = 1.0;
                    delta[j] = 0.0;
                }
            }
            let ok = cholesky_solve(&mut m, &mut delta, n);
            if ok {
                for j in 0..n {
                    trial[j] = p[j] + delta[j];
                }
                project(&mut trial);
                let c = problem.cost(&trial);
                evaluations += 1;
                if c.is_finite() && c < cost {
                    let rel = (cost - c) / cost;
                    p.copy_from_slice(&trial);
                    cost = c;
                    lambda = (lambda / 3.0).max(1e-12);
                    // Stop after two consecutive accepted steps with a negligible decrease.
                    if rel < opts.rel_tolerance {
                        small_steps += 1;
                        if small_steps >= 2 {
                            break 'outer;
                        }
                    } else {
                        small_steps = 0;
                    }
                    break;
                }
            }
            lambda *= 4.0;
            if lambda > 1e12 {
                break 'outer;
            }
        }
    }
    LmResult {
        params: p,
        cost,
        iterations,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock as least squares: r = (10(y − x²), 1 − x).
    struct Rosen;
    impl LeastSquares for Rosen {
        fn n_params(&self) -> usize {
            2
        }
        fn cost(&self, p: &[f64]) -> f64 {
            let a = 10.0 * (p[1] - p[0] * p[0]);
            let b = 1.0 - p[0];
            0.5 * (a * a + b * b)
        }
        fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
            let r = [10.0 * (p[1] - p[0] * p[0]), 1.0 - p[0]];
            let j = [[-20.0 * p[0], 10.0], [-1.0, 0.0]];
            for a in 0..2 {
                jtr[a] = j[0][a] * r[0] + j[1][a] * r[1];
                for b in 0..2 {
                    jtj[a * 2 + b] = j[0][a] * j[0][b] + j[1][a] * j[1][b];
                }
            }
            0.5 * (r[0] * r[0] + r[1] * r[1])
        }
    }

    #[test]
    fn rosenbrock_unconstrained_and_bounded() {
        let free = [(-10.0, 10.0); 2];
        let r = minimize(&Rosen, &[-1.2, 1.0], &free, &LmOptions::default());
        assert!(
            (r.params[0] - 1.0).abs() < 1e-6 && (r.params[1] - 1.0).abs() < 1e-6,
            "{r:?}"
        );
        // With x ≤ 0.5 the constrained minimum is at x = 0.5, y = 0.25.
        let boxed = [(-10.0, 0.5), (-10.0, 10.0)];
        let r = minimize(&Rosen, &[-1.2, 1.0], &boxed, &LmOptions::default());
        assert!(
            (r.params[0] - 0.5).abs() < 1e-9 && (r.params[1] - 0.25).abs() < 1e-6,
            "{r:?}"
        );
    }
}
