//! Shared by the mixture tests (`mixture.rs`, `student_t.rs`): a mixture of microfacet lobes
//! under a Schlick mirror and Lambert, written as a material file, and its BRDF by the explicit
//! closed form `ρ/π + s F(i·h) D(h) G₂(i, o) / (4 cos θi cos θo)` with Smith's
//! `G₂ = 1/(1 + Λ(i) + Λ(o))`.

use glam::DVec3;
use meso_core::frame::half_vector;
use meso_core::ndf::Mixture;

/// Schlick's `f0` of the material.
pub const F0: [f64; 3] = [0.9, 0.6, 0.3];
/// The mirror's specular scale.
pub const SPECULAR: f64 = 0.8;
/// The Lambert albedo (all channels).
pub const ALBEDO: f64 = 0.05;

/// The material file of a `kind = "mixture"` NDF with `lobes` (TOML inline tables, one a line)
/// under a Schlick mirror with [`F0`], [`SPECULAR`], Smith shadowing and [`ALBEDO`].
pub fn mirror_mixture_toml(lobes: &[&str]) -> String {
    let lobes: String = lobes.iter().map(|l| format!("  {l},\n")).collect();
    format!(
        "form = \"microfacet\"\n[ndf]\nkind = \"mixture\"\nlobes = [\n{lobes}]\n[transfer]\n\
         kind = \"mirror\"\nfresnel = \"schlick\"\nf0 = {F0:?}\n\
         specular = [{SPECULAR:?}, {SPECULAR:?}, {SPECULAR:?}]\n[shadowing]\nkind = \"smith\"\n\
         [diffuse]\nalbedo = [{ALBEDO:?}, {ALBEDO:?}, {ALBEDO:?}]\n"
    )
}

/// The BRDF of [`mirror_mixture_toml`]'s material with NDF `mx` by the explicit formula (module
/// docs), per channel.
pub fn closed_form_brdf(mx: &Mixture, i: DVec3, o: DVec3) -> [f64; 3] {
    let h = half_vector(i, o).unwrap();
    let c = i.dot(h);
    let g2 = 1.0 / (1.0 + mx.lambda(i) + mx.lambda(o));
    [0, 1, 2].map(|k| {
        let fr = F0[k] + (1.0 - F0[k]) * (1.0 - c).powi(5);
        ALBEDO / std::f64::consts::PI + SPECULAR * fr * mx.d(h) * g2 / (4.0 * i.z * o.z)
    })
}
