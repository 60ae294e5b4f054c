//! The Rusinkiewicz half/difference parameterisation of a pair of directions
//! (S. Rusinkiewicz, "A New Change of Variables for Efficient BRDF Representation", EGWR 1998),
//! as used by the MERL BRDF database.
//!
//! # Definition
//! With `i` (towards the light) and `o` (towards the viewer) unit directions in meso's local frame
//! (normal +z, tangent +x, see [`meso_core::frame`]):
//! * the half vector `h = normalize(i + o)` has spherical angles `(θh, φh)`;
//! * the difference vector is `d = Ry(−θh) · Rz(−φh) · i` — `i` expressed in a frame where `h` is the
//!   pole — with spherical angles `(θd, φd)`; `θd ∈ [0, π/2]` is the angle between `i` and `h`.
//!
//! The rotations are right-handed about +z then +y. Swapping `i` and `o` maps `d` to
//! `(−dx, −dy, dz)`, i.e. `φd ↦ φd + π`: a reciprocal BRDF is π-periodic in `φd`, which is why a
//! MERL table only stores `φd ∈ [0, π)`.
//!
//! Angles are radians. `φh` and `φd` returned by [`half_diff_from_dirs`] are in `(−π, π]`
//! (`atan2`), as in MERL's reference code.

use glam::DVec3;

/// Half/difference angles of a direction pair, radians (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfDiff {
    /// Polar angle of the half vector from the normal, `[0, π]`.
    pub theta_h: f64,
    /// Azimuth of the half vector from the tangent, `(−π, π]`.
    pub phi_h: f64,
    /// Polar angle of the difference vector (angle between `i` and `h`), `[0, π/2]`.
    pub theta_d: f64,
    /// Azimuth of the difference vector in the half-vector frame, `(−π, π]`.
    pub phi_d: f64,
}

#[inline]
fn rot_z(v: DVec3, a: f64) -> DVec3 {
    let (s, c) = a.sin_cos();
    DVec3::new(v.x * c - v.y * s, v.x * s + v.y * c, v.z)
}

#[inline]
fn rot_y(v: DVec3, a: f64) -> DVec3 {
    let (s, c) = a.sin_cos();
    DVec3::new(v.x * c + v.z * s, v.y, -v.x * s + v.z * c)
}

/// Half/difference angles of the unit directions `wi`, `wo` (MERL's
/// `std_coords_to_half_diff_coords`). If the directions are opposite the half vector is undefined;
/// the normal is used instead.
#[must_use]
pub fn half_diff_from_dirs(wi: DVec3, wo: DVec3) -> HalfDiff {
    let h = meso_core::frame::half_vector(wi, wo).unwrap_or(DVec3::Z);
    let theta_h = h.z.clamp(-1.0, 1.0).acos();
    let phi_h = h.y.atan2(h.x);
    let d = rot_y(rot_z(wi, -phi_h), -theta_h);
    let theta_d = d.z.clamp(-1.0, 1.0).acos();
    let phi_d = d.y.atan2(d.x);
    HalfDiff {
        theta_h,
        phi_h,
        theta_d,
        phi_d,
    }
}

/// The unit directions `(wi, wo)` of half/difference angles: the inverse of
/// [`half_diff_from_dirs`]. `wi = Rz(φh)·Ry(θh)·d` and `wo` is `wi` mirrored about `h`.
#[must_use]
pub fn dirs_from_half_diff(hd: HalfDiff) -> (DVec3, DVec3) {
    let d = meso_core::frame::spherical_direction(hd.theta_d, hd.phi_d);
    let d_mirror = DVec3::new(-d.x, -d.y, d.z);
    let wi = rot_z(rot_y(d, hd.theta_h), hd.phi_h);
    let wo = rot_z(rot_y(d_mirror, hd.theta_h), hd.phi_h);
    (wi, wo)
}

/// Half/difference angles from the spherical angles `(θi, φi, θo, φo)` of the two directions,
/// radians.
#[must_use]
pub fn half_diff_from_angles(theta_i: f64, phi_i: f64, theta_o: f64, phi_o: f64) -> HalfDiff {
    half_diff_from_dirs(
        meso_core::frame::spherical_direction(theta_i, phi_i),
        meso_core::frame::spherical_direction(theta_o, phi_o),
    )
}

/// Spherical angles `(θi, φi, θo, φo)` (radians, φ in `[0, 2π)`) of half/difference angles.
#[must_use]
pub fn angles_from_half_diff(hd: HalfDiff) -> (f64, f64, f64, f64) {
    let (wi, wo) = dirs_from_half_diff(hd);
    let (ti, pi) = meso_core::frame::spherical_angles(wi);
    let (to, po) = meso_core::frame::spherical_angles(wo);
    (ti, pi, to, po)
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::frame::spherical_direction;
    use std::f64::consts::PI;

    fn pseudo(k: usize, salt: f64) -> f64 {
        ((k as f64 * 0.618_033_988_749_895 + salt) * 7.31)
            .fract()
            .abs()
    }

    #[test]
    fn round_trip_dirs_to_half_diff_and_back() {
        for k in 0..2000 {
            let wi = spherical_direction(0.5 * PI * pseudo(k, 0.1), 2.0 * PI * pseudo(k, 0.2));
            let wo = spherical_direction(0.5 * PI * pseudo(k, 0.3), 2.0 * PI * pseudo(k, 0.4));
            if (wi + wo).length() < 1e-6 {
                continue;
            }
            let hd = half_diff_from_dirs(wi, wo);
            assert!(hd.theta_d <= 0.5 * PI + 1e-12);
            let (a, b) = dirs_from_half_diff(hd);
            assert!((a - wi).length() < 1e-10, "wi {wi} vs {a}");
            assert!((b - wo).length() < 1e-10, "wo {wo} vs {b}");
        }
    }

    #[test]
    fn round_trip_half_diff_to_dirs_and_back() {
        for k in 0..2000 {
            let hd = HalfDiff {
                theta_h: 0.01 + 1.5 * pseudo(k, 0.5),
                phi_h: -3.1 + 6.2 * pseudo(k, 0.6),
                theta_d: 0.01 + 1.5 * pseudo(k, 0.7),
                phi_d: -3.1 + 6.2 * pseudo(k, 0.8),
            };
            let (wi, wo) = dirs_from_half_diff(hd);
            assert!((wi.length() - 1.0).abs() < 1e-12 && (wo.length() - 1.0).abs() < 1e-12);
            let back = half_diff_from_dirs(wi, wo);
            for (x, y) in [
                (hd.theta_h, back.theta_h),
                (hd.phi_h, back.phi_h),
                (hd.theta_d, back.theta_d),
                (hd.phi_d, back.phi_d),
            ] {
                assert!((x - y).abs() < 1e-9, "{hd:?} vs {back:?}");
            }
        }
    }

    #[test]
    fn known_configurations() {
        // Mirror configuration: h = normal, θd = θi (φh is then arbitrary, so is φd).
        let wi = spherical_direction(0.6, PI);
        let wo = spherical_direction(0.6, 0.0);
        let hd = half_diff_from_dirs(wi, wo);
        assert!(hd.theta_h.abs() < 1e-12);
        assert!((hd.theta_d - 0.6).abs() < 1e-12);
        // In the plane of incidence φ = 0 with h tilted towards +x: d stays in the x–z plane,
        // on the side of i (φd = π when i is further from +x than h).
        let wi = spherical_direction(0.2, PI);
        let wo = spherical_direction(0.8, 0.0);
        let hd = half_diff_from_dirs(wi, wo);
        assert!((hd.theta_h - 0.3).abs() < 1e-12 && hd.phi_h.abs() < 1e-12);
        assert!((hd.theta_d - 0.5).abs() < 1e-12);
        assert!((hd.phi_d.abs() - PI).abs() < 1e-12);
        // Retro-reflection: i = o ⇒ θd = 0 and h = i.
        let w = spherical_direction(0.9, 1.2);
        let hd = half_diff_from_dirs(w, w);
        assert!(hd.theta_d.abs() < 1e-7 && (hd.theta_h - 0.9).abs() < 1e-12);
        // Swapping i and o shifts φd by π.
        let wi = spherical_direction(0.4, 0.3);
        let wo = spherical_direction(1.1, 2.5);
        let a = half_diff_from_dirs(wi, wo);
        let b = half_diff_from_dirs(wo, wi);
        let dphi = (a.phi_d - b.phi_d).rem_euclid(2.0 * PI);
        assert!((dphi - PI).abs() < 1e-9);
        assert!((a.theta_h - b.theta_h).abs() < 1e-12 && (a.theta_d - b.theta_d).abs() < 1e-12);
    }
}
