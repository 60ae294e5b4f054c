//! Single-lobe filtering baselines (mip-mapped normal, Toksvig, LEAN, vMF), computed from the
//! same area-weighted normals as the multi-lobe fit. They are NDFs, not a convolution engine:
//! every one is returned as a core [`Ndf`] ([`fit_baseline`]), whose effective BRDF is
//! `meso_core::convolution::effective_brdf_with` like any other NDF's, or as the Phong peaks a
//! map file stores ([`baseline_lobes`]).
//!
//! # The conversions
//! Every NDF here is the paper's Eq. 1 density (per unit *microsurface* area, `∫ n dω = 1`).
//!
//! | baseline | [`fit_baseline`] (core NDF) | [`baseline_lobes`] (map file) |
//! | --- | --- | --- |
//! | [`Baseline::MipNormal`] | `Ndf::PhongPeaks`, one lobe of η = [`ETA_MAX`] about the mean normal | the same lobe |
//! | [`Baseline::Toksvig`] | `Ndf::PhongPeaks`, one lobe of η = 4R̄/(1 − R̄) | the same lobe |
//! | [`Baseline::Vmf`] | `Ndf::VonMisesFisher` (the core's own vMF: the same density) | η = 4κ |
//! | [`Baseline::Lean`] | `Ndf::Tabulated`: [`Lean::density`], slightly broadened, on an equal-area grid sized to the lobe ([`Lean::to_ndf`]) | isotropised, η = 8/tr Σ |
//!
//! Why: the Phong baselines and the vMF are core NDFs as they are. LEAN's anisotropic,
//! off-centre Gaussian-slope density is no core analytic NDF (the core's Beckmann has neither a
//! mean slope nor a correlation), so the core sees it tabulated, which keeps its anisotropy
//! (the NDF and BRDF errors of `examples/extract_bench.rs` measure LEAN itself, not a Toksvig
//! look-alike). The tabulation broadens the lobe by an eighth of its slope spread in every
//! direction (no grid resolves the ridge of one-directional slopes, e.g. V-grooves), and further
//! where the lobe is narrower than its finest grid (slope spread below about 0.03). A map file stores isotropic Phong lobes only, hence the isotropised LEAN and the
//! vMF's Phong peak of the same small-angle shape (`cos^η(α/2) ≈ exp((η/4)(cos α − 1))`).

use crate::fit::ETA_MAX;
use glam::{DMat2, DVec2, DVec3};
use meso_core::grid::EqualAreaGrid;
use meso_core::ndf::{Ndf, PhongLobe, PhongPeaks, Tabulated, VonMisesFisher};
use std::f64::consts::PI;

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

    /// LEAN's slope moments of area-weighted normals (Eq. 1 weights; need not be normalised).
    #[must_use]
    pub fn from_normals(normals: &[(DVec3, f64)]) -> Lean {
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
        Lean::new(
            mu,
            DMat2::from_cols(DVec2::new(cxx, cxy), DVec2::new(cxy, cyy)),
        )
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

    /// The slope spread `√tr Σ` (about the lobe's angular width, radians, for small slopes).
    #[must_use]
    pub fn width(&self) -> f64 {
        (self.cov.x_axis.x + self.cov.y_axis.y).max(0.0).sqrt()
    }

    /// The normal of the mean slope.
    #[must_use]
    pub fn mean_normal(&self) -> DVec3 {
        DVec3::new(-self.mean.x, -self.mean.y, 1.0).normalize()
    }

    /// The isotropised Phong peak a map file stores: about the mean-slope normal with
    /// `η = 8/tr(Σ)` (angular variance `8/η` = slope variance), at most [`ETA_MAX`].
    #[must_use]
    pub fn to_phong_lobe(&self) -> PhongLobe {
        let tr = (self.cov.x_axis.x + self.cov.y_axis.y).max(1e-300);
        PhongLobe::new(
            DVec3::new(-self.mean.x, -self.mean.y, 1.0),
            1.0,
            (8.0 / tr).min(ETA_MAX),
        )
    }

    /// The density as a core `Ndf::Tabulated` on an equal-area grid sized to the lobe. The
    /// covariance is first broadened by `(w/8)²` on its diagonal (`w` = [`Lean::width`]), so
    /// that no direction of the lobe is narrower than `w/8` (a V-groove's slopes vary along x
    /// only: its LEAN lobe is a ridge no grid resolves); then the grid has bands of polar-cap
    /// radius and sectors of arc (at the lobe's far side) at most half the lobe's narrowest
    /// width `w_min`, each cell the mean of 3 × 3 samples, at most 16384 bands × 4096 sectors
    /// and 2²⁰ cells (lobes narrower than about 0.03 come out broadened further). Falls back to
    /// the isotropised Phong peak ([`Lean::to_phong_lobe`]) where the grid misses the lobe.
    #[must_use]
    pub fn to_ndf(&self) -> Ndf {
        let w = self.width().max(1e-6);
        let floor = (w / 8.0) * (w / 8.0);
        let b = Lean::new(
            self.mean,
            self.cov + DMat2::from_diagonal(DVec2::new(floor, floor)),
        );
        let (a, c, d) = (b.cov.x_axis.x, b.cov.x_axis.y, b.cov.y_axis.y);
        let lambda_min = 0.5 * (a + d - ((a - d) * (a - d) + 4.0 * c * c).sqrt());
        let w_min = lambda_min.max(floor).sqrt();
        let theta0 = self.mean.length().atan();
        let n_z = (8.0 / (w_min * w_min)).ceil().clamp(64.0, 16384.0) as usize;
        let n_phi = (4.0 * PI * (theta0 + w) / w_min).ceil().clamp(64.0, 4096.0) as usize;
        let n_phi = n_phi.min(((1usize << 20) / n_z).max(64));
        match Tabulated::from_fn(EqualAreaGrid::new(n_z, n_phi), 3, |m| b.density(m)) {
            Ok(t) => Ndf::Tabulated(t),
            Err(_) => phong(vec![self.to_phong_lobe()]),
        }
    }
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

/// A baseline as fitted, before conversion to a core NDF or to Phong peaks.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Fitted {
    /// One Phong peak (mip normal, Toksvig).
    Lobe(PhongLobe),
    /// One vMF lobe `κ/(4π sinh κ) · exp(κ a·m)`.
    Vmf { axis: DVec3, kappa: f64 },
    /// LEAN.
    Lean(Lean),
}

fn fit(method: Baseline, normals: &[(DVec3, f64)]) -> Fitted {
    let tot: f64 = normals.iter().map(|p| p.1).sum::<f64>().max(1e-300);
    let mean = normals.iter().map(|(n, w)| *n * *w).sum::<DVec3>() / tot;
    let rbar = mean.length().min(1.0);
    let axis = if rbar > 0.0 { mean / rbar } else { DVec3::Z };
    match method {
        Baseline::MipNormal => Fitted::Lobe(PhongLobe {
            axis,
            weight: 1.0,
            exponent: ETA_MAX,
        }),
        Baseline::Toksvig => {
            let eta = if rbar >= 1.0 - 4.0 / ETA_MAX {
                ETA_MAX
            } else {
                (4.0 * rbar / (1.0 - rbar)).min(ETA_MAX)
            };
            Fitted::Lobe(PhongLobe {
                axis,
                weight: 1.0,
                exponent: eta,
            })
        }
        Baseline::Vmf => {
            let r = rbar.min(1.0 - 1e-9);
            Fitted::Vmf {
                axis,
                kappa: (r * (3.0 - r * r) / (1.0 - r * r)).min(4.0 * ETA_MAX),
            }
        }
        Baseline::Lean => Fitted::Lean(Lean::from_normals(normals)),
    }
}

fn phong(lobes: Vec<PhongLobe>) -> Ndf {
    Ndf::PhongPeaks(PhongPeaks::new(lobes).expect("one unit-weight lobe is a valid NDF"))
}

/// Fit a baseline to area-weighted normals (Eq. 1 weights; need not be normalised) as a core
/// NDF (module docs). The mean normal of the single-lobe baselines is the area-weighted mean;
/// LEAN takes projected weights.
#[must_use]
pub fn fit_baseline(method: Baseline, normals: &[(DVec3, f64)]) -> Ndf {
    match fit(method, normals) {
        Fitted::Lobe(l) => phong(vec![l]),
        Fitted::Vmf { axis, kappa } => {
            // The core's vMF needs κ > 0; below 1e-8 it is the uniform sphere to rounding.
            Ndf::VonMisesFisher(
                VonMisesFisher::new(axis, kappa.max(1e-8)).expect("unit axis and κ > 0"),
            )
        }
        Fitted::Lean(l) => l.to_ndf(),
    }
}

/// Fit a baseline and convert it to the Phong peaks (weights summing to 1) a map file stores
/// (module docs): the Phong baselines as they are, a vMF lobe as `η = 4κ`, LEAN isotropised.
#[must_use]
pub fn baseline_lobes(method: Baseline, normals: &[(DVec3, f64)]) -> Vec<PhongLobe> {
    match fit(method, normals) {
        Fitted::Lobe(l) => vec![l],
        Fitted::Vmf { axis, kappa } => vec![PhongLobe::new(axis, 1.0, (4.0 * kappa).min(ETA_MAX))],
        Fitted::Lean(l) => vec![l.to_phong_lobe()],
    }
}

fn cholesky(c: DMat2) -> DMat2 {
    let l11 = c.x_axis.x.max(0.0).sqrt();
    let l21 = if l11 > 0.0 { c.x_axis.y / l11 } else { 0.0 };
    let l22 = (c.y_axis.y - l21 * l21).max(0.0).sqrt();
    DMat2::from_cols(DVec2::new(l11, l21), DVec2::new(0.0, l22))
}
