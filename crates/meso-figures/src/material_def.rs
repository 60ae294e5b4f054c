//! The built-in materials' definitions ([`MaterialDef`]: lobes, a Phong transfer, a Lambert
//! term) and their conversion to meso-core's [`MaterialSpec`], which writes their files.

use crate::{ferr, FigureError};
use glam::DVec3;
use meso_core::catalogue::{phong_spec, MultipleSurface};
use meso_core::frame::spherical_direction_deg;
use meso_core::material::{Material, MaterialSpec};
use meso_core::ndf::{DeltaSum, Ndf, PhongLobe, PhongPeaks, WeightedNormal};

/// One lobe of a built-in material: axis `[θ, φ]` in degrees in the local frame, weight, and
/// exponent (Phong peaks only).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobe {
    /// Polar angle from the normal, degrees.
    pub theta_deg: f64,
    /// Azimuth from the tangent towards the bitangent, degrees.
    pub phi_deg: f64,
    /// Weight (normalised by the material).
    pub weight: f64,
    /// Exponent η of a Phong peak; `None` for a delta (a normal of a multiple surface).
    pub exponent: Option<f64>,
}

impl Lobe {
    /// A delta lobe (one normal of a multiple surface).
    #[must_use]
    pub fn delta(theta_deg: f64, phi_deg: f64, weight: f64) -> Lobe {
        Lobe {
            theta_deg,
            phi_deg,
            weight,
            exponent: None,
        }
    }

    /// A lobe from a unit local axis.
    #[must_use]
    pub fn from_axis(axis: DVec3, weight: f64, exponent: Option<f64>) -> Lobe {
        let (t, p) = meso_core::frame::spherical_angles(axis);
        let phi = p.to_degrees().rem_euclid(360.0);
        Lobe {
            theta_deg: t.to_degrees(),
            phi_deg: phi,
            weight,
            exponent,
        }
    }
}

impl From<&MultipleSurface> for MaterialDef {
    /// A multiple surface of [`meso_core::catalogue`] (its normals as delta lobes, same
    /// degrees and weights, same facets): [`MaterialDef::to_spec`] of it is the catalogue's
    /// [`MultipleSurface::spec`].
    fn from(m: &MultipleSurface) -> MaterialDef {
        MaterialDef {
            name: m.name.clone(),
            lobes: m
                .normals
                .iter()
                .map(|n| Lobe::delta(n.theta_deg, n.phi_deg, n.weight))
                .collect(),
            exponent: m.exponent,
            specular: m.specular,
            diffuse: m.diffuse,
        }
    }
}

/// A built-in material: an NDF of lobes (deltas or Phong peaks), a Phong (N·H) transfer and a
/// Lambert term, written as a meso material file by [`MaterialDef::toml`].
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialDef {
    /// Display name.
    pub name: String,
    /// The lobes; all deltas or all Phong peaks.
    pub lobes: Vec<Lobe>,
    /// Phong transfer exponent η.
    pub exponent: f64,
    /// Phong transfer specular colour (1/sr).
    pub specular: [f64; 3],
    /// Lambert albedo.
    pub diffuse: [f64; 3],
}

impl MaterialDef {
    /// The material as meso-core's [`MaterialSpec`], at the precision of the figures' files:
    /// angles rounded to 1e-4 degrees, weights to 1e-6, exponents to 1e-3.
    ///
    /// # Errors
    /// Lobes that make no NDF (a bug in the definition).
    pub fn to_spec(&self) -> Result<MaterialSpec, FigureError> {
        let bad = |e: meso_core::NdfError| ferr(format!("built-in material {:?}: {e}", self.name));
        let axis =
            |l: &Lobe| spherical_direction_deg(rounded(l.theta_deg, 4), rounded(l.phi_deg, 4));
        let peaks = self.lobes.iter().any(|l| l.exponent.is_some());
        let ndf = if peaks {
            Ndf::PhongPeaks(
                PhongPeaks::new(
                    self.lobes
                        .iter()
                        .map(|l| {
                            PhongLobe::new(
                                axis(l),
                                rounded(l.weight, 6),
                                rounded(l.exponent.unwrap_or(0.0), 3),
                            )
                        })
                        .collect(),
                )
                .map_err(bad)?,
            )
        } else {
            Ndf::Deltas(
                DeltaSum::new(
                    self.lobes
                        .iter()
                        .map(|l| WeightedNormal {
                            normal: axis(l),
                            weight: rounded(l.weight, 6),
                        })
                        .collect(),
                )
                .map_err(bad)?,
            )
        };
        Ok(phong_spec(
            &self.name,
            ndf,
            rounded(self.exponent, 3),
            self.specular,
            self.diffuse,
        ))
    }

    /// The material file text (`docs/material-format.md`): [`MaterialDef::to_spec`] written by
    /// [`MaterialSpec::to_toml`].
    ///
    /// # Errors
    /// As [`MaterialDef::to_spec`].
    pub fn toml(&self) -> Result<String, FigureError> {
        Ok(self.to_spec()?.to_toml())
    }

    /// The material, parsed from [`MaterialDef::toml`] (so the file and the picture agree).
    ///
    /// # Errors
    /// The material parser's message (a bug in the definition).
    pub fn material(&self) -> Result<Material, FigureError> {
        Material::from_toml_str(&self.toml()?)
            .map_err(|e| ferr(format!("built-in material {:?}: {e}", self.name)))
    }

    /// The NDF blend `(1 − t)·self + t·other` (lobe weights scaled, lobe lists joined); the
    /// transfer and diffuse term are `self`'s.
    #[must_use]
    pub fn blend(&self, other: &MaterialDef, t: f64) -> MaterialDef {
        let sum = |m: &MaterialDef| m.lobes.iter().map(|l| l.weight).sum::<f64>();
        let (sa, sb) = (sum(self), sum(other));
        let mut lobes: Vec<Lobe> = Vec::new();
        for (m, k, s) in [(self, 1.0 - t, sa), (other, t, sb)] {
            if k > 0.0 {
                lobes.extend(m.lobes.iter().map(|l| Lobe {
                    weight: l.weight / s * k,
                    ..*l
                }));
            }
        }
        MaterialDef {
            name: format!("blend t = {t:.2}"),
            lobes,
            ..self.clone()
        }
    }
}

/// `x` rounded to `decimals` decimals, as `format!("{x:.decimals$}")` writes it.
fn rounded(x: f64, decimals: usize) -> f64 {
    format!("{x:.decimals$}").parse().unwrap_or(x)
}
