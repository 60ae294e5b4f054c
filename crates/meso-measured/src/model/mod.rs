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
