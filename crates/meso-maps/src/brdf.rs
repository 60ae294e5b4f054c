//! Patch NDFs (fitted lobes, raw facets, baselines) and the effective BRDF of a patch.
//!
//! # Convention
//! Every [`PatchNdf`] is the paper's Eq. 1 density `n(m)`: normals per unit of *microsurface*
//! area, `∫ n dω = 1` — the convention of `meso_core::ndf` (raw facets carry their true areas,
//! see `crate::facets`; fitted lobes are fitted to those).
//!
//! # The microfacet form (default)
//! The same as `meso_core::convolution`'s: with `D(m) = n(m) / ∫_{z>0} n (m·z) dω` (so that
//! `p(m) = D(m)(m·z)` is the density of normals per unit *projected* area, `∫_{z>0} p = 1`),
//! ```text
//! f(i, o) = ∫_{z>0} D(m) f_μ(i, o; m) (i·m)⁺(o·m)⁺ / ((i·z)(o·z)) · G(i, o, m) dm
//!         = ∫ p(m) f_μ(i, o; m) (i·m)⁺(o·m)⁺ / ((i·z)(o·z)(m·z)) · G dm,
//! ```
//! with `f_μ` the facet BRDF evaluated in the facet frame ([`FacetBrdf`], normal +z, tangent =
//! macro +x projected), and `G` one of [`Shadowing`]. Summed over every facet of a map with
//! [`PatchNdf::Facets`] and no shadowing this is exact for the piecewise-linear surface as long
//! as nothing is masked.
//!
//! [`Form::NormalMapping`] is the classic bump/normal-mapping shading (the core's default,
//! multiple-surface form): `f(i, o) = ∫ n(m) f_μ(i, o; m) max(0, m·i) dm / (i·z)`, no
//! foreshortening, no `G`.
//!
//! # Smith masking–shadowing
//! `Λ(ω) = ∫_{z>0} D(m) max(0, ω·m) dm / cos θ_ω − 1` with `D` as above (`∫ D (m·z) dm = 1`);
//! height-correlated `G₂ = 1/(1 + Λ(i) + Λ(o))`.
//!
//! Integrals over fitted lobes use a deterministic stratified quadrature: `n × n` samples of
//! each lobe's exact sampler (`PhongLobe::sample`), each carrying `weight/n²`.

use crate::fit::{lobe_bin_mass, ETA_MAX};
use crate::horizon::HorizonStats;
use crate::sphgrid::SphereGrid;
use glam::{DMat2, DVec2, DVec3};
use meso_core::frame::Frame;
use meso_core::ndf::PhongLobe;
use std::f64::consts::PI;

/// A facet BRDF `f_μ(i, o)` in 1/sr, RGB, with both directions in the facet's local frame
/// (facet normal +z, pointing away from the surface). Implemented for
/// `meso_core::transfer::Transfer`, [`Lambert`] and [`PhongFacet`].
pub trait FacetBrdf: Sync {
    /// BRDF value (1/sr, without cosine) for unit directions `i` (to the light), `o` (to the eye).
    fn eval(&self, i: DVec3, o: DVec3) -> [f64; 3];
}

/// A core transfer function as a facet BRDF: `meso_core::transfer::Transfer::eval` already takes
/// its directions in the facet frame (normal +z, tangent = macro +x projected), as the core's
/// convolution and this crate both build it with `Frame::from_normal_tangent(m, DVec3::X)`.
impl FacetBrdf for meso_core::transfer::Transfer {
    fn eval(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        meso_core::transfer::Transfer::eval(self, i, o)
    }
}

/// Lambertian facet: `albedo/π` (1/sr) whenever both directions are above the facet.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Diffuse albedo per channel.
    pub albedo: [f64; 3],
}

impl FacetBrdf for Lambert {
    fn eval(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        if i.z <= 0.0 || o.z <= 0.0 {
            return [0.0; 3];
        }
        self.albedo.map(|a| a / PI)
    }
}

/// Phong facet, Eq. 10 as written: `specular · max(0, z·H)^η`, unnormalised (1/sr).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongFacet {
    /// Exponent η on `N·H`.
    pub exponent: f64,
    /// Specular colour.
    pub specular: [f64; 3],
}

impl FacetBrdf for PhongFacet {
    fn eval(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        match meso_core::frame::half_vector(i, o) {
            Some(h) if h.z > 0.0 => {
                let v = h.z.powf(self.exponent);
                self.specular.map(|s| s * v)
            }
            _ => [0.0; 3],
        }
    }
}

/// LEAN mapping (Olano & Baker 2010): the five slope moments of a footprint as an anisotropic
/// Beckmann (Gaussian slope) distribution. Slopes of a normal are `s = (−m_x/m_z, −m_y/m_z)`;
/// the Gaussian `P22(s)` is a density per unit *projected* area, so the moments are taken with
/// projected weights (area weight × `m_z`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lean {
    /// Mean slope `E[s]`.
    pub mean: DVec2,
    /// Slope covariance `E[s sᵀ] − E[s]E[s]ᵀ` (a small floor is added on the diagonal).
    pub cov: DMat2,
    /// Microsurface area per unit projected area, `E_P22[√(1 + |s|²)] = ∫ P22/m_z⁴ dω` (≥ 1).
    pub area: f64,
}

impl Lean {
    /// A LEAN distribution from its slope mean and covariance; computes [`Lean::area`] by
    /// quadrature (64 × 64 stratified Gaussian nodes).
    #[must_use]
    pub fn new(mean: DVec2, cov: DMat2) -> Lean {
        let mut l = Lean {
            mean,
            cov,
            area: 1.0,
        };
        let nodes = l.slope_nodes(64);
        l.area = nodes
            .iter()
            .map(|s| (1.0 + s.length_squared()).sqrt())
            .sum::<f64>()
            / nodes.len() as f64;
        l
    }

    /// `n × n` stratified slopes of the Gaussian (Box–Muller on cell centres), equal weights.
    fn slope_nodes(&self, n: usize) -> Vec<DVec2> {
        let chol = cholesky(self.cov);
        let mut out = Vec::with_capacity(n * n);
        for a in 0..n {
            for b in 0..n {
                let u = [(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64];
                let r = (-2.0 * (1.0 - u[0]).ln()).sqrt();
                let g = DVec2::new(r * (2.0 * PI * u[1]).cos(), r * (2.0 * PI * u[1]).sin());
                out.push(self.mean + chol * g);
            }
        }
        out
    }

    /// Density in the Eq. 1 convention (per microsurface area, ∫ = 1):
    /// `P22(s(m)) / (m_z⁴ · area)` for `m_z > 0` (the Beckmann `D` over its total area).
    #[must_use]
    pub fn density(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let s = DVec2::new(-m.x / m.z, -m.y / m.z) - self.mean;
        let det = self.cov.determinant();
        let q = s.dot(self.cov.inverse() * s);
        let mz2 = m.z * m.z;
        (-0.5 * q).exp() / (2.0 * PI * det.sqrt()) / (mz2 * mz2 * self.area)
    }
}

/// The distribution of meso-normals of a patch in the Eq. 1 convention (per unit microsurface
/// area, normalised to 1).
#[derive(Clone, Debug, PartialEq)]
pub enum PatchNdf {
    /// A sum of Phong peaks (weights summing to 1).
    Lobes(Vec<PhongLobe>),
    /// Raw facets `(unit normal, area weight)`, weights summing to 1.
    Facets(Vec<(DVec3, f64)>),
    /// LEAN: anisotropic Beckmann from five moments.
    Lean(Lean),
    /// One von Mises–Fisher lobe `κ/(4π sinh κ) · exp(κ a·m)`.
    Vmf {
        /// Unit mean axis.
        axis: DVec3,
        /// Concentration κ ≥ 0.
        kappa: f64,
    },
}

/// Baseline single-lobe NDFs computed from the same footprints as the multi-lobe fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Baseline {
    /// The mip-mapped (averaged, renormalised) normal: one delta-like lobe (η = [`ETA_MAX`]).
    MipNormal,
    /// Toksvig (2005): one Phong peak about the mean normal with `η = 4R̄/(1 − R̄)`, where R̄ is
    /// the length of the mean normal (the small-angle match of the lobe's angular variance
    /// `8/η` to Toksvig's `2(1 − R̄)/R̄`).
    Toksvig,
    /// LEAN mapping (five slope moments → anisotropic Beckmann).
    Lean,
    /// One von Mises–Fisher lobe, κ from R̄ by Banerjee et al.'s `R̄(3 − R̄²)/(1 − R̄²)`.
    Vmf,
}

/// Fit a baseline to area-weighted normals (Eq. 1 weights; need not be normalised). The mean
/// normal of the single-lobe baselines is the area-weighted mean; LEAN takes projected weights.
#[must_use]
pub fn fit_baseline(method: Baseline, normals: &[(DVec3, f64)]) -> PatchNdf {
    let tot: f64 = normals.iter().map(|p| p.1).sum::<f64>().max(1e-300);
    let mean = normals.iter().map(|(n, w)| *n * *w).sum::<DVec3>() / tot;
    let rbar = mean.length().min(1.0);
    let axis = if rbar > 0.0 { mean / rbar } else { DVec3::Z };
    match method {
        Baseline::MipNormal => PatchNdf::Lobes(vec![PhongLobe {
            axis,
            weight: 1.0,
            exponent: ETA_MAX,
        }]),
        Baseline::Toksvig => {
            let eta = if rbar >= 1.0 - 4.0 / ETA_MAX {
                ETA_MAX
            } else {
                (4.0 * rbar / (1.0 - rbar)).min(ETA_MAX)
            };
            PatchNdf::Lobes(vec![PhongLobe {
                axis,
                weight: 1.0,
                exponent: eta,
            }])
        }
        Baseline::Vmf => {
            let r = rbar.min(1.0 - 1e-9);
            PatchNdf::Vmf {
                axis,
                kappa: (r * (3.0 - r * r) / (1.0 - r * r)).min(4.0 * ETA_MAX),
            }
        }
        Baseline::Lean => {
            let mut m1 = DVec2::ZERO;
            let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
            let mut wt = 0.0;
            for (n, w) in normals {
                if n.z <= 1e-6 {
                    continue;
                }
                // Projected weight: the slope moments are per unit projected area.
                let w = w * n.z;
                let s = DVec2::new(-n.x / n.z, -n.y / n.z);
                m1 += s * w;
                sxx += s.x * s.x * w;
                sxy += s.x * s.y * w;
                syy += s.y * s.y * w;
                wt += w;
            }
            let wt = wt.max(1e-300);
            let mu = m1 / wt;
            let floor = 1e-8;
            let cxx = (sxx / wt - mu.x * mu.x).max(0.0) + floor;
            let cyy = (syy / wt - mu.y * mu.y).max(0.0) + floor;
            let cxy = sxy / wt - mu.x * mu.y;
            PatchNdf::Lean(Lean::new(
                mu,
                DMat2::from_cols(DVec2::new(cxx, cxy), DVec2::new(cxy, cyy)),
            ))
        }
    }
}

impl PatchNdf {
    /// Density per unit solid angle in the Eq. 1 convention (1/sr). Raw facets are deltas: 0.
    #[must_use]
    pub fn density(&self, m: DVec3) -> f64 {
        match self {
            PatchNdf::Lobes(l) => l.iter().map(|l| l.density(m)).sum(),
            PatchNdf::Facets(_) => 0.0,
            PatchNdf::Lean(l) => l.density(m),
            PatchNdf::Vmf { axis, kappa } => vmf_density(*axis, *kappa, m),
        }
    }

    /// Quadrature nodes `(normal, weight)` with weights summing to 1: `n × n` stratified samples
    /// per lobe (or the facets themselves).
    #[must_use]
    pub fn nodes(&self, n: usize) -> Vec<(DVec3, f64)> {
        let n = n.max(1);
        let uv = |a: usize, b: usize| [(a as f64 + 0.5) / n as f64, (b as f64 + 0.5) / n as f64];
        let mut out = Vec::new();
        match self {
            PatchNdf::Facets(f) => out.extend_from_slice(f),
            PatchNdf::Lobes(lobes) => {
                for l in lobes {
                    for a in 0..n {
                        for b in 0..n {
                            out.push((l.sample(uv(a, b)), l.weight / (n * n) as f64));
                        }
                    }
                }
            }
            PatchNdf::Lean(l) => {
                // Gaussian slopes are projected-area samples: weight each by its area 1/m_z.
                let slopes = l.slope_nodes(n);
                let tot: f64 = slopes
                    .iter()
                    .map(|s| (1.0 + s.length_squared()).sqrt())
                    .sum();
                for s in slopes {
                    let w = (1.0 + s.length_squared()).sqrt() / tot;
                    out.push((DVec3::new(-s.x, -s.y, 1.0).normalize(), w));
                }
            }
            PatchNdf::Vmf { axis, kappa } => {
                let f = Frame::from_normal(*axis);
                for a in 0..n {
                    for b in 0..n {
                        let u = uv(a, b);
                        let c = if *kappa < 1e-8 {
                            1.0 - 2.0 * u[0]
                        } else {
                            1.0 + (u[0] + (1.0 - u[0]) * (-2.0 * kappa).exp()).ln() / kappa
                        }
                        .clamp(-1.0, 1.0);
                        let s = (1.0 - c * c).max(0.0).sqrt();
                        let p = 2.0 * PI * u[1];
                        out.push((
                            f.to_world(DVec3::new(s * p.cos(), s * p.sin(), c)),
                            1.0 / (n * n) as f64,
                        ));
                    }
                }
            }
        }
        out
    }

    /// The NDF as Phong peaks (weights summing to 1), for storage in a map file: lobes as they
    /// are; a vMF lobe as the Phong peak of the same small-angle shape, `η = 4κ`
    /// (`cos^η(α/2) ≈ exp((η/4)(cos α − 1))`); LEAN isotropised, about its mean normal with
    /// `η = 8/tr(Σ)` (angular variance `8/η` = slope variance); raw facets one delta-like lobe
    /// each (η = [`ETA_MAX`]).
    #[must_use]
    pub fn to_phong_lobes(&self) -> Vec<PhongLobe> {
        match self {
            PatchNdf::Lobes(l) => l.clone(),
            PatchNdf::Facets(f) => f
                .iter()
                .map(|(n, w)| PhongLobe::new(*n, *w, ETA_MAX))
                .collect(),
            PatchNdf::Vmf { axis, kappa } => {
                vec![PhongLobe::new(*axis, 1.0, (4.0 * kappa).min(ETA_MAX))]
            }
            PatchNdf::Lean(l) => {
                let tr = (l.cov.x_axis.x + l.cov.y_axis.y).max(1e-300);
                vec![PhongLobe::new(
                    DVec3::new(-l.mean.x, -l.mean.y, 1.0),
                    1.0,
                    (8.0 / tr).min(ETA_MAX),
                )]
            }
        }
    }

    /// Probability per bin of an equal-area grid (used for NDF errors).
    pub fn bin_mass(&self, grid: SphereGrid, out: &mut [f64]) {
        match self {
            PatchNdf::Lobes(l) => lobe_bin_mass(l, grid, out),
            PatchNdf::Facets(f) => {
                out.fill(0.0);
                for (n, w) in f {
                    out[grid.bin(*n)] += w;
                }
            }
            PatchNdf::Lean(l) => {
                let width = (l.cov.x_axis.x + l.cov.y_axis.y).sqrt();
                let centre = DVec3::new(-l.mean.x, -l.mean.y, 1.0).normalize();
                density_bin_mass(|m| l.density(m), width, centre, grid, out)
            }
            PatchNdf::Vmf { axis, kappa } => density_bin_mass(
                |m| vmf_density(*axis, *kappa, m),
                1.0 / (kappa + 1.0).sqrt(),
                *axis,
                grid,
                out,
            ),
        }
    }
}

fn vmf_density(axis: DVec3, kappa: f64, m: DVec3) -> f64 {
    if kappa < 1e-8 {
        return 1.0 / (4.0 * PI);
    }
    kappa / (2.0 * PI * (1.0 - (-2.0 * kappa).exp())) * (kappa * (axis.dot(m) - 1.0)).exp()
}

fn cholesky(c: DMat2) -> DMat2 {
    let l11 = c.x_axis.x.max(0.0).sqrt();
    let l21 = if l11 > 0.0 { c.x_axis.y / l11 } else { 0.0 };
    let l22 = (c.y_axis.y - l21 * l21).max(0.0).sqrt();
    DMat2::from_cols(DVec2::new(l11, l21), DVec2::new(0.0, l22))
}

fn density_bin_mass(
    f: impl Fn(DVec3) -> f64,
    width: f64,
    centre: DVec3,
    grid: SphereGrid,
    out: &mut [f64],
) {
    out.fill(0.0);
    let da = grid.bin_solid_angle();
    if width < 0.25 * da.sqrt() {
        out[grid.bin(centre)] = 1.0;
        return;
    }
    let mut tot = 0.0;
    for (k, o) in out.iter_mut().enumerate() {
        let mut s = 0.0;
        for a in 0..3 {
            for b in 0..3 {
                s += f(grid.point(k, (a as f64 + 0.5) / 3.0, (b as f64 + 0.5) / 3.0));
            }
        }
        *o = s / 9.0 * da;
        tot += *o;
    }
    if tot > 0.0 {
        out.iter_mut().for_each(|o| *o /= tot);
    }
}

/// Masking–shadowing term of the microfacet form.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum Shadowing {
    /// No masking or shadowing (`G = 1`).
    None,
    /// Smith, height-correlated, from the patch NDF itself (the default: closest to the
    /// ray-traced gonioreflectometer on the Gaussian, V-groove and woven fixtures, at θ ≤ 60° and
    /// by far at grazing angles; table in docs/heightmaps.md).
    #[default]
    Smith,
    /// Horizon mapping: `G = V(i)·V(o)` with the visibility fractions of [`HorizonStats`].
    Horizon(HorizonStats),
}

/// Which effective-BRDF formula to use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Form {
    /// The microfacet form with foreshortening and `G` (default).
    #[default]
    Microfacet,
    /// Classic normal mapping: `∫ p f_μ max(0, m·i) dm / cos θ_i`, no `G`.
    NormalMapping,
}

/// The effective BRDF of a patch: quadrature nodes of its NDF plus the shadowing model.
#[derive(Clone, Debug)]
pub struct EffectiveBrdf {
    /// `(m, n-weight, facet frame)`; the weights sum to 1 (Eq. 1 area shares).
    nodes: Vec<(DVec3, f64, Frame)>,
    /// `1 / ∫_{z>0} n (m·z) dω`: turns `n` into the microfacet `D` (0 if nothing faces up).
    inv_projected: f64,
    shadowing: Shadowing,
    form: Form,
}

impl EffectiveBrdf {
    /// Build from a patch NDF with `n × n` quadrature samples per lobe (e.g. 32).
    #[must_use]
    pub fn new(ndf: &PatchNdf, n: usize, shadowing: Shadowing, form: Form) -> EffectiveBrdf {
        let raw = ndf.nodes(n);
        let tot: f64 = raw.iter().map(|p| p.1).sum::<f64>().max(1e-300);
        let projected: f64 = raw
            .iter()
            .filter(|p| p.0.z > 0.0)
            .map(|p| p.1 * p.0.z)
            .sum::<f64>()
            / tot;
        let nodes = raw
            .into_iter()
            .map(|(m, w)| (m, w / tot, Frame::from_normal_tangent(m, DVec3::X)))
            .collect();
        EffectiveBrdf {
            nodes,
            inv_projected: if projected > 0.0 {
                1.0 / projected
            } else {
                0.0
            },
            shadowing,
            form,
        }
    }

    /// `∫_{z>0} n(m)(m·z) dω`: projected area per unit microsurface area (1 for a flat patch).
    #[must_use]
    pub fn projected_area(&self) -> f64 {
        if self.inv_projected > 0.0 {
            1.0 / self.inv_projected
        } else {
            0.0
        }
    }

    /// Smith `Λ(ω)` of the patch NDF for a unit direction with `ω_z > 0`.
    #[must_use]
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        let mut s = 0.0;
        for (m, wt, _) in &self.nodes {
            if m.z > 0.0 {
                s += wt * w.dot(*m).max(0.0);
            }
        }
        (s * self.inv_projected / w.z - 1.0).max(0.0)
    }

    /// The masking–shadowing factor `G(i, o)` of the chosen [`Shadowing`].
    #[must_use]
    pub fn g(&self, i: DVec3, o: DVec3) -> f64 {
        match &self.shadowing {
            Shadowing::None => 1.0,
            Shadowing::Smith => 1.0 / (1.0 + self.lambda(i) + self.lambda(o)),
            Shadowing::Horizon(h) => h.visibility(i) * h.visibility(o),
        }
    }

    /// The effective BRDF (1/sr, RGB) for unit directions `i`, `o` in the macro frame (z up).
    #[must_use]
    pub fn eval(&self, facet: &dyn FacetBrdf, i: DVec3, o: DVec3) -> [f64; 3] {
        let mut acc = [0.0; 3];
        if i.z <= 0.0 || o.z <= 0.0 {
            return acc;
        }
        match self.form {
            Form::Microfacet => {
                let g = self.g(i, o);
                if g <= 0.0 {
                    return acc;
                }
                for (m, w, fr) in &self.nodes {
                    let (im, om) = (i.dot(*m), o.dot(*m));
                    if m.z <= 0.0 || im <= 0.0 || om <= 0.0 {
                        continue;
                    }
                    let f = facet.eval(fr.to_local(i), fr.to_local(o));
                    let k = w * im * om / (i.z * o.z);
                    for c in 0..3 {
                        acc[c] += k * f[c];
                    }
                }
                let s = g * self.inv_projected;
                acc.map(|a| a * s)
            }
            Form::NormalMapping => {
                for (m, w, fr) in &self.nodes {
                    let im = i.dot(*m);
                    if im <= 0.0 {
                        continue;
                    }
                    let f = facet.eval(fr.to_local(i), fr.to_local(o));
                    let k = w * im / i.z;
                    for c in 0..3 {
                        acc[c] += k * f[c];
                    }
                }
                acc
            }
        }
    }
}
