//! The paper's materials, defined once: the multiple surfaces of Fournier 1992, §4 — Figure 2's
//! anisotropic surface and surfaces of two, three and seven normals, Figure 3's velvet and
//! Figure 4's silk.
//!
//! The paper shows these as pictures and gives no numbers. What it does fix:
//! * a **multiple surface** is "one where each point has more than one normal, each adding a Phong
//!   reflectance function to the total" (§4): a sum of deltas (Eq. 9, [`Ndf::Deltas`]) under the
//!   Phong transfer `(N·H)^η` (Eq. 10, [`Transfer::Phong`]) — the same pair that filtering a bump
//!   map gives (§3.2: "a sum of δ() functions, and the transfer function is a Phong
//!   distribution"). Every material here is one, shaded in the multiple-surface form (the default
//!   for inline NDFs), plus a small Lambert term that shows the shape;
//! * the **anisotropic** surface is "obtained in a very straightforward manner" from the normals
//!   of a cylinder (Eq. 15): normals spread along one great circle;
//! * the **seven normals** "were obtained from the filtering of a bump-map extracted from a
//!   geometric model describing a cylinder": [`seven_normals`] holds the top-level lobes of such
//!   a map's pyramid (`meso_figures::cylinder_map`, extracted by `meso_maps::extract`; a test in
//!   meso-figures extracts the map again and requires these numbers);
//! * **velvet** and **silk** are "two different multiple surfaces" on the same geometry (§4,
//!   Figures 3 and 4).
//!
//! The directions, weights, exponents and colours are this project's choices within those
//! constraints; each function's documentation states them. Axes are `[θ, φ]` in degrees in the
//! local frame (θ from the normal, φ from the tangent towards the bitangent). The figures
//! (`meso figures`), the editor's presets (`meso serve`), the tests and the benchmarks all take
//! the paper's materials from here.

use crate::convolution::Accuracy;
use crate::frame::spherical_direction_deg;
use crate::material::{Material, MaterialSpec, NdfSpec, NoExternalNdfs};
use crate::ndf::{DeltaSum, Ndf, WeightedNormal};
use crate::transfer::{PhongVariant, Transfer};

/// Specular colour of the Figure 2 surfaces (the Phong facets' lobe height, 1/sr).
pub const FIG2_SPECULAR: [f64; 3] = [0.95, 0.9, 0.8];
/// Lambert albedo of the Figure 2 surfaces (enough to show the shape).
pub const FIG2_DIFFUSE: [f64; 3] = [0.06, 0.07, 0.09];

/// One normal of a multiple surface: a delta of Eq. 9 at `[θ, φ]` (degrees, local frame) with
/// its weight (the weights of a surface are normalised to sum 1 when the NDF is built).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Normal {
    /// Polar angle from the surface normal, degrees.
    pub theta_deg: f64,
    /// Azimuth from the tangent towards the bitangent, degrees.
    pub phi_deg: f64,
    /// Relative weight (≥ 0).
    pub weight: f64,
}

impl Normal {
    /// The normal at `[theta_deg, phi_deg]` with `weight`.
    #[must_use]
    pub const fn new(theta_deg: f64, phi_deg: f64, weight: f64) -> Normal {
        Normal {
            theta_deg,
            phi_deg,
            weight,
        }
    }

    /// The normal at signed angle `signed_theta_deg` on the great circle through the surface
    /// normal at azimuth `phi_deg`: negative angles lie at `phi_deg + 180°`.
    #[must_use]
    pub fn on_circle(signed_theta_deg: f64, phi_deg: f64, weight: f64) -> Normal {
        if signed_theta_deg < 0.0 {
            Normal::new(-signed_theta_deg, phi_deg + 180.0, weight)
        } else {
            Normal::new(signed_theta_deg, phi_deg, weight)
        }
    }
}

/// A multiple surface of the paper (§4): normals ([`Normal`], Eq. 9) under a Phong facet
/// `specular · (N·H)^η` (Eq. 10) in the multiple-surface form, plus a Lambert term.
#[derive(Clone, Debug, PartialEq)]
pub struct MultipleSurface {
    /// Display name (the material file's `name`).
    pub name: String,
    /// Where in the paper and what it models, in one sentence.
    pub description: &'static str,
    /// The normals.
    pub normals: Vec<Normal>,
    /// Phong exponent η of the facets.
    pub exponent: f64,
    /// Phong lobe height per channel (1/sr).
    pub specular: [f64; 3],
    /// Lambert albedo.
    pub diffuse: [f64; 3],
}

impl MultipleSurface {
    /// The material file's value: the normals as a `deltas` NDF (axes from their degrees), the
    /// Phong (`N·H`) transfer, the Lambert term; form, masking and quadrature left to their
    /// defaults. Its file is [`MaterialSpec::to_toml`] of this.
    ///
    /// # Panics
    /// Never for the materials of this module (their normals make a valid NDF).
    #[must_use]
    pub fn spec(&self) -> MaterialSpec {
        let normals = self
            .normals
            .iter()
            .map(|n| WeightedNormal {
                normal: spherical_direction_deg(n.theta_deg, n.phi_deg),
                weight: n.weight,
            })
            .collect();
        let ndf = DeltaSum::new(normals).expect("the catalogue's normals make a valid NDF");
        phong_spec(
            &self.name,
            Ndf::Deltas(ndf),
            self.exponent,
            self.specular,
            self.diffuse,
        )
    }

    /// The material, built from [`MultipleSurface::spec`].
    ///
    /// # Panics
    /// Never for the materials of this module (their specs build).
    #[must_use]
    pub fn material(&self) -> Material {
        self.spec()
            .build(&NoExternalNdfs)
            .expect("the catalogue's materials build")
    }
}

/// The spec of a material named `name` with the NDF `ndf` under Phong (`N·H`) facets
/// `specular · (N·H)^exponent` and a Lambert term of albedo `diffuse`, in the default form
/// (multiple-surface for an inline NDF), masking and quadrature: the shape of every material of
/// this catalogue (and of other built-in Phong materials, e.g. the figures' Phong-peak surfaces).
#[must_use]
pub fn phong_spec(
    name: &str,
    ndf: Ndf,
    exponent: f64,
    specular: [f64; 3],
    diffuse: [f64; 3],
) -> MaterialSpec {
    MaterialSpec {
        name: Some(name.to_owned()),
        ndf: NdfSpec::Inline(ndf),
        transfer: Transfer::Phong {
            exponent,
            specular,
            variant: PhongVariant::Half,
        },
        diffuse,
        form: None,
        shadowing: None,
        accuracy: Accuracy::default(),
    }
}

/// Figure 2, anisotropic surface: 33 normals every 5° along the half great circle in the
/// tangent–normal plane (θ from −80° to 80°, i.e. φ = 0° and 180°) — the NDF of a cylinder bump
/// whose axis is the bitangent (Eq. 15, `half`), sampled — with equal weights (a cylinder's
/// normals are uniform in angle); Phong η = 150, [`FIG2_SPECULAR`], [`FIG2_DIFFUSE`]. The
/// highlight stretches along the tangent.
#[must_use]
pub fn anisotropic() -> MultipleSurface {
    MultipleSurface {
        name: "anisotropic (cylinder NDF)".into(),
        description: "Fig. 2a: the normals of a cylinder bump across the tangent, sampled every \
                      5°: a highlight stretched along the tangent.",
        normals: (-16..=16)
            .map(|k| Normal::on_circle(5.0 * f64::from(k), 0.0, 1.0))
            .collect(),
        exponent: 150.0,
        specular: FIG2_SPECULAR,
        diffuse: FIG2_DIFFUSE,
    }
}

/// Figure 2, two normals: θ = 20° at φ = 0° and 180° (tilted either way along the tangent),
/// equal weights; Phong η = 80, [`FIG2_SPECULAR`], [`FIG2_DIFFUSE`]. Every highlight splits in
/// two along the tangent.
#[must_use]
pub fn two_normals() -> MultipleSurface {
    MultipleSurface {
        name: "2 normals".into(),
        description: "Fig. 2b: two normals tilted ±20° along the tangent: every highlight \
                      splits in two.",
        normals: vec![Normal::new(20.0, 0.0, 1.0), Normal::new(20.0, 180.0, 1.0)],
        exponent: 80.0,
        specular: FIG2_SPECULAR,
        diffuse: FIG2_DIFFUSE,
    }
}

/// Figure 2, three normals: θ = 25° at φ = 90°, 210° and 330° (120° apart), equal weights;
/// Phong η = 80, [`FIG2_SPECULAR`], [`FIG2_DIFFUSE`]. Three highlights in a triangle.
#[must_use]
pub fn three_normals() -> MultipleSurface {
    MultipleSurface {
        name: "3 normals".into(),
        description: "Fig. 2c: three normals 25° from the normal, 120° apart: three highlights \
                      in a triangle.",
        normals: vec![
            Normal::new(25.0, 90.0, 1.0),
            Normal::new(25.0, 210.0, 1.0),
            Normal::new(25.0, 330.0, 1.0),
        ],
        exponent: 80.0,
        specular: FIG2_SPECULAR,
        diffuse: FIG2_DIFFUSE,
    }
}

/// The normals of [`seven_normals`]: `[θ, φ, weight]`, the top-level lobes of the pyramid of a
/// 64×64 map of touching half-cylinders along the bitangent (period 16 texels), fitted with up
/// to 7 lobes from every normal (`meso_figures::cylinder_map` and `meso_figures::pyramid`),
/// angles rounded to 1e-4°, weights to 1e-6, in the fitter's order. (The azimuth of the normal
/// at θ = 0 is immaterial; it is kept as fitted, so that the material file is the one the
/// figures have always written.)
const SEVEN_NORMALS: [[f64; 3]; 7] = [
    [74.4274, 0.0, 0.173507],
    [74.4274, 180.0, 0.173507],
    [0.0, 179.9298, 0.129004],
    [23.2339, 0.0, 0.130169],
    [46.7706, 180.0, 0.131822],
    [46.7706, 0.0, 0.131822],
    [23.2339, 180.0, 0.130169],
];

/// Figure 2, seven normals "obtained from the filtering of a bump-map extracted from a
/// geometric model describing a cylinder" (§4): the lobe axes and weights of the top level (the
/// whole map) of the NDF pyramid of a 64×64 map of touching half-cylinders whose axes run along
/// the bitangent, so that the normals lie in the tangent–normal plane (φ = 0° and 180°), the
/// discrete version of [`anisotropic`]. Phong η = 80, [`FIG2_SPECULAR`], [`FIG2_DIFFUSE`].
#[must_use]
pub fn seven_normals() -> MultipleSurface {
    MultipleSurface {
        name: "7 normals (filtered cylinder bumps)".into(),
        description: "Fig. 2d: the seven normals of a filtered bump map of half-cylinders \
                      across the tangent: seven highlights along the tangent.",
        normals: SEVEN_NORMALS
            .iter()
            .map(|&[t, p, w]| Normal::new(t, p, w))
            .collect(),
        exponent: 80.0,
        specular: FIG2_SPECULAR,
        diffuse: FIG2_DIFFUSE,
    }
}

/// Figure 3, velvet: 12 normals at θ = 78° every 30° in φ (fibres standing up, their sides
/// facing every azimuth), equal weights; broad red Phong facets (η = 6, specular
/// `[0.9, 0.18, 0.3]`) over a dark red base (albedo `[0.1, 0.008, 0.02]`). Each facet lit with
/// its own cosine, the sheen sits near the silhouette while the centre stays dark.
#[must_use]
pub fn velvet() -> MultipleSurface {
    MultipleSurface {
        name: "velvet".into(),
        description: "Fig. 3: twelve normals 78° from the normal (fibre sides facing every \
                      azimuth), broad red facets: a grazing sheen at the silhouette.",
        normals: (0..12)
            .map(|k| Normal::new(78.0, 30.0 * f64::from(k), 1.0))
            .collect(),
        exponent: 6.0,
        specular: [0.9, 0.18, 0.3],
        diffuse: [0.1, 0.008, 0.02],
    }
}

/// Figure 4, silk: threads along the tangent; 9 normals every 15° from −60° to 60° across them
/// (on the great circle in the bitangent–normal plane, φ = 90°/270°, weight 0.08 each, 0.72 in
/// all) and 5 every 10° from −20° to 20° along them (the weft, φ = 0°/180°, 0.056 each, 0.28 in
/// all; the normal itself is in both sets); sharp golden Phong facets (η = 50, specular
/// `[1.0, 0.8, 0.45]`) over a brown base (albedo `[0.1, 0.05, 0.012]`). A cross-shaped
/// anisotropic highlight.
#[must_use]
pub fn silk() -> MultipleSurface {
    let mut normals: Vec<Normal> = (-4..=4)
        .map(|k| Normal::on_circle(15.0 * f64::from(k), 90.0, 0.08))
        .collect();
    normals.extend((-2..=2).map(|k| Normal::on_circle(10.0 * f64::from(k), 0.0, 0.056)));
    MultipleSurface {
        name: "silk".into(),
        description: "Fig. 4: threads along the tangent: normals spread ±60° across them and \
                      ±20° along them, sharp golden facets: a cross-shaped highlight.",
        normals,
        exponent: 50.0,
        specular: [1.0, 0.8, 0.45],
        diffuse: [0.1, 0.05, 0.012],
    }
}

/// Every material of the catalogue, in the paper's order (Fig. 2a–d, 3, 4).
#[must_use]
pub fn all() -> Vec<MultipleSurface> {
    vec![
        anisotropic(),
        two_normals(),
        three_normals(),
        seven_normals(),
        velvet(),
        silk(),
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_material_is_a_multiple_surface_that_reads_back_from_its_file() {
        for m in all() {
            let spec = m.spec();
            assert!(
                matches!(spec.ndf, NdfSpec::Inline(Ndf::Deltas(_))),
                "{}",
                m.name
            );
            let back = MaterialSpec::parse(&spec.to_toml(), std::path::Path::new(""))
                .unwrap_or_else(|e| panic!("{}: {e}", m.name));
            assert_eq!(back, spec, "{}", m.name);
            let mat = m.material();
            assert_eq!(
                mat.form,
                crate::convolution::Form::MultipleSurface,
                "{}",
                m.name
            );
        }
    }

    #[test]
    fn the_counts_are_the_papers() {
        let n: Vec<usize> = all().iter().map(|m| m.normals.len()).collect();
        assert_eq!(n[1..4], [2, 3, 7]);
    }

    /// The anisotropic surface and the seven normals are cylinders across the tangent: their
    /// normals lie in the tangent–normal plane; silk's lie on its two great circles.
    #[test]
    fn cylinder_normals_lie_on_their_great_circles() {
        let on = |n: &Normal, phis: &[f64]| {
            n.theta_deg.abs() < 1e-9 || phis.iter().any(|p| (n.phi_deg - p).abs() < 1e-9)
        };
        for m in [anisotropic(), seven_normals()] {
            assert!(m.normals.iter().all(|n| on(n, &[0.0, 180.0])), "{}", m.name);
        }
        assert!(silk()
            .normals
            .iter()
            .all(|n| on(n, &[0.0, 90.0, 180.0, 270.0])));
        let w: f64 = silk().normals.iter().map(|n| n.weight).sum();
        assert!((w - 1.0).abs() < 1e-12, "{w}");
    }
}
