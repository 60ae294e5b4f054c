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

#[derive(Clone, Debug)]
enum Kind {
    /// Delta sum × Phong (half vector), multiple-surface form.
    DeltaPhong {
        /// The normals as flat arrays `[nx, ny, nz, w, η]`, padded to a multiple of [`LANES`]
        /// (padding: `+z`, weight 0): the per-hit kernel reads them 8 lanes at a time, the
        /// stream kernel the first `count`.
        flat: [Vec<f32>; 5],
        count: usize,
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
                let inv_pi = std::f64::consts::FRAC_1_PI;
                let ns = d.normals();
                let padded = ns.len().div_ceil(LANES) * LANES;
                let lane = |f: &dyn Fn(usize) -> f32, pad: f32| -> Vec<f32> {
                    (0..padded)
                        .map(|k| if k < ns.len() { f(k) } else { pad })
                        .collect()
                };
                let flat = [
                    lane(&|k| ns[k].normal.x as f32, 0.0),
                    lane(&|k| ns[k].normal.y as f32, 0.0),
                    lane(&|k| ns[k].normal.z as f32, 1.0),
                    lane(&|k| ns[k].weight as f32, 0.0),
                    vec![*exponent as f32; padded],
                ];
                Kind::DeltaPhong {
                    flat,
                    count: ns.len(),
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
                flat,
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
                let [nx, ny, nz, w, _] = flat;
                for (((nx, ny), nz), w) in nx
                    .chunks_exact(LANES)
                    .zip(ny.chunks_exact(LANES))
                    .zip(nz.chunks_exact(LANES))
                    .zip(w.chunks_exact(LANES))
                {
                    let mut lane = [0.0f32; LANES];
                    // Indexed over the SoA lanes: vectorised as written.
                    #[allow(clippy::needless_range_loop)]
                    for k in 0..LANES {
                        let nh = (nx[k] * hx + ny[k] * hy + nz[k] * hz).max(0.0);
                        let ni = (nx[k] * ix + ny[k] * iy + nz[k] * iz).max(0.0);
                        lane[k] = w[k] * fast_pow(nh, e) * ni;
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
                count,
                specular,
                diffuse,
                ..
            } => {
                let n = *count;
                let lobes = LobeSlices {
                    nx: &flat[0][..n],
                    ny: &flat[1][..n],
                    nz: &flat[2][..n],
                    weight: &flat[3][..n],
                    exponent: &flat[4][..n],
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
