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
