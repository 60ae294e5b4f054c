//! Materials that vary over the surface with a height map: the bump-mapped ground truth
//! ([`BumpMapped`]) and its filtered counterpart reading an NDF pyramid ([`NdfMapped`]).
//!
//! # Placement
//! Both map the surface's texture coordinates onto the height map's grid of cells:
//! `x = u · texels_per_uv`, `y = v · texels_per_uv` (in cells), wrapped periodically, so the
//! map's columns (its x, `meso_maps` convention) run along the shading tangent (local `+x`)
//! and its rows along the bitangent (local `+y`); heights are along the local normal.
//!
//! # Shading (both materials)
//! A point of the bump map with facet normal `m` (local frame) is shaded as engines shade a
//! bump map, with its own cosine: radiance `f_μ(i, o; m) · E · max(0, m·i)`, where `f_μ` is the
//! material's facet transfer function (evaluated in the facet's frame, tangent = the surface
//! tangent made orthogonal to `m`). Returned to the renderer (which multiplies by `cos θi`)
//! as the BRDF `f_μ(i, o; m) · max(0, m·i) / cos θi`, plus the material's `diffuse/π`.
//! A pixel averages this over its footprint in `uv`, i.e. weights each facet by its
//! **projected** area.
//!
//! * [`BumpMapped`]: texel by texel: the facet normal of the triangulated height map under the
//!   point (two triangles per cell split along the `(i, j)–(i+1, j+1)` diagonal, exactly the
//!   surface `meso_maps` extracts its normals from). Optional shadowing: the light is blocked
//!   when a ray from the point towards it meets the displaced surface (the tiled mesh of the
//!   heights, `meso_maps::Gonio::sees`, as `meso gonio` traces it); on a clamped map, when it is
//!   below the horizon of the nearest height sample (`meso_maps::HorizonMap`, four azimuths
//!   interpolated as `HorizonStats::visibility`, the model of the renderer before 2026-12-06,
//!   `BumpMapped::new_horizon_shadowed`). Supersample it to get the ground truth of a pixel.
//! * [`NdfMapped`]: the pyramid of fitted Phong lobes. The level comes from the sample's
//!   footprint (`ShadingPoint::uv_footprint` from ray differentials, which the renderer shrinks
//!   to the sample's stratum of the pixel, centred at `ShadingPoint::filter_uv`, when it takes
//!   several samples per pixel): `lod = log2(footprint in cells) −
//!   ½` (the −½ matches the bilinear tent's spread to the pixel's box), clamped to the pyramid;
//!   the two nearest levels are blended linearly, and within each level the four nearest texels
//!   bilinearly (trilinear filtering), so zooming is continuous. Footprints under √2 cells
//!   (magnification) read level 0 bilinearly, or with [`NdfMapped::with_sharp_magnification`]
//!   through a box narrower than the bilinear tent, down to the single cell under the point,
//!   so that supersampling converges to the bump map's cells. By default (since 2026-12-02)
//!   a box of the footprint's size replaces the trilinear filter ([`NdfMapped::with_box_filter`],
//!   see "Steep maps"); `with_box_filter(false)` gives the trilinear filter described here.
//!   Each texel's response is computed **in closed form** from its fitted lobes (Eq. 12, area
//!   weights `w`, exponents `η_n`): with projected-area weighting (`× m_z`) the filtered
//!   shading is the average of the bump-mapped shading. Each lobe enters with its **share of
//!   the texel's projected area**, taken from the level-0 normals it stands for (each
//!   level-0 normal's projected area handed to the texel's lobes by the mixture's posterior),
//!   and its shape normalised by its own projected area `E[m_z⁺]` (`η_n/(η_n + 4)·a_z` for a
//!   lobe above the horizon; by quadrature for one that crosses it, whose part below covers
//!   nothing); see "Steep maps" below. Each peak is replaced by the spherical
//!   Gaussian `exp(κ(a·m − 1))` of the same mean cosine `η_n/(η_n + 4)`
//!   ([`meso_core::sg::kappa_same_mean_cos`]), the Phong facet term `(m·h)^η` by
//!   `exp(λ(m·h − 1))` with `λ = η + 1` (same integral, [`meso_core::sg::kappa_transfer`]), their
//!   product integrated exactly (a Gaussian of axis `m* ∝ κa + λh`), the facet cosines
//!   `(m·i)(m·z)` by the product's second moment, and the shapes corrected by the ratios of the
//!   Phong forms to their Gaussians at `m*` (exact for sharp lobes; within 1% of a quadrature of
//!   the lobes for broad ones, tested). Lambert facets and other transfers replace each lobe by 7 weighted nodes
//!   (the axis and a ring of 6 with the lobe's mean cosine, weighted by their `m_z⁺`), so
//!   that a facet facing away from the light (`m·i < 0`) or the viewer (`m·o ≤ 0`, the
//!   bump map's Lambert test) counts for nothing, as in the bump map. Optional shadowing
//!   multiplies **each lobe's** part by its own visibility of the light `V_j(i)`
//!   (`HorizonStats::visibility` of the horizon statistics of the cells the lobe stands for,
//!   [`meso_maps::lobe_stats`]; each node by its lobe's), see "Visibility per lobe" below;
//!   [`NdfMapped::with_texel_visibility`] keeps the model before: the response times the
//!   blended visibility of the texels.
//!
//! Nothing allocates per shading call.
//!
//! # Visibility per lobe
//! A texel's horizon statistics say how much of its footprint sees the light, not which of
//! its facets do: on touching half-cylinders the tops are lit and the creases shadowed, in
//! their negative (grooves, the same heights upside down: the same NDF) the rims are lit and
//! the bottoms shadowed, and one visibility per texel gives both the same answer (issue #11,
//! item 1). [`meso_maps::lobe_stats`] hands each level-0 cell's projected area to a coarse
//! texel's lobes by the mixture's posterior (the shares above) and, weighted by the same
//! area, the cell's horizon distribution ([`meso_maps::HorizonCdf`]: along eight azimuths,
//! the fraction of the cell whose horizon lies at or below each of 16 elevations, from its
//! four corner samples' angles interpolated bilinearly at 4 × 4 points): each lobe gets the
//! distribution of the horizons of the cells whose normals it stands for, pooled exactly.
//! Level 0's lobes take their cell's. Shading multiplies each lobe's closed-form term (Phong
//! facets) or each node (Lambert and general facets) by its lobe's `V_j(i)`; the light's
//! azimuth and elevation are prepared once per light ([`meso_maps::HorizonDirection`]), so a
//! lobe costs two table reads and two interpolations. The same code serves in-memory pyramids
//! and `.map` files (level 0 of a stored pyramid holds the samples' angles); a pyramid without
//! horizon statistics cannot shadow.
//!
//! Until 2026-12-07 a lobe pooled its cells' angles as a mean and a variance along four
//! azimuths, read through a uniform ramp: a lobe holding both wall tops (horizon 0) and
//! recess floors (horizons high) then hid a grazing light from nearly all of it, and lights
//! between the axes read an interpolation of the axes' horizons (a steep facade map at 16
//! cells a pixel under a light along +y: 0.29 of the truth; now 0.90–1.02 at every azimuth,
//! `tests/azimuths.rs`).
//!
//! Test `tests/visibility.rs`: half-cylinders (256², radius 32 cells) and their negative,
//! Phong η = 20 and Lambert facets, lights 65° and 75° from the normal across the cylinders,
//! 8–32 texels per pixel, NDF-mapped at 1 spp against the bump map shadowed by rays at 256
//! spp. Per lobe: mean pixel errors 0.1–2.3 % at 65°, 0.5–3.7 % at 75° but the glossy grooves
//! at 32 texels per pixel (1.22×: within a lobe the facets that reflect most, a sharp
//! highlight picking a few normals of a broad lobe, get the lobe's average visibility); per
//! texel far worse (up to 55 % at 65° and 6× the truth at 75° on the grooves). A gentle
//! Gaussian surface is no worse than per texel.
//!
//! With view weighting, a lobe's visibility of the light is read among what of it sees the
//! viewer ([`meso_maps::HorizonCdf::visibility_given`]): light and viewer 0° or 45° apart in
//! azimuth are one event (the smaller of the two fractions); farther apart, from level 2 on,
//! the lobe's joint horizon distribution says how the two go together
//! ([`meso_maps::HorizonJoint`]: on a facade the wall tops see both, the recess floors
//! neither), below it they are independent (their product). On the steep facade seen 60° from
//! the normal at 16 cells a pixel, with the product: 0.71–0.79 of the truth with the light
//! beside the viewer, 0.14–0.47 with it 90°–180° away; now 1.01–1.06 and 0.74–0.93
//! (`tests/azimuths.rs`); the 1K facade's far views under a light opposite the viewer, which
//! drifted up to 1.14× with the level, stay within 1.06× (docs/heightmaps.md, "Light and
//! viewer together per lobe").
//! Tables: docs/heightmaps.md, "Visibility per lobe" and "Eight azimuths and horizon
//! distributions per lobe".
//!
//! # View weighting
//! A pixel of the bump map averages its footprint by **plane** area: a facet turned away from
//! the viewer, or hidden behind a ridge, counts as much as one facing it. Displaced geometry
//! counts each facet by the area of it the viewer sees, `(m·o)⁺/m_z` per unit of plane area
//! times its visibility of the viewer. Seen from afar, the two differ by 10–50 % on maps with
//! steep walls (the facade height map against `meso gonio`, which traces rays on the displaced
//! mesh: the bump map is 13–49 % too bright). Both materials weigh by view where the map has
//! heights and shadowing is on, the default of height maps and of map files with horizon
//! statistics (scene files: `view_weighting = true | false` to choose):
//!
//! * [`BumpMapped::with_view_weighting`]: each pixel sample weighs `(m·o)⁺/(m_z·o_z)` times
//!   its facet's visibility of the viewer (a ray on the displaced surface, as for the light),
//!   and the pixel is the samples' weighted mean ([`crate::Shader::sample_weight`]; the render
//!   loop divides `Σ w·L` by `Σ w`). One sample per pixel is unchanged. Far views then agree with
//!   `meso gonio` within 2 % (0.3 % on average on the test's steep maps).
//! * [`NdfMapped::with_view_weighting`]: each lobe's response near normal `m` is weighed by
//!   `V_j(o) · (m·o)⁺/m_z` (`V_j(o)` its visibility of the viewer, from the same horizon
//!   statistics as the light's; the closed form takes `m` at the product's axis, the nodes
//!   their own normal) and the footprint's sum is divided by its seen area, `Σ share_j · V_j(o)
//!   · E_j[(m·o)⁺]/E_j[m_z⁺]` over the taps' lobes (the expectation by the lobe's 7 nodes; `a·o
//!   / a_z` when the lobe lies well above both horizons). A texel of one normal shades as
//!   without it (its weight cancels); a far view tends to the map's effective BRDF. Level 0
//!   reads each cell's visibility of the light and of the viewer together, per sub-cell
//!   (`meso_maps::CellHorizon`); coarser levels per lobe (`meso_maps::HorizonJoint`). A
//!   footprint of which under 1/16 is seen turns continuously into the plain average, which
//!   one wholly hidden reads (the ratio of two numbers near 0 is not a pixel's colour:
//!   `SEEN_FLOOR` in `ndf/view.rs`).
//!
//! Normal maps (and height maps with `shadowing = false`) are not weighted by default: with no
//! heights nothing masks their steep facets from the viewer, whose `1/m_z` then dominates the
//! weights, and the glossy steep normal map's NDF-mapped far views come out 11–25 % brighter
//! than its weighted bump map (`tests/steep.rs`; the coarse levels' lobes do not follow it).
//! Tests: `tests/view_weighting.rs` (far views against `meso_maps::Gonio`), meso-figures'
//! `tests/zoom.rs` (the zoom sequence's far frames within 0.75 % of the geometry);
//! docs/heightmaps.md, "View weighting".
//!
//! # Steep maps
//! On steep normal maps (issue #11: a stone wall with 20% of its texels at `n_z < 0.2`,
//! some at or below the horizon) NDF-mapped renders had sparkles and false highlights. Test
//! `tests/steep.rs` generates such a map (128², blocks with steep rims, 20.1% of texels at
//! `n_z < 0.2`, 437 at or below the horizon) and renders it NDF-mapped at 1 spp against the
//! bump map at 256 spp. What was wrong, each measured on that map:
//!
//! * **Lambert facets**: the texel's second moment `E[m (m·z)]·i` let facets facing away
//!   from the light cancel lit ones, and dropped the bump map's `m·o > 0` test: on steep rims
//!   many lit facets face away from the viewer. Renders were up to 47% too bright on
//!   average, one class of sub-texel phase 1.65×, one pixel 54× its truth. Now nodes (above).
//! * **Lobes at the horizon**: the texel's projected area was `Σ w μ a_z`, which counts the
//!   part of a lobe below the horizon negatively; for a lobe of η = 40 at `a_z = 0.05` the
//!   true `E[m_z⁺]` is several times `μ a_z`. Against a quadrature of the same lobes the
//!   closed form was 10–16% too bright on levels 4–6 (Phong η = 20 facets); with `E[m_z⁺]`
//!   within 0.4%.
//! * **Projected area of a fitted lobe**: a normal-map texel of `n_z` has area weight
//!   `1/n_z` (100 for one tilted up to 0.01) and one texel of projected area. A fitted lobe
//!   standing for such texels has a spread and an axis at `z ≥ 0.05` (the fit's bound), so
//!   `w·E[m_z⁺]` of its shape gave them several times their projected area: renders 20–50%
//!   too dark at 8–16 texels per pixel. The shares from the level-0 normals fix the level-1
//!   texels exactly; coarser levels are limited by the fit itself (it spends its lobes on the
//!   heavily weighted steep normals): still 15–29% too dark at 16 texels per pixel.
//!
//! * **The filter**: the trilinear filter weighs texels by a bilinear tent, the supersampled
//!   truth by the pixel's box; on a map this busy that alone leaves a 5.5% mean pixel error at
//!   2 texels per pixel, where levels 0 and 1 are exact. [`NdfMapped::with_box_filter`] takes
//!   the texels the footprint's box overlaps, weighted by overlap, on the level whose texels
//!   are an eighth to a quarter of the box, blended with the next level (up to 136 taps
//!   instead of 8): the default, as the closer of the two on every map measured. By default
//!   it reads finer texels still ([`NdfMapped::with_box_detail`], default
//!   [`default_box_detail`]: two levels finer, three for GGX α ≤ 0.158), whose lobes hold
//!   separate groups of normals and narrow highlights that the coarse texels' lobes merge
//!   (docs/heightmaps.md, "Glossy facets" and "Broad facets read two levels finer").
//!
//! Trilinear (the default), at 2 and 4 texels per pixel: mean radiance within 3.3% of the
//! truth, every class of sub-texel phase within 0.931–1.044, no pixel brighter than its truth
//! by more than 0.77 of the image mean (Lambert before: 1.65× classes, excess 3.96), but mean
//! pixel errors of 5.5–13.5%. Box filter: the 3% up to 8 texels per pixel with Phong
//! facets (0.1–2.9%) and 4 with Lambert facets (0.2–1.2%). Tables, the command and what is
//! left: docs/heightmaps.md, "Steep maps".

use crate::geometry::ShadingPoint;
use crate::shader::{fast_pow, Shader};
use glam::DVec3;
use meso_core::material::Material;
use meso_core::sg;
use meso_core::transfer::{PhongVariant, Transfer};
use meso_maps::{FacetNormals, Gonio, HeightMap, HorizonMap, NormalMap, NormalMode};
use std::f64::consts::FRAC_1_PI;
use std::sync::Arc;

/// The facet transfer function, with fast paths for Phong (half vector), Lambert and isotropic
/// microfacets.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Facet {
    Phong {
        exponent: f32,
        specular: [f32; 3],
    },
    Lambert {
        albedo_pi: [f32; 3],
    },
    /// An isotropic Beckmann or GGX facet (the common glossy material): its Fresnel factor
    /// `F(i·h)` is the same for every facet normal of a shading call, so the NDF-mapped
    /// shader applies it once per light direction as the colour and sums the scalar
    /// `D(m·h) G₂ / (4 (m·o))`: for a lobe broader than the highlight `D`'s core of
    /// Blinn–Phong peaks in closed form and the rest at its nodes, for a sharp one `D` at its
    /// nodes (`ndf/lobes.rs`, `MicrofacetCore`); the bump map per facet
    /// ([`Facet::microfacet_scalar`]).
    Microfacet {
        distribution: meso_core::ndf::Microfacet,
        fresnel: meso_core::transfer::Fresnel,
        /// `D`'s core (`MicrofacetCore::of`, once per material: the tables are built for it
        /// and the shading reads it), `None` for facets too broad to need one.
        core: Option<ndf::MicrofacetCore>,
    },
    General(Transfer),
}

impl Facet {
    fn new(t: &Transfer) -> Facet {
        match *t {
            Transfer::Phong {
                exponent,
                specular,
                variant: PhongVariant::Half,
            } => Facet::Phong {
                exponent: exponent as f32,
                specular: specular.map(|s| s as f32),
            },
            Transfer::Lambert { albedo } => Facet::Lambert {
                albedo_pi: albedo.map(|a| (a * FRAC_1_PI) as f32),
            },
            Transfer::Microfacet {
                distribution,
                fresnel,
            } if distribution.is_isotropic() => Facet::Microfacet {
                distribution,
                fresnel,
                core: ndf::MicrofacetCore::of(&distribution),
            },
            other => Facet::General(other),
        }
    }

    /// Whether the NDF-mapped shader evaluates this facet at its lobes' quadrature nodes (all
    /// but the Phong facet, whose lobes it convolves in closed form): their tables hold nodes.
    fn needs_nodes(&self) -> bool {
        !matches!(self, Facet::Phong { .. })
    }

    /// `D(m·h) G₂(i, o; m) (m·i) / (4 (m·i)(m·o))` of an isotropic microfacet facet of unit
    /// normal `m` (1/sr): [`Facet::lit`] without the Fresnel factor, which depends on `i·h`
    /// only; 0 for a facet that `i` or `o` does not see.
    #[inline]
    fn microfacet_scalar(
        d: &meso_core::ndf::Microfacet,
        m: DVec3,
        i: DVec3,
        o: DVec3,
        h: DVec3,
    ) -> f64 {
        let ci = m.dot(i);
        d.d_vis_isotropic(h.dot(m), ci, m.dot(o)) * ci
    }

    /// `f_μ(i, o; m) · max(0, m·i)` for the unit facet normal `m`; `h` is the unit half vector.
    #[inline]
    fn lit(&self, m: DVec3, i: DVec3, o: DVec3, h: DVec3) -> [f32; 3] {
        let mi = m.dot(i);
        if mi <= 0.0 {
            return [0.0; 3];
        }
        let mi32 = mi as f32;
        match *self {
            Facet::Phong { exponent, specular } => {
                let c = fast_pow(m.dot(h).max(0.0) as f32, exponent) * mi32;
                [specular[0] * c, specular[1] * c, specular[2] * c]
            }
            Facet::Lambert { albedo_pi } => {
                if m.dot(o) <= 0.0 {
                    return [0.0; 3];
                }
                [
                    albedo_pi[0] * mi32,
                    albedo_pi[1] * mi32,
                    albedo_pi[2] * mi32,
                ]
            }
            Facet::Microfacet {
                distribution,
                fresnel,
                ..
            } => {
                let c = Self::microfacet_scalar(&distribution, m, i, o, h);
                let f = fresnel.eval(i.dot(h));
                [(f[0] * c) as f32, (f[1] * c) as f32, (f[2] * c) as f32]
            }
            Facet::General(t) => {
                // From the cosines alone where the transfer is isotropic about `m` (the facet
                // frame only for anisotropic microfacets: `Transfer::eval_facet`).
                let v = t.eval_facet(m, i, o, Some(h));
                [(v[0] * mi) as f32, (v[1] * mi) as f32, (v[2] * mi) as f32]
            }
        }
    }
}

/// Map coordinates of texture coordinates `(u, v)` on a map of `rows` level-0 cell rows with
/// `texels_per_uv` cells per unit of uv: `x = u·texels_per_uv` (cells, to the right) and
/// `y = rows − v·texels_per_uv` (cells, **up** the image as the map's rows run, docs/conventions.md),
/// since meso's `v` follows glTF and grows down the image: `uv = (0, 0)` is the image's top-left
/// corner. Callers wrap both (the texture repeats).
#[inline(always)]
pub(crate) fn map_xy(u: f64, v: f64, texels_per_uv: f64, rows: usize) -> (f64, f64) {
    (u * texels_per_uv, rows as f64 - v * texels_per_uv)
}

/// Refuse a `texels_per_uv` that is not a number in (0, [`crate::limits::MAX_TEXELS_PER_UV`]].
pub(crate) fn check_scale(texels_per_uv: f64) -> Result<(), String> {
    let max = crate::limits::MAX_TEXELS_PER_UV;
    if texels_per_uv.is_finite() && texels_per_uv > 0.0 && texels_per_uv <= max {
        Ok(())
    } else {
        Err(format!(
            "texels_per_uv must be a number > 0 and at most {max:e}, got {texels_per_uv:e}"
        ))
    }
}

mod bump;
mod ndf;
pub use bump::BumpMapped;
pub use ndf::{
    default_box_detail, NdfMapped, BROAD_BOX_DETAIL, DEFAULT_MAX_BOX_DETAIL,
    GLOSSY_BOX_DETAIL_FROM, MAX_BOX_DETAIL, MEMO_BYTES,
};
