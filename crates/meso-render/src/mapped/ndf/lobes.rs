//! The lobes of a texel in the two forms the shading reads: [`SgLobe`], a fitted Phong peak as
//! the spherical Gaussian of the same mean cosine with the constants of [`phong_texel`]'s
//! closed-form response under Phong facets, and [`Node`]s, a peak replaced by 7 weighted unit
//! normals ([`lobe_nodes`]) for Lambert and general facet transfers. Isotropic microfacet
//! facets read both ([`microfacet_texel`]): `D`'s core of Blinn–Phong peaks
//! ([`MicrofacetCore`]) through the closed form, the rest at the nodes.
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
    /// Isotropic microfacet facets: whether the node stands for its lobe's whole response
    /// (`D` at the node), or only for the rest `D − D_core` beside the lobe's core in closed
    /// form ([`microfacet_texel`]); unread by other facets.
    pub(super) whole: bool,
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

/// A Phong peak of exponent `exponent` about the unit `axis` as at most 7 unit normals with
/// weights summing to 1 that keep the peak's mean cosine: the axis (weight ¼) and a ring of 6
/// at the cosine that makes up the rest, or the axis alone for a peak sharper than the ring can
/// resolve. Returns the nodes and how many of them are used.
pub(super) fn peak_nodes(axis: DVec3, exponent: f64) -> ([(DVec3, f64); 1 + RING], usize) {
    let mut out = [(axis, 1.0); 1 + RING];
    let c = ring_cos(exponent);
    if c > 1.0 - 1e-9 {
        return (out, 1);
    }
    let s = (1.0 - c * c).max(0.0).sqrt();
    let f = Frame::from_normal_tangent(axis, DVec3::X);
    out[0].1 = AXIS_WEIGHT;
    for (node, &(ca, sa)) in out[1..].iter_mut().zip(ring()) {
        *node = (
            f.to_world(DVec3::new(s * ca, s * sa, c)).normalize(),
            (1.0 - AXIS_WEIGHT) / RING as f64,
        );
    }
    (out, 1 + RING)
}

/// Over the nodes of [`peak_nodes`] above the horizon (`m_z > 0`): `Σ w (m·o)⁺` and `Σ w m_z`,
/// from the dot products of the ring's frame with `o` and `+z` (no node formed, no square
/// root per node): what a lobe's seen area reads per texel and viewing direction
/// ([`super::view::ViewLobe::seen`]). The same sums as over `peak_nodes`' nodes, to rounding.
#[inline]
pub(super) fn peak_node_sums(axis: DVec3, exponent: f64, o: DVec3) -> (f64, f64) {
    let (ao, az) = (axis.dot(o), axis.z);
    let c = ring_cos(exponent);
    if c > 1.0 - 1e-9 {
        return if az > 0.0 {
            (ao.max(0.0), az)
        } else {
            (0.0, 0.0)
        };
    }
    let s = (1.0 - c * c).max(0.0).sqrt();
    let f = Frame::from_normal_tangent(axis, DVec3::X);
    let (to, bo, tz, bz) = (f.t.dot(o), f.b.dot(o), f.t.z, f.b.z);
    let (mut num, mut den) = (0.0, 0.0);
    if az > 0.0 {
        num += AXIS_WEIGHT * ao.max(0.0);
        den += AXIS_WEIGHT * az;
    }
    let w = (1.0 - AXIS_WEIGHT) / RING as f64;
    for &(ca, sa) in ring() {
        let mz = c * az + s * (ca * tz + sa * bz);
        if mz > 0.0 {
            num += w * (c * ao + s * (ca * to + sa * bo)).max(0.0);
            den += w * mz;
        }
    }
    (num, den)
}

/// The cosines and sines of the ring's azimuths `2πk/RING`, computed once.
fn ring() -> &'static [(f64, f64); RING] {
    static RING_AZIMUTHS: std::sync::OnceLock<[(f64, f64); RING]> = std::sync::OnceLock::new();
    RING_AZIMUTHS.get_or_init(|| {
        std::array::from_fn(|k| {
            let a = std::f64::consts::TAU * k as f64 / RING as f64;
            (a.cos(), a.sin())
        })
    })
}

/// The cosine of the angle between the axis and the ring of [`peak_nodes`] for a Phong peak of
/// exponent `exponent` (1 or nearly: the axis alone).
pub(super) fn ring_cos(exponent: f64) -> f64 {
    let mean = sg::phong_peak_mean_cos(exponent);
    ((mean - AXIS_WEIGHT) / (1.0 - AXIS_WEIGHT)).clamp(-1.0, 1.0)
}

/// Replace a Phong peak (lobe `src` of its pyramid level) by its weighted nodes
/// ([`peak_nodes`]; area weights, times `weight`) with the lobe's mean cosine.
pub(super) fn lobe_nodes(axis: DVec3, weight: f64, exponent: f64, src: u32, out: &mut Vec<Node>) {
    let (nodes, n) = peak_nodes(axis, exponent);
    out.extend(nodes[..n].iter().map(|&(m, w)| Node {
        n: m,
        w: weight * w,
        src,
        whole: true,
    }));
}

/// The Phong facets' response of one texel, `E[(m·h)^η (m·i)⁺]` over its projected area
/// (`m_z`-weighted, normalised), in closed form from its lobes (see
/// [`NdfMapped`](super::NdfMapped)): the sum of [`phong_lobe`] over them, each multiplied by
/// `vis(lobe, m*)` (its visibility of the light, in `[0, 1]`, times its view weight near the
/// product's axis `m*` when the material weights by view; `1` without either), which is
/// called only for lobes that reflect something. `lambda = η + 1` is the Gaussian of the
/// transfer (same integral over the sphere: [`sg::kappa_transfer`]).
#[inline]
pub(super) fn phong_texel(
    lobes: &[SgLobe],
    shapes: &[Shape],
    wi: DVec3,
    h: DVec3,
    eta: f64,
    lambda: f64,
    vis: impl Fn(&SgLobe, DVec3) -> f64,
) -> f64 {
    let mut sum = 0.0;
    for lobe in lobes {
        if let Some((v, m)) = phong_lobe(lobe, shapes, wi, h, eta, lambda, f64::INFINITY) {
            sum += v * vis(lobe, m);
        }
    }
    sum
}

/// One lobe's term of [`phong_texel`], with the unit axis `m*` of the product of the lobe and
/// the transfer (where the product's mass lies), or `None` when it reflects nothing. The
/// product of the lobe and the transfer's Gaussian is [`sg::product`] written out on the
/// lobe's `κa`, with its `r − κ` kept apart for the shape corrections (no allocation, one
/// `exp`). A lobe whose product has at most `e^{−cutoff}` of its mass's bound is skipped
/// (`f64::INFINITY`: none).
#[inline]
pub(super) fn phong_lobe(
    lobe: &SgLobe,
    shapes: &[Shape],
    wi: DVec3,
    h: DVec3,
    eta: f64,
    lambda: f64,
    cutoff: f64,
) -> Option<(f64, DVec3)> {
    let l = &shapes[lobe.shape as usize];
    let ka = lobe.axis * l.kappa;
    let kah = ka.dot(h);
    // `exp(r − κ − λ) ≤ exp(−κλ(1 − a·h)/(κ + λ))` bounds the product's mass: past the cutoff
    // the lobe gives nothing (a lobe far from the half vector for its width and the
    // transfer's).
    if l.kappa * lambda * (1.0 - lobe.axis.dot(h)) > cutoff * (l.kappa + lambda) {
        return None;
    }
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
        return None;
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
    (q > 0.0).then(|| (lobe.w * mass * q * e, m * inv_r))
}

/// The core of an isotropic microfacet distribution `D`: a sum of Blinn–Phong peaks `c_k (η_k +
/// 2)/(2π) (m·h)^{η_k}` that [`microfacet_texel`] convolves with a texel's lobes in closed form,
/// leaving only the rest, `D − D_core`, to the lobes' 7 nodes.
///
/// * **Beckmann** is one peak, `η = 2/α² − 2` (Beckmann's peak and curvature; the rest is
///   ≈ 0).
/// * **GGX** is a scale mixture of Beckmanns: with `x = tan²θ/α²`, its shape `(1 + x)^{−2} =
///   ∫ t e^{−t} e^{−tx} dt`, so `D_GGX = ∫ t e^{−t} (1/t) D_Beckmann(α/√t) dt` exactly. Three
///   Beckmanns ([`GGX_AS_BECKMANNS`]: `Σ c_k t_k e^{−t_k x}` fitted to `(1 + x)^{−2}` for the
///   least largest difference with `Σ c_k = 1`) stand for it within 0.24 % of its peak at
///   every angle, its long tails' mass included (a third of it beyond `x = 2`), so the rest
///   at the nodes is small and of zero mass.
/// * Student-t distributions have no core (their nodes as before).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(in crate::mapped) struct MicrofacetCore {
    /// `(η_k, λ_k, c_k (η_k + 2)/(2π))` of each peak: its exponent, its transfer's Gaussian
    /// ([`sg::kappa_transfer`]) and its normalisation times its weight (1/sr).
    terms: [(f64, f64, f64); 3],
    /// How many of `terms` are used.
    len: usize,
    /// The Phong exponent from which a lobe is [`LobeRole::Whole`].
    sharp_eta: f64,
    /// The Phong exponent up to which a lobe is [`LobeRole::Core`].
    broad_eta: f64,
    /// The cosine below which every peak is under `e^{−CORE_CUTOFF}` of its maximum.
    min_cos: f64,
}

/// The core's lobes and peaks are skipped where their bound is below `e^{−CORE_CUTOFF}` of
/// their maximum ([`phong_lobe`]'s `cutoff`, [`MicrofacetCore`]'s `D_core`).
pub(super) const CORE_CUTOFF: f64 = 40.0;

/// How a lobe is shaded under a facet with a [`MicrofacetCore`] ([`MicrofacetCore::role`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum LobeRole {
    /// At its nodes, each with the whole `D` (not in the table's core lobes).
    Whole,
    /// Through the core in closed form, the rest `D − D_core` at its nodes.
    CoreAndRest,
    /// Through the core alone (no nodes in the table).
    Core,
}

/// [`MicrofacetCore::role`]: a lobe of exponent `η_n ≥ SHARP_LOBE/α²` is
/// [`LobeRole::Whole`].
pub(super) const SHARP_LOBE: f64 = 128.0;

/// [`MicrofacetCore::role`]: a lobe of exponent `η_n ≤ BROAD_LOBE/α²` is [`LobeRole::Core`].
pub(super) const BROAD_LOBE: f64 = 0.125;

/// GGX as three Beckmanns: `(t_k, c_k)`, the Beckmann of roughness `α/√t_k` with weight `c_k`
/// (`Σ c_k = 1`; [`MicrofacetCore`]). Fitted by Nelder–Mead on `x ∈ [0, 2000]`: the largest
/// difference `|(1 + x)^{−2} − Σ c_k t_k e^{−t_k x}|` is 0.0024.
pub(super) const GGX_AS_BECKMANNS: [(f64, f64); 3] = [
    (2.923_835, 0.182_590),
    (0.810_105, 0.532_176),
    (0.115_448, 0.285_234),
];

/// The broadest peak a core may hold, `η_k ≥ 2` (a Beckmann of α ≤ 0.71; GGX's broadest
/// peak has `α/√0.115`, so GGX of α ≤ 0.24): broader facets' highlights span the lobes'
/// nodes, which sample them well.
pub(super) const MICROFACET_CORE_MIN_ETA: f64 = 2.0;

impl MicrofacetCore {
    /// The core of `d` (isotropic), or `None` for a facet too broad to need one
    /// ([`MICROFACET_CORE_MIN_ETA`]) or a Student-t one.
    pub(in crate::mapped) fn of(d: &meso_core::ndf::Microfacet) -> Option<MicrofacetCore> {
        use meso_core::ndf::Distribution;
        let a2 = d.alpha_x * d.alpha_y;
        let peaks: &[(f64, f64)] = match d.distribution {
            Distribution::Beckmann => &[(1.0, 1.0)],
            Distribution::Ggx => &GGX_AS_BECKMANNS,
            Distribution::StudentT { .. } => return None,
        };
        let mut terms = [(0.0, 0.0, 0.0); 3];
        let mut min_eta = f64::INFINITY;
        for (term, &(t, c)) in terms.iter_mut().zip(peaks) {
            let eta = 2.0 * t / a2 - 2.0;
            if eta < MICROFACET_CORE_MIN_ETA {
                return None;
            }
            *term = (
                eta,
                sg::kappa_transfer(eta),
                c * (eta + 2.0) / std::f64::consts::TAU,
            );
            min_eta = min_eta.min(eta);
        }
        Some(MicrofacetCore {
            terms,
            len: peaks.len(),
            sharp_eta: SHARP_LOBE / a2,
            broad_eta: BROAD_LOBE / a2,
            // cos^η ≤ e^{−CORE_CUTOFF} for cos ≤ e^{−CORE_CUTOFF/η}.
            min_cos: (-CORE_CUTOFF / min_eta).exp(),
        })
    }
    /// How a lobe of Phong exponent `eta_n` (width `√(8/η_n)`) is shaded under this facet:
    /// * at least 4× narrower than the highlight (`√(8/η_n) ≤ α/4`, `η_n ≥ 128/α²`,
    ///   [`SHARP_LOBE`]): [`LobeRole::Whole`], where its 7 nodes are close to the lobe's
    ///   integral (a lobe of 1/5.6 the highlight's width: within 10⁻⁴ of its peak response in
    ///   the tests) and cost less than the core's closed forms;
    /// * at least 8× broader (`η_n ≤ 1/(8α²)`, [`BROAD_LOBE`]): [`LobeRole::Core`], the rest
    ///   (of zero mass, within a few α of the half vector) integrating to ≈ 0 over it, where
    ///   its nodes would sample it at points (a node on the half vector would read the rest
    ///   at `D`'s peak, `1/(πα²)`);
    /// * between: [`LobeRole::CoreAndRest`].
    pub(super) fn role(&self, eta_n: f64) -> LobeRole {
        if eta_n >= self.sharp_eta {
            LobeRole::Whole
        } else if eta_n <= self.broad_eta {
            LobeRole::Core
        } else {
            LobeRole::CoreAndRest
        }
    }
    /// `D_core` at the cosine `cos_h` of the normal with the half vector (1/sr); 0 where
    /// even its broadest peak is below `e^{−CORE_CUTOFF}` of its maximum.
    #[inline]
    fn d(&self, cos_h: f64) -> f64 {
        if cos_h <= self.min_cos {
            return 0.0;
        }
        let ln = cos_h.ln();
        self.terms[..self.len]
            .iter()
            .map(|&(eta, _, norm)| norm * (eta * ln).exp())
            .sum()
    }
}

/// The isotropic microfacet facets' response of one texel, `E[D(m·h) G₂ (m·i)⁺ / (4 (m·i)(m·o))]`
/// over its projected area (without the Fresnel factor), from its lobes and their nodes, as
/// the table was built for the `core` ([`MicrofacetCore::role`]): `D = D_core + (D − D_core)`,
/// the core over `lobes` through [`phong_texel`]'s closed form with the visibility term
/// `G₂/(4 (m·i)(m·o))` taken at the product's axis (exact for a lobe much sharper or much
/// broader than the highlight), the rest at the nodes that are not `whole`. A sharp lobe (and
/// every lobe without a core) is its nodes alone, `whole`, each shaded with `D`: exact where
/// the lobe is far narrower than the highlight, and the cheaper. `vis(src)` is a lobe's
/// visibility of the light (its nodes share it), `view(src, m)` its view weight near normal
/// `m` (the product's axis, or the node; 1 when the material does not weigh by view). The sum
/// is kept ≥ 0 (the rest is signed).
#[inline]
#[allow(clippy::too_many_arguments)]
pub(super) fn microfacet_texel(
    lobes: &[SgLobe],
    shapes: &[Shape],
    nodes: &[Node],
    d: &meso_core::ndf::Microfacet,
    core: Option<&MicrofacetCore>,
    wi: DVec3,
    wo: DVec3,
    h: DVec3,
    vis: impl Fn(u32, DVec3) -> f64,
    view: impl Fn(u32, DVec3) -> f64,
) -> f64 {
    let mut a = 0.0;
    if let Some(core) = core {
        for lobe in lobes {
            for &(eta, lambda, norm) in &core.terms[..core.len] {
                let Some((v, m)) = phong_lobe(lobe, shapes, wi, h, eta, lambda, CORE_CUTOFF) else {
                    continue;
                };
                let g = d.vis_isotropic(m.dot(wi), m.dot(wo));
                if g > 0.0 {
                    a += v * norm * g * vis(lobe.src, m) * view(lobe.src, m);
                }
            }
        }
    }
    for nd in nodes {
        let (ci, co) = (nd.n.dot(wi), nd.n.dot(wo));
        let v = d.vis_isotropic(ci, co);
        if v > 0.0 {
            let ch = h.dot(nd.n);
            let dd = match core {
                Some(core) if !nd.whole => d.d_isotropic(ch) - core.d(ch),
                _ => d.d_isotropic(ch),
            };
            a += nd.w * dd * v * ci * vis(nd.src, nd.n) * view(nd.src, nd.n);
        }
    }
    a.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::super::peak_quadrature::for_each_peak_node;
    use super::*;
    use std::f64::consts::{PI, TAU};

    /// The node sums without the nodes are the sums over `peak_nodes`' nodes (random axes,
    /// some below the horizon, sharp to broad exponents, random viewing directions).
    #[test]
    fn node_sums_are_the_sums_over_the_nodes() {
        let mut rng = meso_testkit::rng(0x5eed_5e11);
        for _ in 0..2000 {
            let [u, v] = meso_testkit::uniform2(&mut rng);
            let [p, q] = meso_testkit::uniform2(&mut rng);
            let axis = DVec3::new(3.0 * (u - 0.5), 3.0 * (v - 0.5), p - 0.1).normalize();
            let eta = 10f64.powf(6.0 * q);
            let [x, y] = meso_testkit::uniform2(&mut rng);
            let o = DVec3::new(2.0 * x - 1.0, 2.0 * y - 1.0, 0.2 + x * y).normalize();
            let (nodes, n) = peak_nodes(axis, eta);
            let (mut num, mut den) = (0.0, 0.0);
            for &(m, w) in &nodes[..n] {
                if m.z > 0.0 {
                    num += w * m.dot(o).max(0.0);
                    den += w * m.z;
                }
            }
            let (gn, gd) = peak_node_sums(axis, eta, o);
            assert!(
                (gn - num).abs() < 1e-12 && (gd - den).abs() < 1e-12,
                "axis {axis}, η {eta}: ({gn}, {gd}) vs ({num}, {den})"
            );
        }
    }

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
            |_, _| 1.0,
        )
    }

    /// `E[D(m·h) G₂ (m·i)⁺ / (4 (m·i)(m·o)) m_z⁺] / E[m_z⁺]` over one Phong peak of exponent
    /// `eta_n` by brute force (independent of the closed form and the nodes): a fine grid in
    /// the peak's frame when the peak is the narrower of the two, else a grid in the half
    /// vector's frame warped by `D`'s own sampling (`D(m)(m·h)` as the density), so that the
    /// narrower of the two is always resolved.
    fn microfacet_quadrature(
        axis: DVec3,
        eta_n: f64,
        d: &meso_core::ndf::Microfacet,
        wi: DVec3,
        wo: DVec3,
    ) -> f64 {
        let h = (wi + wo).normalize();
        let f = |m: DVec3| {
            let ci = m.dot(wi);
            d.d_vis_isotropic(m.dot(h), ci, m.dot(wo)) * ci * m.z.max(0.0)
        };
        let peak =
            |m: DVec3| (eta_n + 2.0) / (8.0 * PI) * (0.5 * (1.0 + axis.dot(m))).powf(0.5 * eta_n);
        let num = if (8.0 / eta_n).sqrt() < d.alpha_x {
            let amax = (12.0 * 2.0 / eta_n.sqrt()).min(PI);
            let (na, np) = (600, 360);
            let mut sum = 0.0;
            for_each_peak_node(axis, DVec3::X, eta_n, amax, (na, np), |w, m| {
                sum += w * f(m)
            });
            sum * (amax / na as f64) * (TAU / np as f64) * (eta_n + 2.0) / (8.0 * PI)
        } else {
            let frame = Frame::from_normal_tangent(h, DVec3::X);
            let n = 700;
            let mut sum = 0.0;
            for i in 0..n {
                let u0 = (i as f64 + 0.5) / n as f64;
                for j in 0..n {
                    let u1 = (j as f64 + 0.5) / n as f64;
                    let m = frame.to_world(d.sample([u0, u1]));
                    // The density of the warp in h's frame is D(m)(m·h).
                    let pdf = d.pdf(frame.to_local(m));
                    if pdf > 0.0 {
                        sum += peak(m) * f(m) / pdf;
                    }
                }
            }
            sum / (n * n) as f64
        };
        num / meso_maps::peak_projected_area(axis.z, eta_n)
    }

    /// One lobe under isotropic microfacet facets three ways: the core in closed form and the
    /// rest at the nodes ([`microfacet_texel`]), the 7 nodes alone, and
    /// [`microfacet_quadrature`]. Errors as a fraction of the case's largest value (its lobe's
    /// response with the half vector on its axis).
    fn microfacet_errors(d: &meso_core::ndf::Microfacet) -> (f64, f64, f64) {
        let core = MicrofacetCore::of(d);
        let (mut worst_core, mut worst_nodes, mut mean_core) = (0.0f64, 0.0f64, 0.0);
        let mut cases = 0;
        for eta_n in [4.0, 40.0, 400.0, 4000.0, 1e5] {
            for tilt in [0.0f64, 20.0, 50.0] {
                let t = tilt.to_radians();
                let axis = DVec3::new(t.sin() * 0.8, -t.sin() * 0.6, t.cos()).normalize();
                let mut shapes = Shapes::default();
                let shape = shapes.intern(eta_n);
                let kappa = shapes.list[shape as usize].kappa;
                let e = meso_maps::peak_projected_area(axis.z, eta_n);
                let lobe = SgLobe::new(axis, shape, sg::normaliser_2pi(kappa) / e, 0);
                // The table as `build` makes it: a sharp lobe whole at its nodes, a broad one
                // in the core with the rest at its nodes.
                let mut nodes = Vec::new();
                lobe_nodes(axis, 1.0, eta_n, 0, &mut nodes);
                for n in &mut nodes {
                    n.w *= n.n.z.max(0.0);
                }
                let total: f64 = nodes.iter().map(|n| n.w).sum();
                nodes.retain(|n| n.w > 0.0);
                nodes.iter_mut().for_each(|n| n.w /= total);
                let whole = nodes.clone();
                let role = core.map_or(LobeRole::Whole, |c| c.role(eta_n));
                nodes
                    .iter_mut()
                    .for_each(|n| n.whole = role == LobeRole::Whole);
                if role == LobeRole::Core {
                    nodes.clear();
                }
                let lobes: &[SgLobe] = if role == LobeRole::Whole {
                    &[]
                } else {
                    &[lobe]
                };
                let run = |wi: DVec3, wo: DVec3, core: Option<&MicrofacetCore>| {
                    let h = (wi + wo).normalize();
                    match core {
                        Some(_) => microfacet_texel(
                            lobes,
                            &shapes.list,
                            &nodes,
                            d,
                            core,
                            wi,
                            wo,
                            h,
                            |_, _| 1.0,
                            |_, _| 1.0,
                        ),
                        None => microfacet_texel(
                            &[],
                            &shapes.list,
                            &whole,
                            d,
                            None,
                            wi,
                            wo,
                            h,
                            |_, _| 1.0,
                            |_, _| 1.0,
                        ),
                    }
                };
                // The largest value: the half vector on the lobe's axis (o mirrored about it).
                let wi_peak = DVec3::new(-0.3, 0.2, 0.93).normalize();
                let wi_peak = if wi_peak.dot(axis) < 0.3 {
                    axis
                } else {
                    wi_peak
                };
                let wo_peak = (2.0 * wi_peak.dot(axis) * axis - wi_peak).normalize();
                let scale = microfacet_quadrature(axis, eta_n, d, wi_peak, wo_peak);
                let views = [
                    (DVec3::new(-0.5, 0.3, 0.8), DVec3::new(0.0, -0.5, 0.866)),
                    (DVec3::new(0.6, -0.2, 0.77), DVec3::new(0.1, 0.5, 0.86)),
                    (DVec3::new(-0.9, 0.1, 0.42), DVec3::new(0.0, -0.5, 0.866)),
                    (wi_peak, wo_peak),
                ];
                for (wi, wo) in views {
                    let (wi, wo) = (wi.normalize(), wo.normalize());
                    if wo.z <= 0.0 || wi.z <= 0.0 {
                        continue;
                    }
                    let q = microfacet_quadrature(axis, eta_n, d, wi, wo);
                    let c = run(wi, wo, core.as_ref());
                    let n = run(wi, wo, None);
                    worst_core = worst_core.max((c - q).abs() / scale);
                    worst_nodes = worst_nodes.max((n - q).abs() / scale);
                    mean_core += (c - q).abs() / scale;
                    cases += 1;
                }
            }
        }
        (worst_core, mean_core / cases as f64, worst_nodes)
    }

    /// The core in closed form plus the rest at the nodes is close to the brute-force
    /// quadrature for glossy GGX and Beckmann facets (α = 0.03–0.2), lobes from broad to
    /// delta-like and tilted up to 50°, where the 7 nodes alone are far off; facets too broad
    /// for a core keep the nodes.
    #[test]
    fn microfacet_core_and_rest_match_quadrature() {
        use meso_core::ndf::{Distribution, Microfacet};
        for dist in [Distribution::Ggx, Distribution::Beckmann] {
            for alpha in [0.03, 0.05, 0.1, 0.2] {
                let d = Microfacet::isotropic(dist, alpha).unwrap();
                assert!(MicrofacetCore::of(&d).is_some());
                let (worst, mean, nodes) = microfacet_errors(&d);
                eprintln!(
                    "{dist:?} α {alpha}: core + rest worst {worst:.4} mean {mean:.4}; \
                     7 nodes worst {nodes:.4}"
                );
                // Measured: worst 0.054 / mean 0.0083 up to α = 0.1 (GGX α = 0.1), 0.150 /
                // 0.023 at α = 0.2; the 7 nodes alone 7.8 (α = 0.2) to 400 (α = 0.03).
                let (w, m) = if alpha <= 0.1 {
                    (0.07, 0.012)
                } else {
                    (0.2, 0.03)
                };
                assert!(
                    worst < w && mean < m,
                    "{dist:?} α {alpha}: worst {worst}, mean {mean} of the peak"
                );
            }
        }
        let broad = Microfacet::isotropic(Distribution::Ggx, 0.3).unwrap();
        assert!(MicrofacetCore::of(&broad).is_none());
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
