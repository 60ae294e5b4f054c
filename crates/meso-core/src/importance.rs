//! Importance sampling of a material's effective BRDF, for Monte Carlo renderers that bring their own
//! integrator (the Mitsuba 3 plugin of the Python package, any path tracer).
//!
//! Given the direction towards the viewer `o` (local frame, normal on +z), [`sample_incident`] draws
//! the direction towards the light `i` from a mixture of two strategies:
//!
//! * with probability [`ndf_weight`] (0.75 for an NDF with a density, 0 for singular ones —
//!   [`crate::ndf::Ndf::is_singular`]): a facet normal `m` from the NDF's own sampler
//!   ([`crate::ndf::Ndf::sample`], density [`crate::ndf::Ndf::pdf`] in 1/sr), and `i` its mirror
//!   reflection of `o`; the Jacobian of the reflection gives `pdf(i) = p(m) / (4 |o·m|)`;
//! * otherwise a cosine-weighted direction of the hemisphere, `pdf(i) = cos θ_i / π`.
//!
//! The mixture keeps the density positive over the whole upper hemisphere, so an effective BRDF wider
//! than its NDF (a broad facet transfer, a diffuse term) is still sampled without bias. A draw that
//! lands below the surface (a normal facing away from `o`, or a reflection under the horizon) is
//! declined (`None`); [`sample_pdf`] is then the density of the accepted draws, and integrates to the
//! acceptance probability (≤ 1), as the chi-square test of `tests/importance.rs` checks.

use crate::frame::{half_vector, reflect};
use crate::material::Material;
use glam::DVec3;
use std::f64::consts::PI;

/// Probability of the NDF strategy for `material`: 0.75, or 0 when its NDF has no density (deltas,
/// a cylinder), whose effective BRDF is then sampled by the cosine strategy alone.
#[must_use]
pub fn ndf_weight(material: &Material) -> f64 {
    if material.ndf.is_singular() {
        0.0
    } else {
        0.75
    }
}

/// Draw the direction towards the light for the viewer direction `o` (unit, local frame, `o.z > 0`),
/// with `u ∈ [0,1)³` (the first number picks the strategy). `None` when the draw is declined (see the
/// module documentation) or `o` is below the surface.
#[must_use]
pub fn sample_incident(material: &Material, o: DVec3, u: [f64; 3]) -> Option<DVec3> {
    if o.z <= 0.0 {
        return None;
    }
    let w = ndf_weight(material);
    let i = if u[0] < w {
        let m = material.ndf.sample([u[1], u[2]]);
        if m.dot(o) <= 0.0 {
            return None;
        }
        reflect(o, m)
    } else {
        cosine_hemisphere([u[1], u[2]])
    };
    (i.z > 0.0 && i.is_finite()).then(|| i.normalize())
}

/// The density (1/sr) with which [`sample_incident`] returns `i` for the viewer direction `o`; 0 for
/// either direction below the surface.
#[must_use]
pub fn sample_pdf(material: &Material, o: DVec3, i: DVec3) -> f64 {
    if o.z <= 0.0 || i.z <= 0.0 {
        return 0.0;
    }
    let w = ndf_weight(material);
    let mut pdf = (1.0 - w) * i.z / PI;
    if w > 0.0 {
        if let Some(m) = half_vector(i, o) {
            let om = o.dot(m);
            if om > 0.0 {
                pdf += w * material.ndf.pdf(m) / (4.0 * om);
            }
        }
    }
    pdf
}

/// A cosine-weighted direction of the upper hemisphere (Malley's method), `u ∈ [0,1)²`.
#[must_use]
pub fn cosine_hemisphere(u: [f64; 2]) -> DVec3 {
    let r = u[0].sqrt();
    let phi = 2.0 * PI * u[1];
    let z = (1.0 - u[0]).max(0.0).sqrt();
    DVec3::new(r * phi.cos(), r * phi.sin(), z)
}
