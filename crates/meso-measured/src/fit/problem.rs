//! The non-linear least-squares problem that Levenberg–Marquardt solves for a fit: parameters
//! packed as `θ` then the amplitudes channel by channel (`[θ, A_r, A_g, A_b]`), residuals in the
//! fit's [`Objective`], and the normal equations accumulated from compact Jacobian rows.
//!
//! # Conventions
//! * One residual per sample and channel, weighted by `√weight`; the cost is half their sum of
//!   squares.
//! * A residual depends on `θ` and its own channel's amplitudes only: its Jacobian row has
//!   `nt + nb` entries, scattered into the `nt + 3·nb` parameters.
//! * `∂b/∂θ` is the model's [`BrdfModel::basis_gradient`] where it has one, else forward
//!   differences of [`BrdfModel::basis`] (steps `1e-6·(1 + |θ_k|)`, backwards at an upper
//!   bound).

use super::{eval_model, BrdfModel};
use crate::metric::Objective;
use crate::samples::Sample;
use meso_core::lm::VectorProblem;
use rayon::prelude::*;

pub(super) struct Problem<'a> {
    pub(super) model: &'a dyn BrdfModel,
    pub(super) data: &'a [Sample],
    pub(super) objective: Objective,
    pub(super) nt: usize,
    pub(super) nb: usize,
}

impl Problem<'_> {
    pub(super) fn split<'p>(&self, p: &'p [f64]) -> (&'p [f64], Vec<[f64; 3]>) {
        let (t, a) = p.split_at(self.nt);
        let amps = (0..self.nb)
            .map(|j| [a[j], a[self.nb + j], a[2 * self.nb + j]])
            .collect();
        (t, amps)
    }
}

impl VectorProblem for Problem<'_> {
    fn n_params(&self) -> usize {
        self.nt + 3 * self.nb
    }

    fn cost(&self, p: &[f64]) -> f64 {
        let (theta, amps) = self.split(p);
        let nb = self.nb;
        self.data
            .par_chunks(1024)
            .map(|chunk| {
                let mut scratch = vec![0.0; nb];
                let mut acc = 0.0;
                for s in chunk {
                    let f = eval_model(self.model, theta, &amps, s.wi, s.wo, &mut scratch);
                    for (&fc, &dc) in f.iter().zip(&s.rgb) {
                        let r = self.objective.residual(fc, dc, s.wi.z);
                        acc += s.weight * r * r;
                    }
                }
                acc
            })
            .sum::<f64>()
            * 0.5
    }

    fn normal_equations(&self, p: &[f64], jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
        let (theta, amps) = self.split(p);
        let (nt, nb) = (self.nt, self.nb);
        let n = nt + 3 * nb;
        // One residual depends on θ and on the amplitudes of its own channel only: a compact row
        // of `nt + nb` entries, scattered through `index[c]`.
        let m = nt + nb;
        let index: Vec<Vec<usize>> = (0..3)
            .map(|c| {
                (0..m)
                    .map(|x| if x < nt { x } else { nt + c * nb + (x - nt) })
                    .collect()
            })
            .collect();
        // Forward-difference steps, for models without an analytic derivative.
        let bounds = self.model.bounds();
        let steps: Vec<f64> = (0..nt)
            .map(|k| {
                let h = 1e-6 * (1.0 + theta[k].abs());
                if theta[k] + h > bounds[k].1 {
                    -h
                } else {
                    h
                }
            })
            .collect();
        let thetas: Vec<Vec<f64>> = (0..nt)
            .map(|k| {
                let mut t = theta.to_vec();
                t[k] += steps[k];
                t
            })
            .collect();
        let (a, g, cost) = self
            .data
            .par_chunks(512)
            .map(|chunk| {
                let mut a = vec![0.0; n * n];
                let mut g = vec![0.0; n];
                let mut cost = 0.0;
                let mut b0 = vec![0.0; nb];
                let mut db = vec![0.0; nt * nb];
                let mut bk = vec![0.0; nb];
                let mut row = vec![0.0; m];
                for s in chunk {
                    if !self
                        .model
                        .basis_gradient(theta, s.wi, s.wo, &mut b0, &mut db)
                    {
                        self.model.basis(theta, s.wi, s.wo, &mut b0);
                        for k in 0..nt {
                            self.model.basis(&thetas[k], s.wi, s.wo, &mut bk);
                            for j in 0..nb {
                                db[k * nb + j] = (bk[j] - b0[j]) / steps[k];
                            }
                        }
                    }
                    let sw = s.weight.sqrt();
                    for (c, idx) in index.iter().enumerate() {
                        let f: f64 = (0..nb).map(|j| amps[j][c] * b0[j]).sum();
                        let r = sw * self.objective.residual(f, s.rgb[c], s.wi.z);
                        let dr = sw * self.objective.d_residual(f, s.rgb[c], s.wi.z);
                        cost += r * r;
                        for k in 0..nt {
                            let d = &db[k * nb..(k + 1) * nb];
                            let df: f64 = (0..nb).map(|j| amps[j][c] * d[j]).sum();
                            row[k] = dr * df;
                        }
                        for j in 0..nb {
                            row[nt + j] = dr * b0[j];
                        }
                        for x in 0..m {
                            let rx = row[x];
                            if rx == 0.0 {
                                continue;
                            }
                            let ix = idx[x];
                            g[ix] += rx * r;
                            let ax = &mut a[ix * n..(ix + 1) * n];
                            for y in x..m {
                                ax[idx[y]] += rx * row[y];
                            }
                        }
                    }
                }
                (a, g, cost)
            })
            .reduce(
                || (vec![0.0; n * n], vec![0.0; n], 0.0),
                |(mut a, mut g, c), (a2, g2, c2)| {
                    a.iter_mut().zip(&a2).for_each(|(x, y)| *x += y);
                    g.iter_mut().zip(&g2).for_each(|(x, y)| *x += y);
                    (a, g, c + c2)
                },
            );
        for x in 0..n {
            jtr[x] = g[x];
            for y in x..n {
                jtj[x * n + y] = a[x * n + y];
                jtj[y * n + x] = a[x * n + y];
            }
        }
        0.5 * cost
    }
}

pub(super) fn pack(theta: &[f64], amps: &[[f64; 3]]) -> Vec<f64> {
    let nb = amps.len();
    let mut p = theta.to_vec();
    for c in 0..3 {
        for a in amps.iter().take(nb) {
            p.push(a[c]);
        }
    }
    p
}
