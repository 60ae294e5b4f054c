//! Fresnel reflectance for a facet, per RGB channel, as a function of `cos θ` between the
//! direction and the facet normal.

/// The Fresnel term of a facet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Fresnel {
    /// Reflectance 1 at every angle ("none").
    None,
    /// A conductor with complex index `η + i k` per channel (exact unpolarised formula).
    Conductor {
        /// Real part of the relative index, per channel.
        eta: [f64; 3],
        /// Extinction coefficient, per channel.
        k: [f64; 3],
    },
    /// A dielectric with relative index `η` (outside → inside), exact unpolarised formula with
    /// total internal reflection for `η < 1`.
    Dielectric {
        /// Relative index of refraction.
        eta: f64,
    },
    /// Schlick's approximation `F0 + (1 − F0)(1 − cos θ)⁵`.
    Schlick {
        /// Normal-incidence reflectance per channel.
        f0: [f64; 3],
    },
}

impl Fresnel {
    /// Reflectance per channel at `cos θ` (clamped to `[0, 1]`).
    #[must_use]
    pub fn eval(&self, cos_theta: f64) -> [f64; 3] {
        let c = cos_theta.clamp(0.0, 1.0);
        match *self {
            Fresnel::None => [1.0; 3],
            Fresnel::Dielectric { eta } => [dielectric(c, eta); 3],
            Fresnel::Conductor { eta, k } => [
                conductor(c, eta[0], k[0]),
                conductor(c, eta[1], k[1]),
                conductor(c, eta[2], k[2]),
            ],
            Fresnel::Schlick { f0 } => {
                let t = (1.0 - c).powi(5);
                [
                    f0[0] + (1.0 - f0[0]) * t,
                    f0[1] + (1.0 - f0[1]) * t,
                    f0[2] + (1.0 - f0[2]) * t,
                ]
            }
        }
    }
}

/// Unpolarised dielectric reflectance.
#[must_use]
pub fn dielectric(cos_i: f64, eta: f64) -> f64 {
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Unpolarised conductor reflectance for the complex index `η + i k` (e.g. pbrt-v4's
/// `FrComplex`, written with real arithmetic).
#[must_use]
pub fn conductor(cos_i: f64, eta: f64, k: f64) -> f64 {
    let c2 = cos_i * cos_i;
    let s2 = 1.0 - c2;
    let e2 = eta * eta;
    let k2 = k * k;
    let t0 = e2 - k2 - s2;
    let a2b2 = (t0 * t0 + 4.0 * e2 * k2).sqrt();
    let a = (0.5 * (a2b2 + t0)).max(0.0).sqrt();
    let t1 = a2b2 + c2;
    let t2 = 2.0 * cos_i * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + s2 * s2;
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    0.5 * (rs + rp)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_closed_forms() {
        // F(0) = ((η−1)/(η+1))² for a dielectric; ((η−1)² + k²)/((η+1)² + k²) for a conductor.
        assert!((dielectric(1.0, 1.5) - 0.04).abs() < 1e-12);
        let (e, k) = (0.2, 3.9);
        let f0 = ((e - 1.0f64).powi(2) + k * k) / ((e + 1.0f64).powi(2) + k * k);
        assert!((conductor(1.0, e, k) - f0).abs() < 1e-12);
        // k = 0 conductor equals the dielectric.
        for c in [0.1, 0.5, 0.9] {
            assert!((conductor(c, 1.5, 0.0) - dielectric(c, 1.5)).abs() < 1e-12);
        }
        // Grazing incidence reflects everything.
        assert!((dielectric(0.0, 1.5) - 1.0).abs() < 1e-12);
        assert!((conductor(1e-9, 0.2, 3.9) - 1.0).abs() < 1e-6);
    }
}
