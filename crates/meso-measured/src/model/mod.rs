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

/// The `[transfer]` (Schlick mirror with `f0` and the `specular` scale), `[shadowing]` (Smith) and
/// `[diffuse]` tables of a fitted microfacet material, each value clamped to `[0, 1]`: the tail
/// every fitted microfacet material file shares (Phong-peak lobes, GGX lobes, the
/// non-parametric NDF). Starts with `[transfer]`; the caller writes what comes before.
#[must_use]
pub fn mirror_material_tail(f0: [f64; 3], specular: [f64; 3], albedo: [f64; 3]) -> String {
    use std::fmt::Write;
    let c = |v: [f64; 3]| v.map(|x| x.clamp(0.0, 1.0));
    let (f, k, a) = (c(f0), c(specular), c(albedo));
    let mut s = String::from("[transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\n");
    let _ = writeln!(s, "f0 = [{:?}, {:?}, {:?}]", f[0], f[1], f[2]);
    let _ = writeln!(s, "specular = [{:?}, {:?}, {:?}]", k[0], k[1], k[2]);
    s.push_str("\n[shadowing]\nkind = \"smith\"\n");
    let _ = writeln!(
        s,
        "\n[diffuse]\nalbedo = [{:?}, {:?}, {:?}]",
        a[0], a[1], a[2]
    );
    s
}
