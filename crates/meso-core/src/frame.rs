//! Directions, local frames and spherical coordinates — the one place where meso's
//! conventions are written down.
//!
//! # Conventions
//! * A direction is a unit [`DVec3`]. Directions used in BRDFs point *away* from the surface
//!   (towards the light for `i`, towards the viewer for `o`).
//! * The local ("Frenet") frame of a surface point has the **normal on +z**, the **tangent on +x**
//!   and the **bitangent on +y** (right-handed: `t × b = n`).
//! * Spherical coordinates: θ is the polar angle from +z (the normal), in `[0, π]`; φ is the
//!   azimuth from +x (the tangent) towards +y, in `[0, 2π)`.
//! * Angles are radians in code; degrees only in files and on the command line
//!   (see [`deg_to_rad`] / [`rad_to_deg`]).
//! * The upper hemisphere is `z > 0`. Solid angle is in steradians.

use glam::DVec3;
use std::f64::consts::PI;

/// Degrees → radians.
#[inline]
#[must_use]
pub fn deg_to_rad(d: f64) -> f64 {
    d * (PI / 180.0)
}

/// Radians → degrees.
#[inline]
#[must_use]
pub fn rad_to_deg(r: f64) -> f64 {
    r * (180.0 / PI)
}

/// Unit direction from spherical coordinates (θ from +z, φ from +x towards +y), radians.
#[inline]
#[must_use]
pub fn spherical_direction(theta: f64, phi: f64) -> DVec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    DVec3::new(st * cp, st * sp, ct)
}

/// Unit direction from spherical coordinates given in **degrees** (file / CLI convention).
#[inline]
#[must_use]
pub fn spherical_direction_deg(theta_deg: f64, phi_deg: f64) -> DVec3 {
    spherical_direction(deg_to_rad(theta_deg), deg_to_rad(phi_deg))
}

/// Spherical coordinates `(θ, φ)` in radians of a (not necessarily unit) non-zero vector;
/// φ is wrapped into `[0, 2π)`.
#[inline]
#[must_use]
pub fn spherical_angles(v: DVec3) -> (f64, f64) {
    let r = v.length();
    let theta = (v.z / r).clamp(-1.0, 1.0).acos();
    let mut phi = v.y.atan2(v.x);
    if phi < 0.0 {
        phi += 2.0 * PI;
    }
    (theta, phi)
}

/// cos θ of a unit direction in the local frame.
#[inline]
#[must_use]
pub fn cos_theta(w: DVec3) -> f64 {
    w.z
}

/// The unit half vector `H = (i + o)/|i + o|` of two unit directions (Blinn's bisector, Eq. 10).
/// Returns `None` when the directions are opposite (no bisector).
#[inline]
#[must_use]
pub fn half_vector(i: DVec3, o: DVec3) -> Option<DVec3> {
    let h = i + o;
    let l2 = h.length_squared();
    if l2 < 1e-24 {
        None
    } else {
        Some(h / l2.sqrt())
    }
}

/// Mirror reflection of the unit direction `w` about the unit normal `n` (both pointing away).
#[inline]
#[must_use]
pub fn reflect(w: DVec3, n: DVec3) -> DVec3 {
    2.0 * w.dot(n) * n - w
}

/// An orthonormal frame: `t` (tangent, local +x), `b` (bitangent, local +y), `n` (normal, local +z).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Tangent, local +x.
    pub t: DVec3,
    /// Bitangent, local +y.
    pub b: DVec3,
    /// Normal, local +z.
    pub n: DVec3,
}

impl Frame {
    /// The identity frame (world = local).
    pub const IDENTITY: Frame = Frame {
        t: DVec3::X,
        b: DVec3::Y,
        n: DVec3::Z,
    };

    /// A frame around the unit normal `n` with a tangent chosen without branching on the
    /// hemisphere (Duff et al. 2017, "Building an orthonormal basis, revisited"). The tangent is
    /// continuous except where `n.z = -1`; use [`Frame::from_normal_tangent`] when the tangent
    /// direction matters (anisotropic lobes).
    #[must_use]
    pub fn from_normal(n: DVec3) -> Frame {
        let sign = 1.0f64.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let bb = n.x * n.y * a;
        let t = DVec3::new(1.0 + sign * n.x * n.x * a, sign * bb, -sign * n.x);
        let b = DVec3::new(bb, sign + n.y * n.y * a, -n.y);
        Frame { t, b, n }
    }

    /// A frame with normal `n` and the tangent closest to `tangent` (Gram–Schmidt). Falls back to
    /// [`Frame::from_normal`] when `tangent` is (nearly) parallel to `n`.
    #[must_use]
    pub fn from_normal_tangent(n: DVec3, tangent: DVec3) -> Frame {
        let t = tangent - n * n.dot(tangent);
        let l = t.length();
        if l < 1e-9 {
            return Frame::from_normal(n);
        }
        let t = t / l;
        Frame {
            t,
            b: n.cross(t),
            n,
        }
    }

    /// Express a world direction in this frame's local coordinates.
    #[inline]
    #[must_use]
    pub fn to_local(&self, w: DVec3) -> DVec3 {
        DVec3::new(w.dot(self.t), w.dot(self.b), w.dot(self.n))
    }

    /// Take a local direction back to world coordinates.
    #[inline]
    #[must_use]
    pub fn to_world(&self, l: DVec3) -> DVec3 {
        self.t * l.x + self.b * l.y + self.n * l.z
    }
}

/// Is `v` a finite vector of unit length within `tol`?
#[inline]
#[must_use]
pub fn is_unit(v: DVec3, tol: f64) -> bool {
    v.is_finite() && (v.length() - 1.0).abs() <= tol
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spherical_round_trip() {
        for k in 0..200 {
            let theta = PI * (k as f64 + 0.5) / 200.0;
            let phi = 2.0 * PI * ((k * 37 % 200) as f64 + 0.5) / 200.0;
            let w = spherical_direction(theta, phi);
            assert!(is_unit(w, 1e-12));
            let (t2, p2) = spherical_angles(w);
            assert!((t2 - theta).abs() < 1e-9 && (p2 - phi).abs() < 1e-9);
        }
    }

    #[test]
    fn axes_follow_the_convention() {
        assert!((spherical_direction(0.0, 0.0) - DVec3::Z).length() < 1e-15);
        assert!((spherical_direction_deg(90.0, 0.0) - DVec3::X).length() < 1e-15);
        assert!((spherical_direction_deg(90.0, 90.0) - DVec3::Y).length() < 1e-15);
    }

    #[test]
    fn frames_are_orthonormal_and_invert() {
        for k in 0..100 {
            let n = spherical_direction(PI * (k as f64 + 0.5) / 100.0, 0.7 * k as f64);
            for f in [
                Frame::from_normal(n),
                Frame::from_normal_tangent(n, DVec3::new(1.0, 0.3, -0.2)),
            ] {
                assert!(f.t.dot(f.b).abs() < 1e-12 && f.t.dot(f.n).abs() < 1e-12);
                assert!((f.t.cross(f.b) - f.n).length() < 1e-12, "right-handed");
                let w = DVec3::new(0.3, -0.5, 0.81).normalize();
                assert!((f.to_world(f.to_local(w)) - w).length() < 1e-12);
            }
        }
    }

    #[test]
    fn half_vector_and_reflect() {
        let i = spherical_direction_deg(30.0, 0.0);
        let o = spherical_direction_deg(30.0, 180.0);
        assert!((half_vector(i, o).unwrap() - DVec3::Z).length() < 1e-12);
        assert!((reflect(i, DVec3::Z) - o).length() < 1e-12);
        assert!(half_vector(DVec3::Z, -DVec3::Z).is_none());
    }
}
