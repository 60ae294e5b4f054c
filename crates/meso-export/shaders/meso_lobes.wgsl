// meso: the specular BRDF of one texel's K lobes (Phong peaks) — WGSL. Same formula as
// meso_lobes.glsl and the CPU reference meso_export::lobes (docs/export.md, "K lobes in a
// shader").
//
// Texel encoding (lobes{k}_mip{l}.png, RGBA16; read as floats in [0, 1], e.g. value / 65535):
//   RG: octahedral unit axis (tangent frame, z = normal), B: log2(1 + eta) / 20, A: weight.
// Usage, per shading point (wi, wo unit, tangent frame):
//   var s = vec4<f32>(0.0);
//   for (var k = 0u; k < K; k++) { s = meso_lobe_add(textureLoad(lobes, uv, k, lod), wi, wo, s); }
//   let f = meso_lobes_finish(s, wi, wo, f0);   // BRDF in 1/sr; radiance = f * Li * wi.z

const MESO_PI: f32 = 3.14159265358979;
const MESO_ETA_LOG2_RANGE: f32 = 20.0;

fn meso_oct_decode(e: vec2<f32>) -> vec3<f32> {
    var p = e * 2.0 - 1.0;
    let z = 1.0 - abs(p.x) - abs(p.y);
    let t = max(-z, 0.0);
    let sgn = select(vec2<f32>(-1.0), vec2<f32>(1.0), p >= vec2<f32>(0.0));
    p = p - t * sgn;
    return normalize(vec3<f32>(p, z));
}

// A texel in [0, 1]^4 -> (axis.xyz, eta, weight).
struct MesoLobe {
    axis: vec3<f32>,
    eta: f32,
    weight: f32,
}

fn meso_lobe_decode(t: vec4<f32>) -> MesoLobe {
    return MesoLobe(meso_oct_decode(t.xy), exp2(MESO_ETA_LOG2_RANGE * t.z) - 1.0, t.w);
}

// erf by Abramowitz & Stegun 7.1.26 (absolute error <= 1.5e-7).
fn meso_erf(x: f32) -> f32 {
    let a = abs(x);
    let t = 1.0 / (1.0 + 0.3275911 * a);
    let p = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741
              + t * (-1.453152027 + t * 1.061405429))));
    let y = 1.0 - p * exp(-a * a);
    return select(y, -y, x < 0.0);
}

// E[(w.m)+] of one lobe whose axis makes cosine c with w: the clamped mean of a normal variable
// with the lobe's mean and variance of w.m.
fn meso_clamped_cos_mean(c: f32, eta: f32) -> f32 {
    let mc = eta / (eta + 4.0);
    let q = (eta + 4.0) * (eta + 6.0);
    let eu2 = 1.0 - 8.0 * (eta + 2.0) / q;
    let t2 = 4.0 * (eta + 2.0) / q;
    let mu = c * mc;
    let v = max(c * c * (eu2 - mc * mc), 0.0) + max(1.0 - c * c, 0.0) * t2;
    let sigma = sqrt(max(v, 1e-12));
    let z = mu / sigma;
    return mu * 0.5 * (1.0 + meso_erf(z * 0.70710678118654752))
         + sigma * exp(-0.5 * z * z) * 0.39894228040143268;
}

// Add one encoded lobe to the sums (n(h), P(z), P(wi), P(wo)).
fn meso_lobe_add(texel: vec4<f32>, wi: vec3<f32>, wo: vec3<f32>, sums: vec4<f32>) -> vec4<f32> {
    let l = meso_lobe_decode(texel);
    if (l.weight <= 0.0) {
        return sums;
    }
    let h = normalize(wi + wo);
    let x = max(0.5 * (1.0 + dot(l.axis, h)), 0.0);
    let n = l.weight * (l.eta + 2.0) / (8.0 * MESO_PI) * pow(x, 0.5 * l.eta);
    return sums + vec4<f32>(n,
                            l.weight * meso_clamped_cos_mean(l.axis.z, l.eta),
                            l.weight * meso_clamped_cos_mean(dot(l.axis, wi), l.eta),
                            l.weight * meso_clamped_cos_mean(dot(l.axis, wo), l.eta));
}

// The BRDF (1/sr, no cosine) from the sums: Schlick mirror facets, D = n/A, Smith-like G2.
fn meso_lobes_finish(sums: vec4<f32>, wi: vec3<f32>, wo: vec3<f32>, f0: vec3<f32>) -> vec3<f32> {
    let h = normalize(wi + wo);
    if (wi.z <= 0.0 || wo.z <= 0.0 || h.z <= 0.0 || sums.y <= 0.0) {
        return vec3<f32>(0.0);
    }
    let A = sums.y;
    let li = max(sums.z / (A * wi.z) - 1.0, 0.0);
    let lo = max(sums.w / (A * wo.z) - 1.0, 0.0);
    let g2 = 1.0 / (1.0 + li + lo);
    let s = pow(1.0 - clamp(dot(wi, h), 0.0, 1.0), 5.0);
    let c = sums.x / A * g2 / (4.0 * wi.z * wo.z);
    return (f0 + (1.0 - f0) * s) * c;
}
