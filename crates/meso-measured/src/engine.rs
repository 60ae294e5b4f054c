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
    let plan = FastBrdf::with_policy(material, Policy::Accurate);
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
    let eval = |wi: glam::DVec3, wo: glam::DVec3| {
        let mut sum = [0.0; 3];
        for q in &turns {
            let v = plan.eval(*q * wi, *q * wo);
            for (s, x) in sum.iter_mut().zip(v) {
                *s += x;
            }
        }
        sum.map(|s| s / turns.len() as f64)
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
