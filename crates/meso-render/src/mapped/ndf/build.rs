//! Building an [`NdfMapped`] from a pyramid: per level and texel, its lobes as spherical
//! Gaussians weighted by their share of the texel's projected area over their own
//! ([`SgLobe`]), and for Lambert and general facets their nodes weighted by projected area
//! ([`Node`]); with shadowing, the horizon statistics of each texel and of each lobe (both
//! from [`meso_maps::lobe_stats`], which hands the level-0 normals' projected area and horizons
//! to the lobes that stand for them).
//!
//! # Conventions
//! * A texel with no lobe facing up shades as the flat surface (one lobe of
//!   `meso_maps::limits::ETA_MAX` on the normal; one node on the normal).
//! * Each texel's node weights sum to 1.

use super::lobes::{lobe_nodes, Node, SgLobe, Shapes, NO_LOBE};
use super::{NdfMapped, NodeLevel};
use crate::mapped::{check_scale, Facet};
use glam::DVec3;
use meso_core::material::Material;
use meso_core::sg;
use meso_maps::{lobe_stats_by_cell, peak_projected_area, Pyramid};
use std::f64::consts::FRAC_1_PI;

impl NdfMapped {
    /// The filtered material of `pyramid` with the facet transfer and diffuse term of
    /// `surface` (its NDF is ignored), `texels_per_uv` level-0 cells per unit of texture
    /// coordinate, and horizon shadowing of the light when `shadowing` is true (needs a
    /// pyramid extracted from a height map).
    ///
    /// # Errors
    /// A message for a bad `texels_per_uv`, or shadowing asked of a pyramid without horizon
    /// statistics (normal maps).
    pub fn new(
        pyramid: &Pyramid,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<NdfMapped, String> {
        check_levels(pyramid, texels_per_uv, shadowing)?;
        let facet = Facet::new(&surface.transfer);
        let stats = lobe_stats_by_cell(pyramid, shadowing);
        let mut lobe_horizons = stats.horizon.map(Vec::into_iter);
        let levels = pyramid
            .levels
            .iter()
            .zip(&stats.shares)
            .map(|(l, shares)| {
                let horizon = if shadowing { l.horizon.clone() } else { None };
                let lobe_horizon = lobe_horizons.as_mut().and_then(Iterator::next);
                node_level(l, shares, &facet, horizon, lobe_horizon)
            })
            .collect();
        Ok(NdfMapped::with_levels(
            levels,
            facet,
            surface,
            texels_per_uv,
            shadowing,
        ))
    }

    /// [`NdfMapped::new`] taking the pyramid: the same material, built with less memory at
    /// its peak (what `meso render` does with a map file's pyramid, which nothing else
    /// reads). Each level's horizon statistics move into the material instead of being
    /// copied, and each level's lobes, shares and lobe horizons are freed as soon as its
    /// table is built, so the peak is the pyramid, its lobe statistics and the finest level's
    /// table (`docs/benchmarks.md`, "Rendering a 4K map").
    ///
    /// # Errors
    /// As [`NdfMapped::new`].
    pub fn from_pyramid(
        mut pyramid: Pyramid,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<NdfMapped, String> {
        check_levels(&pyramid, texels_per_uv, shadowing)?;
        let facet = Facet::new(&surface.transfer);
        let stats = lobe_stats_by_cell(&pyramid, shadowing);
        let mut lobe_horizons = stats.horizon.map(Vec::into_iter);
        let mut levels = Vec::with_capacity(pyramid.levels.len());
        for (mut l, shares) in pyramid.levels.drain(..).zip(stats.shares) {
            let horizon = if shadowing { l.horizon.take() } else { None };
            let lobe_horizon = lobe_horizons.as_mut().and_then(Iterator::next);
            levels.push(node_level(&l, &shares, &facet, horizon, lobe_horizon));
            // `l` (its lobes) and `shares` are dropped here, before the next level's table.
        }
        Ok(NdfMapped::with_levels(
            levels,
            facet,
            surface,
            texels_per_uv,
            shadowing,
        ))
    }

    /// The material of these level tables, with the defaults of the options.
    fn with_levels(
        levels: Vec<NodeLevel>,
        facet: Facet,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> NdfMapped {
        NdfMapped {
            levels,
            facet,
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
            shadowing,
            footprint_scale: 1.0,
            sharp_magnification: false,
            box_filter: true,
            texel_visibility: false,
        }
    }
}

/// What [`NdfMapped::new`] refuses: a bad `texels_per_uv`, a pyramid without levels, and
/// shadowing asked of a level without horizon statistics.
fn check_levels(pyramid: &Pyramid, texels_per_uv: f64, shadowing: bool) -> Result<(), String> {
    check_scale(texels_per_uv)?;
    if shadowing {
        if let Some(k) = pyramid.levels.iter().position(|l| l.horizon.is_none()) {
            return Err(format!(
                "level {k} of the pyramid has no horizon statistics (a normal map?): \
                 shadowing needs a height map"
            ));
        }
    }
    if pyramid.levels.is_empty() {
        return Err("the pyramid has no levels".into());
    }
    Ok(())
}

/// The table of one pyramid level `l`: per texel its lobes as spherical Gaussians weighted by
/// `shares` (each lobe's share of its texel's projected area, [`meso_maps::lobe_stats`]), and for Lambert
/// and general facets its nodes; with the level's texel and lobe horizon statistics when
/// shadowing (`None` otherwise).
fn node_level(
    l: &meso_maps::Level,
    shares: &[f64],
    facet: &Facet,
    horizon: Option<meso_maps::Horizons>,
    lobe_horizon: Option<meso_maps::Horizons>,
) -> NodeLevel {
    // Lambert facets read nodes too: their response clips `m·i` and `m·o` (see `texel`).
    let general = matches!(facet, Facet::General(_) | Facet::Lambert { .. });
    let mut lobe_start = Vec::with_capacity(l.texels() + 1);
    let mut lobes = Vec::with_capacity(l.lobes.len());
    let mut shapes = Shapes::default();
    let mut node_start = Vec::new();
    let mut nodes = Vec::new();
    let mut tmp = Vec::new();
    lobe_start.push(0u32);
    if general {
        node_start.push(0u32);
    }
    let mut src = Vec::new();
    for t in 0..l.texels() {
        src.clear();
        src.extend(
            l.lobes
                .range(l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize),
        );
        // Each lobe's share of the texel's projected area (see `projected_shares`)
        // and its own projected area E[m_z⁺] per unit of weight.
        let share = &shares[l.lobe_start[t] as usize..l.lobe_start[t + 1] as usize];
        let mut any = false;
        let first = l.lobe_start[t];
        for (j, (p, &sh)) in src.iter().zip(share).enumerate() {
            let e = peak_projected_area(p.axis.z, p.exponent);
            if sh <= 0.0 || e <= 1e-12 {
                continue;
            }
            any = true;
            let shape = shapes.intern(p.exponent);
            let norm = sg::normaliser_2pi(shapes.list[shape as usize].kappa);
            lobes.push(SgLobe::new(p.axis, shape, sh / e * norm, first + j as u32));
        }
        if !any {
            // No lobe faces up: shade as the flat surface.
            let shape = shapes.intern(meso_maps::limits::ETA_MAX);
            let kappa = shapes.list[shape as usize].kappa;
            lobes.push(SgLobe::new(
                DVec3::Z,
                shape,
                sg::normaliser_2pi(kappa) / sg::phong_peak_mean_cos(meso_maps::limits::ETA_MAX),
                NO_LOBE,
            ));
        }
        lobe_start.push(lobes.len() as u32);
        if general {
            // Each lobe's nodes weighted by their projected area, scaled to the lobe's
            // share.
            let before = nodes.len();
            for (j, (p, &sh)) in src.iter().zip(share).enumerate() {
                tmp.clear();
                lobe_nodes(p.axis, 1.0, p.exponent, first + j as u32, &mut tmp);
                for n in &mut tmp {
                    n.w *= n.n.z.max(0.0);
                }
                let total: f64 = tmp.iter().map(|n| n.w).sum();
                if sh > 0.0 && total > 0.0 {
                    nodes.extend(tmp.iter().filter(|n| n.w > 0.0).map(|n| Node {
                        w: n.w / total * sh,
                        ..*n
                    }));
                }
            }
            let total: f64 = nodes[before..].iter().map(|n| n.w).sum();
            if total > 0.0 {
                for n in &mut nodes[before..] {
                    n.w /= total;
                }
            } else {
                nodes.truncate(before);
                nodes.push(Node {
                    n: DVec3::Z,
                    w: 1.0,
                    src: NO_LOBE,
                });
            }
            node_start.push(nodes.len() as u32);
        }
    }
    NodeLevel {
        cols: l.cols,
        rows: l.rows,
        span: l.span as f64,
        lobe_start,
        lobes,
        shapes: shapes.list,
        node_start,
        nodes,
        horizon,
        // `lobe_stats_by_cell`: level 0's lobe horizons are per texel (its cell's).
        lobe_horizon_by_texel: l.span == 1,
        lobe_horizon,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use meso_maps::{extract, fixtures, lobe_stats, ExtractParams, Source};

    /// [`NdfMapped::from_pyramid`] builds the very tables of [`NdfMapped::new`]; every lobe is
    /// shadowed with the statistics [`lobe_stats`] gives it (level 0's held once per texel),
    /// every texel with its pyramid texel's, and a texel's lobes and shapes are the pyramid's
    /// lobes' (axis, η) — on compact (`f32`) and `f64` levels, Phong and Lambert facets.
    #[test]
    fn from_pyramid_builds_the_tables_of_new() {
        // Rough enough that level-0 texels hold two lobes (their triangles' normals).
        let map = fixtures::gaussian(32, 4.0, 0.1, 3, 0.01).unwrap();
        for compact_texels in [usize::MAX, 64] {
            let params = ExtractParams {
                compact_texels,
                ..ExtractParams::default()
            };
            let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
            let stats = lobe_stats(&pyr, true);
            let hz = stats.horizon.as_ref().unwrap();
            for transfer in ["kind = \"phong\"\nexponent = 20.0", "kind = \"lambert\""] {
                let surface =
                    Material::from_toml_str(&format!("[transfer]\n{transfer}\n")).unwrap();
                for shadowing in [true, false] {
                    let a = NdfMapped::new(&pyr, &surface, 32.0, shadowing).unwrap();
                    let b =
                        NdfMapped::from_pyramid(pyr.clone(), &surface, 32.0, shadowing).unwrap();
                    assert_eq!(a.levels, b.levels);
                    let l0 = &pyr.levels[0];
                    assert!(l0.lobes.len() > l0.texels(), "two lobes a texel somewhere");
                    for (k, (l, nl)) in pyr.levels.iter().zip(&a.levels).enumerate() {
                        assert_eq!(nl.lobe_horizon_by_texel, k == 0);
                        for t in 0..l.texels() {
                            let (s, e) = (nl.lobe_start[t] as usize, nl.lobe_start[t + 1] as usize);
                            for sg in &nl.lobes[s..e] {
                                let got = nl.lobe_horizon(t, sg.src);
                                if !shadowing {
                                    assert!(got.is_none());
                                    continue;
                                }
                                let want = if sg.src == NO_LOBE {
                                    l.horizon.as_ref().unwrap().get(t)
                                } else {
                                    hz[k].get(sg.src as usize)
                                };
                                assert_eq!(got, Some(want), "level {k} texel {t}");
                            }
                        }
                        for sg in &nl.lobes {
                            if sg.src != NO_LOBE {
                                let p = l.lobes.get(sg.src as usize);
                                assert_eq!(sg.axis(), p.axis);
                                assert_eq!(
                                    nl.shapes[sg.shape()],
                                    super::super::lobes::Shape::new(p.exponent)
                                );
                            }
                        }
                    }
                }
            }
        }
    }
}
