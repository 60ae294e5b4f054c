//! Amplitudes for fixed non-linear parameters: weighted non-negative linear least squares in
//! the cosine-weighted L2 sense ([`solve_amplitudes`]), the start of every LM run (variable
//! projection).
//!
//! # Conventions
//! * Amplitudes held fixed by [`BrdfModel::amplitude_bounds`] (`lo == hi`) keep their value
//!   and move to the right-hand side; the others are clamped to their bounds.
//! * The three channels share the normal matrix and are solved apart.

use super::BrdfModel;
use crate::samples::SampleSet;
use meso_core::linalg::cholesky_solve;
use rayon::prelude::*;

/// Non-negative least squares for one channel's amplitudes from the normal equations
/// (`m` row-major `nb×nb`, `v` right-hand side), by an active set that drops negative entries.
fn nnls_small(m: &[f64], v: &[f64], nb: usize) -> Vec<f64> {
    let mut free = vec![true; nb];
    for _ in 0..=nb {
        let idx: Vec<usize> = (0..nb).filter(|&j| free[j]).collect();
        let k = idx.len();
        let mut x = vec![0.0; nb];
        if k == 0 {
            return x;
        }
        let mut a = vec![0.0; k * k];
        let mut b = vec![0.0; k];
        let scale = idx
            .iter()
            .map(|&j| m[j * nb + j])
            .fold(0.0f64, f64::max)
            .max(1e-300);
        for (p, &i) in idx.iter().enumerate() {
            b[p] = v[i];
            for (q, &j) in idx.iter().enumerate() {
                a[p * k + q] = m[i * nb + j];
            }
            a[p * k + p] += 1e-12 * scale;
        }
        if !cholesky_solve(&mut a, &mut b, k) {
            return x;
        }
        let mut all_pos = true;
        for (p, &i) in idx.iter().enumerate() {
            if b[p] < 0.0 {
                free[i] = false;
                all_pos = false;
            } else {
                x[i] = b[p];
            }
        }
        if all_pos {
            return x;
        }
    }
    vec![0.0; nb]
}

/// Amplitudes for fixed `theta` by non-negative weighted least squares in the cosine-weighted L2
/// sense (a good start for either metric). Amplitudes held fixed by
/// [`BrdfModel::amplitude_bounds`] keep their value; the others are solved for and clamped to
/// their bounds.
#[must_use]
pub fn solve_amplitudes(model: &dyn BrdfModel, theta: &[f64], data: &SampleSet) -> Vec<[f64; 3]> {
    let nb = model.n_basis();
    let ab = model.amplitude_bounds();
    let (m, v) = data
        .samples
        .par_chunks(1024)
        .map(|chunk| {
            let mut m = vec![0.0; nb * nb];
            let mut v = vec![0.0; 3 * nb];
            let mut b = vec![0.0; nb];
            for s in chunk {
                model.basis(theta, s.wi, s.wo, &mut b);
                let w = s.weight * s.wi.z * s.wi.z;
                for x in 0..nb {
                    for y in 0..nb {
                        m[x * nb + y] += w * b[x] * b[y];
                    }
                    for c in 0..3 {
                        v[c * nb + x] += w * b[x] * s.rgb[c];
                    }
                }
            }
            (m, v)
        })
        .reduce(
            || (vec![0.0; nb * nb], vec![0.0; 3 * nb]),
            |(mut m, mut v), (m2, v2)| {
                m.iter_mut().zip(&m2).for_each(|(x, y)| *x += y);
                v.iter_mut().zip(&v2).for_each(|(x, y)| *x += y);
                (m, v)
            },
        );
    // Fixed amplitudes move to the right-hand side; NNLS on the free ones.
    let free: Vec<usize> = (0..nb).filter(|&j| ab[j].0 < ab[j].1).collect();
    let nf = free.len();
    let mut mf = vec![0.0; nf * nf];
    for (p, &x) in free.iter().enumerate() {
        for (q, &y) in free.iter().enumerate() {
            mf[p * nf + q] = m[x * nb + y];
        }
    }
    let per_c: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            let vf: Vec<f64> = free
                .iter()
                .map(|&x| {
                    let fixed: f64 = (0..nb)
                        .filter(|&j| ab[j].0 >= ab[j].1)
                        .map(|j| m[x * nb + j] * ab[j].0)
                        .sum();
                    v[c * nb + x] - fixed
                })
                .collect();
            let xf = nnls_small(&mf, &vf, nf);
            let mut out: Vec<f64> = ab.iter().map(|b| b.0).collect();
            for (p, &x) in free.iter().enumerate() {
                out[x] = xf[p].clamp(ab[x].0.max(0.0), ab[x].1);
            }
            out
        })
        .collect();
    (0..nb)
        .map(|j| [per_c[0][j], per_c[1][j], per_c[2][j]])
        .collect()
}
