//! Fittable BRDF models: the paper's lobe sums with the Phong transfer ([`lobes`]) and with the
//! microfacet transfer ([`lobes_microfacet`]), mixtures of GGX / Beckmann lobes with the
//! microfacet transfer ([`lobes_ggx`]), and the baselines ([`baselines`](mod@baselines)).
pub mod baselines;
pub mod lobes;
pub mod lobes_ggx;
pub mod lobes_microfacet;
pub mod vmf;

pub use baselines::{AshikhminShirley, BlinnPhong, Lafortune, Microfacet, MicrofacetKind};
pub use lobes::{
    fit_lobes_progressive, lobe_sum_closed_form, LobeModel, LobeParams, TransferExponent,
};
pub use lobes_ggx::{fit_ggx_lobes_progressive, GgxLobe, LobeGgxModel, LobeGgxParams};
pub use lobes_microfacet::{
    fit_microfacet_lobes_progressive, microfacet_lobes_fast, LobeMicrofacetModel,
    LobeMicrofacetParams,
};

use crate::fit::BrdfModel;
use glam::DVec3;
use meso_core::convolution::{Accuracy, Form};
use meso_core::material::{MaterialSpec, NdfSpec, ShadowingKind};
use meso_core::ndf::Ndf;
use meso_core::transfer::{Fresnel, Transfer};
use meso_core::NdfError;

/// All baseline models in the order of the benchmark table: Blinn-Phong, Cook-Torrance (Beckmann),
/// GGX, Ashikhmin–Shirley, Lafortune with 1, 2, 3 lobes.
#[must_use]
pub fn baselines() -> Vec<Box<dyn BrdfModel>> {
    vec![
        Box::new(BlinnPhong),
        Box::new(Microfacet::COOK_TORRANCE),
        Box::new(Microfacet::GGX),
        Box::new(AshikhminShirley),
        Box::new(Lafortune::new(1)),
        Box::new(Lafortune::new(2)),
        Box::new(Lafortune::new(3)),
    ]
}

/// The fitted microfacet material of `ndf`: `form = "microfacet"`, mirror facets with Schlick
/// Fresnel `f0` and the `specular` scale, Smith masking–shadowing and a Lambert `albedo`, each
/// colour clamped to `[0, 1]` — what every fitted microfacet material shares (Phong-peak lobes,
/// GGX lobes, the non-parametric NDF). Written by [`MaterialSpec::to_toml`].
#[must_use]
pub fn mirror_material(
    ndf: Ndf,
    f0: [f64; 3],
    specular: [f64; 3],
    albedo: [f64; 3],
) -> MaterialSpec {
    let c = |v: [f64; 3]| v.map(|x| x.clamp(0.0, 1.0));
    MaterialSpec {
        name: None,
        ndf: NdfSpec::Inline(ndf),
        transfer: Transfer::Mirror {
            fresnel: Fresnel::Schlick { f0: c(f0) },
            specular: c(specular),
        },
        diffuse: c(albedo),
        form: Some(Form::Microfacet),
        shadowing: Some(ShadowingKind::Smith),
        accuracy: Accuracy::default(),
    }
}

/// Schlick's weight `(1 − cos)⁵` (the cosine clamped to `[0, 1]`): `F = f0 + (1 − f0)·m5`.
#[inline]
#[must_use]
pub(crate) fn schlick_m5(cos: f64) -> f64 {
    (1.0 - cos).clamp(0.0, 1.0).powi(5)
}

/// The BRDF (1/sr) per channel of a [`mirror_material`] above the horizon:
/// `albedo/π + X·specular·F(cos)` for the mirror's specular factor `X` and cosine `i·h` in
/// `s` (`None`: no specular term).
#[must_use]
pub(crate) fn mirror_brdf(
    s: Option<(f64, f64)>,
    f0: [f64; 3],
    specular: [f64; 3],
    albedo: [f64; 3],
) -> [f64; 3] {
    [0, 1, 2].map(|c| {
        let spec = s.map_or(0.0, |(x, cos)| {
            x * specular[c] * (f0[c] + (1.0 - f0[c]) * schlick_m5(cos))
        });
        albedo[c] / std::f64::consts::PI + spec
    })
}

/// The half vector of `wi`, `wo` where both directions lie above the horizon and it does too:
/// where the specular basis lobes of the microfacet models are non-zero (`None` elsewhere).
#[inline]
#[must_use]
pub(crate) fn upper_half_vector(wi: DVec3, wo: DVec3) -> Option<DVec3> {
    if wi.z <= 0.0 || wo.z <= 0.0 {
        return None;
    }
    let h = meso_core::frame::half_vector(wi, wo)?;
    if h.z <= 0.0 {
        return None;
    }
    Some(h)
}

/// The basis of the models fitted as a [`mirror_material`]: a Lambert lobe and the mirror's
/// specular lobe split by Schlick's Fresnel into its `f0` and grazing parts (amplitudes
/// `[albedo, u, g]`, [`mirror_from_amplitudes`]).
#[must_use]
pub(crate) fn mirror_basis_names() -> Vec<String> {
    vec![
        "diffuse".into(),
        "specular-f0".into(),
        "specular-grazing".into(),
    ]
}

/// The amplitude bounds of [`mirror_basis_names`]: each in `[0, 1]`.
#[must_use]
pub(crate) fn mirror_amplitude_bounds() -> Vec<(f64, f64)> {
    vec![(0.0, 1.0), (0.0, 1.0), (0.0, 1.0)]
}

/// The mirror's specular scale `s = u + g ≤ 1` (the written material's bound) of
/// [`mirror_basis_names`], kept by the fit rather than clamped afterwards.
#[must_use]
pub(crate) fn mirror_amplitude_sums() -> Vec<(Vec<usize>, f64)> {
    vec![(vec![1, 2], 1.0)]
}

/// The mirror's `(f0, specular)` per channel from the amplitudes `[albedo, u, g]` of
/// [`mirror_basis_names`]: `specular = min(u + g, 1)`, `f0 = min(u/(u + g), 1)` (0 where
/// `u + g = 0`), negative amplitudes read as 0.
#[must_use]
pub(crate) fn mirror_from_amplitudes(amps: &[[f64; 3]]) -> ([f64; 3], [f64; 3]) {
    let (mut f0, mut specular) = ([0.0; 3], [0.0; 3]);
    for c in 0..3 {
        let (u, g) = (amps[1][c].max(0.0), amps[2][c].max(0.0));
        let s = u + g;
        specular[c] = s.min(1.0);
        f0[c] = if s > 0.0 { (u / s).min(1.0) } else { 0.0 };
    }
    (f0, specular)
}

/// The specular value `x` of a mirror model split into its two basis lobes
/// ([`mirror_basis_names`]): `out[1] = x`, `out[2] = x·m5` for Schlick's weight `m5`
/// ([`schlick_m5`]). With `out` at `grad[3q..]`, the same split of the derivative in `θ_q`.
#[inline]
pub(crate) fn split_schlick(out: &mut [f64], x: f64, m5: f64) {
    out[1] = x;
    out[2] = x * m5;
}

/// The material file of a fit: `spec` with `comment`'s lines as `#` comments first
/// ([`MaterialSpec::to_toml_with_comment`]). Parameters that make no NDF (a fit that diverged to
/// non-finite numbers) give the comment and a comment line saying why, a file the material
/// parser refuses (no `[transfer]`).
#[must_use]
pub fn material_file(spec: Result<MaterialSpec, NdfError>, comment: &str) -> String {
    match spec {
        Ok(s) => s.to_toml_with_comment(comment),
        Err(e) => format!("{comment}\nno material: {e}")
            .lines()
            .map(|l| format!("# {l}\n"))
            .collect(),
    }
}
