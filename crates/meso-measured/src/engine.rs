//! Engine parameters of a measured BRDF: the best single GGX lobe plus a Lambert term, fitted by
//! the same machinery as every other model ([`crate::model::Microfacet::GGX`]), expressed in
//! glTF 2.0's metallic–roughness parameters (base colour, metallic, roughness).
//!
//! The fitted model is `f = k_d/π + k_s · D G F_Schlick(F0) / (4 cos θi cos θo)` with per-channel
//! `k_d`, `k_s` and one `F0`, `α`. glTF's is `(1 − m) b/π` diffuse and a GGX lobe of the same `α`
//! whose normal-incidence reflectance is `0.04 (1 − m) + m b` per channel (`F90 = 1`). The
//! translation keeps `roughness = √α` and, over `m ∈ [0, 1]` in steps of 0.01, picks the metallic
//! `m` and base colour `b` that match both `(1 − m) b_c ≈ k_d,c` and `0.04 (1 − m) + m b_c ≈
//! k_s,c F0` in least squares (per channel, `b_c` clamped to [0, 1]). What glTF cannot hold (a
//! grazing reflectance `k_s ≠ 1`, a diffuse term beside a metal's colour) is left out; the
//! remaining mismatch of those two reflectances is reported as `mismatch`.

use crate::fit::{FitError, FitOptions, FitResult};
use crate::samples::SampleSet;

/// glTF metallic–roughness parameters of a measured BRDF, and the GGX + Lambert fit they come from.
#[derive(Clone, Debug)]
pub struct EngineParams {
    /// glTF `baseColorFactor` (linear RGB, each in [0, 1]).
    pub base_color: [f64; 3],
    /// glTF `metallicFactor`, in [0, 1].
    pub metallic: f64,
    /// glTF `roughnessFactor` = √α, in [0, 1] (clamped).
    pub roughness: f64,
    /// The fitted GGX α.
    pub alpha: f64,
    /// The fit's diffuse albedo `k_d` per channel.
    pub diffuse: [f64; 3],
    /// The fit's normal-incidence specular reflectance `k_s F0` per channel.
    pub specular_f0: [f64; 3],
    /// RMS over channels of the two reflectances' differences between the glTF parameters and
    /// the fit (albedo units, 0 = exact).
    pub mismatch: f64,
    /// The GGX + Lambert fit (its errors, held-out errors, iterations).
    pub fit: FitResult,
}

/// The glTF parameters of a fitted GGX + Lambert model (`θ = [ln α, F0]`, amplitudes
/// `[diffuse, specular]`), as the module documentation describes.
#[must_use]
pub fn from_ggx_fit(r: FitResult) -> EngineParams {
    let alpha = r.theta[0].exp();
    let f0 = r.theta[1];
    let kd = r.amps[0];
    let ks = r.amps[1];
    let s = [ks[0] * f0, ks[1] * f0, ks[2] * f0];
    let mut best = (f64::INFINITY, 0.0, [0.0; 3]);
    for step in 0..=100 {
        let m = f64::from(step) / 100.0;
        let mut b = [0.0; 3];
        let mut err = 0.0;
        for c in 0..3 {
            // Least squares in b of (1−m) b = kd and m b = s − 0.04 (1−m).
            let (a1, y1) = (1.0 - m, kd[c]);
            let (a2, y2) = (m, s[c] - 0.04 * (1.0 - m));
            let den = a1 * a1 + a2 * a2;
            b[c] = if den > 0.0 {
                ((a1 * y1 + a2 * y2) / den).clamp(0.0, 1.0)
            } else {
                0.0
            };
            err += (a1 * b[c] - y1).powi(2) + (a2 * b[c] - y2).powi(2);
        }
        if err < best.0 {
            best = (err, m, b);
        }
    }
    EngineParams {
        base_color: best.2,
        metallic: best.1,
        roughness: alpha.sqrt().min(1.0),
        alpha,
        diffuse: kd,
        specular_f0: s,
        mismatch: (best.0 / 6.0).sqrt(),
        fit: r,
    }
}

/// Fit the GGX + Lambert model to `data` with `opts` and translate it ([`from_ggx_fit`]).
///
/// # Errors
/// The fit's.
pub fn fit_engine(data: &SampleSet, opts: &FitOptions) -> Result<EngineParams, FitError> {
    Ok(from_ggx_fit(crate::fit::fit(
        &crate::model::Microfacet::GGX,
        data,
        opts,
    )?))
}

/// Azimuths of the half vector over which [`of_material`] averages a material whose NDF is not
/// known to be isotropic (evenly spaced over 2π). With 64, the engine parameters of a GGX lobe
/// of α 0.1 × 0.4 (tabulated) agree to four digits whether it is turned by 0°, 37° or 90°
/// (`tests/engine.rs`); with 16 they were up to 0.01 apart in base colour; seen along one
/// azimuth, as before, the same lobe gave α 0.115 turned 0° and 0.409 with F0 2.9 turned 90°.
pub const ENGINE_AZIMUTHS: usize = 64;

/// MERL cells [`of_material`] fits the engine parameters to (the default of `meso fit`'s
/// sampling, [`MerlSampling`](crate::samples::MerlSampling)).
pub const ENGINE_FITTED: u64 = 30_000;

/// MERL cells [`of_material`] holds out to score the fit.
pub const ENGINE_HELD_OUT: u64 = 20_000;

/// MERL cells whose BRDF [`of_material`] evaluates: fitted and held out.
pub const ENGINE_CELLS: u64 = ENGINE_FITTED + ENGINE_HELD_OUT;

/// The turns of [`of_material`] are `2π (k + AZIMUTH_OFFSET) / ENGINE_AZIMUTHS`: a MERL table's
/// half vectors lie at azimuth 0, which is a sector edge of a tabulated NDF's grid (and turned by
/// `2π k / 16`, again an edge), where rounding picks the cell on either side; the offset keeps
/// them inside cells.
const AZIMUTH_OFFSET: f64 = 0.381_966;

/// The engine parameters of a meso material: its BRDF (meso-core's compiled plan,
/// `Policy::Accurate`) tabulated as a MERL table would hold it (the lower bin edges), sampled as
/// `meso fit` samples a MERL table (30 000 stratified cells fitted; 20 000 held out), and the GGX +
/// Lambert fit of [`fit_engine`] on them: what `meso fit` reports for the same material given as
/// data. A MERL table is isotropic (it holds no azimuth of the half vector), so a material whose
/// NDF is not known to be isotropic ([`meso_core::ndf::Ndf::is_isotropic`]) is tabulated as its
/// average over [`ENGINE_AZIMUTHS`] turns of the pair about the normal — the isotropic BRDF
/// that an engine's single isotropic GGX lobe stands for — not along one azimuth.
///
/// # Errors
/// The fit's, or [`FitError::BadModel`] when the material's BRDF cannot be tabulated (not
/// finite).
pub fn of_material(material: &meso_core::material::Material) -> Result<EngineParams, FitError> {
    of_material_with(material, &|_, _| {})
}

/// [`of_material`] reporting its progress: `progress(done, total)` after each MERL cell whose
/// BRDF is evaluated (`total` = [`ENGINE_CELLS`]; from the worker threads). Most of the time of
/// a material without a closed form goes there (a quadrature per evaluation, and
/// [`ENGINE_AZIMUTHS`] of them per cell when the NDF is not isotropic).
///
/// # Errors
/// As [`of_material`].
pub fn of_material_with(
    material: &meso_core::material::Material,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<EngineParams, FitError> {
    use crate::merl::CellPosition;
    use crate::samples::MerlSampling;
    use meso_core::shading::{FastBrdf, Policy};
    let turns: Vec<glam::DQuat> = if material.ndf.is_isotropic() {
        vec![glam::DQuat::IDENTITY]
    } else {
        (0..ENGINE_AZIMUTHS)
            .map(|k| {
                glam::DQuat::from_rotation_z(
                    2.0 * std::f64::consts::PI * (k as f64 + AZIMUTH_OFFSET)
                        / ENGINE_AZIMUTHS as f64,
                )
            })
            .collect()
    };
    let turned = TurnAverage {
        plan: FastBrdf::with_policy(material, Policy::Accurate),
        turns,
    };
    // One evaluation per cell instead of one per turn where the BRDF is linear in the NDF.
    let averaged = (turned.turns.len() > 1)
        .then(|| azimuthal_average(material, &turned))
        .flatten();
    let eval = |wi: glam::DVec3, wo: glam::DVec3| match &averaged {
        Some(plan) => plan.eval(wi, wo),
        None => turned.eval(wi, wo),
    };
    use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
    let counter = AtomicU64::new(0);
    // Only the cells the fit samples are evaluated (50 000 of the table's 1.46 M): the same
    // samples as tabulating the whole table first, bit for bit.
    let (samples, _) = SampleSet::from_merl_fn(
        CellPosition::Edge,
        &MerlSampling {
            target: ENGINE_FITTED as usize,
            held_out: ENGINE_HELD_OUT as usize,
            ..MerlSampling::default()
        },
        eval,
        &|| progress(counter.fetch_add(1, Relaxed) + 1, ENGINE_CELLS),
    )
    .map_err(|e| FitError::BadModel {
        model: "engine parameters".into(),
        what: format!("the material's BRDF as a MERL table: {e}"),
    })?;
    fit_engine(&samples, &FitOptions::default())
}

/// A material's BRDF averaged over turns of the direction pair about the normal.
struct TurnAverage {
    plan: meso_core::shading::FastBrdf,
    turns: Vec<glam::DQuat>,
}

impl TurnAverage {
    fn eval(&self, wi: glam::DVec3, wo: glam::DVec3) -> [f64; 3] {
        let mut sum = [0.0; 3];
        for q in &self.turns {
            let v = self.plan.eval(*q * wi, *q * wo);
            for (s, x) in sum.iter_mut().zip(v) {
                *s += x;
            }
        }
        sum.map(|s| s / self.turns.len() as f64)
    }
}

/// Polar nodes of [`azimuthal_average`]'s radial NDF (uniform over [0, π/2]) …
const AVERAGE_THETAS: usize = 2048;
/// … and azimuths averaged at each.
const AVERAGE_PHIS: usize = 2048;
/// Largest relative difference (to the largest value of the check pairs) between the averaged
/// NDF's BRDF and the turns' average that [`azimuthal_average`] accepts.
const AVERAGE_TOLERANCE: f64 = 1e-4;

/// The compiled plan of `material` with its NDF replaced by the NDF's average over azimuth (a
/// `radial` NDF of [`AVERAGE_THETAS`] nodes, each the mean of [`AVERAGE_PHIS`] azimuths), when
/// that is the turns' average of [`of_material`] at the cost of one evaluation: the BRDF is
/// linear in the NDF (no masking–shadowing: the microfacet form's projected area does not
/// change under a turn), the facets' BRDF does not depend on their own tangent (not an
/// anisotropic microfacet transfer), the NDF has no mass below the horizon (a radial NDF holds
/// only the upper hemisphere) and, checked, the two agree within [`AVERAGE_TOLERANCE`] of the
/// largest value on 18 direction pairs. `None` otherwise (the turns are evaluated). A Phong-peaks
/// material with a lobe tilted 30° (docs/material-format.md's example) took ≈ 52 min of CPU
/// with the 64 turns; averaged, 48 s, within 8·10⁻⁶ of 256 turns (docs/export.md).
fn azimuthal_average(
    material: &meso_core::material::Material,
    turned: &TurnAverage,
) -> Option<meso_core::shading::FastBrdf> {
    use meso_core::material::ShadowingKind;
    use meso_core::shading::{FastBrdf, Policy};
    use meso_core::transfer::Transfer;
    use rayon::prelude::*;
    use std::f64::consts::{FRAC_PI_2, PI};
    if material.shadowing != ShadowingKind::None {
        return None;
    }
    if let Transfer::Microfacet { distribution, .. } = &material.transfer {
        if !distribution.is_isotropic() {
            return None;
        }
    }
    let theta: Vec<f64> = (0..AVERAGE_THETAS)
        .map(|k| FRAC_PI_2 * k as f64 / (AVERAGE_THETAS - 1) as f64)
        .collect();
    let density: Vec<f64> = theta
        .par_iter()
        .map(|&t| {
            let (s, c) = t.sin_cos();
            (0..AVERAGE_PHIS)
                .map(|j| {
                    let p = 2.0 * PI * (j as f64 + 0.5) / AVERAGE_PHIS as f64;
                    material
                        .ndf
                        .eval(glam::DVec3::new(s * p.cos(), s * p.sin(), c))
                })
                .sum::<f64>()
                / AVERAGE_PHIS as f64
        })
        .collect();
    // The upper hemisphere's mass (trapezoids of n̄ sin θ); the rest would be dropped.
    let h = theta[1];
    let upper: f64 = 2.0
        * PI
        * h
        * density
            .windows(2)
            .zip(theta.windows(2))
            .map(|(d, t)| 0.5 * (d[0] * t[0].sin() + d[1] * t[1].sin()))
            .sum::<f64>();
    if (upper - 1.0).abs() > 1e-4 || !upper.is_finite() {
        return None;
    }
    let radial = meso_core::ndf::Radial::new(theta, density).ok()?;
    let mut averaged = material.clone();
    averaged.ndf = meso_core::ndf::Ndf::Radial(radial);
    let plan = FastBrdf::with_policy(&averaged, Policy::Accurate);
    // The check: 18 pairs over elevations and azimuths.
    let d = meso_core::frame::spherical_direction_deg;
    let pairs: Vec<(glam::DVec3, glam::DVec3)> = [10.0, 40.0, 70.0]
        .iter()
        .flat_map(|&ti| {
            [
                (15.0, 180.0),
                (45.0, 150.0),
                (65.0, 60.0),
                (30.0, 0.0),
                (ti, 180.0),
                (80.0, 170.0),
            ]
            .map(move |(to, po)| (d(ti, 20.0), d(to, 20.0 + po)))
        })
        .collect();
    let got: Vec<([f64; 3], [f64; 3])> = pairs
        .par_iter()
        .map(|&(i, o)| (plan.eval(i, o), turned.eval(i, o)))
        .collect();
    let peak = got
        .iter()
        .flat_map(|(_, t)| t.iter().copied())
        .fold(0.0_f64, f64::max);
    let worst = got
        .iter()
        .flat_map(|(a, t)| a.iter().zip(t).map(|(x, y)| (x - y).abs()))
        .fold(0.0_f64, f64::max);
    (peak > 0.0 && worst <= AVERAGE_TOLERANCE * peak).then_some(plan)
}

impl EngineParams {
    /// Write [`EngineParams::describe`] into the material file `text` as a comment line, after
    /// its leading comment lines (the header): what every `meso fit` writes beside its NDF, so
    /// that the file carries what an engine needs. The material's meaning is unchanged.
    pub fn annotate(&self, text: &mut String) {
        let at: usize = text
            .split_inclusive('\n')
            .take_while(|l| l.starts_with('#'))
            .map(str::len)
            .sum();
        text.insert_str(at, &format!("# {}\n", self.describe()));
    }

    /// One report line: `engine (glTF metallic-roughness, from a GGX + Lambert fit): …`.
    #[must_use]
    pub fn describe(&self) -> String {
        let b = self.base_color;
        format!(
            "engine (glTF metallic-roughness, from a GGX + Lambert fit): base colour [{:.4}, {:.4}, {:.4}], \
             metallic {:.2}, roughness {:.4} (GGX alpha {:.4}); fit: diffuse [{:.4}, {:.4}, {:.4}], \
             specular F0 [{:.4}, {:.4}, {:.4}]; glTF mismatch {:.4}",
            b[0],
            b[1],
            b[2],
            self.metallic,
            self.roughness,
            self.alpha,
            self.diffuse[0],
            self.diffuse[1],
            self.diffuse[2],
            self.specular_f0[0],
            self.specular_f0[1],
            self.specular_f0[2],
            self.mismatch
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_core::material::Material;
    use meso_core::shading::{FastBrdf, Policy};

    /// The material of docs/material-format.md's example: Phong peaks (one lobe tilted 30°)
    /// under Phong facets, the multiple-surface form.
    const TILTED: &str = "[ndf]\nkind = \"phong-peaks\"\nlobes = [\n  \
        { axis = [0.0, 0.0], weight = 0.6, exponent = 40.0 },\n  \
        { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },\n]\n\
        [transfer]\nkind = \"phong\"\nexponent = 50.0\nspecular = [1.0, 0.8, 0.6]\n";

    fn turns_of(m: &Material) -> TurnAverage {
        TurnAverage {
            plan: FastBrdf::with_policy(m, Policy::Accurate),
            turns: (0..ENGINE_AZIMUTHS)
                .map(|k| {
                    glam::DQuat::from_rotation_z(
                        2.0 * std::f64::consts::PI * (k as f64 + AZIMUTH_OFFSET)
                            / ENGINE_AZIMUTHS as f64,
                    )
                })
                .collect(),
        }
    }

    /// The averaged NDF's BRDF is the 64 turns' average at random pairs (not those of the
    /// built-in check) within 10⁻⁴ of the largest value (measured ≈ 4·10⁻⁶ relative against 256
    /// turns), at one evaluation per pair instead of 64.
    #[test]
    fn the_azimuthal_average_is_the_turns_average() {
        let m = Material::from_toml_str(TILTED).unwrap();
        let turned = turns_of(&m);
        let plan = azimuthal_average(&m, &turned).expect("linear, isotropic facets, no mass below");
        // Directions of a golden-ratio sequence, elevations 3°–87°.
        let dir = |k: usize, a: f64| {
            let z = 0.05 + 0.95 * ((k as f64 + 0.5) * 0.618_033_988_75 + a).fract();
            let r = (1.0 - z * z).sqrt();
            let p = 2.0 * std::f64::consts::PI * ((k as f64) * 0.754_877_666_2 + a).fract();
            glam::DVec3::new(r * p.cos(), r * p.sin(), z)
        };
        let pairs: Vec<_> = (0..40).map(|k| (dir(k, 0.0), dir(k, 0.37))).collect();
        let got: Vec<([f64; 3], [f64; 3])> = pairs
            .iter()
            .map(|&(i, o)| (plan.eval(i, o), turned.eval(i, o)))
            .collect();
        let peak = got.iter().map(|(_, t)| t[0]).fold(0.0_f64, f64::max);
        for ((a, t), (i, o)) in got.iter().zip(&pairs) {
            for c in 0..3 {
                assert!(
                    (a[c] - t[c]).abs() <= 1e-4 * peak,
                    "{i:?} {o:?}: averaged NDF {a:?}, 64 turns {t:?}"
                );
            }
        }
    }

    /// Where the turns' average is not the averaged NDF's BRDF, the turns are kept: masking
    /// (not linear in the NDF), anisotropic facets (their tangent matters), mass below the
    /// horizon (a radial NDF holds none).
    #[test]
    fn the_average_is_refused_where_it_would_differ() {
        let cases = [
            TILTED.replace("[ndf]", "form = \"microfacet\"\n[shadowing]\nkind = \"smith\"\n[ndf]"),
            "[ndf]\nkind = \"ggx\"\nalpha_x = 0.1\nalpha_y = 0.4\n[transfer]\nkind = \"microfacet\"\n\
             alpha_x = 0.05\nalpha_y = 0.3\n"
                .to_owned(),
            TILTED.replace("axis = [30.0, 90.0], weight = 0.4, exponent = 100.0", "axis = [80.0, 90.0], weight = 0.4, exponent = 2.0"),
        ];
        for text in &cases {
            let m = Material::from_toml_str(text).unwrap();
            assert!(
                azimuthal_average(&m, &turns_of(&m)).is_none(),
                "averaged: {text}"
            );
        }
    }
}
