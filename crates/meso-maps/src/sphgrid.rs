//! An equal-area grid on the whole sphere (Clarberg's octahedral equal-area map, as in pbrt-v4),
//! used to bin normals into histograms and to measure NDF errors.
//!
//! The square `[0,1]²` is split into `R × R` pixels; every pixel covers exactly `4π/R²` sr.

use glam::DVec3;
use std::f64::consts::{FRAC_PI_4, PI};

/// Map a unit direction to `[0,1]²` (equal-area).
#[must_use]
pub fn sphere_to_square(d: DVec3) -> (f64, f64) {
    let (x, y, z) = (d.x.abs(), d.y.abs(), d.z.abs());
    let r = (1.0 - z).max(0.0).sqrt();
    let a = x.max(y);
    let b = x.min(y);
    let b = if a == 0.0 { 0.0 } else { b / a };
    let mut phi = b.atan() * 2.0 / PI;
    if x < y {
        phi = 1.0 - phi;
    }
    let mut v = phi * r;
    let mut u = r - v;
    if d.z < 0.0 {
        std::mem::swap(&mut u, &mut v);
        u = 1.0 - u;
        v = 1.0 - v;
    }
    u = u.copysign(d.x);
    v = v.copysign(d.y);
    (0.5 * (u + 1.0), 0.5 * (v + 1.0))
}

/// Map a point of `[0,1]²` to a unit direction (inverse of [`sphere_to_square`]).
#[must_use]
pub fn square_to_sphere(p: (f64, f64)) -> DVec3 {
    let u = 2.0 * p.0 - 1.0;
    let v = 2.0 * p.1 - 1.0;
    let (up, vp) = (u.abs(), v.abs());
    let sd = 1.0 - (up + vp);
    let d = sd.abs();
    let r = 1.0 - d;
    let phi = if r == 0.0 { 1.0 } else { (vp - up) / r + 1.0 } * FRAC_PI_4;
    let z = (1.0 - r * r).copysign(sd);
    let cp = phi.cos().copysign(u);
    let sp = phi.sin().copysign(v);
    let s = r * (2.0 - r * r).max(0.0).sqrt();
    DVec3::new(cp * s, sp * s, z)
}

/// An `R × R` equal-area grid of the sphere.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SphereGrid {
    /// Pixels per side.
    pub res: usize,
}

impl SphereGrid {
    /// Number of bins `R²`.
    #[must_use]
    pub fn bins(&self) -> usize {
        self.res * self.res
    }
    /// Solid angle of one bin, `4π/R²` sr.
    #[must_use]
    pub fn bin_solid_angle(&self) -> f64 {
        4.0 * PI / (self.res * self.res) as f64
    }
    /// The bin containing a unit direction.
    #[inline]
    #[must_use]
    pub fn bin(&self, d: DVec3) -> usize {
        let (u, v) = sphere_to_square(d);
        let r = self.res;
        let iu = ((u * r as f64) as usize).min(r - 1);
        let iv = ((v * r as f64) as usize).min(r - 1);
        iv * r + iu
    }
    /// The direction at fractional position `(a, b) ∈ [0,1]²` inside bin `k`.
    #[inline]
    #[must_use]
    pub fn point(&self, k: usize, a: f64, b: f64) -> DVec3 {
        let r = self.res as f64;
        let (iu, iv) = ((k % self.res) as f64, (k / self.res) as f64);
        square_to_sphere(((iu + a) / r, (iv + b) / r))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_equal_area() {
        let g = SphereGrid { res: 16 };
        // Round trip of pixel centres.
        for k in 0..g.bins() {
            let d = g.point(k, 0.5, 0.5);
            assert!((d.length() - 1.0).abs() < 1e-12);
            assert_eq!(g.bin(d), k);
        }
        // Equal area: uniform directions (Fibonacci sphere) fill bins evenly.
        let n = 400_000;
        let mut counts = vec![0usize; g.bins()];
        let ga = PI * (3.0 - 5f64.sqrt());
        for s in 0..n {
            let z = 1.0 - 2.0 * (s as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let p = ga * s as f64;
            counts[g.bin(DVec3::new(r * p.cos(), r * p.sin(), z))] += 1;
        }
        let mean = n as f64 / g.bins() as f64;
        for c in counts {
            assert!((c as f64 / mean - 1.0).abs() < 0.03, "{c} vs {mean}");
        }
    }
}
