//! Transfer functions: the BRDF `f_μ(i, o; m)` of one facet, in 1/sr, evaluated in the facet's own
//! frame (facet normal on +z; `i` towards the light, `o` towards the viewer, both unit).
//!
//! These are the `F_i` / `R` of Eq. 2 and Eq. 8: the convolution with an NDF
//! ([`crate::convolution`]) turns them into the effective BRDF of the surface.

pub mod fresnel;

pub use fresnel::Fresnel;

use crate::frame::{half_vector, reflect};
use crate::ndf::Microfacet;
use glam::DVec3;
use std::f64::consts::PI;

/// The cap of facet normals where a transfer matters for one pair of directions
/// ([`Transfer::support`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Support {
    /// The cap's axis (the half vector), a unit vector in the local frame.
    pub axis: DVec3,
    /// The cosine of the cap's angular radius.
    pub cos_radius: f64,
    /// An upper bound of `f_μ(i, o; m)(m·i)⁺(m·o)⁺` (1/sr, every channel) for facet normals
    /// `m` outside the cap.
    pub bound: f64,
}

/// Which Phong lobe shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PhongVariant {
    /// Eq. 10: `(N·H)^η` with `H` the bisector of `i` and `o` (Blinn's form).
    Half,
    /// The reflected-direction form `(R·o)^η`, `R` the mirror of `i` about `N` (Phong 1975).
    Reflect,
}

/// A facet transfer function.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Transfer {
    /// Phong specular, Eq. 10 as written, **unnormalised**: `specular · max(0, N·H)^η`
    /// (or `specular · max(0, R·o)^η`). Not energy conserving for large `specular`.
    Phong {
        /// Exponent η ≥ 0.
        exponent: f64,
        /// RGB scale (1/sr).
        specular: [f64; 3],
        /// Bisector (Eq. 10) or reflected-direction form.
        variant: PhongVariant,
    },
    /// Lambert: `albedo/π` for `i` and `o` above the facet, 0 otherwise.
    Lambert {
        /// RGB albedo in `[0, 1]`.
        albedo: [f64; 3],
    },
    /// A perfect mirror facet with Fresnel: a Dirac BRDF,
    /// `specular · F(i·m) δ(o − reflect(i, m))/(o·m)`. It is only meaningful convolved with a
    /// continuous NDF, where the integral collapses onto `m = H` (the classic microfacet BRDF; see
    /// [`crate::convolution`]).
    Mirror {
        /// Fresnel of the facet.
        fresnel: Fresnel,
        /// Per-channel scale of the facet BRDF, dimensionless, each in `[0, 1]` (`[1, 1, 1]`: the
        /// plain Fresnel mirror). With every component ≤ 1 the facet reflects at most what the
        /// Fresnel mirror does, so the white-furnace bound of the unscaled mirror still holds.
        specular: [f64; 3],
    },
    /// A rough microfacet facet (Cook–Torrance/Walter): `F(i·h) D(h) G₂(i,o) / (4 cos θᵢ cos θₒ)`
    /// with Beckmann or GGX `D`, height-correlated Smith `G₂ = 1/(1 + Λ(i) + Λ(o))`.
    Microfacet {
        /// Beckmann or GGX with its roughness.
        distribution: Microfacet,
        /// Fresnel of the facet.
        fresnel: Fresnel,
    },
}

/// Eq. 10's value `specular · c^η` for the Phong cosine `c` (`N·H` or `R·o`), 0 for `c ≤ 0`.
#[inline]
fn phong_value(c: f64, exponent: f64, specular: [f64; 3]) -> [f64; 3] {
    if c <= 0.0 {
        return [0.0; 3];
    }
    let v = c.powf(exponent);
    [specular[0] * v, specular[1] * v, specular[2] * v]
}

impl Transfer {
    /// `f_μ(i, o)` in 1/sr, RGB, in the facet frame (facet normal +z). Zero when `i` or `o` is
    /// below the facet, except for the Phong form which is Eq. 10 as written (it only needs `H`).
    /// A [`Transfer::Mirror`] returns 0 here: it has no pointwise value.
    #[must_use]
    pub fn eval(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        match *self {
            Transfer::Phong {
                exponent,
                specular,
                variant,
            } => {
                let c = match variant {
                    PhongVariant::Half => match half_vector(i, o) {
                        Some(h) => h.z,
                        None => return [0.0; 3],
                    },
                    PhongVariant::Reflect => reflect(i, DVec3::Z).dot(o),
                };
                phong_value(c, exponent, specular)
            }
            Transfer::Lambert { albedo } => {
                if i.z <= 0.0 || o.z <= 0.0 {
                    return [0.0; 3];
                }
                [albedo[0] / PI, albedo[1] / PI, albedo[2] / PI]
            }
            Transfer::Mirror { .. } => [0.0; 3],
            Transfer::Microfacet {
                distribution,
                fresnel,
            } => {
                if i.z <= 0.0 || o.z <= 0.0 {
                    return [0.0; 3];
                }
                let Some(h) = half_vector(i, o) else {
                    return [0.0; 3];
                };
                let g2 = 1.0 / (1.0 + distribution.lambda(i) + distribution.lambda(o));
                let common = distribution.d(h) * g2 / (4.0 * i.z * o.z);
                let f = fresnel.eval(i.dot(h));
                [f[0] * common, f[1] * common, f[2] * common]
            }
        }
    }

    /// `f_μ(i, o; m)`: [`Transfer::eval`] for the facet of unit normal `m`, with `i`, `o` (and
    /// their half vector `h`, [`half_vector`]) in the macro surface's local frame — the
    /// facet's frame has `m` as its normal and the macro `+x`, made orthogonal to `m`, as its
    /// tangent (as the convolution builds it). Transfers that are isotropic about the facet
    /// normal (Lambert, both Phong forms, isotropic microfacets) are evaluated from the cosines
    /// alone; anisotropic microfacets build the frame.
    #[inline]
    #[must_use]
    pub fn eval_facet(&self, m: DVec3, i: DVec3, o: DVec3, h: Option<DVec3>) -> [f64; 3] {
        match *self {
            Transfer::Lambert { albedo } => {
                if m.dot(i) <= 0.0 || m.dot(o) <= 0.0 {
                    return [0.0; 3];
                }
                [albedo[0] / PI, albedo[1] / PI, albedo[2] / PI]
            }
            Transfer::Phong {
                exponent,
                specular,
                variant,
            } => {
                let c = match variant {
                    PhongVariant::Half => match h {
                        Some(h) => h.dot(m),
                        None => return [0.0; 3],
                    },
                    // reflect(i, m)·o = 2(i·m)(o·m) − i·o.
                    PhongVariant::Reflect => 2.0 * m.dot(i) * m.dot(o) - i.dot(o),
                };
                phong_value(c, exponent, specular)
            }
            Transfer::Mirror { .. } => [0.0; 3],
            Transfer::Microfacet {
                distribution,
                fresnel,
            } if distribution.is_isotropic() => {
                let (ci, co) = (m.dot(i), m.dot(o));
                if ci <= 0.0 || co <= 0.0 {
                    return [0.0; 3];
                }
                let Some(h) = h else {
                    return [0.0; 3];
                };
                let common = distribution.d_vis_isotropic(h.dot(m), ci, co);
                let f = fresnel.eval(i.dot(h));
                [f[0] * common, f[1] * common, f[2] * common]
            }
            Transfer::Microfacet { .. } => {
                let fr = crate::frame::Frame::from_normal_tangent(m, DVec3::X);
                self.eval(fr.to_local(i), fr.to_local(o))
            }
        }
    }

    /// Where this transfer matters for the pair `(i, o)`: a cap of facet normals about the half
    /// vector outside which every facet's share `f_μ(i, o; m) (m·i)⁺ (m·o)⁺` is at most
    /// [`Support::bound`] (about `1e-11` of the transfer's peak); `None` where the transfer has
    /// no such cap worth using (Lambert, GGX's long tails, broad lobes, mirrors).
    /// Beckmann (α ≤ 0.5): the cap `tan θ ≤ 5 α_max`, outside it `D ≤ e^{−25}/(π α_x α_y
    /// cos⁴θ)` (decreasing in θ there), Fresnel ≤ 1 and `G₂ ≤ 1`; Phong (half-vector form,
    /// η > 16): `cos^η θ ≤ e^{−25}`.
    #[must_use]
    pub fn support(&self, i: DVec3, o: DVec3) -> Option<Support> {
        let h = half_vector(i, o)?;
        let (cos_r, bound) = match *self {
            Transfer::Microfacet { distribution, .. }
                if distribution.distribution == crate::ndf::Distribution::Beckmann
                    && distribution.alpha_x.max(distribution.alpha_y) <= 0.5 =>
            {
                let t = 5.0 * distribution.alpha_x.max(distribution.alpha_y);
                let c2 = 1.0 / (1.0 + t * t);
                // f_μ (m·i)(m·o) = F D G₂ / 4 ≤ D / 4.
                let d =
                    (-25.0f64).exp() / (PI * distribution.alpha_x * distribution.alpha_y * c2 * c2);
                (c2.sqrt(), 0.25 * d)
            }
            Transfer::Phong {
                exponent,
                specular,
                variant: PhongVariant::Half,
            } if exponent > 16.0 => {
                let c = (-25.0 / exponent).exp();
                let s = specular[0].max(specular[1]).max(specular[2]);
                (c, s * c.powf(exponent))
            }
            _ => return None,
        };
        (cos_r > 0.1).then_some(Support {
            axis: h,
            cos_radius: cos_r,
            bound,
        })
    }

    /// The reflectance of a [`Transfer::Mirror`] facet for the cosine `cos_d = i·m` between the
    /// light and the facet normal: `specular · F(cos_d)` per channel (dimensionless, in `[0, 1]`
    /// for the validated inputs). Every evaluation of the collapsed mirror integral multiplies
    /// the NDF term by this. `None` for the other transfers.
    #[must_use]
    pub fn mirror_reflectance(&self, cos_d: f64) -> Option<[f64; 3]> {
        match *self {
            Transfer::Mirror { fresnel, specular } => {
                let f = fresnel.eval(cos_d);
                Some([0, 1, 2].map(|c| specular[c] * f[c]))
            }
            _ => None,
        }
    }

    /// Where in the space of facet normals `m` this transfer function peaks for the pair `(i, o)`
    /// and how sharply — the hint the lobe-adapted quadrature uses. `None` for smooth ones.
    #[must_use]
    pub fn peak(&self, i: DVec3, o: DVec3) -> Option<crate::integrate::Peak> {
        let h = half_vector(i, o)?;
        let exponent = match *self {
            // (m·H)^η ≈ exp(−η β²/2); a Phong-peak warp cos^e(β/2) ≈ exp(−e β²/8) ⇒ e = 4η.
            Transfer::Phong {
                exponent,
                variant: PhongVariant::Half,
                ..
            } => 4.0 * exponent,
            // (R·o)^η: moving m by β turns R by 2β ⇒ e = 16η.
            Transfer::Phong {
                exponent,
                variant: PhongVariant::Reflect,
                ..
            } => 16.0 * exponent,
            // D(h) ≈ exp(−β²/α²) ⇒ e = 8/α² (α the smaller roughness).
            Transfer::Microfacet { distribution, .. } => {
                8.0 / distribution.alpha_x.min(distribution.alpha_y).powi(2)
            }
            Transfer::Lambert { .. } | Transfer::Mirror { .. } => return None,
        };
        (exponent > 8.0).then_some(crate::integrate::Peak {
            axis: h,
            exponent: exponent.min(1e7),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::spherical_direction_deg;
    use crate::ndf::Distribution;

    #[test]
    fn phong_is_eq10_as_written() {
        let t = Transfer::Phong {
            exponent: 50.0,
            specular: [1.0, 0.8, 0.6],
            variant: PhongVariant::Half,
        };
        let i = spherical_direction_deg(30.0, 0.0);
        let o = spherical_direction_deg(20.0, 180.0);
        let h = (i + o).normalize();
        let v = t.eval(i, o);
        assert!((v[0] / h.z.powf(50.0) - 1.0).abs() < 1e-12, "{v:?}");
        assert!((v[2] / (0.6 * h.z.powf(50.0)) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rough_microfacet_is_reciprocal_and_bounded() {
        let d = Microfacet::new(Distribution::Ggx, 0.3, 0.15).unwrap();
        let t = Transfer::Microfacet {
            distribution: d,
            fresnel: Fresnel::None,
        };
        for (a, b, c, e) in [(10.0, 0.0, 60.0, 200.0), (45.0, 30.0, 45.0, 210.0)] {
            let i = spherical_direction_deg(a, b);
            let o = spherical_direction_deg(c, e);
            let f1 = t.eval(i, o)[0];
            let f2 = t.eval(o, i)[0];
            assert!((f1 - f2).abs() <= 1e-12 * f1.abs().max(1.0));
        }
        // White furnace: ∫ f cos θo dωo ≤ 1 (energy is lost to single-scattering masking only).
        for theta in [0.0, 40.0, 75.0] {
            let i = spherical_direction_deg(theta, 20.0);
            let albedo =
                crate::quadrature::integrate_hemisphere(|o| t.eval(i, o)[0] * o.z, 400, 256);
            assert!(albedo <= 1.0 + 2e-3 && albedo > 0.8, "θ={theta}: {albedo}");
        }
    }
}
