//! meso-core materials as shaders: [`MaterialShader`].
//!
//! A [`MaterialShader`] wraps a [`meso_core::material::Material`] compiled for fast evaluation
//! ([`FastBrdf`]) and returns its effective BRDF in 1/sr (no cosine) as f32, in the local
//! frame of the hit (normal `+z`, tangent `+x`, see `meso_core::frame`), as the [`Shader`]
//! contract asks. The material's NDF lobe axes are therefore expressed in the renderer's
//! shading frame: on a sphere the tangent runs along the parallels around the pole, on quads
//! along `edge_u` (`docs/scene-format.md`).
//!
//! The hot case of the paper — a multiple surface (delta sum of ≤ a few dozen normals) with
//! Phong (`N·H`) facets in the multiple-surface form (Eq. 4/11),
//! `f(i, o) = Σ_k w_k · spec · max(0, N_k·H)^η · max(0, N_k·i) / cos θ_i + diffuse/π` —
//! is evaluated here on flat f32 lanes with the renderer's branch-free [`fast_pow`]
//! (relative error ≈ `1.5e-7·(1 + |η log2(N·H)|)`), eight normals per chunk. Every other
//! material goes through [`FastBrdf::eval`] (exact sums, the Phong-peak node kernel, the
//! collapsed mirror, or the fast quadrature; see `meso_core::shading`). Nothing allocates per
//! call.
//!
//! ```
//! use meso_core::material::Material;
//! use meso_render::{MaterialShader, Shader};
//! let m = Material::from_toml_str("[transfer]\nkind = \"lambert\"\nalbedo = [1, 1, 1]\n").unwrap();
//! let s = MaterialShader::new(&m);
//! let sp = meso_render::material::local_point(glam::DVec2::ZERO, 0.0);
//! let f = s.eval(&sp, glam::DVec3::Z, glam::DVec3::Z);
//! assert!((f[0] - 1.0 / std::f32::consts::PI).abs() < 1e-6);
//! ```

use crate::geometry::{MaterialId, ShadingPoint};
use crate::shader::{colour_pairs, fast_pow, lobe_pairs, pairs_one_by_one, LobeSlices, Shader};
use glam::{DVec2, DVec3};
use meso_core::convolution::Form;
use meso_core::frame::Frame;
use meso_core::material::Material;
use meso_core::ndf::Ndf;
use meso_core::shading::FastBrdf;
use meso_core::transfer::{PhongVariant, Transfer};

/// A shading point at the origin with the identity frame (world = local), texture coordinates
/// `uv` and an isotropic pixel footprint of `uv_footprint` uv units per pixel step — for
/// evaluating shaders outside a render (tests, previews, BRDF queries).
#[must_use]
pub fn local_point(uv: DVec2, uv_footprint: f64) -> ShadingPoint {
    ShadingPoint {
        position: DVec3::ZERO,
        geometric_normal: DVec3::Z,
        frame: Frame::IDENTITY,
        uv,
        dpdu: DVec3::X,
        dpdv: DVec3::Y,
        dpdx: DVec3::X * uv_footprint,
        dpdy: DVec3::Y * uv_footprint,
        duvdx: DVec2::new(uv_footprint, 0.0),
        duvdy: DVec2::new(0.0, uv_footprint),
        filter_uv: uv,
        material: MaterialId(0),
    }
}

/// Lanes of one chunk of the delta-sum kernel.
const LANES: usize = 8;

/// Up to [`LANES`] normals of a multiple surface as a structure of arrays (unused lanes have
/// weight 0).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Chunk {
    nx: [f32; LANES],
    ny: [f32; LANES],
    nz: [f32; LANES],
    w: [f32; LANES],
}

#[derive(Clone, Debug)]
enum Kind {
    /// Delta sum × Phong (half vector), multiple-surface form.
    DeltaPhong {
        chunks: Vec<Chunk>,
        /// The same normals as flat arrays `[nx, ny, nz, w, η]` for the stream kernel.
        flat: [Vec<f32>; 5],
        exponent: f32,
        specular: [f32; 3],
        diffuse: [f32; 3],
    },
    /// Anything else: the core's fast evaluation.
    General,
}

/// A meso-core material as a [`Shader`] (see the module docs).
#[derive(Clone, Debug)]
pub struct MaterialShader {
    brdf: FastBrdf,
    kind: Kind,
}

impl MaterialShader {
    /// Compile `material` for rendering (once per material; the result is shared by threads).
    #[must_use]
    pub fn new(material: &Material) -> MaterialShader {
        let brdf = FastBrdf::new(material);
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
                let mut chunks = Vec::new();
                for group in d.normals().chunks(LANES) {
                    let mut c = Chunk {
                        nx: [0.0; LANES],
                        ny: [0.0; LANES],
                        nz: [1.0; LANES],
                        w: [0.0; LANES],
                    };
                    for (k, n) in group.iter().enumerate() {
                        c.nx[k] = n.normal.x as f32;
                        c.ny[k] = n.normal.y as f32;
                        c.nz[k] = n.normal.z as f32;
                        c.w[k] = n.weight as f32;
                    }
                    chunks.push(c);
                }
                let inv_pi = std::f64::consts::FRAC_1_PI;
                let ns = d.normals();
                let flat = [
                    ns.iter().map(|n| n.normal.x as f32).collect(),
                    ns.iter().map(|n| n.normal.y as f32).collect(),
                    ns.iter().map(|n| n.normal.z as f32).collect(),
                    ns.iter().map(|n| n.weight as f32).collect(),
                    vec![*exponent as f32; ns.len()],
                ];
                Kind::DeltaPhong {
                    chunks,
                    flat,
                    exponent: *exponent as f32,
                    specular: specular.map(|s| s as f32),
                    diffuse: material.diffuse.map(|a| (a * inv_pi) as f32),
                }
            }
            _ => Kind::General,
        };
        MaterialShader { brdf, kind }
    }

    /// The compiled material.
    #[must_use]
    pub fn brdf(&self) -> &FastBrdf {
        &self.brdf
    }

    /// The material this shader was built from.
    #[must_use]
    pub fn material(&self) -> &Material {
        self.brdf.material()
    }

    /// A short name of the evaluation path (for reports).
    #[must_use]
    pub fn path(&self) -> &'static str {
        match self.kind {
            Kind::DeltaPhong { .. } => "weighted normals, f32 fast_pow kernel (Eq. 4/11)",
            Kind::General => self.brdf.path(),
        }
    }
}

impl Shader for MaterialShader {
    #[inline]
    fn eval(&self, _sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        match &self.kind {
            Kind::DeltaPhong {
                chunks,
                exponent,
                specular,
                diffuse,
                ..
            } => {
                let h = wi + wo;
                let l = h.length();
                if l < 1e-12 {
                    return [0.0; 3];
                }
                let h = h / l;
                let (hx, hy, hz) = (h.x as f32, h.y as f32, h.z as f32);
                let (ix, iy, iz) = (wi.x as f32, wi.y as f32, wi.z as f32);
                let e = *exponent;
                let mut acc = 0.0f32;
                for c in chunks {
                    let mut lane = [0.0f32; LANES];
                    // Indexed over the SoA lanes: vectorised as written.
                    #[allow(clippy::needless_range_loop)]
                    for k in 0..LANES {
                        let nh = (c.nx[k] * hx + c.ny[k] * hy + c.nz[k] * hz).max(0.0);
                        let ni = (c.nx[k] * ix + c.ny[k] * iy + c.nz[k] * iz).max(0.0);
                        lane[k] = c.w[k] * fast_pow(nh, e) * ni;
                    }
                    acc += lane.iter().sum::<f32>();
                }
                let s = acc / iz;
                [
                    specular[0] * s + diffuse[0],
                    specular[1] * s + diffuse[1],
                    specular[2] * s + diffuse[2],
                ]
            }
            Kind::General => self.brdf.eval(wi, wo).map(|v| v as f32),
        }
    }

    #[inline]
    fn needs_surface_parameters(&self) -> bool {
        false
    }

    #[inline]
    fn direction_only(&self) -> bool {
        true
    }

    /// Weighted normals: the stream kernel ([`lobe_pairs`] in the multiple-surface form) across
    /// pairs; anything else: [`FastBrdf::eval`] pair by pair.
    fn eval_pairs(&self, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let [o0, o1, o2] = out;
        match &self.kind {
            Kind::DeltaPhong {
                flat,
                specular,
                diffuse,
                ..
            } => {
                let lobes = LobeSlices {
                    nx: &flat[0],
                    ny: &flat[1],
                    nz: &flat[2],
                    weight: &flat[3],
                    exponent: &flat[4],
                };
                lobe_pairs(&lobes, true, wi, wo, o0);
                colour_pairs(o0, o1, o2, *specular, *diffuse);
            }
            Kind::General => pairs_one_by_one(wi, wo, [o0, o1, o2], |i, o| {
                if i.z <= 0.0 || o.z <= 0.0 {
                    [0.0; 3]
                } else {
                    self.brdf.eval(i, o).map(|v| v as f32)
                }
            }),
        }
    }
}
