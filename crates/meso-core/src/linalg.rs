//! Small dense linear algebra for the fitters (normal equations of Levenberg–Marquardt steps,
//! a few to a few dozen unknowns): no allocation, row-major slices.

/// Solve the symmetric positive definite system `a x = b` by Cholesky, in place (`a` row-major
/// `n × n`, destroyed; `b` becomes `x`). Returns `false` if `a` is not positive definite (or
/// holds NaN or infinities).
pub fn cholesky_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    for j in 0..n {
        let mut d = a[j * n + j];
        for k in 0..j {
            d -= a[j * n + k] * a[j * n + k];
        }
        if d.is_nan() || d <= 0.0 || !d.is_finite() {
            return false;
        }
        let d = d.sqrt();
        a[j * n + j] = d;
        for i in j + 1..n {
            let mut s = a[i * n + j];
            for k in 0..j {
                s -= a[i * n + k] * a[j * n + k];
            }
            a[i * n + j] = s / d;
        }
    }
    cholesky_substitute(a, b, n);
    true
}

/// Solve `L Lᵀ x = b` in place (`b` becomes `x`) with the factor `L` that [`cholesky_solve`]
/// leaves in the lower triangle of its `a` (row-major `n × n`): further right-hand sides of a
/// system already factored.
pub fn cholesky_substitute(l: &[f64], b: &mut [f64], n: usize) {
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i * n + k] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in i + 1..n {
            s -= l[k * n + i] * b[k];
        }
        b[i] = s / l[i * n + i];
    }
}

/// Solve the square system `a x = b` by Gaussian elimination with partial pivoting, in place
/// (`a` row-major `n × n`, destroyed; `b` becomes `x`): for systems that are not positive
/// definite (the KKT systems of constrained least squares). A pivot below `1e-13` times the
/// largest entry of `a` counts as singular: its unknown is set to 0 and the result is `false`.
pub fn gauss_solve(a: &mut [f64], b: &mut [f64], n: usize) -> bool {
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tiny = 1e-13 * scale;
    let mut regular = scale.is_finite() && scale > 0.0;
    for col in 0..n {
        let piv = (col..n)
            .max_by(|&x, &y| a[x * n + col].abs().total_cmp(&a[y * n + col].abs()))
            .unwrap_or(col);
        if piv != col {
            for k in 0..n {
                a.swap(col * n + k, piv * n + k);
            }
            b.swap(col, piv);
        }
        let d = a[col * n + col];
        if d.abs() <= tiny {
            regular = false;
            continue;
        }
        for r in col + 1..n {
            let f = a[r * n + col] / d;
            if f != 0.0 {
                for k in col..n {
                    a[r * n + k] -= f * a[col * n + k];
                }
                b[r] -= f * b[col];
            }
        }
    }
    for r in (0..n).rev() {
        let d = a[r * n + r];
        if d.abs() <= tiny {
            b[r] = 0.0;
            continue;
        }
        let mut acc = b[r];
        for k in r + 1..n {
            acc -= a[r * n + k] * b[k];
        }
        b[r] = acc / d;
    }
    regular && b.iter().all(|v| v.is_finite())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gauss_solves_indefinite_systems_and_reports_singular_ones() {
        // A KKT matrix: [[2, 0, 1], [0, 2, 1], [1, 1, 0]] (min x² + y² with x + y = 1).
        let mut a = vec![2.0, 0.0, 1.0, 0.0, 2.0, 1.0, 1.0, 1.0, 0.0];
        let mut b = vec![0.0, 0.0, 1.0];
        assert!(gauss_solve(&mut a, &mut b, 3));
        assert!(
            (b[0] - 0.5).abs() < 1e-15 && (b[1] - 0.5).abs() < 1e-15 && (b[2] + 1.0).abs() < 1e-15
        );
        let mut a = vec![1.0, 2.0, 2.0, 4.0];
        let mut b = vec![1.0, 2.0];
        assert!(!gauss_solve(&mut a, &mut b, 2));
    }

    #[test]
    fn cholesky_solves() {
        let mut a = vec![4.0, 2.0, 0.6, 2.0, 5.0, 1.0, 0.6, 1.0, 3.0];
        let a0 = a.clone();
        let x = [1.0, -2.0, 0.5];
        let mut b: Vec<f64> = (0..3)
            .map(|i| (0..3).map(|k| a0[i * 3 + k] * x[k]).sum())
            .collect();
        assert!(cholesky_solve(&mut a, &mut b, 3));
        for i in 0..3 {
            assert!((b[i] - x[i]).abs() < 1e-12);
        }
        let mut bad = vec![1.0, 2.0, 2.0, 1.0];
        assert!(!cholesky_solve(&mut bad, &mut [1.0, 1.0], 2));
    }
}
