//! Fast evaluation of a material's effective BRDF for renderers and interactive previews.
//!
//! [`FastBrdf::new`] compiles a [`Material`] into the cheapest evaluation that is exact or
//! documented-approximate for it:
//!
//! | material | evaluation | error |
//! |---|---|---|
//! | delta sum (multiple surface), Phong (N·H) facets | Eq. 4/11, flat f32 arrays of ≤ 8 lanes per chunk | f32 rounding |
//! | delta sum, any other facet | Eq. 4, f64 | exact |
//! | Phong peaks × Phong (N·H) facets, multiple-surface form | each lobe replaced by a fixed quadrature of weighted nodes (a dense multiple surface), then the f32 kernel; beyond [`MAX_NODES`] nodes the vMF closed form | < 1% (tested) / closed form: docs/benchmarks.md |
//! | mirror facets (either form) | collapses onto `m = H`; Smith `Λ` tabulated once | table interpolation, < 1e-3 |
//! | anything else | the Eq. 2/8 quadrature at [`Accuracy::fast`] | ~1e-3 |
//!
//! The renderer calls it per shading point and light, so nothing here allocates per call.

use crate::convolution::{Accuracy, Form, SmithMasking};
use crate::frame::{half_vector, Frame};
use crate::material::{Material, ShadowingKind};
use crate::ndf::{Ndf, PhongLobe};
use crate::transfer::{PhongVariant, Transfer};
use glam::DVec3;
use std::f64::consts::PI;

/// Lanes of the f32 delta-sum kernel.
pub const LANES: usize = 8;

/// A chunk of up to [`LANES`] normals of a multiple surface, structure of arrays.
#[derive(Clone, Copy, Debug, PartialEq)]
struct DeltaChunk {
    nx: [f32; LANES],
    ny: [f32; LANES],
    nz: [f32; LANES],
    w: [f32; LANES],
}

/// [`FastBrdf::path`] of a Beckmann or GGX NDF under mirror facets in the microfacet form with
/// Smith shadowing: the classic microfacet BRDF `R(i·h) D(h) / ((1 + Λ(i) + Λ(o)) 4 cos θᵢ
/// cos θₒ)`, everything in closed form.
pub const CLOSED_MICROFACET_PATH: &str =
    "mirror facets, closed-form microfacet BRDF (analytic D, Smith Lambda)";

/// Smith Λ of a mirror-facet material's NDF: closed form for Beckmann and GGX, else tabulated.
#[derive(Clone, Debug, PartialEq)]
enum Lambda {
    Closed(crate::ndf::microfacet::Microfacet),
    Table(LambdaTable),
}

impl Lambda {
    fn lookup(&self, w: DVec3) -> f64 {
        match self {
            Lambda::Closed(mf) => mf.lambda(w),
            Lambda::Table(t) => t.lookup(w),
        }
    }
}

/// Smith Λ tabulated over the upper hemisphere in (cos θ, φ), bilinear.
#[derive(Clone, Debug, PartialEq)]
struct LambdaTable {
    n_u: usize,
    n_phi: usize,
    values: Vec<f64>,
}

impl LambdaTable {
    fn new(m: &SmithMasking<'_>) -> LambdaTable {
        let (n_u, n_phi) = (48, 32);
        let mut values = Vec::with_capacity(n_u * n_phi);
        for a in 0..n_u {
            // Nodes denser near grazing: u = cos θ = ((a + 0.5)/n_u)^2 …(keeps Λ smooth in u).
            let u = Self::node_u(a, n_u);
            for b in 0..n_phi {
                let phi = 2.0 * PI * b as f64 / n_phi as f64;
                let s = (1.0 - u * u).max(0.0).sqrt();
                values.push(m.lambda(DVec3::new(s * phi.cos(), s * phi.sin(), u)));
            }
        }
        LambdaTable { n_u, n_phi, values }
    }

    fn node_u(a: usize, n: usize) -> f64 {
        let t = (a as f64 + 0.5) / n as f64;
        t.sqrt()
    }

    fn lookup(&self, w: DVec3) -> f64 {
        if w.z <= 0.0 {
            return f64::INFINITY;
        }
        let t = (w.z * w.z * self.n_u as f64 - 0.5).clamp(0.0, (self.n_u - 1) as f64);
        let a0 = (t as usize).min(self.n_u - 2);
        let fa = t - a0 as f64;
        let mut phi = w.y.atan2(w.x);
        if phi < 0.0 {
            phi += 2.0 * PI;
        }
        let p = phi / (2.0 * PI) * self.n_phi as f64;
        let b0 = (p as usize) % self.n_phi;
        let b1 = (b0 + 1) % self.n_phi;
        let fb = p - p.floor();
        let v = |a: usize, b: usize| self.values[a * self.n_phi + b];
        let l0 = v(a0, b0) * (1.0 - fb) + v(a0, b1) * fb;
        let l1 = v(a0 + 1, b0) * (1.0 - fb) + v(a0 + 1, b1) * fb;
        l0 * (1.0 - fa) + l1 * fa
    }
}

/// Pack weighted normals into f32 chunks of [`LANES`].
fn chunk(nodes: &[(DVec3, f64)]) -> Vec<DeltaChunk> {
    nodes
        .chunks(LANES)
        .map(|c| {
            let mut ch = DeltaChunk {
                nx: [0.0; LANES],
                ny: [0.0; LANES],
                nz: [1.0; LANES],
                w: [0.0; LANES],
            };
            for (k, (n, w)) in c.iter().enumerate() {
                ch.nx[k] = n.x as f32;
                ch.ny[k] = n.y as f32;
                ch.nz[k] = n.z as f32;
                ch.w[k] = *w as f32;
            }
            ch
        })
        .collect()
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

/// How a [`FastBrdf`] evaluates.
#[derive(Clone, Debug)]
enum Kind {
    DeltaPhong {
        chunks: Vec<DeltaChunk>,
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

/// A material compiled for fast repeated evaluation (see the module docs).
#[derive(Clone, Debug)]
pub struct FastBrdf {
    material: Material,
    kind: Kind,
    diffuse: [f64; 3],
}

impl FastBrdf {
    /// Compile a material.
    #[must_use]
    pub fn new(material: &Material) -> FastBrdf {
        let mut material = material.clone();
        let kind = match (&material.ndf, &material.transfer, material.form) {
            (
                Ndf::Deltas(d),
                Transfer::Phong {
                    exponent,
                    specular,
                    variant: PhongVariant::Half,
                },
                Form::MultipleSurface,
            ) => {
                let nodes: Vec<(DVec3, f64)> =
                    d.normals().iter().map(|n| (n.normal, n.weight)).collect();
                let chunks = chunk(&nodes);
                Kind::DeltaPhong {
                    chunks,
                    exponent: *exponent as f32,
                    specular: specular.map(|s| s as f32),
                }
            }
            (Ndf::Deltas(_), _, _) => Kind::Deltas,
            (
                Ndf::PhongPeaks(p),
                Transfer::Phong {
                    exponent,
                    specular,
                    variant: PhongVariant::Half,
                },
                Form::MultipleSurface,
            ) => {
                let nodes = lobe_nodes(p.lobes(), *exponent);
                if nodes.len() <= MAX_NODES {
                    Kind::DeltaPhong {
                        chunks: chunk(&nodes),
                        exponent: *exponent as f32,
                        specular: specular.map(|s| s as f32),
                    }
                } else {
                    Kind::PhongClosed {
                        lobes: p.lobes().to_vec(),
                        exponent: *exponent,
                        specular: *specular,
                    }
                }
            }
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
            (ndf, Transfer::Mirror { .. }, form) => {
                let sm = SmithMasking::new(ndf, Accuracy::default());
                let lambda = (form == Form::Microfacet
                    && material.shadowing == ShadowingKind::Smith)
                    .then(|| Lambda::Table(LambdaTable::new(&sm)));
                Kind::Mirror {
                    projected_area: sm.projected_area,
                    lambda,
                }
            }
            _ => {
                material.accuracy = Accuracy::fast();
                Kind::Quadrature
            }
        };
        FastBrdf {
            diffuse: material.diffuse,
            material,
            kind,
        }
    }

    /// The material this was compiled from.
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
            Kind::PhongClosed { .. } => "Phong peaks, vMF closed form",
            Kind::Mirror {
                lambda: Some(Lambda::Closed(_)),
                ..
            } => CLOSED_MICROFACET_PATH,
            Kind::Mirror { .. } => "mirror facets, collapsed at H",
            Kind::Quadrature => "quadrature (fast)",
        }
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
                let (hx, hy, hz) = (h.x as f32, h.y as f32, h.z as f32);
                let (ix, iy, iz) = (i.x as f32, i.y as f32, i.z as f32);
                let mut acc = 0.0f32;
                for c in chunks {
                    let mut lane = [0.0f32; LANES];
                    // Indexed over the SoA lanes: vectorised as written.
                    #[allow(clippy::needless_range_loop)]
                    for k in 0..LANES {
                        let nh = (c.nx[k] * hx + c.ny[k] * hy + c.nz[k] * hz).max(0.0);
                        let ni = (c.nx[k] * ix + c.ny[k] * iy + c.nz[k] * iz).max(0.0);
                        lane[k] = c.w[k] * nh.powf(*exponent) * ni;
                    }
                    acc += lane.iter().sum::<f32>();
                }
                let s = f64::from(acc) / i.z;
                [
                    f64::from(specular[0]) * s,
                    f64::from(specular[1]) * s,
                    f64::from(specular[2]) * s,
                ]
            }
            Kind::Deltas | Kind::Quadrature => self.material.convolved(i, o),
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
