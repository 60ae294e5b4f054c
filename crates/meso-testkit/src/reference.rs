//! Reference samplers with exactly known densities, for testing the harness itself and as
//! baselines in other tests. `u ∈ [0, 1)²`; directions in the local frame (+z up).

use glam::DVec3;
use std::f64::consts::PI;

/// Uniform on the sphere (Archimedes: `z` uniform in `[−1, 1]`); pdf `1/(4π)`.
#[must_use]
pub fn uniform_sphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - 2.0 * u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    DVec3::new(r * c, r * s, z)
}

/// The density of [`uniform_sphere`]: `1/(4π)`.
#[must_use]
pub fn uniform_sphere_pdf(_d: DVec3) -> f64 {
    0.25 / PI
}

/// Uniform on the upper hemisphere (`z` uniform in `(0, 1]`); pdf `1/(2π)` for `z > 0`.
#[must_use]
pub fn uniform_hemisphere(u: [f64; 2]) -> DVec3 {
    let z = 1.0 - u[0];
    let r = (1.0 - z * z).max(0.0).sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    DVec3::new(r * c, r * s, z)
}

/// The density of [`uniform_hemisphere`]: `1/(2π)` for `z > 0`, else 0.
#[must_use]
pub fn uniform_hemisphere_pdf(d: DVec3) -> f64 {
    if d.z > 0.0 {
        0.5 / PI
    } else {
        0.0
    }
}

/// Cosine-weighted on the upper hemisphere (Malley: uniform on the disk, lifted); pdf `cos θ/π`.
#[must_use]
pub fn cosine_hemisphere(u: [f64; 2]) -> DVec3 {
    let r = u[0].sqrt();
    let (s, c) = (2.0 * PI * u[1]).sin_cos();
    DVec3::new(r * c, r * s, (1.0 - u[0]).max(0.0).sqrt())
}

/// The density of [`cosine_hemisphere`]: `max(cos θ, 0)/π`.
#[must_use]
pub fn cosine_hemisphere_pdf(d: DVec3) -> f64 {
    d.z.max(0.0) / PI
}
