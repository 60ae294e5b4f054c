//! An isotropic NDF tabulated in the polar angle `θ_m` alone: the **non-parametric** NDF of a
//! measured material (#13, after Dupuy et al. 2015 and Bagher et al. 2016), `n(m) = n(θ_m)`.
//!
//! * **Density:** linear in `θ_m` between nodes `θ_0 = 0 < θ_1 < … < θ_{N−1} ≤ π/2`; 0 beyond
//!   the last node and below the horizon. Normalised on construction so that `∫ n dω = 1` over
//!   the sphere (Eq. 1), with the exact integral of each linear piece,
//!   `2π ∫ (a + bθ) sin θ dθ = 2π [b sin θ − (a + bθ) cos θ]`.
//! * **Sampler:** a band `[θ_j, θ_{j+1}]` by its exact mass, then `cos θ` uniform within it and
//!   `φ` uniform: its density [`Radial::pdf`] is the band's mean density (piecewise constant),
//!   close to `n` where the bands are narrow (the sampler's own pdf is exact, chi-square tested).
//! * Nodes are typically MERL's half-angle bins `θ_h = (k/90)² · 90°`, dense near the normal
//!   where glossy peaks live.

use super::NdfError;
use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, PI};

/// Most nodes a [`Radial`] NDF may have.
pub const MAX_NODES: usize = 4096;

/// An isotropic NDF tabulated in `θ_m` (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct Radial {
    /// Node polar angles in radians, increasing from 0 to at most π/2.
    theta: Vec<f64>,
    /// `n(θ_j)` in 1/sr, normalised.
    values: Vec<f64>,
    /// Cumulative mass at each node (`cdf[0] = 0`, last = 1).
    cdf: Vec<f64>,
    /// Root-mean-square polar angle of the normals (radians), for quadrature warps.
    rms_theta: f64,
}

/// `2π ∫_{t0}^{t1} (a + bθ) sin θ dθ` for the linear piece through `(t0, v0)`, `(t1, v1)`.
fn piece_mass(t0: f64, t1: f64, v0: f64, v1: f64) -> f64 {
    let b = (v1 - v0) / (t1 - t0);
    let a = v0 - b * t0;
    let f = |t: f64| b * t.sin() - (a + b * t) * t.cos();
    2.0 * PI * (f(t1) - f(t0))
}

/// `2π ∫_{t0}^{t1} (a + bθ) θ² sin θ dθ` by 8-point Gauss–Legendre (for the rms angle only).
fn piece_theta2(t0: f64, t1: f64, v0: f64, v1: f64) -> f64 {
    const X: [f64; 4] = [
        0.183_434_642_495_649_8,
        0.525_532_409_916_329,
        0.796_666_477_413_626_7,
        0.960_289_856_497_536_3,
    ];
    const W: [f64; 4] = [
        0.362_683_783_378_362,
        0.313_706_645_877_887_3,
        0.222_381_034_453_374_5,
        0.101_228_536_290_376_3,
    ];
    let (h, c) = (0.5 * (t1 - t0), 0.5 * (t1 + t0));
    let mut s = 0.0;
    for (x, w) in X.iter().zip(W) {
        for t in [c - h * x, c + h * x] {
            let v = v0 + (v1 - v0) * (t - t0) / (t1 - t0);
            s += w * v * t * t * t.sin();
        }
    }
    2.0 * PI * h * s
}

impl Radial {
    /// An NDF from nodes `theta` (radians: `theta[0] = 0`, strictly increasing, at most π/2)
    /// and densities `values` (≥ 0, finite; any scale: normalised here to Eq. 1).
    ///
    /// # Errors
    /// Fewer than 2 or more than [`MAX_NODES`] nodes, lengths that differ, nodes out of order or
    /// range, negative or non-finite densities, or no mass at all.
    pub fn new(theta: Vec<f64>, values: Vec<f64>) -> Result<Radial, NdfError> {
        let bad = |m: String| Err(NdfError::Invalid(format!("radial NDF: {m}")));
        if theta.len() != values.len() {
            return bad(format!(
                "{} angles but {} densities",
                theta.len(),
                values.len()
            ));
        }
        if theta.len() < 2 || theta.len() > MAX_NODES {
            return bad(format!("{} nodes (need 2 to {MAX_NODES})", theta.len()));
        }
        if theta[0] != 0.0 {
            return bad(format!("the first angle must be 0, got {}", theta[0]));
        }
        for (k, w) in theta.windows(2).enumerate() {
            if w[1].partial_cmp(&w[0]) != Some(std::cmp::Ordering::Greater) || !w[1].is_finite() {
                return bad(format!(
                    "angles must increase strictly: node {} is {} after {}",
                    k + 1,
                    w[1],
                    w[0]
                ));
            }
        }
        let last = *theta.last().unwrap_or(&0.0);
        if last > FRAC_PI_2 + 1e-12 {
            return bad(format!(
                "the last angle {:.6} rad is past the horizon (π/2)",
                last
            ));
        }
        if let Some((k, v)) = values
            .iter()
            .enumerate()
            .find(|(_, v)| !v.is_finite() || **v < 0.0)
        {
            return bad(format!("density {k} is {v} (must be finite and ≥ 0)"));
        }
        let mut cdf = Vec::with_capacity(theta.len());
        cdf.push(0.0);
        let mut total = 0.0;
        let mut second = 0.0;
        for j in 0..theta.len() - 1 {
            total += piece_mass(theta[j], theta[j + 1], values[j], values[j + 1]);
            second += piece_theta2(theta[j], theta[j + 1], values[j], values[j + 1]);
            cdf.push(total);
        }
        if total.is_nan() || total <= 0.0 || !total.is_finite() {
            return bad("the densities have no mass".to_owned());
        }
        let values = values.into_iter().map(|v| v / total).collect();
        cdf.iter_mut().for_each(|c| *c /= total);
        Ok(Radial {
            theta,
            values,
            cdf,
            rms_theta: (second / total).sqrt(),
        })
    }

    /// The node angles (radians).
    #[must_use]
    pub fn theta(&self) -> &[f64] {
        &self.theta
    }

    /// The normalised densities at the nodes (1/sr).
    #[must_use]
    pub fn values(&self) -> &[f64] {
        &self.values
    }

    /// Root-mean-square polar angle of the normals (radians).
    #[must_use]
    pub fn rms_theta(&self) -> f64 {
        self.rms_theta
    }

    /// The density at polar angle `t` (radians).
    #[must_use]
    pub fn eval_theta(&self, t: f64) -> f64 {
        let last = self.theta.len() - 1;
        if t.is_nan() || t < 0.0 || t > self.theta[last] {
            return 0.0;
        }
        let j = self.theta.partition_point(|&x| x <= t).clamp(1, last) - 1;
        let (t0, t1) = (self.theta[j], self.theta[j + 1]);
        let s = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
        self.values[j] + (self.values[j + 1] - self.values[j]) * s
    }

    /// The density `n(m)` (1/sr) at the unit direction `m`.
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        self.eval_theta((m.x * m.x + m.y * m.y).sqrt().atan2(m.z))
    }

    /// Draw a normal with density [`Radial::pdf`]; `u ∈ [0, 1)²`.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let last = self.theta.len() - 1;
        let j = self.cdf.partition_point(|&c| c <= u[0]).clamp(1, last) - 1;
        let span = self.cdf[j + 1] - self.cdf[j];
        let s = if span > 0.0 {
            ((u[0] - self.cdf[j]) / span).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let (c0, c1) = (self.theta[j].cos(), self.theta[j + 1].cos());
        let cz = c0 + (c1 - c0) * s;
        let sz = (1.0 - cz * cz).max(0.0).sqrt();
        let phi = 2.0 * PI * u[1];
        DVec3::new(sz * phi.cos(), sz * phi.sin(), cz)
    }

    /// The density (1/sr) of [`Radial::sample`] at `m`: the mean density of its band.
    #[must_use]
    pub fn pdf(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let t = (m.x * m.x + m.y * m.y).sqrt().atan2(m.z);
        let last = self.theta.len() - 1;
        if t > self.theta[last] {
            return 0.0;
        }
        let j = self.theta.partition_point(|&x| x <= t).clamp(1, last) - 1;
        let solid = 2.0 * PI * (self.theta[j].cos() - self.theta[j + 1].cos());
        (self.cdf[j + 1] - self.cdf[j]) / solid
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_tables_are_refused_with_the_reason() {
        for (t, v, want) in [
            (vec![0.0], vec![1.0], "nodes"),
            (vec![0.0, 0.5], vec![1.0], "densities"),
            (vec![0.1, 0.5], vec![1.0, 1.0], "first angle"),
            (vec![0.0, 0.5, 0.4], vec![1.0, 1.0, 1.0], "increase"),
            (vec![0.0, 2.0], vec![1.0, 1.0], "horizon"),
            (vec![0.0, 0.5], vec![1.0, f64::NAN], "finite"),
            (vec![0.0, 0.5], vec![1.0, -1.0], "finite"),
            (vec![0.0, 0.5], vec![0.0, 0.0], "no mass"),
        ] {
            let e = Radial::new(t, v).unwrap_err().to_string();
            assert!(e.contains(want), "{e}");
        }
    }

    #[test]
    fn mass_and_rms_of_a_uniform_cap_are_exact() {
        // Constant density on the cap θ ≤ 0.3: mass 2π(1 − cos 0.3)·v.
        let r = Radial::new(vec![0.0, 0.1, 0.3], vec![2.0, 2.0, 2.0]).unwrap();
        let v = 1.0 / (2.0 * PI * (1.0 - 0.3f64.cos()));
        assert!((r.values()[0] - v).abs() < 1e-12 * v);
        assert!((r.eval(DVec3::Z) - v).abs() < 1e-12 * v);
        assert_eq!(r.eval(DVec3::new(1.0, 0.0, 0.0)), 0.0);
        // E[θ²] on the cap: ∫θ² sinθ / ∫ sinθ over [0, 0.3].
        let num = {
            let f = |t: f64| (2.0 - t * t) * t.cos() + 2.0 * t * t.sin();
            f(0.3) - f(0.0)
        };
        let e2 = num / (1.0 - 0.3f64.cos());
        assert!((r.rms_theta() - e2.sqrt()).abs() < 1e-9);
    }
}
