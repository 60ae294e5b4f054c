//! Materials as seen by the renderer: the [`Shader`] trait and two built-in shaders.
//!
//! # Contract
//! [`Shader::eval`] returns the BRDF `f(wi, wo)` in **1/sr**, RGB, *without* the cosine
//! factor, for unit directions given in the hit's **local frame** (normal `+z`, tangent `+x`,
//! bitangent `+y`, see `meso_core::frame`), both pointing away from the surface: `wi` towards the
//! light, `wo` towards the viewer. The renderer multiplies by the incident radiance (or
//! irradiance) and by `cos θi = max(0, wi.z)` (the shading normal's cosine).
//!
//! Shaders are shared between threads (`Send + Sync`) and evaluated in the per-pixel inner
//! loop: they must not allocate.

use crate::geometry::{MaterialId, ShadingPoint};
use glam::{DVec2, DVec3};
pub use meso_core::fastmath::{fast_exp, fast_pow};
use meso_core::fastmath::{fast_pow_impl, madd};
use meso_core::frame::{half_vector, Frame};
use std::f64::consts::FRAC_1_PI;

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

/// A material the renderer can shade with. See the module docs for the contract.
pub trait Shader: Send + Sync {
    /// BRDF value (1/sr, no cosine) for local unit directions `wi` (to the light) and `wo`
    /// (to the viewer) at the shading point `sp`.
    fn eval(&self, sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3];

    /// Evaluate several incident directions at once: `out[k] = eval(sp, wi[k], wo)`
    /// (`wi.len() == out.len()`, at most [`crate::render::LIGHT_BATCH`]). The renderer calls
    /// this once per hit and batch of light samples, so a material that must do per-point work
    /// first (e.g. fetch and blend the lobes of an NDF pyramid at the footprint's level) can do
    /// it once per point. The default calls [`Shader::eval`] for each direction.
    #[inline]
    fn eval_many(&self, sp: &ShadingPoint, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        for (o, &w) in out.iter_mut().zip(wi) {
            *o = self.eval(sp, w, wo);
        }
    }

    /// Whether the shader reads the [`ShadingPoint`]'s surface parameters and footprint
    /// (`uv`, `dpdu`, `dpdv`, `dpdx`, `dpdy`, `duvdx`, `duvdy`). Shaders that only use the
    /// local directions (and the frame, position or material) return `false`; when every
    /// material of a scene does, [`crate::render()`] skips the ray differentials and the
    /// sphere's texture coordinates, leaving those fields zero. The default, `true` unless the
    /// shader is [`Shader::direction_only`] (which reads no [`ShadingPoint`] at all), is always
    /// correct.
    #[inline]
    fn needs_surface_parameters(&self) -> bool {
        !self.direction_only()
    }

    /// Whether the data this shader read while shading was sound: `Err` (naming the file) when
    /// a file it reads as it goes (a map file's level 0 held by band,
    /// [`meso_maps::Pyramid::check_mapped`]) changed in place while in use, so that some
    /// values it shaded with were not the file's. Checked by the renderer's callers before
    /// anything is written ([`crate::Scene::check_sources`]). Default: `Ok` (nothing read as it
    /// goes).
    ///
    /// # Errors
    /// The reader's message, naming the file.
    fn check_sources(&self) -> Result<(), String> {
        Ok(())
    }

    /// The weight of a pixel sample that hit this material at `sp`, seen from the local unit
    /// direction `wo`, in its pixel's average (the renderer averages `Σ w·L / Σ w` over a
    /// pixel's samples): the area of the surface the sample stands for as the viewer sees it,
    /// relative to the plain surface's. Default 1 (every sample alike: the plain average). A
    /// bump map weighted by view ([`crate::BumpMapped::with_view_weighting`]) returns its
    /// facet's `(m·o)⁺/(m_z·o_z)` times the facet's visibility of the viewer, as displaced
    /// geometry would show it.
    #[inline]
    fn sample_weight(&self, _sp: &ShadingPoint, _wo: DVec3) -> f64 {
        1.0
    }

    /// One line that says how the material shades, for a user reading `meso render`'s output
    /// or the editor's preview (e.g. an NDF-mapped texture's levels, filter and visibility);
    /// `None` (the default) for materials with nothing to say beyond their file.
    fn describe(&self) -> Option<String> {
        None
    }

    /// Whether the BRDF depends on the local directions `wi`, `wo` only (not on the
    /// [`ShadingPoint`]: no position, frame, texture coordinates or footprint). The renderer
    /// then shades whole tiles light by light through [`Shader::eval_pairs`] (its fast path).
    /// The default, `false`, is always correct.
    #[inline]
    fn direction_only(&self) -> bool {
        false
    }

    /// The BRDF (1/sr, no cosine) for `n` pairs of unit local directions in structure-of-arrays
    /// form: `out[c][k] = eval(wi_k, wo_k)[c]` with `wi_k = (wi[0][k], wi[1][k], wi[2][k])`
    /// (towards the light) and `wo_k` likewise (towards the viewer); every slice has length
    /// `n`. Called by the renderer only for shaders that are [`Shader::direction_only`]. The
    /// default evaluates [`Shader::eval`] pair by pair at a dummy shading point; lobe shaders
    /// override it with a kernel that runs across pairs, eight at a time.
    fn eval_pairs(&self, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let sp = local_point(DVec2::ZERO, 0.0);
        pairs_one_by_one(wi, wo, out, |i, o| self.eval(&sp, i, o));
    }
}

/// A Lambertian (perfectly diffuse) reflector: `f = albedo / π`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lambert {
    /// Hemispherical reflectance per channel, in `[0, 1]` for energy conservation.
    pub albedo: [f32; 3],
}

impl Shader for Lambert {
    #[inline]
    fn eval(&self, _sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let k = FRAC_1_PI as f32;
        [self.albedo[0] * k, self.albedo[1] * k, self.albedo[2] * k]
    }

    #[inline]
    fn direction_only(&self) -> bool {
        true
    }
}

/// The number of lanes of [`PhongLobes`]: up to 8 lobes, evaluated as one flat f32 array.
pub const PHONG_LANES: usize = 8;
// The lane reduction in `sum_at_portable` is written out for eight lanes.
const _: () = assert!(PHONG_LANES == 8);

/// A multiple surface in the paper's shading form (§4, after \[Dret90\]): a sum of Phong terms,
/// one per normal,
/// `f(wi, wo) = Σ_k w_k · max(0, n_k · H)^{η_k}` (1/sr), `H = (wi + wo)/|wi + wo|`,
/// with the lobe normals `n_k` in the local frame. Stored as a structure of arrays of
/// [`PHONG_LANES`] f32 lanes (unused lanes have weight 0), so the loop over lobes is flat,
/// branch-free and vectorised by the compiler; the power uses [`fast_pow`] (relative error
/// about `1.5e-7·(1 + |η log2(n·H)|)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongLobes {
    nx: [f32; PHONG_LANES],
    ny: [f32; PHONG_LANES],
    nz: [f32; PHONG_LANES],
    weight: [f32; PHONG_LANES],
    exponent: [f32; PHONG_LANES],
    /// RGB colour multiplying the sum.
    pub color: [f32; 3],
    count: usize,
    /// AVX2 + FMA detected at construction (x86-64): use the 8-wide kernel.
    avx2: bool,
}

impl PhongLobes {
    /// Build from `(unit local normal, weight in 1/sr, exponent η ≥ 0)` triples; returns `None`
    /// when there are more than [`PHONG_LANES`] lobes or a value is not finite / negative.
    #[must_use]
    pub fn new(lobes: &[(DVec3, f64, f64)], color: [f32; 3]) -> Option<PhongLobes> {
        if lobes.len() > PHONG_LANES {
            return None;
        }
        let mut s = PhongLobes {
            nx: [0.0; PHONG_LANES],
            ny: [0.0; PHONG_LANES],
            nz: [1.0; PHONG_LANES],
            weight: [0.0; PHONG_LANES],
            exponent: [1.0; PHONG_LANES],
            color,
            count: lobes.len(),
            avx2: detect_avx2(),
        };
        for (k, &(n, w, e)) in lobes.iter().enumerate() {
            if !(n.is_finite()
                && n.length() > 0.0
                && w.is_finite()
                && w >= 0.0
                && e.is_finite()
                && e >= 0.0)
            {
                return None;
            }
            let n = n.normalize();
            s.nx[k] = n.x as f32;
            s.ny[k] = n.y as f32;
            s.nz[k] = n.z as f32;
            s.weight[k] = w as f32;
            s.exponent[k] = e as f32;
        }
        Some(s)
    }

    /// Number of lobes in use.
    #[must_use]
    pub fn len(&self) -> usize {
        self.count
    }

    /// True when no lobe is in use.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// `Σ_k w_k max(0, n_k·h)^{η_k}` for a unit local half vector `h` (f32 kernel; 8-wide
    /// AVX2/FMA code when the CPU has it, SSE2 otherwise).
    #[inline]
    #[must_use]
    pub fn sum_at(&self, h: [f32; 3]) -> f32 {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the running CPU supports AVX2 and FMA.
            return unsafe { sum_at_avx2(self, h) };
        }
        self.sum_at_portable(h)
    }

    #[inline(always)]
    fn sum_at_portable(&self, h: [f32; 3]) -> f32 {
        self.sum_at_impl::<false>(h)
    }

    /// The lane kernel; `FMA` fuses the multiply-adds (only where the CPU has FMA: without
    /// it `mul_add` would be a library call).
    #[inline(always)]
    fn sum_at_impl<const FMA: bool>(&self, h: [f32; 3]) -> f32 {
        let mut acc = [0.0f32; PHONG_LANES];
        // Indexed loop over the lanes of the SoA arrays: vectorised as written.
        #[allow(clippy::needless_range_loop)]
        for k in 0..PHONG_LANES {
            let c = madd::<FMA>(
                self.nx[k],
                h[0],
                madd::<FMA>(self.ny[k], h[1], self.nz[k] * h[2]),
            )
            .max(0.0);
            acc[k] = self.weight[k] * fast_pow_impl::<FMA>(c, self.exponent[k]);
        }
        // Pairwise (tree) reduction: three vector add steps instead of a serial chain.
        let a4 = [
            acc[0] + acc[4],
            acc[1] + acc[5],
            acc[2] + acc[6],
            acc[3] + acc[7],
        ];
        let a2 = [a4[0] + a4[2], a4[1] + a4[3]];
        a2[0] + a2[1]
    }
}

impl Shader for PhongLobes {
    #[inline]
    fn eval(&self, _sp: &ShadingPoint, wi: DVec3, wo: DVec3) -> [f32; 3] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        let Some(h) = half_vector(wi, wo) else {
            return [0.0; 3];
        };
        let s = self.sum_at([h.x as f32, h.y as f32, h.z as f32]);
        [self.color[0] * s, self.color[1] * s, self.color[2] * s]
    }

    /// All light directions at once: the half vectors are formed in f32 and the lobe kernel
    /// runs for each direction over its [`PHONG_LANES`] lanes, the whole loop inside one AVX2
    /// region (no call per light). Same values as [`PhongLobes::eval`] up to the f32
    /// rounding of `H`.
    #[inline]
    fn eval_many(&self, _sp: &ShadingPoint, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        #[cfg(target_arch = "x86_64")]
        if self.avx2 {
            // SAFETY: `avx2` is set only when the running CPU supports AVX2 and FMA.
            unsafe { eval_many_avx2(self, wo, wi, out) };
            return;
        }
        self.eval_many_portable(wo, wi, out);
    }

    #[inline]
    fn direction_only(&self) -> bool {
        true
    }

    /// The lobe kernel across pairs ([`lobe_pairs`]), then the colour.
    fn eval_pairs(&self, wi: [&[f32]; 3], wo: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let n = self.count;
        let lobes = LobeSlices {
            nx: &self.nx[..n],
            ny: &self.ny[..n],
            nz: &self.nz[..n],
            weight: &self.weight[..n],
            exponent: &self.exponent[..n],
        };
        let [o0, o1, o2] = out;
        lobe_pairs(&lobes, false, wi, wo, o0);
        colour_pairs(o0, o1, o2, self.color, [0.0; 3]);
    }
}

impl PhongLobes {
    #[inline(always)]
    fn eval_many_portable(&self, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        self.eval_many_impl::<false>(wo, wi, out);
    }

    #[inline(always)]
    fn eval_many_impl<const FMA: bool>(&self, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
        let wo32 = [wo.x as f32, wo.y as f32, wo.z as f32];
        let up = wo.z > 0.0;
        for (o, w) in out.iter_mut().zip(wi) {
            let h = [
                w.x as f32 + wo32[0],
                w.y as f32 + wo32[1],
                w.z as f32 + wo32[2],
            ];
            let l2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
            let s = if up && w.z > 0.0 && l2 >= 1e-24 {
                let r = 1.0 / l2.sqrt();
                self.sum_at_impl::<FMA>([h[0] * r, h[1] * r, h[2] * r])
            } else {
                0.0
            };
            *o = [self.color[0] * s, self.color[1] * s, self.color[2] * s];
        }
    }
}

/// Fill `out` (structure of arrays, as [`Shader::eval_pairs`]) by calling `f(wi, wo)` for each
/// pair of directions, widened to f64.
pub(crate) fn pairs_one_by_one(
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    out: [&mut [f32]; 3],
    mut f: impl FnMut(DVec3, DVec3) -> [f32; 3],
) {
    let [o0, o1, o2] = out;
    for k in 0..o0.len() {
        let d =
            |v: [&[f32]; 3]| DVec3::new(f64::from(v[0][k]), f64::from(v[1][k]), f64::from(v[2][k]));
        let v = f(d(wi), d(wo));
        o0[k] = v[0];
        o1[k] = v[1];
        o2[k] = v[2];
    }
}

/// Phong lobes `(n_k, w_k, η_k)` as parallel slices (local frame; weight in 1/sr), the input
/// of [`lobe_pairs`].
#[derive(Clone, Copy, Debug)]
pub struct LobeSlices<'a> {
    /// x components of the unit lobe normals.
    pub nx: &'a [f32],
    /// y components.
    pub ny: &'a [f32],
    /// z components.
    pub nz: &'a [f32],
    /// Weights `w_k`.
    pub weight: &'a [f32],
    /// Exponents `η_k ≥ 0`.
    pub exponent: &'a [f32],
}

/// Pairs processed together by [`lobe_pairs`] (one AVX register of f32; two with AVX-512).
const PAIR_LANES: usize = 8;

/// The lobe sum for many direction pairs at once (the renderer's stream-shading kernel):
/// `sum[k] = Σ_j w_j max(0, n_j·H_k)^{η_j}` with `H_k` the unit half vector of `wi_k`, `wo_k`
/// (local frame), or, with `cosine`, the multiple-surface form of Eq. 4/11,
/// `Σ_j w_j max(0, n_j·H_k)^{η_j} max(0, n_j·wi_k) / wi_k.z`. Pairs with either direction
/// below the horizon (or `wi = −wo`) get `−1` as a marker (see [`colour_pairs`]). Pairs run
/// across 8 (AVX2) or 16 (AVX-512) f32 lanes, lobes in the inner loop; AVX2 + FMA when the CPU has it.
/// The power is [`fast_pow`]. `sum.len()` is the number of pairs.
pub fn lobe_pairs(
    lobes: &LobeSlices<'_>,
    cosine: bool,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    sum: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::arch::is_x86_feature_detected!("avx512f")
            && std::arch::is_x86_feature_detected!("avx512vl")
            && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the running CPU supports AVX-512F/VL and FMA (checked just above).
            unsafe { lobe_pairs_avx512(lobes, cosine, wi, wo, sum) };
            return;
        }
        if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
        {
            // SAFETY: the running CPU supports AVX2 and FMA (checked just above).
            unsafe { lobe_pairs_avx2(lobes, cosine, wi, wo, sum) };
            return;
        }
    }
    lobe_pairs_impl::<false, PAIR_LANES>(lobes, cosine, wi, wo, sum);
}

/// [`lobe_pairs`] compiled for AVX2 + FMA (8 pairs per step).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn lobe_pairs_avx2(
    lobes: &LobeSlices<'_>,
    cosine: bool,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    sum: &mut [f32],
) {
    lobe_pairs_impl::<true, PAIR_LANES>(lobes, cosine, wi, wo, sum);
}

/// [`lobe_pairs`] compiled for AVX-512 (16 pairs per step, one zmm register).
///
/// # Safety
/// The CPU must support AVX-512F, AVX-512VL, AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512vl,avx2,fma")]
unsafe fn lobe_pairs_avx512(
    lobes: &LobeSlices<'_>,
    cosine: bool,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    sum: &mut [f32],
) {
    lobe_pairs_impl::<true, { 2 * PAIR_LANES }>(lobes, cosine, wi, wo, sum);
}

#[inline(always)]
fn lobe_pairs_impl<const FMA: bool, const L: usize>(
    lobes: &LobeSlices<'_>,
    cosine: bool,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    sum: &mut [f32],
) {
    if cosine {
        lobe_pairs_form::<FMA, true, L>(lobes, wi, wo, sum);
    } else {
        lobe_pairs_form::<FMA, false, L>(lobes, wi, wo, sum);
    }
}

/// One step's direction pairs: `[x, y, z]` × `L` lanes.
type Octet<const L: usize> = [[f32; L]; 3];

/// Copy pairs `base..base + m` into a step; lanes past the end get a below-horizon pair.
#[inline(always)]
fn load_octet<const L: usize>(v: [&[f32]; 3], base: usize, m: usize, out: &mut Octet<L>) {
    if m == L {
        for c in 0..3 {
            out[c].copy_from_slice(&v[c][base..base + L]);
        }
    } else {
        *out = [[0.0; L], [0.0; L], [-1.0; L]];
        for c in 0..3 {
            out[c][..m].copy_from_slice(&v[c][base..base + m]);
        }
    }
}

#[inline(always)]
fn lobe_pairs_form<const FMA: bool, const COS: bool, const L: usize>(
    lobes: &LobeSlices<'_>,
    wi: [&[f32]; 3],
    wo: [&[f32]; 3],
    sum: &mut [f32],
) {
    let n = sum.len();
    let count = lobes
        .weight
        .len()
        .min(lobes.nx.len())
        .min(lobes.ny.len())
        .min(lobes.nz.len())
        .min(lobes.exponent.len());
    let (nx, ny, nz) = (&lobes.nx[..count], &lobes.ny[..count], &lobes.nz[..count]);
    let (lw, le) = (&lobes.weight[..count], &lobes.exponent[..count]);
    let mut base = 0;
    let mut i: Octet<L> = [[0.0; L]; 3];
    let mut o: Octet<L> = [[0.0; L]; 3];
    while base < n {
        let m = (n - base).min(L);
        load_octet(wi, base, m, &mut i);
        load_octet(wo, base, m, &mut o);
        let mut h: Octet<L> = [[0.0; L]; 3];
        let mut valid = [0.0f32; L];
        for j in 0..L {
            let hx = i[0][j] + o[0][j];
            let hy = i[1][j] + o[1][j];
            let hz = i[2][j] + o[2][j];
            let l2 = hx * hx + hy * hy + hz * hz;
            let ok = i[2][j] > 0.0 && o[2][j] > 0.0 && l2 >= 1e-24;
            valid[j] = if ok { 1.0 } else { 0.0 };
            let r = 1.0 / l2.max(1e-24).sqrt();
            h[0][j] = hx * r;
            h[1][j] = hy * r;
            h[2][j] = hz * r;
        }
        let mut acc = [0.0f32; L];
        for q in 0..count {
            let (ax, ay, az, w, e) = (nx[q], ny[q], nz[q], lw[q], le[q]);
            for j in 0..L {
                let c = madd::<FMA>(ax, h[0][j], madd::<FMA>(ay, h[1][j], az * h[2][j])).max(0.0);
                let mut t = w * fast_pow_impl::<FMA>(c, e);
                if COS {
                    t *= madd::<FMA>(ax, i[0][j], madd::<FMA>(ay, i[1][j], az * i[2][j])).max(0.0);
                }
                acc[j] += t;
            }
        }
        let mut res = [0.0f32; L];
        for j in 0..L {
            let s = if COS {
                acc[j] / i[2][j].max(1e-30)
            } else {
                acc[j]
            };
            // The marker −1 where the pair is invalid (a select, not a branch).
            res[j] = if valid[j] > 0.5 { s } else { -1.0 };
        }
        sum[base..base + m].copy_from_slice(&res[..m]);
        base += L;
    }
}

/// Turn lobe sums from [`lobe_pairs`] into RGB in place: `out_c = specular_c · s + diffuse_c`
/// where `s ≥ 0`, and 0 on every channel where `s` is the below-horizon marker (`< 0`).
/// `s` is read from (and channel 0 written to) `s_r`.
pub fn colour_pairs(
    s_r: &mut [f32],
    g: &mut [f32],
    b: &mut [f32],
    specular: [f32; 3],
    diffuse: [f32; 3],
) {
    for ((r, g), b) in s_r.iter_mut().zip(g.iter_mut()).zip(b.iter_mut()) {
        let s = *r;
        let ok = s >= 0.0;
        *r = if ok {
            specular[0] * s + diffuse[0]
        } else {
            0.0
        };
        *g = if ok {
            specular[1] * s + diffuse[1]
        } else {
            0.0
        };
        *b = if ok {
            specular[2] * s + diffuse[2]
        } else {
            0.0
        };
    }
}

/// Whether the CPU has AVX-512F, AVX-512VL and FMA (detected once).
#[must_use]
pub(crate) fn has_avx512() -> bool {
    static HAS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *HAS.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        {
            std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("fma")
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            false
        }
    })
}

/// Whether the CPU has AVX2 and FMA (detected once).
#[must_use]
pub(crate) fn has_avx2_fma() -> bool {
    static HAS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *HAS.get_or_init(detect_avx2)
}

fn detect_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The lobe sum compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn sum_at_avx2(l: &PhongLobes, h: [f32; 3]) -> f32 {
    l.sum_at_impl::<true>(h)
}

/// [`PhongLobes`]' `eval_many` compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn eval_many_avx2(l: &PhongLobes, wo: DVec3, wi: &[DVec3], out: &mut [[f32; 3]]) {
    l.eval_many_impl::<true>(wo, wi, out);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn phong_lobes_sum_matches_scalar_formula() {
        let lobes = [
            (DVec3::new(0.2, 0.1, 1.0).normalize(), 0.3, 20.0),
            (DVec3::new(-0.4, 0.0, 1.0).normalize(), 0.5, 5.0),
            (DVec3::new(0.0, 0.7, 0.7).normalize(), 0.2, 60.0),
        ];
        let s = PhongLobes::new(&lobes, [1.0, 0.5, 0.25]).unwrap();
        assert_eq!(s.len(), 3);
        let wi = DVec3::new(0.3, -0.2, 0.9).normalize();
        let wo = DVec3::new(-0.1, 0.4, 0.8).normalize();
        let h = (wi + wo).normalize();
        let expect: f64 = lobes
            .iter()
            .map(|(n, w, e)| w * n.dot(h).max(0.0).powf(*e))
            .sum();
        let sp = crate::geometry::tests_support::dummy_point();
        let got = s.eval(&sp, wi, wo);
        assert!((f64::from(got[0]) - expect).abs() < 1e-5 * expect.max(1e-3));
        assert!((f64::from(got[2]) - 0.25 * expect).abs() < 1e-5 * expect.max(1e-3));
        // The batched form agrees with one-at-a-time evaluation, including directions below
        // the horizon and more directions than one batch.
        let wis: Vec<DVec3> = (0..37)
            .map(|k| {
                let a = 0.37 * f64::from(k);
                DVec3::new(a.cos(), a.sin(), 0.9 - 0.05 * f64::from(k)).normalize()
            })
            .collect();
        let mut many = vec![[0.0f32; 3]; wis.len()];
        s.eval_many(&sp, wo, &wis, &mut many);
        for (w, m) in wis.iter().zip(&many) {
            let one = s.eval(&sp, *w, wo);
            for c in 0..3 {
                assert!(
                    (m[c] - one[c]).abs() <= 1e-4 * one[c].max(1e-3),
                    "{m:?} vs {one:?}"
                );
            }
        }
        assert!(many.iter().any(|m| m[0] > 0.0) && many.iter().any(|m| m[0] == 0.0));
        let mut below = [[1.0f32; 3]; 1];
        s.eval_many(&sp, DVec3::new(0.0, 0.6, -0.8), &wis[..1], &mut below);
        assert_eq!(below[0], [0.0; 3]);
        assert!(!s.needs_surface_parameters());
        assert!(PhongLobes::new(&[(DVec3::Z, 1.0, 1.0); 9], [1.0; 3]).is_none());
        assert!(PhongLobes::new(&[(DVec3::Z, -1.0, 1.0)], [1.0; 3]).is_none());
    }
}
