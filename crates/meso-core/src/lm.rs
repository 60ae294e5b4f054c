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

use crate::linalg::{cholesky_solve, gauss_solve};

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
    /// Correct the step `delta` (solved from the damped normal equations, whose Cholesky factor
    /// is `factor`, row-major lower triangle) for constraints it would break, before
    /// [`LeastSquares::retract`]; `held` are the parameters held this iteration. None by
    /// default; [`Boxed`] keeps its [`SumLimit`]s this way.
    fn limit_step(&self, _p: &Self::Point, _factor: &[f64], _delta: &mut [f64], _held: &[bool]) {}
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
                problem.limit_step(p, m, delta, held);
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

/// A limit on a sum of parameters, `Σ_{j ∈ indices} p_j ≤ limit`, for parameters that are also
/// non-negative (their box's lower bound 0): e.g. the Schlick amplitudes `u = s·f0` and
/// `g = s·(1 − f0)` of a mirror whose specular scale `s = u + g` may not exceed 1.
#[derive(Clone, Debug, PartialEq)]
pub struct SumLimit {
    /// The parameters summed.
    pub indices: Vec<usize>,
    /// The largest sum allowed.
    pub limit: f64,
}

impl SumLimit {
    /// Whether `p` keeps the limit (to a relative 1e-12).
    #[must_use]
    pub fn holds(&self, p: &[f64]) -> bool {
        let sum: f64 = self.indices.iter().map(|&j| p[j]).sum();
        sum <= self.limit * (1.0 + 1e-12)
    }

    /// Scale `p`'s entries at [`SumLimit::indices`] down by one factor so that their sum is the
    /// limit (unchanged when within it): the point that keeps their proportions, e.g. a mirror's
    /// `f0` when its specular scale is brought down to 1.
    pub fn scale_into(&self, p: &mut [f64]) {
        let sum: f64 = self.indices.iter().map(|&j| p[j]).sum();
        if sum > self.limit && sum > 0.0 {
            let f = self.limit / sum;
            for &j in &self.indices {
                p[j] *= f;
            }
        }
    }

    /// Project `p`'s entries at [`SumLimit::indices`] onto `{x ≥ 0, Σ x ≤ limit}` (the nearest
    /// point in the Euclidean sense; unchanged when the sum is within the limit).
    pub fn project(&self, p: &mut [f64]) {
        let sum: f64 = self.indices.iter().map(|&j| p[j].max(0.0)).sum();
        if sum <= self.limit {
            return;
        }
        // The simplex projection: subtract the τ that brings the positive parts' sum to the limit.
        let mut v: Vec<f64> = self.indices.iter().map(|&j| p[j]).collect();
        v.sort_by(|a, b| b.total_cmp(a));
        let (mut acc, mut tau) = (0.0, 0.0);
        for (k, x) in v.iter().enumerate() {
            acc += x;
            let t = (acc - self.limit) / (k + 1) as f64;
            if *x - t > 0.0 {
                tau = t;
            }
        }
        for &j in &self.indices {
            p[j] = (p[j] - tau).max(0.0);
        }
    }
}

/// The exact minimiser of a small **linear** least-squares problem inside a box `0 ≤ x ≤ upper`
/// and under sum limits ([`SumLimit`]), from its normal equations `ata x = atb` (`ata`
/// row-major `n × n`, symmetric positive semi-definite): the linear counterpart of
/// [`minimize_limited`], for a handful of unknowns (e.g. a Lambert albedo and the two Schlick
/// amplitudes of a mirror, whose specular scale `u + g` may not exceed 1).
///
/// Every set of at most `n` active constraints is solved as equalities (its KKT system, by
/// [`gauss_solve`]); of the feasible solutions the one with the lowest cost
/// `xᵀ ata x − 2 atbᵀ x` is returned. The cost is convex, so its minimum over the feasible set
/// is among them: the result is the constrained optimum, not a clamped unconstrained one.
/// `x = 0` is always feasible (limits are non-negative), so there is always an answer. The work
/// grows as `2^(constraints)`: meant for `n` up to about 6.
///
/// # Panics
/// If `atb` or `upper` do not have `n` entries (`n² = ata.len()`), a limit names an unknown that
/// does not exist, or has a negative limit.
#[must_use]
pub fn linear_least_squares_limited(
    ata: &[f64],
    atb: &[f64],
    upper: &[f64],
    sums: &[SumLimit],
) -> Vec<f64> {
    let n = atb.len();
    assert_eq!(ata.len(), n * n, "ata is n × n");
    assert_eq!(upper.len(), n, "one upper bound per unknown");
    // Every constraint as `c·x ≤ d`.
    let mut rows: Vec<(Vec<f64>, f64)> = Vec::new();
    for j in 0..n {
        let mut c = vec![0.0; n];
        c[j] = -1.0;
        rows.push((c, 0.0));
        if upper[j].is_finite() {
            let mut c = vec![0.0; n];
            c[j] = 1.0;
            rows.push((c, upper[j]));
        }
    }
    for s in sums {
        assert!(s.limit >= 0.0, "a sum limit is non-negative");
        let mut c = vec![0.0; n];
        for &j in &s.indices {
            c[j] = 1.0;
        }
        rows.push((c, s.limit));
    }
    let m = rows.len();
    let cost = |x: &[f64]| -> f64 {
        let mut q = 0.0;
        for i in 0..n {
            let ax: f64 = (0..n).map(|k| ata[i * n + k] * x[k]).sum();
            q += x[i] * ax - 2.0 * atb[i] * x[i];
        }
        q
    };
    let feasible = |x: &[f64]| -> bool {
        rows.iter().all(|(c, d)| {
            let cx: f64 = c.iter().zip(x).map(|(a, b)| a * b).sum();
            let size: f64 = c.iter().zip(x).map(|(a, b)| (a * b).abs()).sum::<f64>() + d.abs();
            cx <= d + 1e-9 * (1.0 + size)
        })
    };
    let mut best = (vec![0.0; n], 0.0);
    let mut kkt = Vec::new();
    let mut rhs = Vec::new();
    for mask in 0u64..(1u64 << m) {
        let active: Vec<usize> = (0..m).filter(|k| mask & (1 << k) != 0).collect();
        if active.len() > n {
            continue;
        }
        let dim = n + active.len();
        kkt.clear();
        kkt.resize(dim * dim, 0.0);
        rhs.clear();
        rhs.resize(dim, 0.0);
        for i in 0..n {
            kkt[i * dim..i * dim + n].copy_from_slice(&ata[i * n..(i + 1) * n]);
            rhs[i] = atb[i];
        }
        for (r, &k) in active.iter().enumerate() {
            let (c, d) = &rows[k];
            for (j, &cj) in c.iter().enumerate() {
                kkt[(n + r) * dim + j] = cj;
                kkt[j * dim + n + r] = cj;
            }
            rhs[n + r] = *d;
        }
        if !gauss_solve(&mut kkt, &mut rhs, dim) {
            continue;
        }
        let x = &rhs[..n];
        if feasible(x) {
            let q = cost(x);
            if q < best.1 {
                best = (x.to_vec(), q);
            }
        }
    }
    // Put rounding back inside: the box, then each limit.
    let mut x = best.0;
    for (v, &u) in x.iter_mut().zip(upper) {
        *v = v.clamp(0.0, u);
    }
    for s in sums {
        s.scale_into(&mut x);
    }
    x
}

/// A [`VectorProblem`] inside box bounds `lo ≤ p ≤ hi` and sum limits ([`SumLimit`]): steps are
/// added and projected onto the box and then onto each limit, and a parameter on a bound whose
/// descent direction points outwards is held (the active set); a step that would break a limit
/// is first solved again with that limit as an equality ([`LeastSquares::limit_step`]).
#[derive(Clone, Copy, Debug)]
pub struct Boxed<'a, P> {
    /// The problem.
    pub problem: &'a P,
    /// `(lo, hi)` per parameter.
    pub bounds: &'a [(f64, f64)],
    /// Limits on sums of parameters (none for a plain box).
    pub sums: &'a [SumLimit],
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
        for s in self.sums {
            s.project(out);
        }
    }
    fn held(&self, p: &Vec<f64>, j: usize, jtr_j: f64) -> bool {
        let (lo, hi) = self.bounds[j];
        (p[j] <= lo && jtr_j > 0.0) || (p[j] >= hi && jtr_j < 0.0)
    }
    /// The limits that `p + δ` would break become equalities of the step: `δ` is replaced by
    /// the minimiser of the same damped quadratic model on them (`δ − M⁻¹Aᵀ(AM⁻¹Aᵀ)⁻¹(A(p + δ)
    /// − limit)`, `M` the damped matrix, `A` the limits' rows over the free parameters), so the
    /// step is a descent step inside the limits (a Euclidean projection of the free step is not,
    /// with a scaled `M`). Allocates only when a limit is broken.
    fn limit_step(&self, p: &Vec<f64>, factor: &[f64], delta: &mut [f64], held: &[bool]) {
        let n = delta.len();
        let over = |l: &SumLimit| l.indices.iter().map(|&j| p[j] + delta[j]).sum::<f64>() - l.limit;
        let active: Vec<&SumLimit> = self.sums.iter().filter(|l| over(l) > 0.0).collect();
        if active.is_empty() {
            return;
        }
        let k = active.len();
        let mut z = vec![0.0; k * n];
        for (c, l) in active.iter().enumerate() {
            let zc = &mut z[c * n..(c + 1) * n];
            for &j in &l.indices {
                if !held[j] {
                    zc[j] = 1.0;
                }
            }
            crate::linalg::cholesky_substitute(factor, zc, n);
        }
        let mut s = vec![0.0; k * k];
        let mut r: Vec<f64> = active.iter().map(|l| over(l)).collect();
        for (a, l) in active.iter().enumerate() {
            for b in 0..k {
                s[a * k + b] = l
                    .indices
                    .iter()
                    .filter(|&&j| !held[j])
                    .map(|&j| z[b * n + j])
                    .sum();
            }
        }
        if !cholesky_solve(&mut s, &mut r, k) {
            return;
        }
        for (c, mu) in r.iter().enumerate() {
            for (d, zj) in delta.iter_mut().zip(&z[c * n..(c + 1) * n]) {
                *d -= zj * mu;
            }
        }
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
    minimize_limited(problem, p0, bounds, &[], opts)
}

/// [`minimize_boxed`] with limits on sums of parameters ([`SumLimit`]; `p0` is projected onto
/// them too).
///
/// # Panics
/// If `p0` or `bounds` do not have the problem's number of parameters, or a limit names a
/// parameter that does not exist.
pub fn minimize_limited<P: VectorProblem>(
    problem: &P,
    p0: &[f64],
    bounds: &[(f64, f64)],
    sums: &[SumLimit],
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
    for s in sums {
        s.project(&mut p);
    }
    let r = minimize(
        &Boxed {
            problem,
            bounds,
            sums,
        },
        &mut p,
        opts,
        &mut Workspace::new(n),
    );
    (p, r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sum_limit_projects_onto_the_simplex() {
        let l = SumLimit {
            indices: vec![0, 2],
            limit: 1.0,
        };
        // Within the limit: unchanged.
        let mut p = [0.3, 9.0, 0.6];
        l.project(&mut p);
        assert_eq!(p, [0.3, 9.0, 0.6]);
        // Over it: the nearest point of the segment u + g = 1 (equal shares of the excess).
        let mut p = [0.8, 9.0, 0.6];
        l.project(&mut p);
        assert!(
            (p[0] - 0.6).abs() < 1e-12 && (p[2] - 0.4).abs() < 1e-12,
            "{p:?}"
        );
        assert_eq!(p[1], 9.0);
        // Far over on one side: the corner (1, 0).
        let mut p = [2.0, 0.0, 0.1];
        l.project(&mut p);
        assert!((p[0] - 1.0).abs() < 1e-12 && p[2] == 0.0, "{p:?}");
        // Brute force: the projection is the closest feasible point of a fine grid.
        for &(a, b) in &[(0.9, 0.7), (1.4, -0.2), (0.55, 0.55), (3.0, 2.5)] {
            let mut p = [a, 0.0, b];
            l.project(&mut p);
            let d = |x: f64, y: f64| (x - a).powi(2) + (y - b).powi(2);
            let mut best = f64::INFINITY;
            for i in 0..=1000 {
                for j in 0..=(1000 - i) {
                    best = best.min(d(i as f64 / 1000.0, j as f64 / 1000.0));
                }
            }
            assert!(d(p[0], p[2]) <= best + 1e-6, "({a}, {b}) -> {p:?}");
        }
    }

    /// The constrained linear least squares against brute force: random 3-unknown problems
    /// (albedo ≤ 1, two amplitudes with sum ≤ 1, all ≥ 0), the cost of the answer no higher than
    /// the lowest on a fine grid of the feasible set, and the answer feasible.
    #[test]
    fn linear_least_squares_limited_is_the_constrained_optimum() {
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        let mut rnd = || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let limit = [SumLimit {
            indices: vec![1, 2],
            limit: 1.0,
        }];
        let mut active_limit = 0;
        for _ in 0..40 {
            // 12 rows a·x ≈ y with y drawn around a point that may lie outside the set.
            let target = [2.0 * rnd() - 0.5, 1.6 * rnd(), 1.6 * rnd() - 0.3];
            let (mut ata, mut atb) = ([0.0; 9], [0.0; 3]);
            let mut yy = 0.0;
            for _ in 0..12 {
                let a = [rnd(), rnd(), rnd()];
                let y: f64 = (0..3).map(|k| a[k] * target[k]).sum::<f64>() + 0.05 * (rnd() - 0.5);
                for i in 0..3 {
                    atb[i] += a[i] * y;
                    for k in 0..3 {
                        ata[i * 3 + k] += a[i] * a[k];
                    }
                }
                yy += y * y;
            }
            let q = |x: &[f64]| -> f64 {
                let mut s = yy;
                for i in 0..3 {
                    s -= 2.0 * atb[i] * x[i];
                    for k in 0..3 {
                        s += x[i] * ata[i * 3 + k] * x[k];
                    }
                }
                s
            };
            let x = linear_least_squares_limited(
                &ata,
                &atb,
                &[1.0, f64::INFINITY, f64::INFINITY],
                &limit,
            );
            assert!(
                x.iter().all(|v| *v >= 0.0) && x[0] <= 1.0 && x[1] + x[2] <= 1.0 + 1e-12,
                "{x:?}"
            );
            if x[1] + x[2] > 1.0 - 1e-9 {
                active_limit += 1;
            }
            let steps = 60;
            let mut grid_best = f64::INFINITY;
            for i in 0..=steps {
                for j in 0..=steps {
                    for k in 0..=(steps - j) {
                        let p = [
                            i as f64 / steps as f64,
                            j as f64 / steps as f64,
                            k as f64 / steps as f64,
                        ];
                        grid_best = grid_best.min(q(&p));
                    }
                }
            }
            assert!(
                q(&x) <= grid_best + 1e-12,
                "{x:?}: {} > grid {grid_best}",
                q(&x)
            );
        }
        // The draws reach the limit often enough for the test to mean something.
        assert!(
            active_limit >= 5,
            "the limit was active {active_limit} times"
        );
    }

    /// `½(w₀(x − 1)² + w₁(y − 1)²)`: its unconstrained optimum (1, 1) lies outside `x + y ≤ 1`.
    struct Pull([f64; 2]);
    impl VectorProblem for Pull {
        fn n_params(&self) -> usize {
            2
        }
        fn cost(&self, p: &[f64]) -> f64 {
            0.5 * (self.0[0] * (p[0] - 1.0).powi(2) + self.0[1] * (p[1] - 1.0).powi(2))
        }
        fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
            jtj.copy_from_slice(&[self.0[0], 0.0, 0.0, self.0[1]]);
            jtr[0] = self.0[0] * (p[0] - 1.0);
            jtr[1] = self.0[1] * (p[1] - 1.0);
            self.cost(p)
        }
    }

    #[test]
    fn limited_minimum_is_on_the_limit() {
        let limit = [SumLimit {
            indices: vec![0, 1],
            limit: 1.0,
        }];
        let b = [(0.0, 1.0), (0.0, 1.0)];
        let o = LmOptions::default();
        let (p, _) = minimize_limited(&Pull([1.0, 1.0]), &[0.1, 0.0], &b, &limit, &o);
        assert!(
            (p[0] - 0.5).abs() < 1e-6 && (p[1] - 0.5).abs() < 1e-6,
            "{p:?}"
        );
        // Without the limit, the box alone: (1, 1).
        let (p, _) = minimize_boxed(&Pull([1.0, 1.0]), &[0.1, 0.0], &b, &o);
        assert!(
            (p[0] - 1.0).abs() < 1e-6 && (p[1] - 1.0).abs() < 1e-6,
            "{p:?}"
        );
        // Unequal weights, started on the limit: the minimum on x + y = 1 is where
        // w₀(x − 1) = w₁(y − 1), x = 1 − μ/w₀ with μ = 1/(1/w₀ + 1/w₁). A free step projected onto
        // the limit in the Euclidean sense is not a descent step of the scaled problem (without
        // `limit_step` this stayed at the start).
        let w = [1.0, 100.0];
        let (p, _) = minimize_limited(&Pull(w), &[0.5, 0.5], &b, &limit, &o);
        let mu = 1.0 / (1.0 / w[0] + 1.0 / w[1]);
        let want = [1.0 - mu / w[0], 1.0 - mu / w[1]];
        assert!(
            (p[0] - want[0]).abs() < 1e-6 && (p[1] - want[1]).abs() < 1e-6,
            "{p:?} vs {want:?}"
        );
    }

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
                sums: &[],
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
                sums: &[],
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
