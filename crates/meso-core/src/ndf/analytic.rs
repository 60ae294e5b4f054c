//! Analytic NDFs of simple geometry (§3.1) and the von Mises–Fisher lobe.
//!
//! * [`Sphere`] — Eq. 14: a sphere has every normal once, `n = 1/(4π)`.
//! * [`Cylinder`] — Eq. 15: the normals of a cylinder lie on the great circle perpendicular to
//!   its axis, uniformly: `n(m) = δ(m · a)/(2π)` (a line density; `∫ δ(m·a) dω = 2π`). The paper
//!   writes `½ δ(φ)` for the cylinder "with axis in the φ = 0 direction": its normals fill the
//!   plane containing the surface normal and perpendicular to the axis, split evenly between the two
//!   half-planes; here the axis is any unit vector. `half = true` keeps only the upper half circle
//!   (`m·z ≥ 0`) — a half-cylinder lying on a plane, the bump of a corrugated surface.
//! * [`VonMisesFisher`] — `n(m) = κ / (2π (1 − e^{−2κ})) · e^{κ(μ·m − 1)}`, the lobe that a Phong
//!   peak `cos^η(α/2)` approaches with `κ = η/4`.

use crate::frame::Frame;
use glam::DVec3;
use std::f64::consts::PI;

/// The NDF of a sphere, Eq. 14: uniform, `1/(4π)` per sr.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Sphere;

impl Sphere {
    /// `1/(4π)`.
    #[must_use]
    pub fn eval(&self, _m: DVec3) -> f64 {
        1.0 / (4.0 * PI)
    }

    /// Uniform direction on the sphere.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let z = 1.0 - 2.0 * u[0];
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * u[1];
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// The NDF of a cylinder, Eq. 15: normals uniform on the great circle perpendicular to `axis`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cylinder {
    /// Unit axis of the cylinder in the local frame (e.g. +x for a cylinder lying along the tangent).
    pub axis: DVec3,
    /// Keep only normals with `m·z ≥ 0` (a half-cylinder on a plane).
    pub half: bool,
}

impl Cylinder {
    /// A cylinder with the given axis (normalised here).
    ///
    /// # Errors
    /// When the axis is not a finite non-zero vector, or `half` is asked of an axis along ±z
    /// (whose circle of normals is the horizon).
    pub fn new(axis: DVec3, half: bool) -> Result<Cylinder, crate::NdfError> {
        let l = axis.length();
        if !(l.is_finite() && l > 1e-12) {
            return Err(crate::NdfError::Invalid(
                "cylinder axis must be a finite non-zero vector".into(),
            ));
        }
        let axis = axis / l;
        if half && axis.z.abs() > 1.0 - 1e-9 {
            return Err(crate::NdfError::Invalid(
                "a half cylinder needs an axis that is not along the normal".into(),
            ));
        }
        Ok(Cylinder { axis, half })
    }

    /// Two unit vectors spanning the circle of normals: `e1` is the in-circle direction closest to
    /// +z (the "top" of the cylinder), `e2 = axis × e1`.
    #[must_use]
    pub fn circle_basis(&self) -> (DVec3, DVec3) {
        let f = Frame::from_normal_tangent(self.axis, DVec3::Z);
        // f.t is the projection of +z onto the plane ⊥ axis (or arbitrary when axis ∥ z).
        (f.t, f.b)
    }

    /// The half-angle range of the circle parameter ψ: normals are `cos ψ e1 + sin ψ e2` with
    /// ψ ∈ [−range, range].
    #[must_use]
    pub fn psi_range(&self) -> f64 {
        if self.half {
            // e1·z = sin(angle of axis to z) > 0; m·z = cos ψ (e1·z) ≥ 0 ⇔ |ψ| ≤ π/2.
            0.5 * PI
        } else {
            PI
        }
    }

    /// The normal at circle parameter ψ.
    #[must_use]
    pub fn normal_at(&self, psi: f64) -> DVec3 {
        let (e1, e2) = self.circle_basis();
        e1 * psi.cos() + e2 * psi.sin()
    }

    /// Sample a normal uniformly on the (half) circle.
    #[must_use]
    pub fn sample(&self, u: f64) -> DVec3 {
        let r = self.psi_range();
        self.normal_at(-r + 2.0 * r * u)
    }
}

/// The von Mises–Fisher distribution on the sphere, mean direction `mu`, concentration `kappa`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VonMisesFisher {
    /// Unit mean direction.
    pub mu: DVec3,
    /// Concentration κ > 0 (1/rad²-like; the lobe's angular variance is about 2/κ).
    pub kappa: f64,
}

impl VonMisesFisher {
    /// A vMF lobe.
    ///
    /// # Errors
    /// When κ is not finite and positive or `mu` is not a finite non-zero vector.
    pub fn new(mu: DVec3, kappa: f64) -> Result<VonMisesFisher, crate::NdfError> {
        let l = mu.length();
        if !(l.is_finite() && l > 1e-12) {
            return Err(crate::NdfError::Invalid(
                "vMF mean direction must be a finite non-zero vector".into(),
            ));
        }
        if !(kappa.is_finite() && kappa > 0.0) {
            return Err(crate::NdfError::Invalid(format!(
                "vMF kappa must be finite and > 0, got {kappa}"
            )));
        }
        Ok(VonMisesFisher { mu: mu / l, kappa })
    }

    /// Density in 1/sr.
    #[must_use]
    pub fn eval(&self, m: DVec3) -> f64 {
        crate::sg::Sg::normalised(self.mu, self.kappa).eval(m)
    }

    /// Exact sampling (Wood 1994 / Jakob 2012): the cosine to the mean by the inverse CDF
    /// [`crate::sg::sample_cos`], the azimuth uniform.
    #[must_use]
    pub fn sample(&self, u: [f64; 2]) -> DVec3 {
        let w = crate::sg::sample_cos(self.kappa, u[0]);
        let s = (1.0 - w * w).max(0.0).sqrt();
        let phi = 2.0 * PI * u[1];
        Frame::from_normal(self.mu).to_world(DVec3::new(s * phi.cos(), s * phi.sin(), w))
    }
}
