//! The lobes of a texel in the two forms the shading reads: [`SgLobe`], a fitted Phong peak as
//! the spherical Gaussian of the same mean cosine with the constants of [`phong_texel`]'s
//! closed-form response under Phong facets, and [`Node`]s, a peak replaced by 7 weighted unit
//! normals ([`lobe_nodes`]) for Lambert and general facet transfers.
//!
//! # Conventions
//! * Directions are unit vectors in the local frame (normal +z); `h` is the half vector.
//! * A Phong peak is `((1 + a·m)/2)^(η/2)` about its axis `a`, normalised over the sphere.

use glam::DVec3;
use meso_core::frame::Frame;
use meso_core::sg;

/// One node of a texel's filtered NDF (general facet transfers only): a unit normal with its
/// projected-area weight and the lobe it comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Node {
    pub(super) n: DVec3,
    pub(super) w: f64,
    /// Index of its lobe among the pyramid level's lobes (for the lobe's horizon statistics),
    /// or [`NO_LOBE`].
    pub(super) src: u32,
}

/// The `src` of a lobe or node that stands for no lobe of the pyramid (a texel with nothing
/// facing up shaded as the flat surface): it takes its texel's horizon statistics.
pub(super) const NO_LOBE: u32 = u32::MAX;

/// The constants of a lobe's spherical Gaussian that depend on its Phong exponent η alone
/// (what [`phong_texel`]'s loop reads besides the axis and weight), held once per distinct η
/// of a level ([`Shapes`]): a map file's exponents are 16-bit codes, so a level has at most
/// 65 536 of them (a height map's level 0 one or a few), where its lobes number millions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Shape {
    /// Concentration κ ([`sg::kappa_same_mean_cos`] of η).
    pub(super) kappa: f64,
    /// `η/2` of the Phong peak.
    half_eta: f64,
    /// `ln` of the Phong peak's normalisation over the Gaussian's.
    ln_ratio: f64,
}

impl Shape {
    /// The constants of the Phong peak of exponent `eta`.
    pub(super) fn new(eta: f64) -> Shape {
        let kappa = sg::kappa_same_mean_cos(eta);
        // Phong: (η + 2)/(8π); Gaussian: sg::normaliser(κ) = κ/(2π(1 − e^{−2κ})).
        let ratio = 0.25 * (eta + 2.0) / sg::normaliser_2pi(kappa);
        Shape {
            kappa,
            half_eta: 0.5 * eta,
            ln_ratio: ratio.ln(),
        }
    }
}

/// A level's [`Shape`]s, one per distinct exponent (by its bits: the same η gives the very
/// constants a lobe of its own would hold), built as the level's lobes are.
#[derive(Debug, Default)]
pub(super) struct Shapes {
    pub(super) list: Vec<Shape>,
    index: std::collections::HashMap<u64, u32>,
}

impl Shapes {
    /// The index of the shape of exponent `eta` in `list`, added if new.
    pub(super) fn intern(&mut self, eta: f64) -> u32 {
        let list = &mut self.list;
        *self.index.entry(eta.to_bits()).or_insert_with(|| {
            list.push(Shape::new(eta));
            (list.len() - 1) as u32
        })
    }
}

/// One fitted lobe of a texel, as the spherical Gaussian `c·exp(κ(a·m − 1))` of the same mean
/// cosine ([`sg::kappa_same_mean_cos`]: the lobe's projected area normalises it, see
/// [`NdfMapped`](super::NdfMapped)'s docs): its axis, weight and the index of its [`Shape`]
/// (40 bytes; the constants of [`phong_texel`]'s loop, built by [`meso_core::sg`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct SgLobe {
    /// Unit axis (`κ · axis`, which the response reads, is formed where it is read).
    axis: DVec3,
    /// Area weight ÷ the texel's projected area × the Gaussian's normalisation `κ/(1 − e^{−2κ})`
    /// (without its `1/2π`, which the product integral's `2π` cancels).
    w: f64,
    /// Index of the lobe among the pyramid level's lobes (for its horizon statistics), or
    /// [`NO_LOBE`].
    pub(super) src: u32,
    /// Index of its [`Shape`] among the level's.
    shape: u32,
}

impl SgLobe {
    /// The lobe of axis `axis` and shape `shape` (an index into the level's [`Shapes`]) with
    /// weight `w` (normalisation included), lobe `src` of its pyramid level (or [`NO_LOBE`]).
    pub(super) fn new(axis: DVec3, shape: u32, w: f64, src: u32) -> SgLobe {
        SgLobe {
            axis,
            w,
            src,
            shape,
        }
    }
    /// Its axis.
    #[cfg(test)]
    pub(super) fn axis(&self) -> DVec3 {
        self.axis
    }
    /// The index of its shape.
    #[cfg(test)]
    pub(super) fn shape(&self) -> usize {
        self.shape as usize
    }
}

/// Nodes per fitted lobe (general transfers only): the axis and a ring of 6.
const RING: usize = 6;
/// Weight of the axis node.
const AXIS_WEIGHT: f64 = 0.25;

/// Replace a Phong peak (lobe `src` of its pyramid level) by 7 weighted nodes (area weights)
/// with the lobe's mean cosine.
pub(super) fn lobe_nodes(axis: DVec3, weight: f64, exponent: f64, src: u32, out: &mut Vec<Node>) {
    let mean = sg::phong_peak_mean_cos(exponent);
    let c = ((mean - AXIS_WEIGHT) / (1.0 - AXIS_WEIGHT)).clamp(-1.0, 1.0);
    if c > 1.0 - 1e-9 {
        out.push(Node {
            n: axis,
            w: weight,
            src,
        });
        return;
    }
    let s = (1.0 - c * c).max(0.0).sqrt();
    let f = Frame::from_normal_tangent(axis, DVec3::X);
    out.push(Node {
        n: axis,
        w: weight * AXIS_WEIGHT,
        src,
    });
    for k in 0..RING {
        let a = std::f64::consts::TAU * k as f64 / RING as f64;
        out.push(Node {
            n: f.to_world(DVec3::new(s * a.cos(), s * a.sin(), c))
                .normalize(),
            w: weight * (1.0 - AXIS_WEIGHT) / RING as f64,
            src,
        });
    }
}

/// A lobe broader than the facets' own highlight (microfacet facets, [`is_wide`]). Its 7
/// nodes alone would sample a sharp facet BRDF at 7 points of a broad lobe (a glossy facet
/// under a coarse level's lobe: sparkle, and the highlight lost or doubled); the lobe's
/// response is split between two rules by the balance heuristic: the lobe's own nodes (in the
/// texel's `wide_nodes`, weighted as [`Node`]s are) take `f·p/(p + q)` and the facet's nodes
/// about the half vector ([`FacetNodes`]) take `f·q/(p + q)`, `p` the lobe's density and `q`
/// the facet's highlight's (a GGX of the facet's roughness about `h`). Each rule integrates
/// the part where its own density dominates, where the other's would miss it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct WideLobe {
    /// Unit axis.
    axis: DVec3,
    /// `η/2` of the Phong peak.
    half_eta: f64,
    /// `ln` of the peak's normalisation over the sphere, `(η + 2)/(8π)`.
    ln_norm: f64,
    /// The lobe's share of the texel's projected area ÷ its own projected area `E[m_z⁺]`.
    scale: f64,
    /// Its nodes: `wide_nodes[start..start + count]` of the tile.
    pub(super) start: u32,
    pub(super) count: u32,
    /// Index of the lobe among the pyramid level's lobes (for its horizon statistics).
    pub(super) src: u32,
}

impl WideLobe {
    /// The Phong peak of axis `axis` and exponent `eta` standing for `share` of its texel's
    /// projected area, its own projected area being `area` (`E[m_z⁺]`, > 0); lobe `src`, its
    /// nodes `wide_nodes[start..start + count]`.
    pub(super) fn new(
        axis: DVec3,
        eta: f64,
        share: f64,
        area: f64,
        src: u32,
        (start, count): (u32, u32),
    ) -> WideLobe {
        WideLobe {
            axis,
            half_eta: 0.5 * eta,
            ln_norm: ((eta + 2.0) / (8.0 * std::f64::consts::PI)).ln(),
            scale: share / area,
            start,
            count,
            src,
        }
    }

    /// Multiply its share by `k` (the texel's shares normalised to sum 1).
    pub(super) fn rescale(&mut self, k: f64) {
        self.scale *= k;
    }

    /// The lobe's density at the unit normal `m` (1/sr, over the sphere).
    #[inline]
    pub(super) fn density(&self, m: DVec3) -> f64 {
        let c = 0.5 * (1.0 + self.axis.dot(m));
        if c <= 0.0 {
            return 0.0;
        }
        (self.ln_norm + self.half_eta * c.ln()).exp()
    }
}

/// Whether a Phong peak of exponent `eta` is a [`WideLobe`] under microfacet facets of
/// roughness `alpha`: when the facet's highlight is narrower than [`WIDE_RATIO`] × the peak's
/// own width `√(8/η)` (the Beckmann roughness of the same spread).
pub(super) fn is_wide(eta: f64, alpha: f64) -> bool {
    alpha < WIDE_RATIO * (8.0 / eta.max(1e-12)).sqrt()
}

/// See [`is_wide`]: measured in `wide_lobes_follow_the_quadrature` (below).
pub(super) const WIDE_RATIO: f64 = 1.0;

/// The core of a [`WideLobe`]: where its density is above `e^{−CORE}` of its peak's. With the
/// half vector there, the facet's nodes alone integrate the lobe (the lobe is smooth across
/// the highlight); elsewhere the balance heuristic splits it ([`WideLobe`]).
pub(super) const CORE: f64 = 2.0;

/// Rings (Gauss–Legendre in the GGX's cumulative distribution of the angle to the half
/// vector) and azimuths of [`FacetNodes`].
const FACET_RINGS: usize = 3;
const FACET_AZIMUTHS: usize = 6;
const FACET_NODES: usize = FACET_RINGS * FACET_AZIMUTHS;

/// Three-point Gauss–Legendre on `(0, 1)`: nodes and weights (summing to 1).
const GL3: [(f64, f64); FACET_RINGS] = [
    (0.112_701_665_379_258_3, 5.0 / 18.0),
    (0.5, 8.0 / 18.0),
    (0.887_298_334_620_741_7, 5.0 / 18.0),
];

/// The density over the sphere of a GGX of roughness `alpha` about `h` in the cosine-weighted
/// form `D(m)(m·h)` (which integrates to 1), at the cosine `c = m·h`; 0 for `c ≤ 0`.
#[inline]
pub(super) fn highlight_density(alpha: f64, c: f64) -> f64 {
    if c <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let c2 = c * c;
    let t2 = (1.0 - c2).max(0.0) / c2;
    1.0 / (std::f64::consts::PI * a2 * c2 * c * (1.0 + t2 / a2).powi(2))
}

/// The facet's nodes for one light and view: normals `m` about the half vector `h` spread as
/// the facet's highlight, a GGX of roughness `alpha` ([`highlight_density`] `q`), each with
/// the facet's `f(i, o; m)(m·i)` divided by `q` and times its quadrature weight. Built once per
/// light and view, shared by every [`WideLobe`] the shading call reads
/// ([`FacetNodes::lobe`]).
pub(super) struct FacetNodes {
    m: [DVec3; FACET_NODES],
    value: [[f64; 3]; FACET_NODES],
    q: [f64; FACET_NODES],
    alpha: f64,
    h: DVec3,
}

impl FacetNodes {
    /// The nodes about `h` for facets of roughness `alpha`, `lit(m)` the facet's
    /// `f(i, o; m)(m·i)⁺` (RGB).
    pub(super) fn new(alpha: f64, h: DVec3, lit: impl Fn(DVec3) -> [f32; 3]) -> FacetNodes {
        let f = Frame::from_normal(h);
        let a2 = alpha * alpha;
        let mut m = [DVec3::Z; FACET_NODES];
        let mut value = [[0.0; 3]; FACET_NODES];
        let mut qs = [0.0; FACET_NODES];
        let mut k = 0;
        for (j, &(s, u)) in GL3.iter().enumerate() {
            // tan²θ = α² s/(1 − s): the GGX's angle at cumulative probability s.
            let t2 = a2 * s / (1.0 - s);
            let cos = 1.0 / (1.0 + t2).sqrt();
            let sin = (t2 * cos * cos).sqrt();
            let q = highlight_density(alpha, cos);
            let w = u / (FACET_AZIMUTHS as f64 * q);
            for b in 0..FACET_AZIMUTHS {
                // Rings staggered by half a step.
                let phi =
                    std::f64::consts::TAU * (b as f64 + 0.5 * j as f64) / FACET_AZIMUTHS as f64;
                let n = f.to_world(DVec3::new(sin * phi.cos(), sin * phi.sin(), cos));
                m[k] = n;
                value[k] = lit(n).map(|c| f64::from(c) * w);
                qs[k] = q;
                k += 1;
            }
        }
        FacetNodes {
            m,
            value,
            q: qs,
            alpha,
            h,
        }
    }

    /// The highlight's density at `m` ([`highlight_density`] about these nodes' `h`).
    #[inline]
    pub(super) fn density(&self, m: DVec3) -> f64 {
        highlight_density(self.alpha, m.dot(self.h))
    }

    /// A wide lobe's response (RGB, as [`Node`] sums are: per unit of the texel's projected
    /// area): its nodes' part (`nodes`, its `wide_nodes`; `lit(m)` the facet's
    /// `f(i, o; m)(m·i)⁺`) and these nodes' part, by the balance heuristic ([`WideLobe`]).
    #[inline]
    pub(super) fn lobe(
        &self,
        l: &WideLobe,
        nodes: &[Node],
        lit: impl Fn(DVec3) -> [f32; 3],
    ) -> [f64; 3] {
        self.lobe_with(l, nodes, lit, CORE)
    }

    /// [`FacetNodes::lobe`] with the core's bound `core` ([`CORE`]).
    #[inline]
    pub(super) fn lobe_with(
        &self,
        l: &WideLobe,
        nodes: &[Node],
        lit: impl Fn(DVec3) -> [f32; 3],
        core: f64,
    ) -> [f64; 3] {
        let mut a = [0.0; 3];
        let c = 0.5 * (1.0 + l.axis.dot(self.h));
        if c > 0.0 && l.half_eta * c.ln() > -core {
            // The half vector within the lobe's core: the facet's nodes alone.
            for (m, v) in self.m.iter().zip(&self.value) {
                if m.z <= 0.0 || *v == [0.0; 3] {
                    continue;
                }
                let w = l.scale * l.density(*m) * m.z;
                for (a, v) in a.iter_mut().zip(v) {
                    *a += w * v;
                }
            }
            return a;
        }
        for nd in nodes {
            let v = lit(nd.n);
            if v == [0.0; 3] {
                continue;
            }
            let p = l.density(nd.n);
            let w = nd.w * p / (p + self.density(nd.n));
            for (a, v) in a.iter_mut().zip(v) {
                *a += w * f64::from(v);
            }
        }
        for ((m, v), &q) in self.m.iter().zip(&self.value).zip(&self.q) {
            if m.z <= 0.0 || *v == [0.0; 3] {
                continue;
            }
            let p = l.density(*m);
            let w = l.scale * p * m.z * q / (p + q);
            for (a, v) in a.iter_mut().zip(v) {
                *a += w * v;
            }
        }
        a
    }
}

/// The Phong facets' response of one texel, `E[(m·h)^η (m·i)⁺]` over its projected area
/// (`m_z`-weighted, normalised), in closed form from its lobes (see
/// [`NdfMapped`](super::NdfMapped)). `lambda = η + 1` is the Gaussian of the transfer (same
/// integral over the sphere: [`sg::kappa_transfer`]). The product of the lobe and the
/// transfer's Gaussian is [`sg::product`] written out on the lobe's `κa`, with its
/// `r − κ` kept apart for the shape corrections (no allocation, one `exp` per lobe). Each
/// lobe's term is multiplied by `vis(lobe)` (its visibility of the light, in `[0, 1]`; `1`
/// without shadowing), which is called only for lobes that reflect something.
#[inline]
pub(super) fn phong_texel(
    lobes: &[SgLobe],
    shapes: &[Shape],
    wi: DVec3,
    h: DVec3,
    eta: f64,
    lambda: f64,
    vis: impl Fn(&SgLobe) -> f64,
) -> f64 {
    let mut sum = 0.0;
    for lobe in lobes {
        let l = &shapes[lobe.shape as usize];
        let ka = lobe.axis * l.kappa;
        let kah = ka.dot(h);
        let r = (l.kappa * l.kappa + lambda * (2.0 * kah + lambda))
            .max(1e-24)
            .sqrt();
        let inv_r = 1.0 / r;
        // Axis of the product Gaussian (unnormalised: × r).
        let m = ka + lambda * h;
        let mh = (kah + lambda) * inv_r;
        // Nothing to reflect when the product's axis faces away from the half vector or lies
        // below the macro surface (it has no projected area there).
        if mh <= 0.0 || m.z <= 0.0 {
            continue;
        }
        // r − κ without cancellation.
        let r_minus_k = lambda * (2.0 * kah + lambda) / (r + l.kappa);
        // exp(r − κ − λ) × (the Phong transfer / its Gaussian) × (the Phong peak / its
        // Gaussian)^β, both ratios taken at the product's axis m*: a sharp lobe gives exactly
        // (a·h)^η, a lobe much broader than the transfer its exact density at h. In between
        // the peak's ratio varies over the product's spread; β = (λ/(λ + κ))² (calibrated
        // against a quadrature, see the tests) keeps the error under 1% of the peak.
        let am = (l.kappa + lambda * lobe.axis.dot(h)) * inv_r;
        let am_minus_1 = -(r_minus_k - lambda * lobe.axis.dot(h)) * inv_r;
        let beta = lambda / (lambda + l.kappa);
        let beta = beta * beta;
        let e = (r_minus_k - lambda * mh
            + eta * mh.ln()
            + beta
                * (l.half_eta * (0.5 * (1.0 + am)).max(1e-300).ln() - l.kappa * am_minus_1
                    + l.ln_ratio))
            .exp();
        // (1 − e^{−2r}) / r, and E[(m·i)(m·z)] = (A/r) i_z + (1 − 3A/r)(m*·i)(m*·z).
        let (mass, a_r) = (sg::integral_per_2pi(r), sg::mean_cos(r) * inv_r);
        let q = a_r * wi.z + (1.0 - 3.0 * a_r) * m.dot(wi) * m.z * inv_r * inv_r;
        if q > 0.0 {
            sum += lobe.w * mass * q * e * vis(lobe);
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::super::peak_quadrature::for_each_peak_node;
    use super::*;

    /// `E[(m·h)^η (m·i)⁺ m_z⁺] / E[m_z⁺]` over one Phong peak `cos^η_n(α/2)` by a fine
    /// quadrature in the lobe's frame (independent of the Gaussian forms).
    fn quadrature(axis: DVec3, eta_n: f64, wi: DVec3, h: DVec3, eta: f64) -> f64 {
        let amax = (12.0 * 2.0 / eta_n.sqrt()).min(std::f64::consts::PI);
        let (mut num, mut den) = (0.0, 0.0);
        for_each_peak_node(axis, DVec3::X, eta_n, amax, (600, 240), |d, m| {
            let w = d * m.z.max(0.0);
            num += w * m.dot(h).max(0.0).powf(eta) * m.dot(wi).max(0.0);
            den += w;
        });
        num / den
    }

    fn closed(axis: DVec3, eta_n: f64, wi: DVec3, h: DVec3, eta: f64) -> f64 {
        let mut shapes = Shapes::default();
        let shape = shapes.intern(eta_n);
        let kappa = shapes.list[shape as usize].kappa;
        let area = eta_n / (eta_n + 4.0) * axis.z;
        let lobe = SgLobe::new(axis, shape, sg::normaliser_2pi(kappa) / area, NO_LOBE);
        phong_texel(
            &[lobe],
            &shapes.list,
            wi,
            h,
            eta,
            sg::kappa_transfer(eta),
            |_| 1.0,
        )
    }

    /// `E[m_z⁺ f(i, o; m)(m·i)⁺] / E[m_z⁺]` over one Phong peak under GGX facets of roughness
    /// `alpha`: by a fine quadrature (`truth`), by the lobe's 7 nodes and by the facet's nodes.
    fn glossy_cases(alpha: f64, eta: f64, tilt: f64, wi: DVec3, wo: DVec3) -> (f64, f64, f64) {
        use meso_core::ndf::microfacet::{Distribution, Microfacet};
        use meso_core::transfer::{Fresnel, Transfer};
        let t = Transfer::Microfacet {
            distribution: Microfacet::new(Distribution::Ggx, alpha, alpha).unwrap(),
            fresnel: Fresnel::None,
        };
        let facet = crate::mapped::Facet::new(&t);
        let h = (wi + wo).normalize();
        let lit = |m: DVec3| f64::from(facet.lit(m, wi, wo, h)[0]);
        let tr = tilt.to_radians();
        let axis = DVec3::new(tr.sin() * 0.6, tr.sin() * 0.8, tr.cos()).normalize();
        let amax = (12.0 * 2.0 / eta.sqrt()).min(std::f64::consts::PI);
        let (mut num, mut den) = (0.0, 0.0);
        for_each_peak_node(axis, DVec3::X, eta, amax, (3000, 1440), |d, m| {
            let w = d * m.z.max(0.0);
            num += w * lit(m);
            den += w;
        });
        let truth = num / den;
        let mut nodes = Vec::new();
        lobe_nodes(axis, 1.0, eta, 0, &mut nodes);
        let b: f64 = nodes.iter().map(|n| n.w * n.n.z.max(0.0)).sum();
        for n in &mut nodes {
            n.w *= n.n.z.max(0.0) / b;
        }
        let seven: f64 = nodes.iter().map(|n| n.w * lit(n.n)).sum();
        let e = meso_maps::peak_projected_area(axis.z, eta);
        let fnodes = FacetNodes::new(alpha, h, |m| facet.lit(m, wi, wo, h));
        let lobe = WideLobe::new(axis, eta, 1.0, e, 0, (0, nodes.len() as u32));
        let wide = fnodes.lobe(&lobe, &nodes, |m| facet.lit(m, wi, wo, h))[0];
        (truth, seven, wide)
    }

    /// Glossy facets (GGX α = 0.05–0.2) under Phong peaks from broad (η = 4) to sharp
    /// (η = 4096), tilted 0–60°, at three light and view pairs: each lobe's response by the
    /// rule [`is_wide`] picks (the lobe's 7 nodes, or the facet's nodes with the balance
    /// heuristic) against a fine quadrature, as a fraction of the largest value of the three
    /// pairs. Measured (`cargo test --release -p meso-render --lib wide_lobes -- --nocapture`):
    /// worst 0.139 (α = 0.1, η = 64, tilted 60°, where the 7 nodes alone are 0.269 off), mean
    /// 0.011; the 7 nodes alone: worst 9.5 (a broad lobe's node on the highlight), mean 0.46.
    #[test]
    fn wide_lobes_follow_the_quadrature() {
        let pairs = [
            (DVec3::new(-0.5, 0.3, 0.8), DVec3::new(0.4, -0.2, 0.9)),
            (DVec3::new(0.2, 0.9, 0.35), DVec3::new(0.0, -0.4, 0.9)),
            (DVec3::new(-0.7, 0.1, 0.7), DVec3::new(-0.2, 0.5, 0.84)),
        ];
        let (mut worst, mut sum, mut worst7, mut sum7, mut n) = (0.0f64, 0.0, 0.0f64, 0.0, 0.0);
        for alpha in [0.05, 0.1, 0.2] {
            for eta in [4.0, 16.0, 64.0, 256.0, 1024.0, 4096.0] {
                for tilt in [0.0, 30.0, 60.0] {
                    let cases: Vec<_> = pairs
                        .iter()
                        .map(|&(i, o)| glossy_cases(alpha, eta, tilt, i.normalize(), o.normalize()))
                        .collect();
                    let peak = cases.iter().fold(0.0f64, |m, c| m.max(c.0));
                    for (truth, seven, wide) in cases {
                        let picked = if is_wide(eta, alpha) { wide } else { seven };
                        let (e, e7) = ((picked - truth).abs() / peak, (seven - truth).abs() / peak);
                        eprintln!(
                            "α {alpha} η {eta} tilt {tilt}: truth {truth:.4e}, picked {:+.3}, \
                             7 nodes {:+.3} (of the case's peak), wide {}",
                            (picked - truth) / peak,
                            (seven - truth) / peak,
                            is_wide(eta, alpha)
                        );
                        (worst, sum, worst7, sum7, n) =
                            (worst.max(e), sum + e, worst7.max(e7), sum7 + e7, n + 1.0);
                    }
                }
            }
        }
        let (mean, mean7) = (sum / n, sum7 / n);
        eprintln!(
            "picked: worst {worst:.3}, mean {mean:.4}; 7 nodes: worst {worst7:.3}, mean {mean7:.4}"
        );
        assert!(worst < 0.15 && mean < 0.02, "worst {worst}, mean {mean}");
    }

    /// A lobe is 40 bytes (axis, weight, source and shape index) and a level's shapes are one
    /// per distinct exponent, the same constants (bits) for the same exponent.
    #[test]
    fn lobes_share_their_shapes() {
        assert_eq!(std::mem::size_of::<SgLobe>(), 40);
        let mut shapes = Shapes::default();
        let (a, b, c) = (shapes.intern(1e6), shapes.intern(40.0), shapes.intern(1e6));
        assert_eq!((a, b, c), (0, 1, 0));
        assert_eq!(shapes.list.len(), 2);
        assert_eq!(shapes.list[0], Shape::new(1e6));
        assert_eq!(shapes.list[1].kappa, sg::kappa_same_mean_cos(40.0));
    }

    /// The closed form of one lobe under Phong facets agrees with the quadrature, from a
    /// delta-like lobe to one broader than the facets' highlight, near and away from the peak.
    #[test]
    fn phong_lobe_closed_form_matches_quadrature() {
        let wo = DVec3::new(0.0, -0.5, 0.866).normalize();
        let mut worst = 0.0f64;
        for (eta_n, eta) in [
            (1e5, 40.0),
            (400.0, 40.0),
            (60.0, 40.0),
            (15.0, 20.0),
            (60.0, 200.0),
        ] {
            for (tilt, wi) in [
                (10.0f64, DVec3::new(-0.75, 0.35, 0.57)),
                (25.0, DVec3::new(-0.5, 0.3, 0.8)),
                (5.0, DVec3::new(0.2, 0.6, 0.77)),
            ] {
                let wi = wi.normalize();
                let h = (wi + wo).normalize();
                let t = tilt.to_radians();
                let axis = DVec3::new(-t.sin() * 0.8, -t.sin() * 0.6, t.cos()).normalize();
                let q = quadrature(axis, eta_n, wi, h, eta);
                let c = closed(axis, eta_n, wi, h, eta);
                // Relative to the lobe's value at its peak (h on the axis), so that the far
                // tails, where both are tiny, do not dominate.
                let peak = quadrature(axis, eta_n, wi, axis, eta).max(q);
                worst = worst.max((c - q).abs() / peak);
            }
        }
        // Measured: at most 0.94% (η_n = 15 under η = 20).
        assert!(worst < 0.015, "worst error {worst} of the peak");
    }

    /// The Gaussian of a Phong peak keeps its mean cosine `η/(η + 4)`
    /// ([`sg::kappa_same_mean_cos`]).
    #[test]
    fn peak_kappa_keeps_the_mean_cosine() {
        for eta in [0.5, 4.0, 40.0, 1e3, 1e6] {
            let mu = eta / (eta + 4.0);
            let k = sg::kappa_same_mean_cos(eta);
            assert!(
                (sg::mean_cos(k) - mu).abs() < 1e-9 * (1.0 + 1.0 / (1.0 - mu)),
                "{eta}: {k}"
            );
        }
    }

    /// `E[m_z⁺]` of a Phong peak (`meso_maps::peak_projected_area`): the closed form above the
    /// horizon and the quadrature across it agree with a brute-force quadrature of the peak over
    /// the sphere (in the lobe's frame), and a lobe at the horizon covers far more than `μ a_z`
    /// says.
    #[test]
    fn peak_projected_area_matches_quadrature() {
        use meso_maps::peak_projected_area;
        for (a_z, eta) in [
            (0.9f64, 40.0f64),
            (0.5, 4.0),
            (0.3, 40.0),
            (0.05, 4.0),
            (0.05, 100.0),
            (0.05, 1e4),
            (0.2, 1e6),
        ] {
            let axis = DVec3::new((1.0 - a_z * a_z).sqrt(), 0.0, a_z);
            let amax = (40.0 / f64::sqrt(eta)).min(std::f64::consts::PI);
            let (mut num, mut den) = (0.0, 0.0);
            for_each_peak_node(axis, DVec3::Y, eta, amax, (4000, 720), |d, m| {
                num += d * m.z.max(0.0);
                den += d;
            });
            let want = num / den;
            let got = peak_projected_area(a_z, eta);
            assert!(
                (got - want).abs() < 2e-3 * want,
                "a_z {a_z}, η {eta}: {got} vs {want}"
            );
        }
        // A lobe of η = 100 at a_z = 0.05: several times μ a_z.
        assert!(peak_projected_area(0.05, 100.0) > 2.0 * 0.05 * 100.0 / 104.0);
    }
}
