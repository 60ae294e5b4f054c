//! K lobes in a shader: a pyramid's per-texel Phong peaks packed as textures, and the specular
//! BRDF of one texel's lobes as a CPU reference of exactly the formula of the shipped WGSL and
//! GLSL functions ([`WGSL`], [`GLSL`]).
//!
//! # Encoding (one RGBA16 PNG per lobe slot and level, `lobes{k}_mip{l}.png`)
//! Texel values `t ∈ [0, 1]⁴` (the 16-bit value ÷ 65535), image order (top row first):
//! * **RG** — the unit axis `a`, octahedral over the whole sphere: `p = a.xy / (|a.x|+|a.y|+|a.z|)`,
//!   folded for `a.z < 0` (`p ← (1 − |p.yx|)·sign(p)`), stored as `p·½ + ½`.
//! * **B** — the exponent η on `cos(α/2)`: `b = log2(1 + η) / 20`, so `η = 2^(20 b) − 1`
//!   (η ∈ [0, 2²⁰ − 1]; one 16-bit step is 0.02 % of `1 + η`).
//! * **A** — the lobe's weight (its share of the texel's normals, in `[0, 1]`; the weights of a
//!   texel sum to 1). Slots beyond a texel's lobe count are all zero (weight 0: no contribution).
//!
//! Slot `k` of texel `t` holds the texel's `k`-th lobe in the pyramid's order; `K` is the largest
//! lobe count of any texel of any level.
//!
//! # The BRDF (1/sr, no cosine factor)
//! The texel's NDF is `n(m) = Σ w_k (η_k + 2)/(8π) ((1 + a_k·m)/2)^(η_k/2)` (Eq. 12, exact),
//! its facets are Schlick-Fresnel mirrors (`F0` per channel), in the microfacet form:
//! ```text
//! f(i, o) = F(i·h) · n(h)/A · G₂ / (4 cos θᵢ cos θₒ),   G₂ = 1/(1 + Λ(i) + Λ(o)),
//! A = P(z),   Λ(ω) = max(0, P(ω)/(A ω_z) − 1),   P(ω) = Σ w_k E_k[(ω·m)⁺].
//! ```
//! The exact `A` and `Λ` (meso's [`meso_core::convolution::SmithMasking`]) are integrals; the
//! shader replaces each lobe's clamped-cosine mean `E_k[(ω·m)⁺]` by that of a normal variable with
//! the lobe's exact mean and variance of `x = ω·m`:
//! ```text
//! c = a_k·ω,  μ = c·η/(η+4),  σ² = c²(E[u²] − (η/(η+4))²) + (1 − c²)·4(η+2)/((η+4)(η+6)),
//! E[u²] = 1 − 8(η+2)/((η+4)(η+6)),   E[x⁺] ≈ μΦ(μ/σ) + σφ(μ/σ),
//! ```
//! (`u = a_k·m`; Φ through Abramowitz & Stegun's 7.1.26 `erf`, absolute error ≤ 1.5·10⁻⁷). `n(h)` and `F` are exact, so
//! the only approximation is the normalisation `A` and the masking `G₂`.
//!
//! Measured against meso's exact effective BRDF
//! ([`meso_core::convolution::effective_brdf`], microfacet form, numerical Smith masking, the
//! same decoded lobes as a [`meso_core::ndf::PhongPeaks`] NDF and the same Schlick mirror),
//! θᵢ, θₒ ∈ {0°, 20°, 40°, 60°, 80°} at three relative azimuths, relative error per channel
//! (`cargo test -p meso-export --test lobes -- --nocapture`):
//!
//! | lobes | median | 95th pct. | max |
//! | --- | --- | --- | --- |
//! | 9 synthetic sets, η ∈ [20, 10⁴], axes up to 60° off the normal, 1–3 lobes | 0.12 % | 2.1 % | 3.0 % |
//! | 7 fitted texels (3 lobes, η 17–660) of a rough height map | 0.03 % | 0.95 % | 4.4 % |
//! | broad lobes η = 0 and η = 2 | 16 % | 38 % | 41 % |
//!
//! The large errors of broad lobes come from the masking: the exact `Λ` counts only facets above
//! the horizon (`m_z > 0`), the shader's `P(ω)` also counts the part of a wide lobe below it
//! that faces `ω`, so it overstates `Λ` at grazing angles (η = 2, θ = 80°: 2.7 for 2.0).

use crate::ExportError;
use glam::DVec3;
use meso_maps::Pyramid;
use std::f64::consts::PI;

/// The WGSL functions (`meso_lobe_add`, `meso_lobes_finish`, `meso_lobe_decode`).
pub const WGSL: &str = include_str!("../shaders/meso_lobes.wgsl");
/// The GLSL ES 3.00 functions (same names and formula as [`WGSL`]).
pub const GLSL: &str = include_str!("../shaders/meso_lobes.glsl");
/// The file name the export writes [`WGSL`] under.
pub const WGSL_FILE: &str = "meso_lobes.wgsl";
/// The file name the export writes [`GLSL`] under.
pub const GLSL_FILE: &str = "meso_lobes.glsl";

/// `log2(1 + η)` range of the B channel: `η = 2^(ETA_LOG2_RANGE · b) − 1`.
pub const ETA_LOG2_RANGE: f64 = 20.0;

/// One decoded lobe: unit axis, exponent η, weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lobe {
    /// Unit axis (tangent frame, normal +z).
    pub axis: DVec3,
    /// Exponent η on `cos(α/2)`.
    pub eta: f64,
    /// Weight in `[0, 1]`.
    pub weight: f64,
}

/// Octahedral encoding of a unit vector to `[0, 1]²`.
#[must_use]
pub fn oct_encode(a: DVec3) -> [f64; 2] {
    let s = a.x.abs() + a.y.abs() + a.z.abs();
    let (mut x, mut y) = (a.x / s, a.y / s);
    if a.z < 0.0 {
        let (ox, oy) = (x, y);
        x = (1.0 - oy.abs()) * sign(ox);
        y = (1.0 - ox.abs()) * sign(oy);
    }
    [x * 0.5 + 0.5, y * 0.5 + 0.5]
}

fn sign(v: f64) -> f64 {
    if v >= 0.0 {
        1.0
    } else {
        -1.0
    }
}

/// The unit vector of an octahedral code in `[0, 1]²` (inverse of [`oct_encode`]).
#[must_use]
pub fn oct_decode(e: [f64; 2]) -> DVec3 {
    let (x, y) = (e[0] * 2.0 - 1.0, e[1] * 2.0 - 1.0);
    let z = 1.0 - x.abs() - y.abs();
    let t = (-z).max(0.0);
    let (x, y) = (x - t * sign(x), y - t * sign(y));
    DVec3::new(x, y, z).normalize()
}

/// Encode one lobe as a texel in `[0, 1]⁴` (see the module docs).
#[must_use]
pub fn encode(axis: DVec3, eta: f64, weight: f64) -> [f64; 4] {
    let [r, g] = oct_encode(axis.normalize());
    let b = ((1.0 + eta.max(0.0)).log2() / ETA_LOG2_RANGE).clamp(0.0, 1.0);
    [r, g, b, weight.clamp(0.0, 1.0)]
}

/// Decode a texel in `[0, 1]⁴` (the shaders' `meso_lobe_decode`).
#[must_use]
pub fn decode(t: [f64; 4]) -> Lobe {
    Lobe {
        axis: oct_decode([t[0], t[1]]),
        eta: (ETA_LOG2_RANGE * t[2]).exp2() - 1.0,
        weight: t[3],
    }
}

/// Quantise a texel to 16 bits per channel.
#[must_use]
pub fn to_u16(t: [f64; 4]) -> [u16; 4] {
    t.map(|v| (v * 65535.0).round().clamp(0.0, 65535.0) as u16)
}

/// A 16-bit texel as `[0, 1]⁴` (what a shader reads from a UNORM16 or float texture).
#[must_use]
pub fn from_u16(t: [u16; 4]) -> [f64; 4] {
    t.map(|v| f64::from(v) / 65535.0)
}

/// `erf(x)` by Abramowitz & Stegun 7.1.26 (absolute error ≤ 1.5·10⁻⁷), as in the shaders.
#[must_use]
pub fn erf(x: f64) -> f64 {
    let a = x.abs();
    let t = 1.0 / (1.0 + 0.327_591_1 * a);
    let p = t
        * (0.254_829_592
            + t * (-0.284_496_736
                + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let y = 1.0 - p * (-a * a).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// `E[(ω·m)⁺]` of one lobe (approximation of the module docs), `c = a·ω`: the clamped mean
/// `μΦ(μ/σ) + σφ(μ/σ)` of a normal variable with the lobe's mean and variance of `ω·m`.
#[must_use]
pub fn clamped_cos_mean(c: f64, eta: f64) -> f64 {
    let mc = eta / (eta + 4.0);
    let q = (eta + 4.0) * (eta + 6.0);
    let eu2 = 1.0 - 8.0 * (eta + 2.0) / q;
    let t2 = 4.0 * (eta + 2.0) / q;
    let mu = c * mc;
    let var = (c * c * (eu2 - mc * mc)).max(0.0) + (1.0 - c * c).max(0.0) * t2;
    let sigma = var.max(1e-12).sqrt();
    let z = mu / sigma;
    mu * 0.5 * (1.0 + erf(z * std::f64::consts::FRAC_1_SQRT_2))
        + sigma * (-0.5 * z * z).exp() / (2.0 * PI).sqrt()
}

/// The running sums of one texel's lobes for the pair `(wi, wo)`: `[n(h), P(z), P(wi), P(wo)]`
/// (the shaders' `vec4` accumulator).
#[must_use]
pub fn lobe_add(l: &Lobe, wi: DVec3, wo: DVec3, sums: [f64; 4]) -> [f64; 4] {
    let h = (wi + wo).normalize_or_zero();
    let x = (0.5 * (1.0 + l.axis.dot(h))).max(0.0);
    let n = l.weight * (l.eta + 2.0) / (8.0 * PI) * x.powf(0.5 * l.eta);
    [
        sums[0] + n,
        sums[1] + l.weight * clamped_cos_mean(l.axis.z, l.eta),
        sums[2] + l.weight * clamped_cos_mean(l.axis.dot(wi), l.eta),
        sums[3] + l.weight * clamped_cos_mean(l.axis.dot(wo), l.eta),
    ]
}

/// The BRDF (RGB, 1/sr) from a texel's sums ([`lobe_add`]) with Schlick `f0`; 0 when either
/// direction or the half vector is at or below the horizon.
#[must_use]
pub fn lobes_finish(sums: [f64; 4], wi: DVec3, wo: DVec3, f0: [f64; 3]) -> [f64; 3] {
    let h = (wi + wo).normalize_or_zero();
    if wi.z <= 0.0 || wo.z <= 0.0 || h.z <= 0.0 || sums[1] <= 0.0 {
        return [0.0; 3];
    }
    let a = sums[1];
    let li = (sums[2] / (a * wi.z) - 1.0).max(0.0);
    let lo = (sums[3] / (a * wo.z) - 1.0).max(0.0);
    let g2 = 1.0 / (1.0 + li + lo);
    let s = (1.0 - wi.dot(h).clamp(0.0, 1.0)).powi(5);
    let c = sums[0] / a * g2 / (4.0 * wi.z * wo.z);
    f0.map(|f| (f + (1.0 - f) * s) * c)
}

/// The specular BRDF (RGB, 1/sr) of one texel's encoded lobes (`[0, 1]⁴` each) for unit
/// directions `wi`, `wo` in the tangent frame — the shaders' `meso_lobes_brdf`.
#[must_use]
pub fn eval_texel(texels: &[[f64; 4]], wi: DVec3, wo: DVec3, f0: [f64; 3]) -> [f64; 3] {
    let mut sums = [0.0; 4];
    for t in texels {
        sums = lobe_add(&decode(*t), wi, wo, sums);
    }
    lobes_finish(sums, wi, wo, f0)
}

/// A pyramid's lobes as textures: `levels[l][k]` is lobe slot `k` of level `l`, RGBA16 texels in
/// image order (top row first).
#[derive(Clone, Debug, PartialEq)]
pub struct LobeTextures {
    /// Lobe slots per texel (the largest lobe count in the pyramid).
    pub k: usize,
    /// `(cols, rows)` per level.
    pub sizes: Vec<(usize, usize)>,
    /// `levels[l][k]`: `cols·rows·4` values.
    pub levels: Vec<Vec<Vec<u16>>>,
}

/// File name of lobe slot `k` of level `l`.
#[must_use]
pub fn lobe_png(k: usize, l: usize) -> String {
    format!("lobes{k}_mip{l}.png")
}

/// Pack a pyramid's lobes (see the module docs).
#[must_use]
pub fn pack(pyramid: &Pyramid) -> LobeTextures {
    let k = pyramid
        .levels
        .iter()
        .flat_map(|l| l.lobe_start.windows(2).map(|w| (w[1] - w[0]) as usize))
        .max()
        .unwrap_or(0)
        .max(1);
    let mut levels = Vec::with_capacity(pyramid.levels.len());
    let mut sizes = Vec::with_capacity(pyramid.levels.len());
    for lev in &pyramid.levels {
        let (cols, rows) = (lev.cols, lev.rows);
        let mut slots = vec![vec![0u16; cols * rows * 4]; k];
        for r in 0..rows {
            // Image row of map row r (map row 0 is the image's bottom row).
            let ir = rows - 1 - r;
            for c in 0..cols {
                let t = r * cols + c;
                let (a, b) = (lev.lobe_start[t] as usize, lev.lobe_start[t + 1] as usize);
                for (s, l) in lev.lobes.range(a, b).enumerate() {
                    let q = to_u16(encode(l.axis, l.exponent, l.weight));
                    let o = (ir * cols + c) * 4;
                    slots[s][o..o + 4].copy_from_slice(&q);
                }
            }
        }
        sizes.push((cols, rows));
        levels.push(slots);
    }
    LobeTextures { k, sizes, levels }
}

/// The files of [`LobeTextures`] (name, bytes): one 16-bit RGBA PNG per slot and level, and the
/// two shader files `meso_lobes.wgsl` and `meso_lobes.glsl`.
///
/// # Errors
/// [`ExportError::Invalid`] when a PNG cannot be encoded.
pub fn files(tex: &LobeTextures) -> Result<Vec<(String, Vec<u8>)>, ExportError> {
    use image::ImageEncoder;
    let mut out = Vec::new();
    for (l, slots) in tex.levels.iter().enumerate() {
        let (cols, rows) = tex.sizes[l];
        for (k, data) in slots.iter().enumerate() {
            // The encoder takes 16-bit samples in native byte order (PNG stores them big-endian).
            let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_ne_bytes()).collect();
            let mut png = Vec::new();
            image::codecs::png::PngEncoder::new(&mut png)
                .write_image(
                    &bytes,
                    cols as u32,
                    rows as u32,
                    image::ExtendedColorType::Rgba16,
                )
                .map_err(|e| ExportError::Invalid(format!("lobe PNG: {e}")))?;
            out.push((lobe_png(k, l), png));
        }
    }
    out.push((WGSL_FILE.into(), WGSL.as_bytes().to_vec()));
    out.push((GLSL_FILE.into(), GLSL.as_bytes().to_vec()));
    Ok(out)
}

/// The synthetic lobe sets of the tests and of the browser check (`examples/lobe_cases.rs`),
/// encoded and quantised to 16 bits (values in `[0, 1]`): single lobes on the normal
/// (η from 0 to 10⁴), tilted lobes (30°, 60°), two- and three-lobe mixtures.
#[must_use]
pub fn sample_texels() -> Vec<Vec<[f64; 4]>> {
    let d = |theta: f64, phi: f64| {
        let (t, p) = (theta.to_radians(), phi.to_radians());
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    };
    let q = |a: DVec3, eta: f64, w: f64| from_u16(to_u16(encode(a, eta, w)));
    let mut sets: Vec<Vec<[f64; 4]>> = [0.0, 2.0, 20.0, 200.0, 2000.0, 10000.0]
        .iter()
        .map(|&eta| vec![q(DVec3::Z, eta, 1.0)])
        .collect();
    sets.push(vec![q(d(30.0, 0.0), 50.0, 1.0)]);
    sets.push(vec![q(d(30.0, 200.0), 500.0, 1.0)]);
    sets.push(vec![q(d(60.0, 45.0), 100.0, 1.0)]);
    sets.push(vec![
        q(d(20.0, 0.0), 100.0, 0.6),
        q(d(35.0, 120.0), 30.0, 0.4),
    ]);
    sets.push(vec![
        q(d(40.0, 0.0), 400.0, 0.45),
        q(d(40.0, 180.0), 400.0, 0.45),
        q(DVec3::Z, 5.0, 0.1),
    ]);
    sets
}

/// The `(wi, wo)` pairs of the tests: θ ∈ {0°, 20°, 40°, 60°, 80°} for both, the light at
/// azimuths 0° and 60°, the viewer at 0°, 90° and 180° from it.
#[must_use]
pub fn sample_directions() -> Vec<(DVec3, DVec3)> {
    let d = |theta: f64, phi: f64| {
        let (t, p) = (f64::to_radians(theta), f64::to_radians(phi));
        DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
    };
    let thetas = [0.0, 20.0, 40.0, 60.0, 80.0];
    let mut out = Vec::new();
    for &ti in &thetas {
        for pi in [0.0, 60.0] {
            for &to in &thetas {
                for dp in [0.0, 90.0, 180.0] {
                    out.push((d(ti, pi), d(to, pi + dp)));
                }
            }
        }
    }
    out
}
