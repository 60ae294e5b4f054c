//! A material's compiled evaluation plan: its effective BRDF, fast, for `meso brdf`, renderers
//! and interactive previews.
//!
//! [`FastBrdf::with_policy`] compiles a [`Material`] into the cheapest evaluation that is exact
//! or documented-approximate for it under a [`Policy`]: [`Policy::Accurate`] (`meso brdf`,
//! Python) keeps only the closed forms and the Λ table (≤ [`LAMBDA_TABLE_TOLERANCE`]),
//! [`Policy::Interactive`] ([`FastBrdf::new`]: the renderer, the editor's plots) takes every
//! row, and [`Policy::Preview`] (the editor's rendered preview, which must answer while a slider
//! moves) two cheaper ones beside them:
//!
//! | material | evaluation | error |
//! |---|---|---|
//! | delta sum (multiple surface), Phong (N·H) facets (interactive) | Eq. 4/11, flat f32 arrays of ≤ 8 lanes per chunk | f32 rounding |
//! | delta sum, any other facet | Eq. 4, f64 | exact |
//! | Phong peaks × Phong (N·H) facets, multiple-surface form (interactive) | each lobe replaced by a fixed quadrature of weighted nodes (a dense multiple surface), then the f32 kernel; beyond [`MAX_NODES`] nodes the vMF closed form | < 1% (tested) / closed form: docs/benchmarks.md |
//! | mirror facets under Beckmann / GGX or a mixture of them (either form) | the closed-form microfacet BRDF (a mixture's `Λ = Σ c_k Λ_k`, [`crate::ndf::mixture`]) | exact |
//! | mirror facets under any other NDF (either form; fitted lobe sums) | collapses onto `m = H`; Smith `Λ` from a table of the projected area, built once (97 1-D integrals for an isotropic NDF, 97 × 64 closed-form areas for a tabulated one, [`crate::ndf::tabulated::ProjectedAreas`], 97 × 64 quadratures otherwise) | < [`LAMBDA_TABLE_TOLERANCE`] of `G₂` (isotropic), < [`LAMBDA_TABLE_TOLERANCE_ANISOTROPIC`] (tested) |
//! | anything else | the Eq. 2/8 quadrature, at [`Accuracy::fast`] when interactive | ~1e-3 / exact |
//! | Phong peaks × Phong (N·H) facets (preview) | the vMF closed form always (a cost per lobe) | a few per cent: docs/benchmarks.md |
//! | anything the quadrature would take (preview; not a delta sum or cylinder) | [`PREVIEW_NORMALS`] normals drawn from the NDF by stratified sampling (a multiple surface with the same distribution), then the rows above | the sampling's noise: a preview |
//!
//! The renderer calls it per shading point and light, so nothing here allocates per call.

use crate::convolution::{Accuracy, Form, SmithMasking};
use lambda::{Lambda, LambdaTable, LobeLambda};
pub use lambda::{
    LAMBDA_LOBES_TOLERANCE, LAMBDA_TABLE_TOLERANCE, LAMBDA_TABLE_TOLERANCE_ANISOTROPIC,
};

mod lambda;
use crate::frame::{half_vector, Frame};
use crate::material::{Material, ShadowingKind};
use crate::ndf::{DeltaSum, Ndf, PhongLobe, PhongPeaks, WeightedNormal};
use crate::transfer::{PhongVariant, Transfer};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Lanes of the f32 delta-sum kernel.
pub const LANES: usize = 8;

/// The weighted normals of a multiple surface as f32 structure-of-arrays, padded to a multiple
/// of [`LANES`] (padding: normal `+z`, weight 0, which adds nothing): what the delta-sum
/// kernels of meso-core and the renderer read, [`LANES`] at a time or the first `count`.
#[derive(Clone, Debug, PartialEq)]
pub struct LaneNormals {
    /// Normal x, y, z (local frame, unit) and the weight of each normal (the Eq. 4 sum's).
    pub nx: Vec<f32>,
    /// See [`LaneNormals::nx`].
    pub ny: Vec<f32>,
    /// See [`LaneNormals::nx`].
    pub nz: Vec<f32>,
    /// See [`LaneNormals::nx`].
    pub w: Vec<f32>,
    /// The real normals (the rest is padding).
    pub count: usize,
}

/// A material compiled to weighted normals under Phong facets (half vector) in the
/// multiple-surface form, Eq. 4/11: `f = specular · Σ w_k (n_k·H)^η (n_k·i)⁺ / cos θi + ρ/π`.
/// Delta sums are that exactly; Phong peaks by a node quadrature (< 1 %).
#[derive(Clone, Copy, Debug)]
pub struct PhongNormals<'a> {
    /// The normals and their weights.
    pub normals: &'a LaneNormals,
    /// The facet exponent η.
    pub exponent: f32,
    /// The facet specular colour (RGB).
    pub specular: [f32; 3],
}

impl PhongNormals<'_> {
    /// The lobe sum of Eq. 4/11 for one pair, without the specular colour:
    /// `Σ_k w_k max(0, n_k·h)^η max(0, n_k·i) / i_z` (1/sr), `h` the unit half vector and `i`
    /// the unit incident direction in the local frame (`i_z > 0`). f32, [`LANES`] normals at a
    /// time, the power by [`crate::fastmath::fast_pow`] (relative error about
    /// `1.5e-7 · (1 + η |log2 (n·h)|)`): the one per-pair kernel of weighted normals, run by
    /// [`FastBrdf::eval`] and the renderer's material shader.
    #[must_use]
    pub fn lobe_sum(&self, h: [f32; 3], i: [f32; 3]) -> f32 {
        let n = self.normals;
        let ([hx, hy, hz], [ix, iy, iz]) = (h, i);
        let e = self.exponent;
        let mut acc = 0.0f32;
        for (((nx, ny), nz), w) in
            n.nx.chunks_exact(LANES)
                .zip(n.ny.chunks_exact(LANES))
                .zip(n.nz.chunks_exact(LANES))
                .zip(n.w.chunks_exact(LANES))
        {
            let mut lane = [0.0f32; LANES];
            // Indexed over the SoA lanes: vectorised as written.
            #[allow(clippy::needless_range_loop)]
            for k in 0..LANES {
                let nh = (nx[k] * hx + ny[k] * hy + nz[k] * hz).max(0.0);
                let ni = (nx[k] * ix + ny[k] * iy + nz[k] * iz).max(0.0);
                lane[k] = w[k] * crate::fastmath::fast_pow(nh, e) * ni;
            }
            acc += lane.iter().sum::<f32>();
        }
        acc / iz
    }
}

/// [`FastBrdf::path`] of a Beckmann or GGX NDF (or a mixture of them) under mirror facets in the microfacet form with
/// Smith shadowing: the classic microfacet BRDF `R(i·h) D(h) / ((1 + Λ(i) + Λ(o)) 4 cos θᵢ
/// cos θₒ)`, everything in closed form.
pub const CLOSED_MICROFACET_PATH: &str =
    "mirror facets, closed-form microfacet BRDF (analytic D, Smith Lambda)";

/// Phong (N·H) facets in the multiple-surface form, the transfer of the paper's materials and
/// of the f32 kernels: the facet exponent and specular colour.
fn phong_facets(m: &Material) -> Option<(f64, [f64; 3])> {
    match (&m.transfer, m.form) {
        (
            Transfer::Phong {
                exponent,
                specular,
                variant: PhongVariant::Half,
            },
            Form::MultipleSurface,
        ) => Some((*exponent, *specular)),
        _ => None,
    }
}

/// Phong peaks under Phong (N·H) facets in the multiple-surface form (the paper's materials):
/// the peaks, the facet exponent and specular colour.
fn phong_peaks_under_phong(m: &Material) -> Option<(&PhongPeaks, f64, [f64; 3])> {
    let Ndf::PhongPeaks(p) = &m.ndf else {
        return None;
    };
    phong_facets(m).map(|(exponent, specular)| (p, exponent, specular))
}

/// The plan of Phong peaks under Phong facets: the weighted nodes of [`lobe_nodes`] when there
/// are at most `max_nodes`, else the vMF closed form.
fn peaks_kind(p: &PhongPeaks, exponent: f64, specular: [f64; 3], max_nodes: usize) -> Kind {
    let nodes = if max_nodes > 0 {
        lobe_nodes(p.lobes(), exponent)
    } else {
        Vec::new()
    };
    if !nodes.is_empty() && nodes.len() <= max_nodes {
        Kind::DeltaPhong {
            chunks: chunk(&nodes),
            exponent: exponent as f32,
            specular: specular.map(|s| s as f32),
        }
    } else {
        Kind::PhongClosed {
            lobes: p.lobes().to_vec(),
            exponent,
            specular,
        }
    }
}

/// Pack weighted normals into padded f32 lanes ([`LaneNormals`]).
fn chunk(nodes: &[(DVec3, f64)]) -> LaneNormals {
    let padded = nodes.len().div_ceil(LANES) * LANES;
    let lane = |f: &dyn Fn(&(DVec3, f64)) -> f64, pad: f32| -> Vec<f32> {
        let mut v: Vec<f32> = nodes.iter().map(|n| f(n) as f32).collect();
        v.resize(padded, pad);
        v
    };
    LaneNormals {
        nx: lane(&|n| n.0.x, 0.0),
        ny: lane(&|n| n.0.y, 0.0),
        nz: lane(&|n| n.0.z, 1.0),
        w: lane(&|n| n.1, 0.0),
        count: nodes.len(),
    }
}

/// A fixed quadrature of Phong peaks by weighted nodes — the NDF as a dense multiple surface.
/// Each lobe is integrated in its own exact warp (Gauss–Legendre in the radial variable ×
/// uniform azimuth), with enough nodes that their spacing is under half the width of the
/// transfer lobe `(m·H)^η_t`, so that Eq. 4 on the nodes converges to Eq. 2.
fn lobe_nodes(lobes: &[PhongLobe], transfer_exponent: f64) -> Vec<(DVec3, f64)> {
    let sigma_t = 1.0 / (transfer_exponent.max(1.0)).sqrt();
    let mut out = Vec::new();
    for l in lobes.iter().filter(|l| l.weight > 0.0) {
        let sigma_n = (2.0 / (l.exponent.max(0.0) + 1.0).sqrt()).min(PI);
        let r = (sigma_n / sigma_t).max(1.0);
        let n_r = ((3.0 * r).ceil() as usize + 3).clamp(4, 40);
        let n_a = ((6.0 * r).ceil() as usize + 6).clamp(8, 96);
        let (xs, ws) = crate::quadrature::gauss_legendre(n_r);
        let frame = Frame::from_normal(l.axis);
        for (x, w) in xs.iter().zip(&ws) {
            let s = 0.5 * (x + 1.0);
            let cos_a = PhongLobe::sample_cos(l.exponent, s);
            let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
            for b in 0..n_a {
                let phi = 2.0 * PI * (b as f64 + 0.5) / n_a as f64;
                let m = frame.to_world(DVec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a));
                out.push((m, l.weight * 0.5 * w / n_a as f64));
            }
        }
    }
    out
}

/// Most weighted normals the node quadrature of Phong peaks may use before [`FastBrdf`] falls back
/// to the vMF closed form (broad lobes under a sharp transfer need many nodes).
pub const MAX_NODES: usize = 512;

/// Normals drawn from an NDF by [`Policy::Preview`] when it would otherwise need the quadrature.
pub const PREVIEW_NORMALS: usize = 48;

/// How a [`FastBrdf`] evaluates.
#[derive(Clone, Debug)]
enum Kind {
    DeltaPhong {
        chunks: LaneNormals,
        exponent: f32,
        specular: [f32; 3],
    },
    Deltas,
    PhongClosed {
        lobes: Vec<PhongLobe>,
        exponent: f64,
        specular: [f64; 3],
    },
    Mirror {
        lambda: Option<Lambda>,
        projected_area: f64,
    },
    Quadrature,
}

/// What a compiled [`FastBrdf`] may trade for speed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Policy {
    /// Only what keeps the result within [`LAMBDA_TABLE_TOLERANCE`] of [`Material::brdf`]
    /// ([`LAMBDA_TABLE_TOLERANCE_ANISOTROPIC`] for anisotropic NDFs):
    /// the closed-form microfacet BRDF of Beckmann / GGX, mirror facets collapsed at `H` with
    /// Smith `Λ` tabulated once; every other material evaluated exactly as [`Material::brdf`]
    /// does (its own quadrature accuracy, f64). `meso brdf`'s default and Python's
    /// `Material.brdf`.
    Accurate,
    /// The editor's rendered preview: [`Policy::Interactive`], but Phong peaks under Phong
    /// facets always by the vMF closed form, and NDFs that would need the quadrature replaced by
    /// [`PREVIEW_NORMALS`] normals sampled from them (module docs).
    Preview,
    /// Renderers and interactive previews: [`Policy::Accurate`] plus the f32 kernel of delta
    /// sums, Phong peaks under Phong facets by a node quadrature (< 1 %) or the vMF closed
    /// form, and the quadrature at [`Accuracy::fast`] for the rest (~1e-3).
    #[default]
    Interactive,
}

/// A material compiled for fast repeated evaluation (see the module docs): meso-core's one
/// evaluation plan of a material, used by `meso brdf`, the renderer, the editor and Python.
#[derive(Clone, Debug)]
pub struct FastBrdf {
    material: Material,
    kind: Kind,
    diffuse: [f64; 3],
    policy: Policy,
    /// [`Policy::Preview`] replaced the NDF by sampled normals (the material holds them).
    sampled: bool,
}

impl FastBrdf {
    /// Compile a material for rendering ([`Policy::Interactive`]).
    #[must_use]
    pub fn new(material: &Material) -> FastBrdf {
        Self::with_policy(material, Policy::Interactive)
    }

    /// Compile a material under a [`Policy`].
    #[must_use]
    pub fn with_policy(material: &Material, policy: Policy) -> FastBrdf {
        if policy == Policy::Preview {
            return Self::preview(material);
        }
        let mut material = material.clone();
        let interactive = policy == Policy::Interactive;
        let peaks = phong_peaks_under_phong(&material).filter(|_| interactive);
        let facets = phong_facets(&material).filter(|_| interactive);
        let kind = if let Some((p, exponent, specular)) = peaks {
            peaks_kind(p, exponent, specular, MAX_NODES)
        } else {
            match (&material.ndf, &material.transfer, material.form) {
                (Ndf::Deltas(d), _, _) => match facets {
                    Some((exponent, specular)) => {
                        let nodes: Vec<(DVec3, f64)> =
                            d.normals().iter().map(|n| (n.normal, n.weight)).collect();
                        Kind::DeltaPhong {
                            chunks: chunk(&nodes),
                            exponent: exponent as f32,
                            specular: specular.map(|s| s as f32),
                        }
                    }
                    None => Kind::Deltas,
                },
                (Ndf::Microfacet(mf), Transfer::Mirror { .. }, form) => {
                    // Beckmann and GGX: Smith Λ in closed form, and `∫ n (m·z) dω = 1/A` exactly
                    // (`n = D/A` and `∫ D (m·z) dω = 1`), so nothing to tabulate or integrate.
                    let lambda = (form == Form::Microfacet
                        && material.shadowing == ShadowingKind::Smith)
                        .then_some(Lambda::Closed(*mf));
                    Kind::Mirror {
                        projected_area: 1.0 / mf.area_ratio(),
                        lambda,
                    }
                }
                (Ndf::Mixture(mx), Transfer::Mirror { .. }, form) => {
                    // Mixtures of Beckmann / GGX lobes: `Λ = Σ c_k Λ_k` and `P = Σ w_k / A_k`
                    // in closed form ([`crate::ndf::mixture`]).
                    let lambda = (form == Form::Microfacet
                        && material.shadowing == ShadowingKind::Smith)
                        .then(|| Lambda::ClosedMixture(mx.clone()));
                    Kind::Mirror {
                        projected_area: mx.projected_area(),
                        lambda,
                    }
                }
                (ndf, Transfer::Mirror { .. }, form) => {
                    let smith =
                        form == Form::Microfacet && material.shadowing == ShadowingKind::Smith;
                    // Tilted Phong peaks above the horizon: per-lobe 1-D tables (exact, fast to
                    // build); otherwise the projected-area table.
                    let lobes = match ndf {
                        Ndf::PhongPeaks(p) if !ndf.is_isotropic() => LobeLambda::new(p.lobes()),
                        _ => None,
                    };
                    match lobes {
                        Some(l) => Kind::Mirror {
                            projected_area: l.projected_area,
                            lambda: smith.then_some(Lambda::Lobes(l)),
                        },
                        None => {
                            let sm = SmithMasking::new(ndf, material.accuracy);
                            let lambda = smith
                                .then(|| Lambda::Table(LambdaTable::new(&sm, ndf.is_isotropic())));
                            Kind::Mirror {
                                projected_area: sm.projected_area,
                                lambda,
                            }
                        }
                    }
                }
                _ => {
                    if interactive {
                        material.accuracy = Accuracy::fast();
                    }
                    Kind::Quadrature
                }
            }
        };
        FastBrdf {
            diffuse: material.diffuse,
            material,
            kind,
            policy,
            sampled: false,
        }
    }

    /// [`Policy::Preview`] (module docs): the closed form for Phong peaks under Phong facets, the
    /// interactive plan of [`PREVIEW_NORMALS`] sampled normals where that would be the
    /// quadrature, the interactive plan otherwise.
    fn preview(material: &Material) -> FastBrdf {
        let tag = |mut f: FastBrdf, sampled: bool| {
            f.policy = Policy::Preview;
            f.sampled = sampled;
            f
        };
        if let Some((p, exponent, specular)) = phong_peaks_under_phong(material) {
            return FastBrdf {
                diffuse: material.diffuse,
                kind: peaks_kind(p, exponent, specular, 0),
                material: material.clone(),
                policy: Policy::Preview,
                sampled: false,
            };
        }
        let fast = Self::with_policy(material, Policy::Interactive);
        if !fast.is_quadrature() || material.ndf.is_singular() {
            return tag(fast, false);
        }
        let n = PREVIEW_NORMALS;
        let normals: Vec<WeightedNormal> = (0..n)
            .map(|k| {
                // Stratified in the first coordinate, van der Corput in the second.
                let u = [
                    (k as f64 + 0.5) / n as f64,
                    f64::from((k as u32).reverse_bits()) / 4_294_967_296.0,
                ];
                WeightedNormal {
                    normal: material.ndf.sample(u),
                    weight: 1.0,
                }
            })
            .collect();
        match DeltaSum::new(normals) {
            Ok(d) => {
                let mut m = material.clone();
                m.ndf = Ndf::Deltas(d);
                tag(Self::with_policy(&m, Policy::Interactive), true)
            }
            Err(_) => tag(fast, false),
        }
    }

    /// A description of the evaluation path: [`FastBrdf::path`], prefixed by how many normals
    /// were sampled from the NDF when [`Policy::Preview`] did that.
    #[must_use]
    pub fn description(&self) -> String {
        if self.sampled {
            format!(
                "{PREVIEW_NORMALS} normals sampled from the NDF, {}",
                self.path()
            )
        } else {
            self.path().to_owned()
        }
    }

    /// The material this was compiled from (under [`Policy::Preview`] with sampled normals: the
    /// material with those normals as its NDF, [`FastBrdf::description`]).
    #[must_use]
    pub fn material(&self) -> &Material {
        &self.material
    }

    /// A short name of the evaluation path (for reports).
    #[must_use]
    pub fn path(&self) -> &'static str {
        match self.kind {
            Kind::DeltaPhong { .. } => "weighted normals, f32 Phong kernel (Eq. 4/11)",
            Kind::Deltas => "delta-sum (Eq. 4)",
            Kind::PhongClosed { .. } => "Phong peaks x Phong facets, vMF closed form",
            Kind::Mirror {
                lambda: Some(Lambda::Closed(_) | Lambda::ClosedMixture(_)),
                ..
            } => CLOSED_MICROFACET_PATH,
            Kind::Mirror { .. } => "mirror facets, collapsed at H",
            Kind::Quadrature => match self.policy {
                Policy::Interactive | Policy::Preview => "quadrature (fast)",
                Policy::Accurate => "quadrature (the material's accuracy)",
            },
        }
    }

    /// The policy this was compiled under.
    #[must_use]
    pub fn policy(&self) -> Policy {
        self.policy
    }

    /// The weighted normals under Phong facets when the plan is one ([`PhongNormals`]: delta
    /// sums and, under [`Policy::Interactive`], Phong peaks by nodes), for kernels of other
    /// crates (the renderer's stream kernel) to run on; `None` otherwise.
    #[must_use]
    pub fn phong_normals(&self) -> Option<PhongNormals<'_>> {
        match &self.kind {
            Kind::DeltaPhong {
                chunks,
                exponent,
                specular,
            } => Some(PhongNormals {
                normals: chunks,
                exponent: *exponent,
                specular: *specular,
            }),
            _ => None,
        }
    }

    /// The Beckmann or GGX NDF when the plan is the closed-form microfacet BRDF of one lobe
    /// (mirror facets, microfacet form, Smith `Λ` in closed form: [`CLOSED_MICROFACET_PATH`]),
    /// for kernels of other crates to specialise; `None` otherwise.
    #[must_use]
    pub fn closed_microfacet(&self) -> Option<&crate::ndf::microfacet::Microfacet> {
        match &self.kind {
            Kind::Mirror {
                lambda: Some(Lambda::Closed(mf)),
                ..
            } => Some(mf),
            _ => None,
        }
    }

    /// True when every evaluation runs the Eq. 2/8 quadrature (no closed form, table or kernel
    /// applies to the material): the slow case, which previews may want to replace.
    #[must_use]
    pub fn is_quadrature(&self) -> bool {
        matches!(self.kind, Kind::Quadrature)
    }

    /// The effective BRDF (RGB, 1/sr, no cosine) for unit local directions; 0 below the surface.
    #[must_use]
    pub fn eval(&self, i: DVec3, o: DVec3) -> [f64; 3] {
        if i.z <= 0.0 || o.z <= 0.0 {
            return [0.0; 3];
        }
        let mut f = match &self.kind {
            Kind::DeltaPhong {
                chunks,
                exponent,
                specular,
            } => {
                let Some(h) = half_vector(i, o) else {
                    return [0.0; 3];
                };
                let normals = PhongNormals {
                    normals: chunks,
                    exponent: *exponent,
                    specular: *specular,
                };
                let s = f64::from(normals.lobe_sum(
                    [h.x as f32, h.y as f32, h.z as f32],
                    [i.x as f32, i.y as f32, i.z as f32],
                ));
                [
                    f64::from(specular[0]) * s,
                    f64::from(specular[1]) * s,
                    f64::from(specular[2]) * s,
                ]
            }
            Kind::Deltas | Kind::Quadrature => {
                self.material
                    .convolved_with(i, o, self.policy == Policy::Accurate)
            }
            Kind::PhongClosed {
                lobes,
                exponent,
                specular,
            } => crate::convolution::phong_closed_form(lobes, *exponent, *specular, i, o),
            Kind::Mirror {
                lambda,
                projected_area,
            } => {
                let Some(h) = half_vector(i, o) else {
                    return [0.0; 3];
                };
                let Some(fr) = self.material.transfer.mirror_reflectance(i.dot(h)) else {
                    unreachable!("Mirror kind is built from mirror transfers only")
                };
                let n = self.material.ndf.eval(h);
                let c = match self.material.form {
                    Form::MultipleSurface => n / (4.0 * o.dot(h) * i.z),
                    Form::Microfacet => {
                        if h.z <= 0.0 {
                            return [0.0; 3];
                        }
                        let g2 = match (lambda, self.material.shadowing) {
                            (Some(t), _) => 1.0 / (1.0 + t.lookup(i) + t.lookup(o)),
                            (None, ShadowingKind::Horizon) => {
                                self.material.horizon.as_ref().map_or(1.0, |hz| hz.g(i, o))
                            }
                            (None, ShadowingKind::Visibility) => self
                                .material
                                .horizon
                                .as_ref()
                                .map_or(1.0, |hz| hz.g_given_normal(i, o, h)),
                            (None, _) => 1.0,
                        };
                        n / projected_area * g2 / (4.0 * i.z * o.z)
                    }
                };
                [fr[0] * c, fr[1] * c, fr[2] * c]
            }
        };
        for (c, d) in f.iter_mut().zip(self.diffuse) {
            *c += d / PI;
        }
        f
    }

    /// [`FastBrdf::eval`] in a world frame: `frame` is the surface's local frame.
    #[must_use]
    pub fn eval_world(&self, frame: &Frame, i: DVec3, o: DVec3) -> [f64; 3] {
        self.eval(frame.to_local(i), frame.to_local(o))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::spherical_direction_deg;

    fn check(toml: &str, tol: f64) {
        let m = Material::from_toml_str(toml).unwrap();
        let fast = FastBrdf::new(&m);
        for (a, b, c, d) in [
            (0.0, 0.0, 0.0, 0.0),
            (30.0, 0.0, 30.0, 180.0),
            (45.0, 90.0, 20.0, 250.0),
            (60.0, 10.0, 50.0, 200.0),
            (70.0, 300.0, 10.0, 45.0),
        ] {
            let (i, o) = (spherical_direction_deg(a, b), spherical_direction_deg(c, d));
            let exact = m.brdf(i, o);
            let got = fast.eval(i, o);
            for k in 0..3 {
                let err = (got[k] - exact[k]).abs() / exact[k].abs().max(1e-3);
                assert!(
                    err < tol,
                    "{} {k} {a} {b} {c} {d}: {} vs {}",
                    fast.path(),
                    got[k],
                    exact[k]
                );
            }
        }
    }

    /// The accurate plan of fitted-like lobe sums (sharp lobes on the normal as `meso fit`
    /// writes them, tilted and broad lobes, a vMF) under mirror facets with Smith: within
    /// [`LAMBDA_TABLE_TOLERANCE`] of the exact material over 4000 random pairs, grazing ones
    /// included.
    #[test]
    fn accurate_plan_of_lobe_sums_is_within_its_tolerance() {
        let lobes = [
            "{ axis = [0.0, 0.0], weight = 0.28, exponent = 1069.0 }, { axis = [0.0, 0.0], weight = 0.35, exponent = 13407.0 }, { axis = [0.0, 0.0], weight = 0.37, exponent = 149082.0 }",
            "{ axis = [0.0, 0.0], weight = 0.5, exponent = 12.0 }, { axis = [0.0, 0.0], weight = 0.5, exponent = 300.0 }",
            "{ axis = [25.0, 40.0], weight = 0.6, exponent = 60.0 }, { axis = [10.0, 200.0], weight = 0.4, exponent = 2000.0 }",
            "{ axis = [40.0, 0.0], weight = 0.5, exponent = 12.0 }, { axis = [0.0, 0.0], weight = 0.5, exponent = 300.0 }",
            // The editor's satin: sharp lobes tilted to 45° and a broad one at the normal that
            // the horizon cuts (its table over the upper hemisphere; it took the 2-D table before).
            "{ axis = [0.0, 90.0], weight = 1.0, exponent = 900.0 }, { axis = [15.0, 90.0], weight = 0.8322, exponent = 900.0 }, { axis = [15.0, 270.0], weight = 0.8322, exponent = 900.0 }, { axis = [30.0, 90.0], weight = 0.4797, exponent = 900.0 }, { axis = [30.0, 270.0], weight = 0.4797, exponent = 900.0 }, { axis = [45.0, 90.0], weight = 0.1915, exponent = 900.0 }, { axis = [45.0, 270.0], weight = 0.1915, exponent = 900.0 }, { axis = [0.0, 0.0], weight = 0.8, exponent = 12.0 }",
        ];
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut uniform = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for l in lobes {
            let toml = format!(
                "form = \"microfacet\"\n[ndf]\nkind = \"phong-peaks\"\nlobes = [{l}]\n[transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.5, 0.1]\n[diffuse]\nalbedo = [0.01, 0.02, 0.03]\n"
            );
            let m = Material::from_toml_str(&toml).unwrap();
            let plan = FastBrdf::with_policy(&m, Policy::Accurate);
            assert!(
                plan.path().starts_with("mirror facets, collapsed"),
                "{}",
                plan.path()
            );
            // Up to 85° from the normal; beyond, the 2-D quadrature of sharp lobes is itself
            // uncertain to ~1e-3 (docs/measured.md, "Fast evaluation of fitted materials").
            const GRAZING_85: f64 = 0.087_155_742_747_658_17; // cos 85°
            let (mut worst, mut worst_85) = (0.0f64, 0.0f64);
            for _ in 0..4000 {
                let mut dir = || {
                    let (u, v) = (uniform(), uniform());
                    let s = (1.0 - u * u).sqrt();
                    DVec3::new(s * (2.0 * PI * v).cos(), s * (2.0 * PI * v).sin(), u)
                };
                let (i, o) = (dir(), dir());
                let (exact, fast) = (m.brdf(i, o), plan.eval(i, o));
                for c in 0..3 {
                    let spec = exact[c] - m.diffuse[c] / PI;
                    if spec > 1e-9 {
                        let e = (fast[c] - exact[c]).abs() / spec;
                        worst = worst.max(e);
                        if i.z.min(o.z) >= GRAZING_85 {
                            worst_85 = worst_85.max(e);
                        }
                    }
                }
            }
            let lobes = matches!(
                plan.kind,
                Kind::Mirror {
                    lambda: Some(Lambda::Lobes(_)),
                    ..
                }
            );
            let tol = if m.ndf.is_isotropic() {
                LAMBDA_TABLE_TOLERANCE
            } else if lobes {
                LAMBDA_LOBES_TOLERANCE
            } else {
                LAMBDA_TABLE_TOLERANCE_ANISOTROPIC
            };
            // The third and fifth materials have lobe tables (lobes above the horizon, or at the
            // normal); the fourth has a tilted lobe reaching below it.
            assert_eq!(
                lobes,
                l.contains("25.0") || l.contains("45.0"),
                "{l}: {}",
                plan.path()
            );
            eprintln!(
                "{l}: worst relative error of the specular part {worst:.2e}, {worst_85:.2e} up to 85° (allowed {tol:.0e})"
            );
            if l.contains("45.0") {
                // Satin: the lobe tables' bound up to 85°, the 2-D table's bound (the path it
                // took before) everywhere. Measured 6.3e-4 and 1.37e-3 (at θi = 89.6°).
                assert!(
                    worst_85 <= tol,
                    "{l}: worst relative error {worst_85:.2e} up to 85°"
                );
                assert!(
                    worst <= LAMBDA_TABLE_TOLERANCE_ANISOTROPIC,
                    "{l}: worst relative error {worst:.2e}"
                );
            } else {
                assert!(worst <= tol, "{l}: worst relative error {worst:.2e}");
            }
        }
    }

    #[test]
    fn fast_paths_agree_with_the_exact_material() {
        check(
            r#"
            [ndf]
            kind = "phong-peaks"
            lobes = [
              { axis = [0.0, 0.0],  weight = 0.6, exponent = 40.0 },
              { axis = [30.0, 90.0], weight = 0.4, exponent = 100.0 },
            ]
            [transfer]
            kind = "phong"
            exponent = 50.0
            specular = [1.0, 0.8, 0.6]
            "#,
            1e-2,
        );
        check(
            r#"
            [ndf]
            kind = "deltas"
            lobes = [ { axis = [0, 0], weight = 1 }, { axis = [30, 0], weight = 2 }, { axis = [25, 200], weight = 1 } ]
            [transfer]
            kind = "phong"
            exponent = 30
            specular = [1.0, 0.5, 0.2]
            [diffuse]
            albedo = [0.2, 0.2, 0.2]
            "#,
            1e-5,
        );
        check(
            r#"
            form = "microfacet"
            [ndf]
            kind = "beckmann"
            alpha_x = 0.3
            alpha_y = 0.15
            [transfer]
            kind = "mirror"
            fresnel = "dielectric"
            eta = 1.5
            "#,
            1e-2,
        );
        check(
            r#"
            form = "microfacet"
            [ndf]
            kind = "ggx"
            alpha_x = 0.1
            alpha_y = 0.4
            [transfer]
            kind = "mirror"
            specular = [1.0, 0.7, 0.4]
            "#,
            1e-2,
        );
        check(
            r#"
            [ndf]
            kind = "vmf"
            kappa = 20
            [transfer]
            kind = "lambert"
            albedo = [0.8, 0.8, 0.8]
            "#,
            5e-3,
        );
    }
}
