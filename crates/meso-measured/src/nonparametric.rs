//! The **non-parametric NDF** of a measured isotropic material (#13 item 3, §3.3 of the paper by
//! the data-driven route of Dupuy et al. 2015, "Extracting microfacet-based BRDF parameters from
//! arbitrary materials with power iterations"): the NDF tabulated in `θ_m`
//! ([`meso_core::ndf::Radial`]) from the back-scattering cells of a MERL table, with Smith
//! masking derived from it, and Schlick Fresnel, the mirror `specular` scale and a Lambert term
//! fitted alongside. The result is an ordinary material file (`[ndf] kind = "radial"`) that every
//! consumer reads: `meso brdf`, the renderer, the editor, export.
//!
//! # Model
//! `f(i, o) = ρ/π + (u + g (1 − i·h)⁵) D(h) G₂(i, o) / (4 cos θi cos θo)` per channel, `D` the
//! NDF in the microfacet convention (`∫ D (m·z) dω = 1`), `G₂ = 1/(1 + Λ(i) + Λ(o))` with
//! `Λ(ω) = a(ω)/cos θ − 1`, `a(ω) = ∫ D(m)(ω·m)⁺ dω` (meso-core's 1-D rule for isotropic NDFs,
//! [`meso_core::convolution::isotropic_projected_area`]) — exactly what meso-core evaluates for
//! the written material.
//!
//! # Fit
//! 1. **Back-scattering** (`i = o`, so `h = i`, `i·h = 1`, `G₂ = cos θ/(2a − cos θ)`): the
//!    measurement is `f_r(θ) = ρ/π + u D(θ) / (4 cos θ (2a(θ) − cos θ))`, hence
//!    `D(θ) ∝ (f_r(θ) − ρ/π) cos θ (2a(θ) − cos θ)`. Since `a` depends on `D`, this is a
//!    fixed point, found by iteration from `a = cos θ` ([`POWER_ITERATIONS`]; Dupuy et al.'s
//!    power iteration). The nodes are MERL's `θh` bins with `θd = 0` (all 90, dense near the
//!    normal), the channels summed (the NDF is the geometry's, shared by r, g, b).
//! 2. **Fresnel, specular, diffuse:** with `D` and `G₂` known the model is linear in
//!    `(ρ, u, g)` per channel: weighted least squares on the fitted cells in the Löw log metric
//!    linearised about the data (weights: the cells' measure × `(cos θi / (1 + f cos θi))²`),
//!    with `0 ≤ ρ ≤ 1`, `u, g ≥ 0` and `u + g ≤ 1`, solved exactly
//!    ([`meso_core::lm::linear_least_squares_limited`]).
//! 3. Steps 1–2 alternate [`OUTER_ITERATIONS`] times (`ρ` enters the back-scattering).
//! 4. The alternation holds Smith's `G₂` from the NDF of the step before, so it can settle on
//!    a self-consistent NDF that is not the best fit: from the power-iteration start, a GGX
//!    α = 0.15 material settled 0.9 % off its NDF (θ ≤ 45°) and 20 % off its Schlick term
//!    (f0 2 % high, the specular scale 2 % low), while started from the truth it stays within
//!    0.22 %. So it runs from two starts, the power iteration and the NDF of the best single
//!    GGX lobe ([`crate::model::lobes_ggx`], K = 1, Löw log metric), and keeps the one with the
//!    lower Löw log error on the fitted samples ([`NonParametric::start`] says which).
//!
//! `s = u + g` and `f0 = u/(u + g)` are written as the mirror's `specular` and `f0`. Step 2
//! keeps `s ≤ 1` as a constraint of its solve (as the lobe models keep it in theirs,
//! [`meso_core::lm::SumLimit`]), so the written material is the fitted one; the report says
//! when the limit is active.

use crate::fit::{evaluate_samples_fn, FitErrors};
use crate::merl::{cell_angles, CellPosition, MerlTable, N_PHI_D, N_THETA_H};
use crate::samples::SampleSet;
use glam::DVec3;
use meso_core::convolution::isotropic_projected_area;
use meso_core::linalg::gauss_solve;
use meso_core::lm::{linear_least_squares_limited, SumLimit};
use meso_core::material::{Material, MaterialSpec};
use meso_core::ndf::{Ndf, Radial};
use meso_core::shading::{FastBrdf, Policy};
use std::f64::consts::{FRAC_PI_2, PI};

/// Fixed-point (power) iterations of the NDF per outer step.
pub const POWER_ITERATIONS: usize = 12;
/// Alternations of the NDF and the linear Fresnel / diffuse fit.
pub const OUTER_ITERATIONS: usize = 40;
/// Back-scattering cells above this `θh` (degrees) are not used: near grazing the measurements
/// are unreliable and the masking dominates; the NDF keeps its last measured density up to 90°.
pub const MAX_THETA_H_DEG: f64 = 85.0;

/// A fitted non-parametric material.
#[derive(Clone, Debug)]
pub struct NonParametric {
    /// The NDF (Eq. 1 convention).
    pub ndf: Radial,
    /// Schlick `f0` per channel, in [0, 1].
    pub f0: [f64; 3],
    /// The mirror's `specular` scale per channel, in [0, 1].
    pub specular: [f64; 3],
    /// Lambert albedo per channel, in [0, 1].
    pub albedo: [f64; 3],
    /// True when the specular scale `u + g` sits at its limit 1 on some channel: the data asked
    /// for more and the fit's constraint held it (the written material is the fitted one).
    pub specular_at_limit: bool,
    /// Errors of the written material on the fitted samples.
    pub fitted: FitErrors,
    /// Errors of the written material on the held-out samples (`None` when none are held out).
    pub held_out: Option<FitErrors>,
    /// Back-scattering nodes used (θh bins with data).
    pub nodes: usize,
    /// The start the kept fit came from.
    pub start: Start,
}

/// Where the alternation of a non-parametric fit started (module docs, "Fit").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Start {
    /// The NDF from the back-scattering cells by power iteration.
    #[default]
    PowerIteration,
    /// The NDF of the best single GGX lobe (+ Lambert) fitted to the same samples.
    Ggx,
}

impl Start {
    /// A short name for reports: `power-iteration` or `ggx`.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Start::PowerIteration => "power-iteration",
            Start::Ggx => "ggx",
        }
    }
}

/// Why a non-parametric fit cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum NonParametricError {
    /// The data has no back-scattering cells (not a MERL table, or too few measured).
    #[error("{0}")]
    Data(String),
}

/// The back-scattering measurements: per θh bin with data, `(θh, [f_r; 3])`.
fn backscattering(table: &MerlTable) -> Vec<(f64, [f64; 3])> {
    let mut out = Vec::new();
    for ih in 0..N_THETA_H {
        let th = cell_angles(ih, 0, 0, CellPosition::Edge).theta_h;
        if th.to_degrees() > MAX_THETA_H_DEG {
            break;
        }
        let mut sum = [0.0; 3];
        let mut n = 0usize;
        for ip in 0..N_PHI_D {
            let v = [
                table.value(0, ih, 0, ip),
                table.value(1, ih, 0, ip),
                table.value(2, ih, 0, ip),
            ];
            if v.iter().all(|x| *x >= 0.0 && x.is_finite()) {
                for c in 0..3 {
                    sum[c] += v[c];
                }
                n += 1;
            }
        }
        if n > 0 {
            out.push((th, sum.map(|s| s / n as f64)));
        }
    }
    out
}

/// The NDF through nodes `theta` with densities `d` (any scale), extended to π/2 with its last
/// density.
fn radial(theta: &[f64], d: &[f64]) -> Result<Radial, NonParametricError> {
    let mut t = theta.to_vec();
    let mut v = d.to_vec();
    if *t.last().unwrap_or(&0.0) < FRAC_PI_2 {
        t.push(FRAC_PI_2);
        v.push(*v.last().unwrap_or(&0.0));
    }
    Radial::new(t, v).map_err(|e| NonParametricError::Data(e.to_string()))
}

/// `a(θ)` of the NDF in the microfacet convention at each node (`a(0) = 1`).
fn projected_areas(ndf: &Ndf, theta: &[f64]) -> Vec<f64> {
    let p = isotropic_projected_area(ndf, 1.0);
    theta
        .iter()
        .map(|t| isotropic_projected_area(ndf, t.cos()) / p)
        .collect()
}

/// The linear terms `(ρ, u, g)` of one channel: least squares `min Σ w (x·a − y)²` over
/// `0 ≤ ρ ≤ 1`, `u, g ≥ 0` and `u + g ≤ 1` (the mirror's specular scale may not exceed 1), solved
/// exactly by [`meso_core::lm::linear_least_squares_limited`] (the limit is a constraint of
/// the solve, not a clamp afterwards).
pub(crate) fn linear3(rows: &[([f64; 3], f64, f64)]) -> [f64; 3] {
    let mut ata = [0.0f64; 9];
    let mut aty = [0.0f64; 3];
    for (a, y, w) in rows {
        for r in 0..3 {
            aty[r] += w * a[r] * y;
            for c in 0..3 {
                ata[r * 3 + c] += w * a[r] * a[c];
            }
        }
    }
    let limit = [SumLimit {
        indices: vec![1, 2],
        limit: 1.0,
    }];
    let x = linear_least_squares_limited(&ata, &aty, &[1.0, f64::INFINITY, f64::INFINITY], &limit);
    [x[0], x[1], x[2]]
}

/// A fitted non-parametric material, isotropic ([`NonParametric`]) or anisotropic
/// ([`crate::nonparametric_aniso::NonParametricAniso`]): what its material file is written from
/// ([`material_spec`]).
pub trait MirrorFit {
    /// The fitted NDF (Eq. 1 convention) as meso-core's [`Ndf`]: `Radial` or `Tabulated`.
    fn mirror_ndf(&self) -> Ndf;
    /// `[f0, specular, albedo]`: Schlick `f0`, the mirror's `specular` scale and the Lambert
    /// albedo, per channel, each in [0, 1].
    fn mirror_terms(&self) -> [[f64; 3]; 3];
}

impl MirrorFit for NonParametric {
    fn mirror_ndf(&self) -> Ndf {
        Ndf::Radial(self.ndf.clone())
    }

    fn mirror_terms(&self) -> [[f64; 3]; 3] {
        [self.f0, self.specular, self.albedo]
    }
}

/// The material of a fit: its NDF (radial or tabulated) under
/// [`crate::model::mirror_material`].
#[must_use]
pub fn material_spec(fit: &impl MirrorFit) -> MaterialSpec {
    let [f0, specular, albedo] = fit.mirror_terms();
    crate::model::mirror_material(fit.mirror_ndf(), f0, specular, albedo)
}

/// The material file of a fit (TOML, with `comment` lines as `#` comments first).
#[must_use]
pub fn material_toml(fit: &impl MirrorFit, comment: &str) -> String {
    material_spec(fit).to_toml_with_comment(comment)
}

/// The material of a fit, as its file reads back.
///
/// # Panics
/// Never for a fit made here (its file always parses).
#[must_use]
pub fn material(fit: &impl MirrorFit) -> Material {
    parsed(&material_spec(fit))
}

/// A fitted material as its file reads back: `spec` written as TOML and parsed.
///
/// # Panics
/// Never for a [`crate::model::mirror_material`] (its file always parses).
pub(crate) fn parsed(spec: &MaterialSpec) -> Material {
    Material::from_toml_str(&spec.to_toml_with_comment("")).expect("a fitted material parses")
}

/// The white mirror material of `ndf` (`f0 = 1`, `specular = 1`, no diffuse), as written and
/// parsed back: its value is the basis `X` of the linear terms ([`linear_terms_of`]).
pub(crate) fn white(ndf: Ndf) -> Material {
    parsed(&crate::model::mirror_material(
        ndf, [1.0; 3], [1.0; 3], [0.0; 3],
    ))
}

/// Fit the non-parametric material (module docs) to a MERL table, scoring it on `data`'s fitted
/// and held-out samples.
///
/// # Errors
/// Fewer than 8 back-scattering bins with data, or data without back-scattering signal.
pub fn fit(table: &MerlTable, data: &SampleSet) -> Result<NonParametric, NonParametricError> {
    let back = backscattering(table);
    if back.len() < 8 {
        return Err(NonParametricError::Data(format!(
            "the non-parametric NDF needs the back-scattering cells (θd = 0) of at least 8 θh \
             bins; this table has {}",
            back.len()
        )));
    }
    let theta: Vec<f64> = back.iter().map(|b| b.0).collect();
    // 1. The starting NDFs: from the back-scattering alone, and the best single GGX lobe.
    let mut starts = vec![(Start::PowerIteration, initial_ndf(&back, &theta)?)];
    if let Some(r) = ggx_start(data, &theta) {
        starts.push((Start::Ggx, r));
    }
    // 2. and 3., alternated from each start; the lower error on the fitted samples wins.
    let mut best: Option<NonParametric> = None;
    for (start, mut r) in starts {
        for _ in 0..OUTER_ITERATIONS {
            let (basis, lin) = linear_terms(&r, data);
            r = refit_nodes(&r, &basis, &lin, data)?;
        }
        let (_, lin) = linear_terms(&r, data);
        let mut fit = finish(r, &lin, back.len(), data);
        fit.start = start;
        let err = |f: &NonParametric| f.fitted.low_log.iter().sum::<f64>();
        if best.as_ref().is_none_or(|b| err(&fit) < err(b)) {
            best = Some(fit);
        }
    }
    best.ok_or_else(|| NonParametricError::Data("no start of the fit converged".to_owned()))
}

/// The NDF of the best single GGX lobe (plus Lambert, Löw log metric: the GGX-lobe family with
/// K = 1) at the nodes `theta`: the second start of the alternation. `None` when that fit fails.
fn ggx_start(data: &SampleSet, theta: &[f64]) -> Option<Radial> {
    use crate::model::lobes_ggx::fit_ggx_lobes_progressive;
    use meso_core::ndf::Distribution;
    let opts = crate::fit::FitOptions::default();
    let fits = fit_ggx_lobes_progressive(1, &[Distribution::Ggx], data, &opts).ok()?;
    let (m, r) = fits.last()?;
    let alpha = m.params(r).lobes.first()?.alpha;
    if !(alpha.is_finite() && alpha > 0.0) {
        return None;
    }
    let a2 = alpha * alpha;
    let d: Vec<f64> = theta
        .iter()
        .map(|t| {
            let c2 = t.cos().powi(2);
            a2 / (PI * (c2 * (a2 - 1.0) + 1.0).powi(2))
        })
        .collect();
    radial(theta, &d).ok()
}

/// Step 1: the NDF by power iteration on the back-scattering (channels summed), each
/// channel's smallest back-scattering value taken as its diffuse floor.
fn initial_ndf(back: &[(f64, [f64; 3])], theta: &[f64]) -> Result<Radial, NonParametricError> {
    let floor: Vec<f64> = (0..3)
        .map(|c| back.iter().map(|(_, f)| f[c]).fold(f64::INFINITY, f64::min))
        .collect();
    let spec: Vec<f64> = back
        .iter()
        .map(|(_, f)| (0..3).map(|c| f[c] - floor[c]).sum())
        .collect();
    let peak = spec.iter().copied().fold(0.0, f64::max);
    if peak.is_nan() || peak <= 0.0 {
        return Err(NonParametricError::Data(
            "the back-scattering cells hold no reflection".to_owned(),
        ));
    }
    let spec: Vec<f64> = spec.iter().map(|s| s.max(1e-6 * peak)).collect();
    let mut a: Vec<f64> = theta.iter().map(|t| t.cos()).collect();
    let mut r = radial(theta, &spec)?;
    for _ in 0..POWER_ITERATIONS {
        let d: Vec<f64> = theta
            .iter()
            .zip(&spec)
            .zip(&a)
            .map(|((t, s), a)| {
                let c = t.cos();
                s * c * (2.0 * a - c).max(c)
            })
            .collect();
        r = radial(theta, &d)?;
        a = projected_areas(&Ndf::Radial(r.clone()), theta);
    }
    Ok(r)
}

/// The linear terms of the fit, per channel: Lambert albedo and the Schlick split of the
/// specular scale, `u + g (1 − cos θd)⁵`.
pub(crate) struct Linear {
    /// Lambert albedo per channel.
    pub(crate) albedo: [f64; 3],
    /// The Fresnel-independent part of the specular scale per channel.
    pub(crate) u: [f64; 3],
    /// Schlick's part of the specular scale per channel.
    pub(crate) g: [f64; 3],
}

impl Linear {
    /// The mirror's `(f0, specular)` per channel, `specular = min(u + g, 1)` and
    /// `f0 = u/(u + g)` (0 where `u + g = 0`), and whether `u + g` sits at its limit 1 on some
    /// channel.
    pub(crate) fn mirror(&self) -> ([f64; 3], [f64; 3], bool) {
        let mut at_limit = false;
        let mut f0 = [0.0; 3];
        let mut specular = [0.0; 3];
        for c in 0..3 {
            let s = self.u[c] + self.g[c];
            at_limit |= s >= 1.0 - 1e-9;
            specular[c] = s.min(1.0);
            f0[c] = if s > 0.0 { self.u[c] / s } else { 0.0 };
        }
        (f0, specular, at_limit)
    }
}

/// The errors of `material` (its plan under [`Policy::Accurate`]) on `data`'s fitted samples
/// and on its held-out ones (`None` when none are held out).
pub(crate) fn scores(material: &Material, data: &SampleSet) -> (FitErrors, Option<FitErrors>) {
    let plan = FastBrdf::with_policy(material, Policy::Accurate);
    let eval = |wi: DVec3, wo: DVec3| plan.eval(wi, wo);
    let fitted = evaluate_samples_fn(&data.samples, eval);
    let held_out = (!data.held_out.is_empty()).then(|| evaluate_samples_fn(&data.held_out, eval));
    (fitted, held_out)
}

/// Per sample: the white mirror's value `X`, its Schlick part `X (1 − c)⁵` and the sample's
/// weight times `cos² θi`.
pub(crate) type Basis = Vec<(f64, f64, f64)>;

/// The log metric linearised about the data: a residual δf in f weighs
/// cos θi / (1 + f cos θi) in ln(1 + f cos θi).
pub(crate) fn log_weight(s: &crate::samples::Sample, ch: usize, w: f64) -> f64 {
    let l = 1.0 + s.rgb[ch].max(0.0) * s.wi.z;
    w / (l * l)
}

/// Step 2: Fresnel, specular and diffuse by linear least squares on the fitted samples: the
/// basis X = D G₂ / (4 cos θi cos θo) from the plan of a white mirror material with NDF `r`.
fn linear_terms(r: &Radial, data: &SampleSet) -> (Basis, Linear) {
    linear_terms_of(&white(Ndf::Radial(r.clone())), data)
}

/// Step 2 for any NDF: the linear terms by least squares on the fitted samples, the basis from
/// the plan of `white`, a white mirror material (`f0 = 1`, `specular = 1`, no diffuse term).
pub(crate) fn linear_terms_of(white: &Material, data: &SampleSet) -> (Basis, Linear) {
    let plan = FastBrdf::with_policy(white, Policy::Accurate);
    let basis: Basis = data
        .samples
        .iter()
        .map(|s| {
            let x = plan.eval(s.wi, s.wo)[0];
            let h = (s.wi + s.wo).normalize_or_zero();
            let c = s.wi.dot(h).clamp(0.0, 1.0);
            (x, x * (1.0 - c).powi(5), s.weight * s.wi.z * s.wi.z)
        })
        .collect();
    let mut lin = Linear {
        albedo: [0.0; 3],
        u: [0.0; 3],
        g: [0.0; 3],
    };
    for ch in 0..3 {
        let rows: Vec<([f64; 3], f64, f64)> = data
            .samples
            .iter()
            .zip(&basis)
            .map(|(s, (x, xg, w))| ([1.0 / PI, *x, *xg], s.rgb[ch], log_weight(s, ch, *w)))
            .collect();
        let [rho, uu, gg] = linear3(&rows);
        lin.albedo[ch] = rho;
        lin.u[ch] = uu;
        lin.g[ch] = gg;
    }
    (basis, lin)
}

/// Step 3: the NDF's node values by linear least squares on every fitted sample (all
/// channels), Fresnel, diffuse and G₂ held: f − ρ/π = S(θd) G₂/(4 cos θi cos θo) ·
/// Σ_j D_j hat_j(θh), a tridiagonal system, non-negative by projected Gauss–Seidel.
fn refit_nodes(
    r: &Radial,
    basis: &Basis,
    lin: &Linear,
    data: &SampleSet,
) -> Result<Radial, NonParametricError> {
    let (u, g, albedo) = (&lin.u, &lin.g, &lin.albedo);
    let nodes: Vec<f64> = r.theta().to_vec();
    let nn = nodes.len();
    let ndf_now = Ndf::Radial(r.clone());
    let p = isotropic_projected_area(&ndf_now, 1.0);
    // Unknowns: the nn node values, then ρ_r, ρ_g, ρ_b (solved jointly: a broad NDF tail
    // and the Lambert term trade against each other).
    let dim = nn + 3;
    let mut ata = vec![0.0f64; dim * dim];
    let mut atb = vec![0.0f64; dim];
    for (s, (x, _, w)) in data.samples.iter().zip(basis) {
        let h = (s.wi + s.wo).normalize_or_zero();
        let dh = r.eval(h) / p;
        if dh.is_nan() || dh <= 0.0 || x.is_nan() || *x <= 0.0 {
            continue;
        }
        let gfac = x / dh; // G₂ / (4 cos θi cos θo)
        let th = (h.x * h.x + h.y * h.y).sqrt().atan2(h.z);
        let j = nodes.partition_point(|&t| t <= th).clamp(1, nn - 1) - 1;
        let t = ((th - nodes[j]) / (nodes[j + 1] - nodes[j])).clamp(0.0, 1.0);
        let c = s.wi.dot(h).clamp(0.0, 1.0);
        for ch in 0..3 {
            let sc = (u[ch] + g[ch] * (1.0 - c).powi(5)) * gfac;
            let row = [(j, sc * (1.0 - t)), (j + 1, sc * t), (nn + ch, 1.0 / PI)];
            let ww = log_weight(s, ch, *w);
            for &(a, va) in &row {
                atb[a] += ww * va * s.rgb[ch];
                for &(b, vb) in &row {
                    ata[a * dim + b] += ww * va * vb;
                }
            }
        }
    }
    // A small ridge towards the current values keeps nodes without data where they are.
    let ridge = 1e-9 * (0..dim).map(|k| ata[k * dim + k]).fold(0.0, f64::max);
    let prior: Vec<f64> = r
        .values()
        .iter()
        .map(|x| x / p)
        .chain(albedo.iter().copied())
        .collect();
    for k in 0..dim {
        ata[k * dim + k] += ridge;
        atb[k] += ridge * prior[k];
    }
    // A singular pivot (cannot happen with the ridge) leaves its unknown at 0.
    gauss_solve(&mut ata, &mut atb, dim);
    let v: Vec<f64> = atb[..nn]
        .iter()
        .map(|x| if x.is_finite() { x.max(0.0) } else { 0.0 })
        .collect();
    // The solved D carries the specular scale: renormalise it and move its scale into u, g.
    Radial::new(nodes, v).map_err(|e| NonParametricError::Data(e.to_string()))
}

/// The fitted material from the final NDF and linear terms (whose specular scale `u + g` the
/// linear solve kept ≤ 1), with its errors on the fitted and held-out samples.
fn finish(ndf: Radial, lin: &Linear, nodes: usize, data: &SampleSet) -> NonParametric {
    let (f0, specular, specular_at_limit) = lin.mirror();
    let mut out = NonParametric {
        ndf,
        f0,
        specular,
        albedo: lin.albedo,
        specular_at_limit,
        fitted: FitErrors::default(),
        held_out: None,
        nodes,
        start: Start::default(),
    };
    (out.fitted, out.held_out) = scores(&material(&out), data);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_terms_are_non_negative_and_keep_the_specular_limit() {
        let rows: Vec<([f64; 3], f64, f64)> = (0..50)
            .map(|k| {
                let x = f64::from(k) / 50.0;
                let a = [1.0, x, x * x];
                (a, 0.2 + 0.5 * x + 0.1 * x * x, 1.0)
            })
            .collect();
        let s = linear3(&rows);
        assert!(
            (s[0] - 0.2).abs() < 1e-9 && (s[1] - 0.5).abs() < 1e-9 && (s[2] - 0.1).abs() < 1e-9
        );
        // y = 1 − x: the x coefficient wants −1, so the best non-negative fit drops it.
        let rows: Vec<([f64; 3], f64, f64)> = (0..50)
            .map(|k| {
                let x = f64::from(k) / 50.0;
                ([1.0, x, x * x], 1.0 - x, 1.0)
            })
            .collect();
        let s = linear3(&rows);
        assert!(s.iter().all(|v| *v >= 0.0), "{s:?}");
        // y = 0.1 + 0.9 x + 0.6 x²: u + g = 1.5 unconstrained; held on u + g = 1, and the
        // answer beats the old clamp (the unconstrained u, g scaled to sum 1).
        let rows: Vec<([f64; 3], f64, f64)> = (0..50)
            .map(|k| {
                let x = f64::from(k) / 50.0;
                ([1.0, x, x * x], 0.1 + 0.9 * x + 0.6 * x * x, 1.0)
            })
            .collect();
        let s = linear3(&rows);
        assert!((s[1] + s[2] - 1.0).abs() < 1e-12, "{s:?}");
        let cost = |p: [f64; 3]| -> f64 {
            rows.iter()
                .map(|(a, y, w)| w * (a[0] * p[0] + a[1] * p[1] + a[2] * p[2] - y).powi(2))
                .sum()
        };
        assert!(cost(s) < cost([0.1, 0.6, 0.4]), "{s:?}");
    }
}
