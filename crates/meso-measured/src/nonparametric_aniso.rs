//! The **non-parametric NDF of anisotropic data** (#13 item 3, 2-D): the NDF tabulated over
//! `(θ_m, φ_m)` on meso-core's equal-area grid ([`meso_core::ndf::Tabulated`], `[ndf] kind =
//! "tabulated"`) from the back-scattering samples of scattered measurements with full
//! directions (a sample CSV), by the power iteration of Dupuy et al. 2015, with Smith masking
//! derived from the table and Schlick Fresnel, the mirror `specular` scale and a Lambert term
//! fitted alongside as in the isotropic fit ([`crate::nonparametric`]). The result is an ordinary
//! material file that every consumer reads (`meso brdf`, the renderer, the editor, export).
//!
//! # Model
//! `f(i, o) = ρ/π + (u + g (1 − i·h)⁵) D(h) G₂(i, o) / (4 cos θi cos θo)` per channel, `D` the
//! table in the microfacet convention (`∫ D (m·z) dω = 1`; the table holds `n = D/A` with
//! `∫ n dω = 1` over the sphere, 0 below the horizon), `G₂ = 1/(1 + Λ(i) + Λ(o))` with
//! `Λ(ω) = a(ω)/cos θ − 1` and `a(ω) = ∫ D(m)(ω·m)⁺ dω` by meso-core's quadrature of a general
//! NDF, read through the compiled plan's table of `a` (97 × 64 nodes,
//! [`meso_core::shading::FastBrdf`]) — exactly what meso-core evaluates for the written material.
//!
//! # Fit
//! 1. **Back-scattering samples:** the fitted samples whose `i` and `o` lie within
//!    [`BACK_TOLERANCE_DEG`] of each other, taken at `ω = h`; only those up to
//!    [`MAX_THETA_DEG`] are used. At `i = o = ω` the model is
//!    `f_r(ω) = ρ/π + u D(ω) / (4 cos θ (2a(ω) − cos θ))` (`i·h = 1`, so Schlick's factor is `u`),
//!    hence `D(ω) ∝ (f_r(ω) − ρ/π) cos θ (2a(ω) − cos θ)`, the channels summed (the NDF is the
//!    geometry's). Each table cell with back-scattering samples takes the mean of its samples;
//!    at least [`MIN_COVERAGE`] of the upper cells up to [`MAX_THETA_DEG`] must hold one, and
//!    every other upper cell takes the value of the covered cell with the nearest centre.
//! 2. **Power iteration:** `a` depends on `D`, so the update is iterated from `a = cos θ`
//!    ([`POWER_ITERATIONS`]): with `X(ω) = D G₂/(4 cos² θ)` the white mirror's value of the
//!    current table at `(ω, ω)` (from its compiled plan), the update is
//!    `n_new(cell) ∝ mean (f_r − ρ/π) n(cell)/X(ω)`, each channel's smallest back-scattering
//!    value taken as its diffuse floor `ρ/π`.
//! 3. **Fresnel, specular, diffuse:** with `D` and `G₂` known the model is linear in `(ρ, u, g)`
//!    per channel: the isotropic fit's weighted least squares on all fitted samples (Löw log
//!    metric linearised about the data, `0 ≤ ρ ≤ 1`, `u, g ≥ 0`, `u + g ≤ 1`, solved exactly).
//! 4. **All samples:** then, [`OUTER_ITERATIONS`] times, step 3 and a refit of every cell and
//!    the three albedos jointly by linear least squares on all fitted samples, `G₂` held from
//!    the table of the step before (each sample touches the cell of its half vector, so the
//!    normal equations are diagonal but for the albedos: a 3 × 3 Schur complement). The
//!    back-scattering alone cannot tell a broad tail from the Lambert term: a power iteration
//!    alternated with step 3 drifted (a GGX material's albedo 0.05 went to 0.15 in four
//!    alternations, the NDF's tail eaten), which the joint refit does not.
//!
//! Round trips (`tests/nonparametric_aniso.rs`; 16 384 back-scattering samples at the cell
//! centres of the default grid, four pairs per cell with the half vector in the cell, 20 000
//! pairs over the hemisphere, 10 000 held out): a GGX material α = (0.2, 0.4) turned by 30°
//! with f0 (0.9, 0.6, 0.3), specular 0.8 and albedo (0.05, 0.1, 0.2) comes back with f0 within
//! 0.9 %, specular within 0.6 %, albedo within 1.2 %, the table within 3.0 % rms of the
//! truth's cell means up to θ = 45° (worst cell 11 %: a cell is fitted to the few samples in
//! it, their weighted mean of `D`, not the cell's), and a held-out Löw log error 1.05–1.06×
//! that of the truth's own table with the true Fresnel and albedo (0.0145 against 0.0137 on
//! red: the error of a piecewise-constant table on this grid, not of the fit). A Beckmann
//! material α = (0.35, 0.2) turned by −60°: f0, specular and albedo within 0.6 %, the table
//! within 7.0 % rms (worst cell 45 %: its tail falls by orders of magnitude across a cell),
//! held-out 1.05–1.06× the truth's own table. Data drawn from a table on the fit's own grid
//! (the family's own parameters) come back within 10⁻³ in every cell, f0, specular and albedo
//! (GGX cell means; 10⁻⁶ for Beckmann's): the fit's fixed point is the truth, and the errors
//! above are those of a piecewise-constant table sampled by a few samples a cell.

//! `s = u + g` and `f0 = u/(u + g)` are written as the mirror's `specular` and `f0`.
//!
//! A piecewise-constant table cannot be finer than its cells: the grid (`n_z` bands of equal
//! height in `z`, `n_phi` sectors) is a parameter ([`AnisoOptions`]); its first band is a cap of
//! angular radius `√(4/n_z)` (5.1° for the default 512), so lobes much narrower than that are
//! averaged over it.

use crate::fit::FitErrors;
use crate::nonparametric::{
    linear_terms_of, log_weight, scores, white, Basis, Linear, MirrorFit, NonParametricError,
};
use crate::samples::SampleSet;
use glam::DVec3;
use meso_core::grid::EqualAreaGrid;
use meso_core::linalg::gauss_solve;
use meso_core::material::MAX_TABLE_CELLS;
use meso_core::ndf::{Ndf, Tabulated};
use meso_core::shading::{FastBrdf, Policy};
use std::f64::consts::PI;

/// Power iterations of the NDF from the back-scattering start.
pub const POWER_ITERATIONS: usize = 6;
/// Alternations of the linear Fresnel / diffuse fit and the refit of the cells on all samples.
pub const OUTER_ITERATIONS: usize = 8;
/// Back-scattering samples above this `θ_h` (degrees) are not used (the masking dominates near
/// grazing); the cells beyond take the value of the nearest covered cell.
pub const MAX_THETA_DEG: f64 = 85.0;
/// A sample is back-scattering when the angle between `i` and `o` is at most this (degrees).
pub const BACK_TOLERANCE_DEG: f64 = 0.5;
/// The share of the table's upper cells up to [`MAX_THETA_DEG`] that must hold a
/// back-scattering sample.
pub const MIN_COVERAGE: f64 = 0.9;

/// The table's grid: `n_z` bands of equal height in `z = cos θ` over the sphere (even, so that
/// the horizon is a band edge; half of them above the horizon) and `n_phi` sectors in φ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct AnisoOptions {
    /// Bands in `z ∈ [−1, 1]` (even, 4 to 4096).
    pub n_z: usize,
    /// Sectors in `φ ∈ [0, 2π)` (1 to 8192).
    pub n_phi: usize,
}

impl Default for AnisoOptions {
    /// 512 × 64: 16 384 cells above the horizon, a polar cap of 5.1°.
    fn default() -> Self {
        AnisoOptions {
            n_z: 512,
            n_phi: 64,
        }
    }
}

/// A fitted anisotropic non-parametric material.
#[derive(Clone, Debug)]
pub struct NonParametricAniso {
    /// The NDF (Eq. 1 convention, 0 below the horizon).
    pub ndf: Tabulated,
    /// Schlick `f0` per channel, in [0, 1].
    pub f0: [f64; 3],
    /// The mirror's `specular` scale per channel, in [0, 1].
    pub specular: [f64; 3],
    /// Lambert albedo per channel, in [0, 1].
    pub albedo: [f64; 3],
    /// True when the specular scale `u + g` sits at its limit 1 on some channel.
    pub specular_at_limit: bool,
    /// Errors of the written material on the fitted samples.
    pub fitted: FitErrors,
    /// Errors of the written material on the held-out samples (`None` when none are held out).
    pub held_out: Option<FitErrors>,
    /// Back-scattering samples used (up to [`MAX_THETA_DEG`]).
    pub back_samples: usize,
    /// Upper cells up to [`MAX_THETA_DEG`] holding a back-scattering sample.
    pub cells_covered: usize,
    /// Upper cells up to [`MAX_THETA_DEG`].
    pub cells_needed: usize,
}

/// One back-scattering sample: its cell, its direction `ω = h` (unit, local frame), and `f_r`
/// per channel (1/sr).
struct Back {
    cell: usize,
    dir: DVec3,
    rgb: [f64; 3],
}

/// A data error with `msg`.
fn err(msg: String) -> NonParametricError {
    NonParametricError::Data(msg)
}

/// Check the grid and the samples (finite, non-negative values; directions above the horizon).
fn validate(data: &SampleSet, opts: &AnisoOptions) -> Result<(), NonParametricError> {
    if opts.n_z < 4
        || !opts.n_z.is_multiple_of(2)
        || opts.n_z > 4096
        || opts.n_phi == 0
        || opts.n_phi > 8192
    {
        return Err(err(format!(
            "the table's grid {} × {} is not usable: n_z must be even, 4 to 4096, n_phi 1 to 8192",
            opts.n_z, opts.n_phi
        )));
    }
    if opts.n_z * opts.n_phi > MAX_TABLE_CELLS {
        return Err(err(format!(
            "the table's grid {} × {} has more than {MAX_TABLE_CELLS} cells",
            opts.n_z, opts.n_phi
        )));
    }
    let all = data.samples.iter().chain(&data.held_out);
    for (k, s) in all.enumerate() {
        if !s.rgb.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(err(format!(
                "sample {}: BRDF value {:?} is not finite and non-negative",
                k + 1,
                s.rgb
            )));
        }
        if !(s.wi.is_finite() && s.wo.is_finite() && s.wi.z > 0.0 && s.wo.z > 0.0) {
            return Err(err(format!(
                "sample {}: directions {:?}, {:?} are not both above the horizon",
                k + 1,
                s.wi,
                s.wo
            )));
        }
    }
    Ok(())
}

/// The fitted samples that are back-scattering, up to [`MAX_THETA_DEG`], by cell.
fn backscattering(data: &SampleSet, grid: EqualAreaGrid) -> Vec<Back> {
    let cos_tol = BACK_TOLERANCE_DEG.to_radians().cos();
    let cos_max = MAX_THETA_DEG.to_radians().cos();
    let mut out: Vec<Back> = data
        .samples
        .iter()
        .filter(|s| s.wi.dot(s.wo) >= cos_tol)
        .filter_map(|s| {
            let h = (s.wi + s.wo).normalize_or_zero();
            (h.z >= cos_max).then(|| Back {
                cell: grid.cell_of(h),
                dir: h,
                rgb: s.rgb,
            })
        })
        .collect();
    out.sort_by_key(|b| b.cell);
    out
}

/// For every cell: `Some(index into the covered list)` of the cell whose value it takes (itself
/// when covered, the covered cell with the nearest centre otherwise) for upper cells, `None`
/// below the horizon.
fn fill_map(grid: EqualAreaGrid, covered: &[usize]) -> Vec<Option<usize>> {
    let first_upper = grid.n_z / 2 * grid.n_phi;
    let centres: Vec<DVec3> = covered.iter().map(|&c| grid.cell_center(c)).collect();
    let mut map = vec![None; grid.len()];
    for (k, &c) in covered.iter().enumerate() {
        map[c] = Some(k);
    }
    for (c, slot) in map.iter_mut().enumerate().skip(first_upper) {
        if slot.is_none() {
            let w = grid.cell_center(c);
            let best = centres
                .iter()
                .enumerate()
                .max_by(|a, b| w.dot(*a.1).total_cmp(&w.dot(*b.1)))
                .map(|(k, _)| k);
            *slot = best;
        }
    }
    map
}

/// The state of the power iteration: the back-scattering samples grouped by covered cell.
struct Power {
    grid: EqualAreaGrid,
    back: Vec<Back>,
    /// Covered cells, ascending, with the range of their samples in `back`.
    covered: Vec<(usize, std::ops::Range<usize>)>,
    map: Vec<Option<usize>>,
}

impl Power {
    fn new(grid: EqualAreaGrid, back: Vec<Back>) -> Power {
        let mut covered = Vec::new();
        let mut start = 0;
        for k in 1..=back.len() {
            if k == back.len() || back[k].cell != back[start].cell {
                covered.push((back[start].cell, start..k));
                start = k;
            }
        }
        let cells: Vec<usize> = covered.iter().map(|c| c.0).collect();
        let map = fill_map(grid, &cells);
        Power {
            grid,
            back,
            covered,
            map,
        }
    }

    /// The specular part of a back-scattering sample, channels summed, above `floor` (`ρ/π`).
    fn spec(b: &Back, floor: &[f64; 3], tiny: f64) -> f64 {
        (0..3).map(|c| b.rgb[c] - floor[c]).sum::<f64>().max(tiny)
    }

    /// The table from one value per covered cell.
    fn table(&self, per_covered: &[f64]) -> Result<Tabulated, NonParametricError> {
        let values = self
            .map
            .iter()
            .map(|m| m.map_or(0.0, |k| per_covered[k]))
            .collect();
        Tabulated::from_values(self.grid, values).map_err(|e| err(e.to_string()))
    }

    /// The start: `D ∝ (f_r − ρ/π) cos² θ` (`a = cos θ`).
    fn start(&self, floor: &[f64; 3], tiny: f64) -> Result<Tabulated, NonParametricError> {
        let v: Vec<f64> = self
            .covered
            .iter()
            .map(|(_, r)| {
                let bs = &self.back[r.clone()];
                bs.iter()
                    .map(|b| Self::spec(b, floor, tiny) * b.dir.z * b.dir.z)
                    .sum::<f64>()
                    / bs.len() as f64
            })
            .collect();
        self.table(&v)
    }

    /// One power iteration (module docs, step 2).
    fn step(
        &self,
        t: &Tabulated,
        floor: &[f64; 3],
        tiny: f64,
    ) -> Result<Tabulated, NonParametricError> {
        let plan = FastBrdf::with_policy(&white(Ndf::Tabulated(t.clone())), Policy::Accurate);
        let v: Vec<f64> = self
            .covered
            .iter()
            .map(|&(cell, ref r)| {
                let n = t.values()[cell];
                let (mut sum, mut k) = (0.0, 0usize);
                for b in &self.back[r.clone()] {
                    let x = plan.eval(b.dir, b.dir)[0];
                    if x.is_finite() && x > 0.0 {
                        sum += Self::spec(b, floor, tiny) * n / x;
                        k += 1;
                    }
                }
                if k == 0 {
                    n
                } else {
                    sum / k as f64
                }
            })
            .collect();
        self.table(&v)
    }
}

pub use crate::nonparametric::{material, material_spec, material_toml};

impl MirrorFit for NonParametricAniso {
    fn mirror_ndf(&self) -> Ndf {
        Ndf::Tabulated(self.ndf.clone())
    }

    fn mirror_terms(&self) -> [[f64; 3]; 3] {
        [self.f0, self.specular, self.albedo]
    }
}

/// Fit the anisotropic non-parametric material (module docs) to scattered samples with full
/// directions, scoring it on `data`'s fitted and held-out samples.
///
/// # Errors
/// A grid that cannot be written; a sample that is not finite and non-negative or not above the
/// horizon; too few back-scattering samples for the grid (fewer than [`MIN_COVERAGE`] of its
/// upper cells up to [`MAX_THETA_DEG`] covered); back-scattering samples without reflection.
pub fn fit(
    data: &SampleSet,
    opts: &AnisoOptions,
) -> Result<NonParametricAniso, NonParametricError> {
    validate(data, opts)?;
    let grid = EqualAreaGrid::new(opts.n_z, opts.n_phi);
    let back = backscattering(data, grid);
    let cos_max = MAX_THETA_DEG.to_radians().cos();
    let needed = (grid.n_z / 2 * grid.n_phi..grid.len())
        .filter(|&c| grid.cell_center(c).z >= cos_max)
        .count();
    let power = Power::new(grid, back);
    let covered = power.covered.len();
    if (covered as f64) < MIN_COVERAGE * needed as f64 {
        return Err(err(format!(
            "the 2-D non-parametric NDF needs back-scattering samples (i and o within {}°) in at \
             least {:.0} % of the {} × {} table's {needed} cells up to {}°; {} samples cover {covered} \
             (measure more back-scattering directions or choose a coarser grid)",
            BACK_TOLERANCE_DEG,
            100.0 * MIN_COVERAGE,
            grid.n_z,
            grid.n_phi,
            MAX_THETA_DEG,
            power.back.len()
        )));
    }
    let mut floor = [0.0; 3];
    for (c, f) in floor.iter_mut().enumerate() {
        *f = power
            .back
            .iter()
            .map(|b| b.rgb[c])
            .fold(f64::INFINITY, f64::min);
    }
    let peak = power
        .back
        .iter()
        .map(|b| (0..3).map(|c| b.rgb[c] - floor[c]).sum::<f64>())
        .fold(0.0, f64::max);
    if peak.is_nan() || peak <= 0.0 {
        return Err(err(
            "the back-scattering samples hold no reflection above their smallest value".to_owned(),
        ));
    }
    let tiny = 1e-6 * peak;
    let mut t = power.start(&floor, tiny)?;
    for _ in 0..POWER_ITERATIONS {
        t = power.step(&t, &floor, tiny)?;
    }
    for _ in 0..OUTER_ITERATIONS {
        let (basis, lin) = linear_terms_of(&white(Ndf::Tabulated(t.clone())), data);
        t = refit_cells(&t, &basis, &lin, data)?;
    }
    let (_, lin) = linear_terms_of(&white(Ndf::Tabulated(t.clone())), data);
    let mut out = finish(t, &lin, data);
    out.back_samples = power.back.len();
    out.cells_covered = covered;
    out.cells_needed = needed;
    Ok(out)
}

/// Step 4: the table's cell values by linear least squares on every fitted sample (all
/// channels), Fresnel held and `G₂` held from the current table:
/// `f − ρ/π = S(θd) X(i, o)/n(h) · n_new(h)` with `X` the white mirror's value, `n` the current
/// table, the three albedos solved jointly (a broad tail and the Lambert term trade against each
/// other). Each sample touches one cell, so the normal equations are diagonal in the cells
/// but for the albedos, which are eliminated first (a 3 × 3 Schur complement); negative cells are
/// set to 0, cells without samples keep their value (a small ridge).
fn refit_cells(
    t: &Tabulated,
    basis: &Basis,
    lin: &Linear,
    data: &SampleSet,
) -> Result<Tabulated, NonParametricError> {
    let grid = t.grid();
    let n = grid.len();
    let mut diag = vec![0.0f64; n];
    let mut rhs = vec![0.0f64; n];
    let mut cross = vec![[0.0f64; 3]; n];
    let mut rr = [0.0f64; 3];
    let mut ry = [0.0f64; 3];
    for (s, (x, _, w)) in data.samples.iter().zip(basis) {
        let h = (s.wi + s.wo).normalize_or_zero();
        let c = grid.cell_of(h);
        let nc = t.values()[c];
        if !(nc > 0.0 && x.is_finite() && *x > 0.0) {
            continue;
        }
        let gfac = x / nc;
        let cd = s.wi.dot(h).clamp(0.0, 1.0);
        for ch in 0..3 {
            let sc = (lin.u[ch] + lin.g[ch] * (1.0 - cd).powi(5)) * gfac;
            let ww = log_weight(s, ch, *w);
            diag[c] += ww * sc * sc;
            rhs[c] += ww * sc * s.rgb[ch];
            cross[c][ch] += ww * sc / PI;
            rr[ch] += ww / (PI * PI);
            ry[ch] += ww * s.rgb[ch] / PI;
        }
    }
    let ridge = 1e-9 * diag.iter().copied().fold(0.0, f64::max);
    for ((d, r), v) in diag.iter_mut().zip(&mut rhs).zip(t.values()) {
        *d += ridge;
        *r += ridge * v;
    }
    // The albedos from the Schur complement of the cells.
    let mut m = [0.0f64; 9];
    let mut b = ry;
    for (ch, v) in rr.iter().enumerate() {
        m[ch * 3 + ch] = *v;
    }
    for ((d, r), x) in diag.iter().zip(&rhs).zip(&cross) {
        if *d <= 0.0 {
            continue;
        }
        for (a, xa) in x.iter().enumerate() {
            b[a] -= xa * r / d;
            for (k, xk) in x.iter().enumerate() {
                m[a * 3 + k] -= xa * xk / d;
            }
        }
    }
    // A singular system (no samples) leaves the albedos at 0.
    let rho = if gauss_solve(&mut m, &mut b, 3) {
        b.map(|v| if v.is_finite() { v } else { 0.0 })
    } else {
        [0.0; 3]
    };
    let values: Vec<f64> = (0..n)
        .map(|c| {
            if diag[c] <= 0.0 {
                return t.values()[c];
            }
            let v = (rhs[c] - (0..3).map(|k| cross[c][k] * rho[k]).sum::<f64>()) / diag[c];
            if v.is_finite() {
                v.max(0.0)
            } else {
                0.0
            }
        })
        .collect();
    Tabulated::from_values(grid, values).map_err(|e| err(e.to_string()))
}

/// The fitted material from the final table and linear terms, with its errors.
fn finish(ndf: Tabulated, lin: &Linear, data: &SampleSet) -> NonParametricAniso {
    let (f0, specular, specular_at_limit) = lin.mirror();
    let mut out = NonParametricAniso {
        ndf,
        f0,
        specular,
        albedo: lin.albedo,
        specular_at_limit,
        fitted: FitErrors::default(),
        held_out: None,
        back_samples: 0,
        cells_covered: 0,
        cells_needed: 0,
    };
    (out.fitted, out.held_out) = scores(&material(&out), data);
    out
}
