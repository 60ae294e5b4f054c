//! meso-core materials as shaders: [`MaterialShader`].
//!
//! A [`MaterialShader`] wraps a [`meso_core::material::Material`] compiled for fast evaluation
//! ([`FastBrdf`]) and returns its effective BRDF in 1/sr (no cosine) as f32, in the local
//! frame of the hit (normal `+z`, tangent `+x`, see `meso_core::frame`), as the [`Shader`]
//! contract asks. The material's NDF lobe axes are therefore expressed in the renderer's
//! shading frame: on a sphere the tangent runs along the parallels around the pole, on quads
//! along `edge_u` (`docs/scene-format.md`).
//!
//! The shader does not look at the material's kinds: it adapts meso-core's compiled plan. Two
//! plans get an f32 kernel:
//! * weighted normals under Phong (`N·H`) facets in the multiple-surface form (Eq. 4/11) — the
//!   hot case of the paper, a delta sum of a few dozen normals, and Phong peaks by their node
//!   quadrature: `f(i, o) = Σ_k w_k · spec · max(0, N_k·H)^η · max(0, N_k·i) / cos θ_i +
//!   diffuse/π`, on the plan's flat f32 lanes ([`FastBrdf::phong_normals`], not copied): per
//!   pair meso-core's own kernel ([`meso_core::shading::PhongNormals::lobe_sum`], the one
//!   [`FastBrdf::eval`] runs; branch-free [`meso_core::fastmath::fast_pow`], relative error ≈
//!   `1.5e-7·(1 + |η log2(N·H)|)`, eight normals per chunk), across pairs the renderer's
//!   stream kernel ([`lobe_pairs`]);
//! * one Beckmann or GGX lobe under Schlick mirror facets with Smith ([`MicrofacetLobe`], from
//!   [`FastBrdf::closed_microfacet`]).
//!
//! Every other plan goes through [`FastBrdf::eval`] (exact sums, the collapsed mirror, or the
//! fast quadrature; see `meso_core::shading`). Nothing allocates per call.
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

use crate::geometry::ShadingPoint;
use crate::shader::{colour_pairs, lobe_pairs, pairs_one_by_one, LobeSlices, Shader};
use glam::DVec3;
use meso_core::frame::half_vector;
use meso_core::material::Material;
use meso_core::shading::FastBrdf;
use meso_core::transfer::Transfer;

// `local_point` lives with the shading contract (`crate::shader`); re-exported here, where
// callers have always found it.
pub use crate::shader::local_point;

/// The renderer's kernel for a compiled plan (the plan itself is meso-core's [`FastBrdf`]).
#[derive(Clone, Debug)]
enum Kind {
    /// Weighted normals under Phong facets ([`FastBrdf::phong_normals`]: delta sums, Phong
    /// peaks by nodes): the normals are the plan's; only the per-normal exponent array of the
    /// stream kernel and `ρ/π` are kept here.
    DeltaPhong {
        /// `η` for each of the plan's `count` normals.
        exponents: Vec<f32>,
        diffuse: [f32; 3],
    },
    /// The common material: a Beckmann or GGX NDF under Schlick mirror facets in the microfacet
    /// form with Smith shadowing, in closed form on f32 lanes ([`MicrofacetLobe`]).
    Microfacet(MicrofacetLobe),
    /// Anything else: the core's fast evaluation.
    General,
}

/// One Beckmann / GGX lobe under Schlick mirror facets, microfacet form, height-correlated Smith
/// (the most common material there is), in f32 for the stream kernel:
/// `f = s F(i·h) D(h) / ((1 + Λ(i) + Λ(o)) 4 cos θi cos θo) + ρ/π`, `D` the microfacet
/// distribution (`∫ D (m·z) dω = 1`), `F` Schlick's. GGX `Λ` is exact; Beckmann's takes erfc
/// from Abramowitz & Stegun 7.1.26; `e^x` is [`crate::shader::fast_exp`]. Tested against
/// meso-core's f64 closed form (module tests).
#[derive(Clone, Copy, Debug)]
pub struct MicrofacetLobe {
    ggx: bool,
    /// `1/αx²`, `1/αy²`.
    inv_ax2: f32,
    inv_ay2: f32,
    /// `αx²`, `αy²`.
    ax2: f32,
    ay2: f32,
    /// `1/(π αx αy)`.
    norm: f32,
    /// `s·f0` and `s·(1 − f0)` per channel.
    u: [f32; 3],
    g: [f32; 3],
    /// `ρ/π` per channel.
    diffuse: [f32; 3],
}

impl MicrofacetLobe {
    /// The lobe of a compiled plan when it is the common material (module docs: the plan's
    /// closed-form microfacet BRDF of one lobe, [`FastBrdf::closed_microfacet`], with Schlick or
    /// no Fresnel), else `None`.
    #[must_use]
    pub fn of(plan: &FastBrdf) -> Option<MicrofacetLobe> {
        use meso_core::ndf::Distribution;
        use meso_core::transfer::Fresnel;
        let mf = plan.closed_microfacet()?;
        let material = plan.material();
        let Transfer::Mirror { fresnel, specular } = &material.transfer else {
            return None;
        };
        let f0 = match fresnel {
            Fresnel::Schlick { f0 } => *f0,
            Fresnel::None => [1.0; 3],
            _ => return None,
        };
        if let Distribution::StudentT { .. } = mf.distribution {
            return None; // the f32 lanes have GGX and Beckmann only
        }
        let (ax, ay) = (mf.alpha_x, mf.alpha_y);
        Some(MicrofacetLobe {
            ggx: mf.distribution == Distribution::Ggx,
            inv_ax2: (1.0 / (ax * ax)) as f32,
            inv_ay2: (1.0 / (ay * ay)) as f32,
            ax2: (ax * ax) as f32,
            ay2: (ay * ay) as f32,
            norm: (1.0 / (std::f64::consts::PI * ax * ay)) as f32,
            u: [0, 1, 2].map(|c| (specular[c] * f0[c]) as f32),
            g: [0, 1, 2].map(|c| (specular[c] * (1.0 - f0[c])) as f32),
            diffuse: material
                .diffuse
                .map(|a| (a * std::f64::consts::FRAC_1_PI) as f32),
        })
    }

    /// Smith `Λ` for a direction with `a² = (wx² αx² + wy² αy²)/wz²`.
    #[inline(always)]
    fn lambda<const GGX: bool>(a2: f32) -> f32 {
        if GGX {
            // ½(√(1+a²) − 1) as ½a²/(1 + √(1+a²)): no cancellation near the normal.
            0.5 * a2 / (1.0 + (1.0 + a2).sqrt())
        } else {
            // Λ = ½(e^{−ν²}/(ν√π) − erfc ν), ν = 1/a, with erfc from Abramowitz & Stegun
            // 7.1.26 (absolute error ≤ 1.5e-7) sharing the exponential.
            let nu = 1.0 / a2.max(1e-20).sqrt();
            let e = crate::shader::fast_exp(-nu * nu);
            let t = 1.0 / (1.0 + 0.327_591_1 * nu);
            let poly = t
                * (0.254_829_6
                    + t * (-0.284_496_74 + t * (1.421_413_7 + t * (-1.453_152 + t * 1.061_405_4))));
            (0.5 * e * (1.0 / (nu * 1.772_453_9) - poly)).max(0.0)
        }
    }

    /// The BRDF (1/sr, RGB) at unit local directions; 0 below the surface.
    #[inline]
    #[must_use]
    pub fn eval(&self, i: [f32; 3], o: [f32; 3]) -> [f32; 3] {
        if self.ggx {
            self.eval_impl::<true>(i, o)
        } else {
            self.eval_impl::<false>(i, o)
        }
    }

    #[inline(always)]
    fn eval_impl<const GGX: bool>(&self, i: [f32; 3], o: [f32; 3]) -> [f32; 3] {
        let (iz, oz) = (i[2], o[2]);
        let h = [i[0] + o[0], i[1] + o[1], i[2] + o[2]];
        let l2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
        let inv = 1.0 / l2.max(1e-30).sqrt();
        let (hx, hy, hz) = (h[0] * inv, h[1] * inv, h[2] * inv);
        let c = ((i[0] * hx + i[1] * hy + i[2] * hz).clamp(0.0, 1.0)).max(0.0);
        let hz2 = (hz * hz).max(1e-30);
        let q = hx * hx * self.inv_ax2 + hy * hy * self.inv_ay2;
        let d = if GGX {
            let t = q + hz2;
            self.norm / (t * t)
        } else {
            self.norm * crate::shader::fast_exp(-q / hz2) / (hz2 * hz2)
        };
        let a2i = (i[0] * i[0] * self.ax2 + i[1] * i[1] * self.ay2) / (iz * iz).max(1e-30);
        let a2o = (o[0] * o[0] * self.ax2 + o[1] * o[1] * self.ay2) / (oz * oz).max(1e-30);
        let g2 = 1.0 / (1.0 + Self::lambda::<GGX>(a2i) + Self::lambda::<GGX>(a2o));
        let m = 1.0 - c;
        let m5 = m * m * m * m * m;
        let x = d * g2 / (4.0 * iz * oz).max(1e-30);
        let above = iz > 0.0 && oz > 0.0;
        let k = if above && hz > 0.0 { x } else { 0.0 };
        let dk = if above { 1.0 } else { 0.0 };
        [
            (self.u[0] + self.g[0] * m5) * k + self.diffuse[0] * dk,
            (self.u[1] + self.g[1] * m5) * k + self.diffuse[1] * dk,
            (self.u[2] + self.g[2] * m5) * k + self.diffuse[2] * dk,
        ]
    }

    /// [`MicrofacetLobe::eval`] over pairs of direction arrays (the stream path), compiled for
    /// AVX2 + FMA where the CPU has them.
    pub fn eval_pairs(&self, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        #[cfg(target_arch = "x86_64")]
        {
            if crate::shader::has_avx512() {
                // SAFETY: the CPU supports AVX-512F/VL and FMA (checked above).
                unsafe { microfacet_pairs_avx512(self, wi, wo, out) };
                return;
            }
            if crate::shader::has_avx2_fma() {
                // SAFETY: the CPU supports AVX2 and FMA (checked above).
                unsafe { microfacet_pairs_avx2(self, wi, wo, out) };
                return;
            }
        }
        self.pairs_impl(wi, wo, out);
    }

    #[inline(always)]
    fn pairs_impl(&self, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        if self.ggx {
            self.pairs_mono::<true>(wi, wo, out);
        } else {
            self.pairs_mono::<false>(wi, wo, out);
        }
    }

    #[inline(always)]
    fn pairs_mono<const GGX: bool>(&self, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let [o0, o1, o2] = out;
        let n = o0.len().min(o1.len()).min(o2.len());
        let (ix, iy, iz) = (&wi[0][..n], &wi[1][..n], &wi[2][..n]);
        let (ox, oy, oz) = (&wo[0][..n], &wo[1][..n], &wo[2][..n]);
        for k in 0..n {
            let v = self.eval_impl::<GGX>([ix[k], iy[k], iz[k]], [ox[k], oy[k], oz[k]]);
            o0[k] = v[0];
            o1[k] = v[1];
            o2[k] = v[2];
        }
    }
}

/// [`MicrofacetLobe::eval_pairs`] compiled for AVX-512.
///
/// # Safety
/// The CPU must support AVX-512F, AVX-512VL and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
unsafe fn microfacet_pairs_avx512(
    l: &MicrofacetLobe,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    out: [&mut [f32]; 3],
) {
    l.pairs_impl(wi, wo, out);
}

/// [`MicrofacetLobe::eval_pairs`] compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn microfacet_pairs_avx2(
    l: &MicrofacetLobe,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    out: [&mut [f32]; 3],
) {
    l.pairs_impl(wi, wo, out);
}

/// A meso-core material as a [`Shader`] (see the module docs).
#[derive(Clone, Debug)]
pub struct MaterialShader {
    brdf: FastBrdf,
    kind: Kind,
}

impl MaterialShader {
    /// Compile `material` for rendering (once per material; the result is shared by threads):
    /// meso-core's plan ([`FastBrdf::new`], the interactive policy), and the renderer's f32
    /// kernel for the plans that have one (weighted normals under Phong facets, one Beckmann or
    /// GGX lobe).
    #[must_use]
    pub fn new(material: &Material) -> MaterialShader {
        let brdf = FastBrdf::new(material);
        let kind = if let Some(p) = brdf.phong_normals() {
            Kind::DeltaPhong {
                exponents: vec![p.exponent; p.normals.count],
                diffuse: material
                    .diffuse
                    .map(|a| (a * std::f64::consts::FRAC_1_PI) as f32),
            }
        } else if let Some(l) = MicrofacetLobe::of(&brdf) {
            Kind::Microfacet(l)
        } else {
            Kind::General
        };
        MaterialShader { brdf, kind }
    }

    /// The plan's weighted normals (for [`Kind::DeltaPhong`], built only from a plan that has
    /// them).
    fn phong(&self) -> meso_core::shading::PhongNormals<'_> {
        self.brdf
            .phong_normals()
            .expect("DeltaPhong is built from a plan with weighted normals")
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
            Kind::Microfacet(_) => {
                "one Beckmann/GGX lobe, Schlick mirror facets, Smith: f32 closed-form kernel"
            }
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
            Kind::DeltaPhong { diffuse, .. } => {
                let p = self.phong();
                let Some(h) = half_vector(wi, wo) else {
                    return [0.0; 3];
                };
                let s = p.lobe_sum(
                    [h.x as f32, h.y as f32, h.z as f32],
                    [wi.x as f32, wi.y as f32, wi.z as f32],
                );
                let specular = p.specular;
                [
                    specular[0] * s + diffuse[0],
                    specular[1] * s + diffuse[1],
                    specular[2] * s + diffuse[2],
                ]
            }
            Kind::Microfacet(l) => l.eval(
                [wi.x as f32, wi.y as f32, wi.z as f32],
                [wo.x as f32, wo.y as f32, wo.z as f32],
            ),
            Kind::General => self.brdf.eval(wi, wo).map(|v| v as f32),
        }
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
            Kind::DeltaPhong { exponents, diffuse } => {
                let p = self.phong();
                let (l, n) = (p.normals, p.normals.count);
                let lobes = LobeSlices {
                    nx: &l.nx[..n],
                    ny: &l.ny[..n],
                    nz: &l.nz[..n],
                    weight: &l.w[..n],
                    exponent: exponents,
                };
                lobe_pairs(&lobes, true, wi, wo, o0);
                colour_pairs(o0, o1, o2, p.specular, *diffuse);
            }
            Kind::Microfacet(l) => l.eval_pairs(wi, wo, [o0, o1, o2]),
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

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// The common material's f32 kernel against meso-core's compiled plan (closed-form f64):
    /// GGX and Beckmann within 1e-4 relative (f32 rounding, the erfc approximation),
    /// isotropic and anisotropic, glossy and rough, at 20 000 random pairs with grazing ones.
    #[test]
    fn microfacet_kernel_matches_the_core() {
        let mut rng = 0x9e37_79b9_7f4a_7c15u64;
        let mut uniform = move || {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng >> 11) as f64 / (1u64 << 53) as f64
        };
        for (kind, ax, ay, tol) in [
            ("ggx", 0.05, 0.05, 1e-4),
            ("ggx", 0.3, 0.1, 1e-4),
            ("beckmann", 0.08, 0.08, 1e-4),
            ("beckmann", 0.5, 0.2, 1e-4),
        ] {
            let toml = format!(
                "form = \"microfacet\"\n[ndf]\nkind = \"{kind}\"\nalpha_x = {ax}\nalpha_y = {ay}\n\
                 [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.5, 0.04]\n\
                 specular = [0.8, 0.9, 1.0]\n[diffuse]\nalbedo = [0.1, 0.2, 0.3]\n"
            );
            let m = Material::from_toml_str(&toml).unwrap();
            let shader = MaterialShader::new(&m);
            assert!(
                matches!(shader.kind, Kind::Microfacet(_)),
                "{}",
                shader.path()
            );
            let core = FastBrdf::with_policy(&m, meso_core::shading::Policy::Accurate);
            let mut worst = 0.0f64;
            let (mut wi, mut wo) = ([vec![], vec![], vec![]], [vec![], vec![], vec![]]);
            let mut want = Vec::new();
            for _ in 0..20_000 {
                let mut dir = || {
                    let (u, v) = (uniform(), uniform());
                    let s = (1.0 - u * u).sqrt();
                    DVec3::new(s * (2.0 * PI * v).cos(), s * (2.0 * PI * v).sin(), u)
                };
                let (i, o) = (dir(), dir());
                want.push(core.eval(i, o));
                for c in 0..3 {
                    wi[c].push(i[c] as f32);
                    wo[c].push(o[c] as f32);
                }
            }
            let n = want.len();
            let (mut r, mut g, mut b) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
            shader.eval_pairs(
                [&wi[0], &wi[1], &wi[2]],
                [&wo[0], &wo[1], &wo[2]],
                [&mut r, &mut g, &mut b],
            );
            for k in 0..n {
                let got = [r[k], g[k], b[k]];
                for c in 0..3 {
                    let e = (f64::from(got[c]) - want[k][c]).abs() / want[k][c].max(1e-6);
                    worst = worst.max(e);
                }
            }
            assert!(
                worst < tol,
                "{kind} {ax} {ay}: worst relative error {worst:.2e}"
            );
        }
    }

    /// A Student-t lobe (no f32 lane of its own) is not taken for Beckmann: it goes to the
    /// general path, which matches the core.
    #[test]
    fn a_student_t_lobe_keeps_off_the_microfacet_lane() {
        let m = Material::from_toml_str(
            "form = \"microfacet\"\n[ndf]\nkind = \"student-t\"\ngamma = 3.5\nalpha = 0.2\n\
             [transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.9, 0.5, 0.04]\n",
        )
        .unwrap();
        let shader = MaterialShader::new(&m);
        assert!(
            !matches!(shader.kind, Kind::Microfacet(_)),
            "{}",
            shader.path()
        );
        let core = FastBrdf::with_policy(&m, meso_core::shading::Policy::Accurate);
        for (t, p) in [(10.0f64, 190.0f64), (40.0, 170.0), (70.0, 200.0)] {
            let i = DVec3::new(0.3f64.sin(), 0.0, 0.3f64.cos());
            let (t, p) = (t.to_radians(), p.to_radians());
            let o = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
            let want = core.eval(i, o);
            let (wi, wo) = (
                i.to_array().map(|x| [x as f32]),
                o.to_array().map(|x| [x as f32]),
            );
            let (mut r, mut g, mut b) = ([0.0f32], [0.0f32], [0.0f32]);
            shader.eval_pairs(
                [&wi[0], &wi[1], &wi[2]],
                [&wo[0], &wo[1], &wo[2]],
                [&mut r, &mut g, &mut b],
            );
            let got = [r[0], g[0], b[0]];
            for c in 0..3 {
                let e = (f64::from(got[c]) - want[c]).abs() / want[c].max(1e-6);
                assert!(e < 1e-3, "{got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn fast_exp_is_accurate() {
        for k in -800..=100 {
            let x = k as f32 * 0.1;
            let (got, want) = (crate::shader::fast_exp(x), f64::from(x).exp());
            if want > 1e-36 {
                assert!(
                    ((f64::from(got) - want) / want).abs() < 2e-6 * (1.0 + f64::from(x.abs())),
                    "{x}: {got} vs {want}"
                );
            }
        }
    }
}
