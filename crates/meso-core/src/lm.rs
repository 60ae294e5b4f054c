//! The one Levenberg–Marquardt solver of meso: dense, small (a few to a few dozen unknowns),
//! generic over the parameter space, and free of allocation inside its loop.
//!
//! The problem supplies the Gauss–Newton normal equations `JᵀJ`, `Jᵀr` and the cost (any fixed
//! multiple of `‖r‖²`: only relative decreases are compared), and a *retraction* that applies a
//! step `δ` to a point and puts the result back into the feasible set: a projection onto box
//! bounds for the measured-BRDF fits (`meso_measured::fit`), a renormalised axis and clamped
//! steps on the sphere for the pyramid's lobe refinement (`meso_maps::fit`). Each iteration solves
//! `(JᵀJ + λ·diag(JᵀJ)) δ = −Jᵀr` by Cholesky ([`crate::linalg::cholesky_solve`]), with the
//! parameters the problem holds fixed this iteration (e.g. on a bound with the gradient pushing
//! outwards: an active set) left out; a step that lowers the cost is taken and λ divided by 3,
//! otherwise λ is multiplied by 4 and the step tried again.
//!
//! Stopping ([`LmOptions`]): after `max_iterations` Jacobian evaluations; after
//! `small_steps_to_stop` consecutive accepted steps that lower the cost by less than the fraction
//! `rel_tolerance`; or when no step is accepted within `max_tries` tries or before λ exceeds
//! `lambda_max`.

use crate::linalg::cholesky_solve;

/// A least-squares problem for [`minimize`], over points of type [`LeastSquares::Point`].
pub trait LeastSquares {
    /// A point of the parameter space (a vector, or lobes with unit axes, …).
    type Point: Clone;
    /// Number of parameters (the size of a step) at `p`.
    fn n_params(&self, p: &Self::Point) -> usize;
    /// The cost at `p` (a fixed positive multiple of `‖r(p)‖²`, e.g. `½‖r‖²`).
    fn cost(&self, p: &Self::Point) -> f64;
    /// Fill `jtj` (row-major `n × n`, both triangles) and `jtr` (`n`) at `p` (they arrive
    /// zeroed); return the cost at `p`.
    fn normal_equations(&self, p: &Self::Point, jtj: &mut [f64], jtr: &mut [f64]) -> f64;
    /// The point `p ⊕ δ` written into `out`: the step applied and the result put back into the
    /// feasible set (projection, renormalisation, step limits).
    fn retract(&self, p: &Self::Point, delta: &[f64], out: &mut Self::Point);
    /// Whether parameter `j` is held fixed this iteration, given the gradient component
    /// `jtr_j` (e.g. on a bound with `−Jᵀr` pointing out of the box). None by default.
    fn held(&self, _p: &Self::Point, _j: usize, _jtr_j: f64) -> bool {
        false
    }
}

/// Options of [`minimize`]. The default is the measured-BRDF fitter's.
#[derive(Clone, Copy, Debug)]
pub struct LmOptions {
    /// Maximum number of outer iterations (Jacobian evaluations).
    pub max_iterations: usize,
    /// An accepted step that lowers the cost by less than this fraction counts as small.
    pub rel_tolerance: f64,
    /// Consecutive small accepted steps after which the solver stops.
    pub small_steps_to_stop: usize,
    /// Initial damping λ.
    pub initial_lambda: f64,
    /// λ never goes below this after an accepted step.
    pub lambda_min: f64,
    /// The solver stops when λ grows beyond this without an accepted step.
    pub lambda_max: f64,
    /// Tries (λ grown by 4 each time) per iteration before the solver stops.
    pub max_tries: usize,
}

impl Default for LmOptions {
    fn default() -> Self {
        LmOptions {
            max_iterations: 100,
            rel_tolerance: 1e-10,
            small_steps_to_stop: 2,
            initial_lambda: 1e-3,
            lambda_min: 1e-12,
            lambda_max: 1e12,
            max_tries: usize::MAX,
        }
    }
}

/// The outcome of [`minimize`] (the point itself is updated in place).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LmReport {
    /// The cost at the final point.
    pub cost: f64,
    /// Outer iterations (Jacobian evaluations).
    pub iterations: usize,
    /// Cost evaluations (trial steps) and Jacobian evaluations.
    pub evaluations: usize,
}

/// Buffers of [`minimize`], reusable across calls (no allocation inside the solver's loop; one
/// workspace per thread serves any number of solves of up to its size).
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    jtj: Vec<f64>,
    m: Vec<f64>,
    jtr: Vec<f64>,
    delta: Vec<f64>,
    held: Vec<bool>,
}

impl Workspace {
    /// A workspace for problems of up to `n` parameters (it grows when a larger one comes).
    #[must_use]
    pub fn new(n: usize) -> Workspace {
        let mut w = Workspace::default();
        w.reserve(n);
        w
    }

    fn reserve(&mut self, n: usize) {
        if self.jtr.len() < n {
            self.jtj.resize(n * n, 0.0);
            self.m.resize(n * n, 0.0);
            self.jtr.resize(n, 0.0);
            self.delta.resize(n, 0.0);
            self.held.resize(n, false);
        }
    }
}

/// Minimise the cost of `problem` from `p` (updated in place), with the buffers of `ws`.
pub fn minimize<P: LeastSquares>(
    problem: &P,
    p: &mut P::Point,
    opts: &LmOptions,
    ws: &mut Workspace,
) -> LmReport {
    let n = problem.n_params(p);
    ws.reserve(n);
    let Workspace {
        jtj,
        m,
        jtr,
        delta,
        held,
    } = ws;
    let (jtj, m, jtr, delta, held) = (
        &mut jtj[..n * n],
        &mut m[..n * n],
        &mut jtr[..n],
        &mut delta[..n],
        &mut held[..n],
    );
    let mut trial = p.clone();
    let mut lambda = opts.initial_lambda;
    let mut cost = if opts.max_iterations == 0 {
        problem.cost(p)
    } else {
        f64::INFINITY
    };
    let mut iterations = 0;
    let mut evaluations = 0;
    let mut small_steps = 0;
    'outer: while iterations < opts.max_iterations {
        iterations += 1;
        jtj.fill(0.0);
        jtr.fill(0.0);
        cost = problem.normal_equations(p, jtj, jtr);
        evaluations += 1;
        if cost == 0.0 {
            break;
        }
        for (j, h) in held.iter_mut().enumerate() {
            *h = problem.held(p, j, jtr[j]);
        }
        let max_diag = (0..n).map(|j| jtj[j * n + j]).fold(0.0f64, f64::max);
        let floor = 1e-12 * max_diag.max(1e-300);
        let mut tries = 0;
        loop {
            if tries == opts.max_tries || lambda > opts.lambda_max {
                break 'outer;
            }
            tries += 1;
            m.copy_from_slice(jtj);
            for j in 0..n {
                delta[j] = -jtr[j];
                m[j * n + j] = jtj[j * n + j].max(floor) * (1.0 + lambda);
                if held[j] {
                    for k in 0..n {
                        m[j * n + k] = 0.0;
                        m[k * n + j] = 0.0;
                    }
                    m[j * n + j] = 1.0;
                    delta[j] = 0.0;
                }
            }
            if cholesky_solve(m, delta, n) {
                problem.retract(p, delta, &mut trial);
                let c = problem.cost(&trial);
                evaluations += 1;
                if c.is_finite() && c < cost {
                    let rel = (cost - c) / cost;
                    std::mem::swap(p, &mut trial);
                    cost = c;
                    lambda = (lambda / 3.0).max(opts.lambda_min);
                    if rel < opts.rel_tolerance {
                        small_steps += 1;
                        if small_steps >= opts.small_steps_to_stop {
                            break 'outer;
                        }
                    } else {
                        small_steps = 0;
                    }
                    break;
                }
            }
            lambda *= 4.0;
        }
    }
    LmReport {
        cost,
        iterations,
        evaluations,
    }
}

/// A least-squares problem on plain parameter vectors, solved inside box bounds by
/// [`minimize_boxed`] (through [`Boxed`]).
pub trait VectorProblem {
    /// Number of parameters.
    fn n_params(&self) -> usize;
    /// The cost at `p` (a fixed positive multiple of `‖r(p)‖²`).
    fn cost(&self, p: &[f64]) -> f64;
    /// Fill `jtj` (row-major `n × n`, both triangles) and `jtr` (`n`) at `p` (they arrive
    /// zeroed); return the cost at `p`.
    fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64;
}

/// A [`VectorProblem`] inside box bounds `lo ≤ p ≤ hi`: steps are added and projected onto the
/// box, and a parameter on a bound whose descent direction points outwards is held (the active
/// set).
#[derive(Clone, Copy, Debug)]
pub struct Boxed<'a, P> {
    /// The problem.
    pub problem: &'a P,
    /// `(lo, hi)` per parameter.
    pub bounds: &'a [(f64, f64)],
}

impl<P: VectorProblem> LeastSquares for Boxed<'_, P> {
    type Point = Vec<f64>;
    fn n_params(&self, _: &Vec<f64>) -> usize {
        self.problem.n_params()
    }
    fn cost(&self, p: &Vec<f64>) -> f64 {
        self.problem.cost(p)
    }
    fn normal_equations(&self, p: &Vec<f64>, jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
        self.problem.normal_equations(p, jtj, jtr)
    }
    fn retract(&self, p: &Vec<f64>, delta: &[f64], out: &mut Vec<f64>) {
        for ((o, (x, d)), &(lo, hi)) in out.iter_mut().zip(p.iter().zip(delta)).zip(self.bounds) {
            *o = (x + d).clamp(lo, hi);
        }
    }
    fn held(&self, p: &Vec<f64>, j: usize, jtr_j: f64) -> bool {
        let (lo, hi) = self.bounds[j];
        (p[j] <= lo && jtr_j > 0.0) || (p[j] >= hi && jtr_j < 0.0)
    }
}

/// Minimise a vector problem inside box bounds ([`Boxed`]) from `p0` (projected onto the box
/// first); returns the point found and the report.
///
/// # Panics
/// If `p0` or `bounds` do not have the problem's number of parameters.
pub fn minimize_boxed<P: VectorProblem>(
    problem: &P,
    p0: &[f64],
    bounds: &[(f64, f64)],
    opts: &LmOptions,
) -> (Vec<f64>, LmReport) {
    let mut p: Vec<f64> = p0
        .iter()
        .zip(bounds)
        .map(|(x, &(lo, hi))| x.clamp(lo, hi))
        .collect();
    let n = problem.n_params();
    assert_eq!(p0.len(), n);
    assert_eq!(bounds.len(), n);
    let r = minimize(
        &Boxed { problem, bounds },
        &mut p,
        opts,
        &mut Workspace::new(n),
    );
    (p, r)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock as least squares: r = (10(y − x²), 1 − x).
    struct Rosen;
    impl VectorProblem for Rosen {
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
        let (p, r) = minimize_boxed(&Rosen, &[-1.2, 1.0], &free, &LmOptions::default());
        assert!(
            (p[0] - 1.0).abs() < 1e-6 && (p[1] - 1.0).abs() < 1e-6,
            "{p:?} {r:?}"
        );
        // With x ≤ 0.5 the constrained minimum is at x = 0.5, y = 0.25.
        let boxed = [(-10.0, 0.5), (-10.0, 10.0)];
        let (p, r) = minimize_boxed(&Rosen, &[-1.2, 1.0], &boxed, &LmOptions::default());
        assert!(
            (p[0] - 0.5).abs() < 1e-9 && (p[1] - 0.25).abs() < 1e-6,
            "{p:?} {r:?}"
        );
    }

    /// A point on the unit circle fitted to a target direction: the retraction renormalises,
    /// so the solver works on a manifold (as the pyramid's lobe axes do).
    struct OnCircle([f64; 2]);
    impl LeastSquares for OnCircle {
        type Point = [f64; 2];
        fn n_params(&self, _: &[f64; 2]) -> usize {
            1
        }
        fn cost(&self, p: &[f64; 2]) -> f64 {
            (p[0] - self.0[0]).powi(2) + (p[1] - self.0[1]).powi(2)
        }
        fn normal_equations(&self, p: &[f64; 2], jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
            // One tangent parameter t: p(t) = p + t·(−p_y, p_x).
            let tan = [-p[1], p[0]];
            let r = [p[0] - self.0[0], p[1] - self.0[1]];
            jtj[0] = tan[0] * tan[0] + tan[1] * tan[1];
            jtr[0] = tan[0] * r[0] + tan[1] * r[1];
            self.cost(p)
        }
        fn retract(&self, p: &[f64; 2], delta: &[f64], out: &mut [f64; 2]) {
            let q = [p[0] - delta[0] * p[1], p[1] + delta[0] * p[0]];
            let l = q[0].hypot(q[1]);
            *out = [q[0] / l, q[1] / l];
        }
    }

    #[test]
    fn a_retraction_keeps_the_point_on_its_manifold() {
        let target = [0.6, 0.8];
        let mut p = [1.0, 0.0];
        let r = minimize(
            &OnCircle(target),
            &mut p,
            &LmOptions {
                rel_tolerance: 1e-12,
                ..LmOptions::default()
            },
            &mut Workspace::new(1),
        );
        assert!((p[0].hypot(p[1]) - 1.0).abs() < 1e-15);
        assert!(
            (p[0] - 0.6).abs() < 1e-7 && (p[1] - 0.8).abs() < 1e-7,
            "{p:?} {r:?}"
        );
    }

    #[test]
    fn max_tries_and_iterations_bound_the_work() {
        let mut p = vec![-1.2, 1.0];
        let b = [(-10.0, 10.0); 2];
        let opts = LmOptions {
            max_iterations: 3,
            ..LmOptions::default()
        };
        let r = minimize(
            &Boxed {
                problem: &Rosen,
                bounds: &b,
            },
            &mut p,
            &opts,
            &mut Workspace::new(2),
        );
        assert_eq!(r.iterations, 3);
        assert!(r.cost < Rosen.cost(&[-1.2, 1.0]));
        // No iteration: the cost of the start, and the start unchanged.
        let mut q = vec![-1.2, 1.0];
        let r0 = minimize(
            &Boxed {
                problem: &Rosen,
                bounds: &b,
            },
            &mut q,
            &LmOptions {
                max_iterations: 0,
                ..LmOptions::default()
            },
            &mut Workspace::new(2),
        );
        assert_eq!(q, vec![-1.2, 1.0]);
        assert_eq!(r0.cost, Rosen.cost(&q));
    }
}
