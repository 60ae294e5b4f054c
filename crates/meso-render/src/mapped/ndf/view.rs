//! What view weighting ([`crate::NdfMapped::with_view_weighting`]) reads and computes: per
//! pyramid lobe its seen-area data ([`ViewLobe`]), per texel and viewing direction the lobes'
//! weights ([`TexelView`]). Module docs of [`crate::mapped`], "View weighting".

use super::lobes;

/// The plain average's weight beside a footprint's seen area, in units of the seen area of a
/// flat footprint wholly seen (`o_z`): a footprint of which a fraction `D` is seen reads
/// `(Σ seen · L + e · Σ L) / (D + e)` per unit of projected area, `e = SEEN_FLOOR · (1 −
/// D / SEEN_FADE)⁺`. So a footprint barely seen, whose weighted mean is the ratio of two
/// small numbers (the edge of a lit texel the box filter grazes, beside texels the viewer
/// cannot see), turns continuously into the plain average, which one wholly hidden reads —
/// as the bump map's pixel does with no sample seen. On the steep facade map (view 60°, light
/// opposite it, 2 cells a pixel) the bare ratio lit rows of hidden pixels, 6.7× the bump
/// map's mean (docs/heightmaps.md, "Footprints barely seen").
pub(super) const SEEN_FLOOR: f64 = 1.0 / 64.0;

/// The seen fraction of a footprint from which the plain average has no part
/// ([`SEEN_FLOOR`]).
pub(super) const SEEN_FADE: f64 = 4.0 * SEEN_FLOOR;
use super::{NodeLevel, NO_LOBE};
use glam::DVec3;

/// What view weighting ([`crate::NdfMapped::with_view_weighting`]) reads of one pyramid lobe
/// of a texel: its axis (local frame, z up), Phong exponent and share of the texel's
/// projected area (0 for a lobe that is not shaded: no share, or no projected area
/// [`meso_maps::peak_projected_area`]), in `f32` (24 bytes a lobe).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct ViewLobe {
    /// The lobe's unit axis.
    pub(super) axis: [f32; 3],
    pub(super) eta: f32,
    pub(super) share: f32,
    /// The sine of the angle between the axis and the ring of its nodes
    /// ([`lobes::ring_cos`]), or 2 when that angle is 90° or more: every node is above a
    /// plane of normal `d` when `a·d` exceeds it.
    pub(super) ring_sin: f32,
}

/// The view weights of one texel's lobes for one viewing direction `o`
/// ([`crate::NdfMapped::with_view_weighting`]): per pyramid lobe `first + k` (`k < n`) its
/// visibility of the viewer `u[k]`, `flat` the weight of a texel shaded as the flat surface
/// ([`NO_LOBE`]), and `den`, the texel's area seen per unit of projected area, `Σ share ·
/// E[(m·o)⁺]/E[m_z⁺] · u` over its lobes ([`ViewLobe::seen`]). A lobe's response near normal
/// `m` is weighted by `u · (m·o)⁺/m_z` ([`TexelView::weight`]), whose mean over the lobe is its
/// term of `den`.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct TexelView {
    /// The viewing direction.
    pub(super) o: DVec3,
    pub(super) first: u32,
    pub(super) n: usize,
    /// Per lobe, its visibility of the viewer (1 without shadowing).
    pub(super) u: [f64; meso_maps::limits::MAX_LOBES],
    pub(super) flat: f64,
    pub(super) den: f64,
}

impl TexelView {
    /// The weights of texel `t` of `l` seen from `o`, each lobe's visibility of the viewer
    /// from `vis_o` (called with the lobe's `src`, or [`NO_LOBE`]; 1 without shadowing).
    pub(super) fn new(l: &NodeLevel, t: usize, o: DVec3, vis_o: impl Fn(u32) -> f64) -> TexelView {
        // Tables built without view weighting (none are read with it): seen nowhere, so the
        // footprint falls back to the plain average if no tap is seen.
        if l.view_start.is_empty() {
            return TexelView::default();
        }
        let (a, b) = (l.view_start[t], l.view_start[t + 1]);
        let mut tv = TexelView {
            o,
            first: a,
            n: ((b - a) as usize).min(meso_maps::limits::MAX_LOBES),
            ..TexelView::default()
        };
        let mut any = false;
        for k in 0..tv.n {
            let vl = &l.view[a as usize + k];
            if vl.share <= 0.0 {
                continue;
            }
            any = true;
            let seen = vl.seen(o);
            if seen > 0.0 {
                let u = vis_o(a + k as u32);
                tv.u[k] = u;
                tv.den += f64::from(vl.share) * seen * u;
            }
        }
        if !any {
            // Shaded as the flat surface (`NO_LOBE`).
            tv.flat = o.z * vis_o(NO_LOBE);
            tv.den = tv.flat;
        }
        tv
    }

    /// The view weight of lobe `src` (a tile's pyramid lobe, or [`NO_LOBE`]) near normal `m`:
    /// its visibility of the viewer times `(m·o)⁺/m_z`, the area seen from `o` per unit of
    /// projected area of facets of normal `m` (0 below the horizon).
    #[inline]
    pub(super) fn weight(&self, src: u32, m: DVec3) -> f64 {
        if src == NO_LOBE {
            return self.flat;
        }
        let k = src.wrapping_sub(self.first) as usize;
        if k >= self.n || m.z <= 0.0 {
            return 0.0;
        }
        self.u[k] * m.dot(self.o).max(0.0) / m.z
    }
}

impl ViewLobe {
    /// What view weighting reads of a lobe of axis `axis` (normalised here) and Phong
    /// exponent `eta`, with `share` of its texel's projected area and projected area `proj_z`
    /// per unit of weight: shaded (a share kept) only when both are positive, as the tables
    /// shade it.
    pub(super) fn new(axis: DVec3, eta: f64, share: f64, proj_z: f64) -> ViewLobe {
        let c = lobes::ring_cos(eta);
        ViewLobe {
            axis: axis.normalize_or_zero().as_vec3().to_array(),
            eta: eta as f32,
            share: if share > 0.0 && proj_z > 1e-12 {
                share as f32
            } else {
                0.0
            },
            ring_sin: if c > 0.0 {
                (1.0 - c * c).max(0.0).sqrt() as f32
            } else {
                2.0
            },
        }
    }

    /// The lobe's area seen from `o` per unit of its projected area, `E[(m·o)⁺]/E[m_z⁺]` by
    /// the lobe's nodes ([`lobes::peak_nodes`], the rule its Lambert and general facets are
    /// shaded by): `Σ w (m·o)⁺ / Σ w m_z⁺` over the nodes above the horizon; `o_z` for a sharp
    /// lobe on +z. Asked of the lobes that are shaded (`share > 0`, [`TexelView::new`]).
    #[inline]
    pub(super) fn seen(&self, o: DVec3) -> f64 {
        let a = DVec3::new(
            f64::from(self.axis[0]),
            f64::from(self.axis[1]),
            f64::from(self.axis[2]),
        );
        // Every node above both horizons (the ring's angular radius ρ plus the axis's angle θ
        // from `o`, and from +z, under π/2, i.e. cos θ > sin ρ): the nodes' weighted mean is
        // `mean cos · a`, so the ratio is `a·o / a_z` without them.
        let (ao, az) = (a.dot(o), a.z);
        let sr = f64::from(self.ring_sin);
        if ao > sr && az > sr {
            return ao / az;
        }
        let (num, den) = lobes::peak_node_sums(a.normalize(), f64::from(self.eta), o);
        if den > 0.0 {
            num / den
        } else {
            0.0
        }
    }
}
