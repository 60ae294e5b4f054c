//! Baseline analytic BRDF models, fitted by the same machinery as the lobe sums so that the
//! comparison is fair. Each has a Lambertian diffuse basis lobe `1/π` (amplitude: the albedo
//! per channel) and specular basis lobes with per-channel amplitudes. All are reciprocal.
//!
//! | model | specular basis lobe(s) | non-linear parameters |
//! |---|---|---|
//! | [`BlinnPhong`] | `(n+8)/(8π) · (N·H)^n` (normalised Blinn-Phong) | `ln n` |
//! | [`Microfacet`] Beckmann ("Cook-Torrance") | `D·G·F/(4 cos θi cos θo)`, Beckmann `D`, Smith height-correlated `G`, Schlick `F` | `ln α`, `F0` |
//! | [`Microfacet`] GGX | idem with the GGX (Trowbridge–Reitz) `D` and its Smith `G` | `ln α`, `F0` |
//! | [`AshikhminShirley`] | `√((nu+1)(nv+1))/(8π) · (N·H)^((nu h_x² + nv h_y²)/(1 − h_z²)) / ((H·i) max(cos θi, cos θo)) · F(H·i)`, Schlick `F` | `ln nu`, `ln nv`, `F0` |
//! | [`Lafortune`] (1–3 lobes) | `(n+2)/(2π) · max(0, (cos ψ (i_x o_x + i_y o_y) + sin ψ i_z o_z)/max(|cos ψ|, sin ψ))^n` per lobe (isotropic, `C_x = C_y`) | `ψ_j`, `ln n_j` |
//!
//! Amplitudes scale the whole specular lobe (for the microfacet models, `F0` shapes the Fresnel
//! curve and the amplitude is the specular colour). Directions are unit vectors in the local
//! frame (normal +z); anisotropy axes are the tangent (+x, `nu`) and bitangent (+y, `nv`).

use crate::fit::BrdfModel;
use glam::DVec3;
use std::f64::consts::PI;

const LN_EXP: (f64, f64) = (-std::f64::consts::LN_2, 13.815_510_557_964_274); // ln 0.5 .. ln 1e6

#[inline]
fn schlick(f0: f64, c: f64) -> f64 {
    let m = (1.0 - c).clamp(0.0, 1.0);
    let m2 = m * m;
    f0 + (1.0 - f0) * m2 * m2 * m
}

/// Normalised Blinn-Phong with a Lambertian term.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BlinnPhong;

impl BrdfModel for BlinnPhong {
    fn name(&self) -> String {
        "blinn-phong".into()
    }
    fn nonlinear_names(&self) -> Vec<String> {
        vec!["ln_n".into()]
    }
    fn basis_names(&self) -> Vec<String> {
        vec!["diffuse".into(), "specular".into()]
    }
    fn bounds(&self) -> Vec<(f64, f64)> {
        vec![LN_EXP]
    }
    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        [3.0f64, 10.0, 30.0, 100.0, 300.0, 1e3, 3e3, 1e4, 3e4]
            .iter()
            .map(|n| vec![n.ln()])
            .collect()
    }
    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let n = theta[0].exp();
        out[0] = 1.0 / PI;
        out[1] = match meso_core::frame::half_vector(wi, wo) {
            Some(h) if h.z > 0.0 => (n + 8.0) / (8.0 * PI) * h.z.powf(n),
            _ => 0.0,
        };
    }
}

/// The microfacet distribution of a [`Microfacet`] model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetKind {
    /// Beckmann (Cook-Torrance).
    Beckmann,
    /// GGX / Trowbridge–Reitz.
    Ggx,
}

/// An isotropic microfacet BRDF (`D·G·F/(4 cos θi cos θo)`) with Smith height-correlated masking–
/// shadowing `G = 1/(1 + Λ(i) + Λ(o))`, Schlick Fresnel, and a Lambertian term.
/// `α` is the roughness (Beckmann: RMS slope; GGX: the usual α).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Microfacet {
    /// Beckmann or GGX.
    pub kind: MicrofacetKind,
}

impl Microfacet {
    /// Cook-Torrance with Beckmann `D`.
    pub const COOK_TORRANCE: Microfacet = Microfacet {
        kind: MicrofacetKind::Beckmann,
    };
    /// GGX.
    pub const GGX: Microfacet = Microfacet {
        kind: MicrofacetKind::Ggx,
    };

    /// The distribution `D(h)` in the microfacet convention (∫ D (h·z) dω = 1), 1/sr.
    #[must_use]
    pub fn d(&self, alpha: f64, cos_h: f64) -> f64 {
        if cos_h <= 0.0 {
            return 0.0;
        }
        let c2 = cos_h * cos_h;
        let a2 = alpha * alpha;
        match self.kind {
            MicrofacetKind::Beckmann => {
                let t2 = (1.0 - c2) / c2;
                (-t2 / a2).exp() / (PI * a2 * c2 * c2)
            }
            MicrofacetKind::Ggx => {
                let d = c2 * (a2 - 1.0) + 1.0;
                a2 / (PI * d * d)
            }
        }
    }

    /// Smith's `Λ(w)` for a direction with `cos θ = c > 0`.
    #[must_use]
    pub fn lambda(&self, alpha: f64, c: f64) -> f64 {
        let s2 = (1.0 - c * c).max(0.0);
        if s2 <= 0.0 {
            return 0.0;
        }
        let tan = s2.sqrt() / c;
        match self.kind {
            MicrofacetKind::Beckmann => {
                let a = 1.0 / (alpha * tan);
                0.5 * (-libm::erfc(a) + (-a * a).exp() / (a * PI.sqrt()))
            }
            MicrofacetKind::Ggx => {
                // ½(√(1+x) − 1) as ½x/(1 + √(1+x)): no cancellation near the normal.
                let x = alpha * alpha * tan * tan;
                0.5 * x / (1.0 + (1.0 + x).sqrt())
            }
        }
    }
}

impl BrdfModel for Microfacet {
    fn name(&self) -> String {
        match self.kind {
            MicrofacetKind::Beckmann => "cook-torrance".into(),
            MicrofacetKind::Ggx => "ggx".into(),
        }
    }
    fn nonlinear_names(&self) -> Vec<String> {
        vec!["ln_alpha".into(), "f0".into()]
    }
    fn basis_names(&self) -> Vec<String> {
        vec!["diffuse".into(), "specular".into()]
    }
    fn bounds(&self) -> Vec<(f64, f64)> {
        vec![(0.001f64.ln(), 1.5f64.ln()), (0.0, 1.0)]
    }
    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        let mut v = Vec::new();
        for a in [0.01f64, 0.03, 0.1, 0.3, 0.6] {
            for f0 in [0.05, 0.5] {
                v.push(vec![a.ln(), f0]);
            }
        }
        v
    }
    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let alpha = theta[0].exp();
        out[0] = 1.0 / PI;
        out[1] = 0.0;
        let (ci, co) = (wi.z, wo.z);
        if ci <= 0.0 || co <= 0.0 {
            return;
        }
        let Some(h) = meso_core::frame::half_vector(wi, wo) else {
            return;
        };
        let g = 1.0 / (1.0 + self.lambda(alpha, ci) + self.lambda(alpha, co));
        out[1] = self.d(alpha, h.z) * g * schlick(theta[1], h.dot(wi)) / (4.0 * ci * co);
    }
}

/// The anisotropic Ashikhmin–Shirley specular lobe (2000) with Schlick Fresnel and a Lambertian
/// term (instead of their coupled diffuse term, as for every baseline here).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AshikhminShirley;

impl BrdfModel for AshikhminShirley {
    fn name(&self) -> String {
        "ashikhmin-shirley".into()
    }
    fn nonlinear_names(&self) -> Vec<String> {
        vec!["ln_nu".into(), "ln_nv".into(), "f0".into()]
    }
    fn basis_names(&self) -> Vec<String> {
        vec!["diffuse".into(), "specular".into()]
    }
    fn bounds(&self) -> Vec<(f64, f64)> {
        vec![LN_EXP, LN_EXP, (0.0, 1.0)]
    }
    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        let mut v = Vec::new();
        for n in [10.0f64, 100.0, 1e3, 1e4] {
            for f0 in [0.05, 0.5] {
                v.push(vec![n.ln(), n.ln(), f0]);
            }
        }
        v.push(vec![30f64.ln(), 300f64.ln(), 0.1]);
        v.push(vec![300f64.ln(), 30f64.ln(), 0.1]);
        v
    }
    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        let (nu, nv) = (theta[0].exp(), theta[1].exp());
        out[0] = 1.0 / PI;
        out[1] = 0.0;
        let Some(h) = super::upper_half_vector(wi, wo) else {
            return;
        };
        let s2 = 1.0 - h.z * h.z;
        let e = if s2 > 1e-14 {
            (nu * h.x * h.x + nv * h.y * h.y) / s2
        } else {
            0.0
        };
        let hk = h.dot(wi);
        out[1] = ((nu + 1.0) * (nv + 1.0)).sqrt() / (8.0 * PI) * h.z.powf(e)
            / (hk * wi.z.max(wo.z))
            * schlick(theta[2], hk);
    }
}

/// Isotropic Lafortune lobes (1997), `k` of them (1–3), with a Lambertian term.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Lafortune {
    /// Number of lobes, 1..=3.
    pub k: usize,
}

impl Lafortune {
    /// `k` lobes, clamped to 1..=3.
    #[must_use]
    pub fn new(k: usize) -> Lafortune {
        Lafortune { k: k.clamp(1, 3) }
    }
}

impl BrdfModel for Lafortune {
    fn name(&self) -> String {
        format!("lafortune-{}", self.k)
    }
    fn nonlinear_names(&self) -> Vec<String> {
        (0..self.k)
            .flat_map(|j| [format!("psi{j}"), format!("ln_n{j}")])
            .collect()
    }
    fn basis_names(&self) -> Vec<String> {
        let mut v = vec!["diffuse".to_string()];
        v.extend((0..self.k).map(|j| format!("lobe{j}")));
        v
    }
    fn bounds(&self) -> Vec<(f64, f64)> {
        (0..self.k)
            .flat_map(|_| [(0.05, PI - 0.05), LN_EXP])
            .collect()
    }
    fn initial_guesses(&self) -> Vec<Vec<f64>> {
        let spec = 0.75 * PI;
        let sets: &[&[f64]] = match self.k {
            1 => &[&[3.0], &[30.0], &[300.0], &[3e3], &[3e4]],
            2 => &[
                &[3.0, 100.0],
                &[10.0, 1e3],
                &[30.0, 3e3],
                &[100.0, 1e4],
                &[3.0, 30.0],
            ],
            _ => &[
                &[3.0, 30.0, 300.0],
                &[10.0, 100.0, 3e3],
                &[30.0, 1e3, 3e4],
                &[3.0, 100.0, 1e4],
            ],
        };
        let mut v: Vec<Vec<f64>> = sets
            .iter()
            .map(|ns| ns.iter().flat_map(|n| [spec, n.ln()]).collect())
            .collect();
        // One start with the broadest lobe retro-/forward-tilted.
        let mut tilted = v[0].clone();
        tilted[0] = 0.6 * PI;
        v.push(tilted);
        v
    }
    fn basis(&self, theta: &[f64], wi: DVec3, wo: DVec3, out: &mut [f64]) {
        out[0] = 1.0 / PI;
        let xy = wi.x * wo.x + wi.y * wo.y;
        let zz = wi.z * wo.z;
        for j in 0..self.k {
            let (s, c) = theta[2 * j].sin_cos();
            let n = theta[2 * j + 1].exp();
            let d = (c * xy + s * zz) / c.abs().max(s);
            out[1 + j] = if d > 0.0 {
                (n + 2.0) / (2.0 * PI) * d.powf(n)
            } else {
                0.0
            };
        }
    }
}
