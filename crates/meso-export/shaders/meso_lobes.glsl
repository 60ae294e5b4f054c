// meso: the specular BRDF of one texel's K lobes (Phong peaks) — GLSL ES 3.00 (WebGL 2) and
// GLSL 3.30+. Same formula as meso_lobes.wgsl and the CPU reference meso_export::lobes
// (docs/export.md, "K lobes in a shader"). Include after your `#version` and `precision` lines.
//
// Texel encoding (lobes{k}_mip{l}.png, RGBA16; read as floats in [0, 1], e.g. value / 65535):
//   RG: octahedral unit axis (tangent frame, z = normal), B: log2(1 + eta) / 20, A: weight.
// Usage, per shading point (wi, wo unit, tangent frame):
//   vec4 s = vec4(0.0);
//   for (int k = 0; k < K; k++) s = meso_lobe_add(texelFetch(lobes[k], uv, lod), wi, wo, s);
//   vec3 f = meso_lobes_finish(s, wi, wo, f0);   // BRDF in 1/sr; radiance = f * Li * wi.z

const float MESO_PI = 3.14159265358979;
const float MESO_ETA_LOG2_RANGE = 20.0;

vec3 meso_oct_decode(vec2 e) {
    vec2 p = e * 2.0 - 1.0;
    float z = 1.0 - abs(p.x) - abs(p.y);
    float t = max(-z, 0.0);
    vec2 sgn = vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    p -= t * sgn;
    return normalize(vec3(p, z));
}

// A texel in [0, 1]^4 -> (axis.xyz, eta) and the weight in `weight`.
vec4 meso_lobe_decode(vec4 t, out float weight) {
    weight = t.a;
    return vec4(meso_oct_decode(t.rg), exp2(MESO_ETA_LOG2_RANGE * t.b) - 1.0);
}

// erf by Abramowitz & Stegun 7.1.26 (absolute error <= 1.5e-7).
float meso_erf(float x) {
    float a = abs(x);
    float t = 1.0 / (1.0 + 0.3275911 * a);
    float p = t * (0.254829592 + t * (-0.284496736 + t * (1.421413741
              + t * (-1.453152027 + t * 1.061405429))));
    float y = 1.0 - p * exp(-a * a);
    return x < 0.0 ? -y : y;
}

// E[(w.m)+] of one lobe whose axis makes cosine c with w: the clamped mean of a normal variable
// with the lobe's mean and variance of w.m.
float meso_clamped_cos_mean(float c, float eta) {
    float mc = eta / (eta + 4.0);
    float q = (eta + 4.0) * (eta + 6.0);
    float eu2 = 1.0 - 8.0 * (eta + 2.0) / q;
    float t2 = 4.0 * (eta + 2.0) / q;
    float mu = c * mc;
    float v = max(c * c * (eu2 - mc * mc), 0.0) + max(1.0 - c * c, 0.0) * t2;
    float sigma = sqrt(max(v, 1e-12));
    float z = mu / sigma;
    return mu * 0.5 * (1.0 + meso_erf(z * 0.70710678118654752))
         + sigma * exp(-0.5 * z * z) * 0.39894228040143268;
}

// Add one encoded lobe to the sums (n(h), P(z), P(wi), P(wo)).
vec4 meso_lobe_add(vec4 texel, vec3 wi, vec3 wo, vec4 sums) {
    float w;
    vec4 l = meso_lobe_decode(texel, w);
    if (w <= 0.0) return sums;
    vec3 a = l.xyz;
    float eta = l.w;
    vec3 h = normalize(wi + wo);
    float x = max(0.5 * (1.0 + dot(a, h)), 0.0);
    float n = w * (eta + 2.0) / (8.0 * MESO_PI) * pow(x, 0.5 * eta);
    return sums + vec4(n,
                       w * meso_clamped_cos_mean(a.z, eta),
                       w * meso_clamped_cos_mean(dot(a, wi), eta),
                       w * meso_clamped_cos_mean(dot(a, wo), eta));
}

// The BRDF (1/sr, no cosine) from the sums: Schlick mirror facets, D = n/A, Smith-like G2.
vec3 meso_lobes_finish(vec4 sums, vec3 wi, vec3 wo, vec3 f0) {
    vec3 h = normalize(wi + wo);
    if (wi.z <= 0.0 || wo.z <= 0.0 || h.z <= 0.0 || sums.y <= 0.0) return vec3(0.0);
    float A = sums.y;
    float li = max(sums.z / (A * wi.z) - 1.0, 0.0);
    float lo = max(sums.w / (A * wo.z) - 1.0, 0.0);
    float g2 = 1.0 / (1.0 + li + lo);
    float s = pow(1.0 - clamp(dot(wi, h), 0.0, 1.0), 5.0);
    float c = sums.x / A * g2 / (4.0 * wi.z * wo.z);
    return (f0 + (1.0 - f0) * s) * c;
}
