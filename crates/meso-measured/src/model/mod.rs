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
