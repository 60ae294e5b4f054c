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

use super::filter::default_box_detail;
use super::lobes::{lobe_nodes, LobeRole, Node, SgLobe, Shapes, NO_LOBE};
use super::view::ViewLobe;
use super::{NdfMapped, NodeLevel, Slot, TexLevel, TileCache, NEXT_MEMO_ID};
use crate::mapped::{check_scale, Facet};
use glam::DVec3;
use meso_core::material::Material;
use meso_core::sg;
use meso_maps::{
    lobe_stats_by_cell, peak_projected_area, rect_lobe_stats_by_cell, Horizons, Pyramid,
};
use std::f64::consts::FRAC_1_PI;
use std::sync::Arc;

/// Side of a tile of [`NdfMapped::from_pyramid`]'s tables, in texels: 64 × 64 texels (a
/// level-0 tile of a height map ≈ 8 k lobes, ≈ 0.5 MB of tables with shadowing).
pub const TILE_TEXELS: usize = 64;

/// The pyramid a lazily built material builds its tiles from.
#[derive(Clone)]
pub(super) struct Source {
    pyramid: Arc<Pyramid>,
}

impl Source {
    /// The pyramid.
    pub(super) fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }
}

impl std::fmt::Debug for Source {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = &self.pyramid;
        write!(
            f,
            "Source({} levels, {}×{} texels)",
            p.levels.len(),
            p.width,
            p.height
        )
    }
}

impl NdfMapped {
    /// The filtered material of `pyramid` with the facet transfer and diffuse term of
    /// `surface` (its NDF is ignored), `texels_per_uv` level-0 cells per unit of texture
    /// coordinate, and horizon shadowing of the light when `shadowing` is true (needs a
    /// pyramid extracted from a height map) and then weighting by view
    /// ([`NdfMapped::with_view_weighting`]). Every level's table is built now, one tile a
    /// level ([`NdfMapped::from_pyramid`] builds them as they are read).
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
        NdfMapped::new_reporting(pyramid, surface, texels_per_uv, shadowing, None)
    }

    /// [`NdfMapped::new`], reporting the progress of its lobes' sums (most of the time it
    /// takes: seconds on a 1024² height map) to `report` when given
    /// ([`meso_maps::lobe_stats_by_cell_reporting`], task [`meso_maps::ProgressTask::Tables`]).
    ///
    /// # Errors
    /// As [`NdfMapped::new`].
    pub fn new_reporting(
        pyramid: &Pyramid,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
        report: Option<&(dyn Fn(meso_maps::Progress) + Sync)>,
    ) -> Result<NdfMapped, String> {
        check_levels(pyramid, texels_per_uv, shadowing)?;
        let facet = Facet::new(&surface.transfer);
        let stats = match report {
            Some(r) => meso_maps::lobe_stats_by_cell_reporting(pyramid, shadowing, r),
            None => lobe_stats_by_cell(pyramid, shadowing),
        };
        let mut lobe_horizons = stats.horizon.map(Vec::into_iter);
        // Level 0 shades with its cells' horizons, not its cells' distributions.
        let mut cells = stats.cells;
        let mut lobe_joints = stats.joint.map(Vec::into_iter);
        let mut lobe_towards = stats.toward.map(Vec::into_iter);
        let levels = pyramid
            .levels
            .iter()
            .zip(&stats.shares)
            .map(|(l, shares)| {
                let horizon = if shadowing { l.horizon.clone() } else { None };
                let lobe_horizon = lobe_horizons
                    .as_mut()
                    .and_then(Iterator::next)
                    .filter(|_| l.span > 1);
                let cells = if l.span == 1 { cells.take() } else { None };
                let lobe_joint = lobe_joints
                    .as_mut()
                    .and_then(Iterator::next)
                    .filter(|j| !j.is_empty());
                let lobe_toward = lobe_towards
                    .as_mut()
                    .and_then(Iterator::next)
                    .filter(|j| !j.is_empty());
                let table = node_level(
                    l,
                    0..l.rows,
                    0..l.cols,
                    shares,
                    &facet,
                    horizon,
                    lobe_horizon,
                    cells,
                    lobe_joint,
                    lobe_toward,
                    // Built up front: ready for view weighting, asked for or not.
                    true,
                );
                TexLevel {
                    cols: l.cols,
                    rows: l.rows,
                    span: l.span as f64,
                    tile: l.cols.max(l.rows),
                    tiles_x: 1,
                    tiles: vec![Slot::built(table)],
                }
            })
            .collect();
        Ok(NdfMapped::with_levels(
            levels,
            None,
            facet,
            surface,
            texels_per_uv,
            shadowing,
        ))
    }

    /// [`NdfMapped::new`] taking the pyramid: the same material (the same shading, bit for
    /// bit), whose tables are built tile by tile (`TILE_TEXELS`² texels of a level) when a
    /// shading call first reads them, each tile's lobe statistics with it
    /// ([`meso_maps::rect_lobe_stats_by_cell`]); the pyramid stays held to build them from.
    /// What `meso render` does with a map file's pyramid: a far view of a big map reads only
    /// coarse levels, a zoomed view the few level-0 tiles in sight, so the memory beyond the
    /// pyramid is the tables of the tiles read (`docs/map-format.md`, "Rendering a map file").
    ///
    /// # Errors
    /// As [`NdfMapped::new`].
    pub fn from_pyramid(
        pyramid: Pyramid,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> Result<NdfMapped, String> {
        check_levels(&pyramid, texels_per_uv, shadowing)?;
        let facet = Facet::new(&surface.transfer);
        let levels = pyramid
            .levels
            .iter()
            .map(|l| {
                let tiles_x = l.cols.div_ceil(TILE_TEXELS);
                let tiles_y = l.rows.div_ceil(TILE_TEXELS);
                TexLevel {
                    cols: l.cols,
                    rows: l.rows,
                    span: l.span as f64,
                    tile: TILE_TEXELS,
                    tiles_x,
                    tiles: (0..tiles_x * tiles_y).map(|_| Slot::default()).collect(),
                }
            })
            .collect();
        let source = Source {
            pyramid: Arc::new(pyramid),
        };
        Ok(NdfMapped::with_levels(
            levels,
            Some(source),
            facet,
            surface,
            texels_per_uv,
            shadowing,
        ))
    }

    /// The most memory (bytes) the tables of [`NdfMapped::from_pyramid`] can take once every
    /// tile of `pyramid` is built (a view reading all of every level), with the facet
    /// transfer of `surface` and `shadowing`, view weighting on or off: per lobe its `SgLobe`
    /// (40 bytes) and what view weighting reads of it (`ViewLobe`, 24 bytes, built only with
    /// view weighting; with Lambert or general facets also its nodes, at most 7 of 40 bytes),
    /// per texel its lobe and view starts (4 + 4, and 4 more for the node start) and with
    /// shadowing its horizon statistics (68 bytes in `f32`, 136 in `f64`: eight azimuths),
    /// on level 0 its cell's horizons (128 bytes, `meso_maps::CellHorizon`), per coarser lobe
    /// its distribution (132, `meso_maps::HorizonCdf`) and from level
    /// `meso_maps::JOINT_FROM_LEVEL` on its joint distribution (356, `meso_maps::HorizonJoint`)
    /// and its facets turned towards each azimuth (136, `meso_maps::HorizonToward`);
    /// per level the lobes' shapes (24 bytes per distinct exponent) and the table itself. What
    /// `meso render` checks against the memory budget, with the pyramid, before rendering
    /// (`docs/limits.md`).
    #[must_use]
    pub fn tables_bytes_bound(pyramid: &Pyramid, surface: &Material, shadowing: bool) -> u64 {
        let facet = Facet::new(&surface.transfer);
        (0..pyramid.levels.len())
            .map(|k| level_tables_bytes(pyramid, k, &facet, shadowing, true))
            .sum()
    }

    /// Bytes of a pyramid as held in memory: its lobes, lobe starts and horizon statistics
    /// (what [`NdfMapped::from_pyramid`] keeps besides its tables).
    #[must_use]
    pub fn pyramid_bytes(pyramid: &Pyramid) -> u64 {
        pyramid
            .levels
            .iter()
            .map(|l| {
                (l.lobes.bytes()
                    + l.lobe_start.len() * 4
                    + l.horizon.as_ref().map_or(0, Horizons::bytes)) as u64
            })
            .sum()
    }

    /// Build tile `i` of level `lev` from the source pyramid.
    ///
    /// # Panics
    /// Without a source (every tile of [`NdfMapped::new`] is built up front).
    pub(super) fn build_tile(&self, lev: usize, i: usize) -> NodeLevel {
        let src = self
            .source
            .as_ref()
            .expect("a material built by NdfMapped::new has all its tiles");
        let p = &*src.pyramid;
        let l = &p.levels[lev];
        let (rows, cols) = self.levels[lev].tile_rect(i);
        let stats = rect_lobe_stats_by_cell(p, lev, rows.clone(), cols.clone(), self.shadowing);
        let horizon = if self.shadowing {
            l.horizon.as_ref().map(|h| {
                let mut v = Vec::with_capacity(rows.len() * cols.len());
                for r in rows.clone() {
                    v.extend(cols.clone().map(|c| h.get(r * l.cols + c)));
                }
                Horizons::new(v, h.is_compact())
            })
        } else {
            None
        };
        node_level(
            l,
            rows,
            cols,
            &stats.shares,
            &self.facet,
            horizon,
            stats.horizon,
            stats.cells,
            stats.joint,
            stats.toward,
            self.view_weighting,
        )
    }

    /// The material of these level tables, with the defaults of the options (view weighting on
    /// with `shadowing`).
    fn with_levels(
        levels: Vec<TexLevel>,
        source: Option<Source>,
        facet: Facet,
        surface: &Material,
        texels_per_uv: f64,
        shadowing: bool,
    ) -> NdfMapped {
        NdfMapped {
            levels,
            source,
            cache: TileCache {
                cap: usize::MAX,
                ..TileCache::default()
            },
            facet,
            diffuse: surface.diffuse.map(|a| (a * FRAC_1_PI) as f32),
            texels_per_uv,
            shadowing,
            footprint_scale: 1.0,
            sharp_magnification: false,
            box_filter: true,
            box_detail: default_box_detail(&surface.transfer),
            detail_floor: 0,
            texel_visibility: false,
            // On where the heights can hide facets from the viewer (docs/heightmaps.md, "View
            // weighting"): a normal map's steep facets, with nothing to mask them, would count
            // 1/n_z times more.
            view_weighting: shadowing,
            memo_id: NEXT_MEMO_ID.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
            memo_cap: super::MEMO_BYTES,
        }
    }
}

/// The most memory (bytes) the tables of level `k` of `pyramid` can take with `facet`,
/// `shadowing` and, when `view_tables`, what view weighting reads (see
/// [`NdfMapped::tables_bytes_bound`], the sum over the levels).
pub(super) fn level_tables_bytes(
    pyramid: &Pyramid,
    k: usize,
    facet: &Facet,
    shadowing: bool,
    view_tables: bool,
) -> u64 {
    let general = facet.needs_nodes();
    let l = &pyramid.levels[k];
    let (texels, lobes) = (l.texels() as u64, l.lobes.len().max(l.texels()) as u64);
    let hz = if l.lobes.is_compact() {
        size_of::<meso_maps::Horizon32>()
    } else {
        size_of::<meso_maps::HorizonStats>()
    } as u64;
    // Lobes as spherical Gaussians (40 bytes) and their texels' starts (one more than the
    // texels), their shapes (at most one a lobe, and a map file's 16-bit exponents give at
    // most 65 536 and the cap's), and the table itself; with view weighting what it reads of
    // each lobe (`ViewLobe`) and their starts.
    let shapes = lobes.min(65_537) * size_of::<super::lobes::Shape>() as u64;
    let mut total = lobes * 40 + (texels + 1) * 4 + shapes + size_of::<super::NodeLevel>() as u64;
    if view_tables {
        total += lobes * size_of::<ViewLobe>() as u64 + (texels + 1) * 4;
    }
    if general {
        total += lobes * 7 * 40 + (texels + 1) * 4;
    }
    if shadowing {
        // Level 0: each texel's cell's horizons; above: each lobe's distribution, and from
        // `JOINT_FROM_LEVEL` on its joint distribution.
        total += texels * hz;
        total += if k == 0 {
            texels * size_of::<meso_maps::CellHorizon>() as u64
        } else {
            lobes * size_of::<meso_maps::HorizonCdf>() as u64
        };
        if k >= meso_maps::JOINT_FROM_LEVEL {
            total += lobes
                * (size_of::<meso_maps::HorizonJoint>() + size_of::<meso_maps::HorizonToward>())
                    as u64;
        }
    }
    total
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

/// The table of the texels `rows × cols` of pyramid level `l` (a tile, or the whole level):
/// per texel its lobes as spherical Gaussians weighted by `shares` (each lobe's share of its
/// texel's projected area, [`meso_maps::lobe_stats`], for the tile's lobes in texel order), and
/// for Lambert and general facets its nodes; with the tile's texel and lobe horizon statistics
/// (on level 0 its cells' horizons, `cells`, instead of the lobes') and its lobes' joint
/// horizon distributions when shadowing (`None` otherwise, and the joint also on levels below
/// [`meso_maps::JOINT_FROM_LEVEL`]), and when `view_tables` what view weighting reads of each
/// lobe (`ViewLobe`). Lobe sources (`src`) count the tile's lobes.
#[allow(clippy::too_many_arguments)]
fn node_level(
    l: &meso_maps::Level,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    shares: &[f64],
    facet: &Facet,
    horizon: Option<meso_maps::Horizons>,
    lobe_horizon: Option<Vec<meso_maps::HorizonCdf>>,
    cells: Option<Vec<meso_maps::CellHorizon>>,
    lobe_joint: Option<Vec<meso_maps::HorizonJoint>>,
    lobe_toward: Option<Vec<meso_maps::HorizonToward>>,
    view_tables: bool,
) -> NodeLevel {
    // Lambert facets read nodes too: their response clips `m·i` and `m·o` (see `texel`).
    let general = facet.needs_nodes();
    // Isotropic microfacet facets: broad lobes convolved with the facet's core in closed form.
    let core = match facet {
        Facet::Microfacet { core, .. } => *core,
        _ => None,
    };
    let (ncols, nrows) = (cols.len(), rows.len());
    let mut lobe_start = Vec::with_capacity(ncols * nrows + 1);
    let mut lobes = Vec::with_capacity(shares.len());
    let mut shapes = Shapes::default();
    let mut node_start = Vec::new();
    let mut nodes = Vec::new();
    let mut tmp = Vec::new();
    lobe_start.push(0u32);
    if general {
        node_start.push(0u32);
    }
    let mut src = Vec::new();
    let mut roles = Vec::new();
    // What view weighting reads (`ViewLobe`), when asked for.
    let (mut view_start, mut view) = (Vec::new(), Vec::new());
    if view_tables {
        view_start.reserve(ncols * nrows + 1);
        view.reserve(shares.len());
        view_start.push(0u32);
    }
    // The tile's lobes seen so far: the first lobe of the texel among them.
    let mut first = 0u32;
    for t in rows.flat_map(|r| cols.clone().map(move |c| r * l.cols + c)) {
        src.clear();
        src.extend(
            l.lobes
                .range(l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize),
        );
        // Each lobe's share of the texel's projected area (see `projected_shares`)
        // and its own projected area E[m_z⁺] per unit of weight.
        let share = &shares[first as usize..first as usize + src.len()];
        let mut any = false;
        // How each lobe is shaded: with a microfacet core, a lobe in the closed form leaves
        // only the rest of `D` to its nodes, or nothing when it is broad.
        roles.clear();
        for (j, (p, &sh)) in src.iter().zip(share).enumerate() {
            let e = peak_projected_area(p.axis.z, p.exponent);
            if view_tables {
                view.push(ViewLobe::new(p.axis, p.exponent, sh, e));
            }
            let role = match core {
                Some(c) if sh > 0.0 && e > 1e-12 => c.role(p.exponent),
                _ => LobeRole::Whole,
            };
            roles.push(role);
            if sh <= 0.0 || e <= 1e-12 {
                continue;
            }
            any = true;
            if role == LobeRole::Whole && core.is_some() {
                // Shaded whole at its nodes (below).
                continue;
            }
            let shape = shapes.intern(p.exponent);
            let norm = sg::normaliser_2pi(shapes.list[shape as usize].kappa);
            lobes.push(SgLobe::new(p.axis, shape, sh / e * norm, first + j as u32));
        }
        if !any && core.is_none() {
            // No lobe faces up: shade as the flat surface (with a microfacet core, the flat
            // node below).
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
            // The shares of the lobes with nodes, or only in the core (below).
            let mut total_share = 0.0;
            for (j, (p, &sh)) in src.iter().zip(share).enumerate() {
                tmp.clear();
                lobe_nodes(p.axis, 1.0, p.exponent, first + j as u32, &mut tmp);
                for n in &mut tmp {
                    n.w *= n.n.z.max(0.0);
                }
                let total: f64 = tmp.iter().map(|n| n.w).sum();
                if sh <= 0.0 {
                    continue;
                }
                // A lobe in the core counts its share with or without nodes above the
                // horizon.
                let role = roles[j];
                if role != LobeRole::Whole || total > 0.0 {
                    total_share += sh;
                }
                if role == LobeRole::Core || total <= 0.0 {
                    continue;
                }
                nodes.extend(tmp.iter().filter(|n| n.w > 0.0).map(|n| Node {
                    w: n.w / total * sh,
                    whole: role == LobeRole::Whole,
                    ..*n
                }));
            }
            if total_share > 0.0 {
                for n in &mut nodes[before..] {
                    n.w /= total_share;
                }
            } else {
                nodes.truncate(before);
                nodes.push(Node {
                    n: DVec3::Z,
                    w: 1.0,
                    src: NO_LOBE,
                    whole: true,
                });
            }
            node_start.push(nodes.len() as u32);
        }
        first += src.len() as u32;
        if view_tables {
            view_start.push(first);
        }
    }
    NodeLevel {
        cols: ncols,
        rows: nrows,
        span: l.span as f64,
        lobe_start,
        lobes,
        shapes: shapes.list,
        node_start,
        nodes,
        horizon,
        lobe_horizon,
        cells,
        lobe_joint,
        lobe_toward,
        view_start,
        view,
    }
}

#[cfg(test)]
mod tests {
    use super::super::LobeHorizon;
    use super::*;
    use crate::shader::local_point;
    use crate::shader::Shader;
    use glam::DVec2;
    use meso_maps::{extract, fixtures, lobe_stats, ExtractParams, Source};

    /// [`NdfMapped::new`] builds one tile a level whose lobes are shadowed with the statistics
    /// [`lobe_stats`] gives them (level 0 with its cells' horizons, once per texel), every texel with its
    /// pyramid texel's, and whose lobes and shapes are the pyramid's lobes' (axis, η) — on
    /// compact (`f32`) and `f64` levels, Phong and Lambert facets.
    #[test]
    fn new_builds_whole_level_tables_of_the_lobe_stats() {
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
            let cells = stats.cells.as_ref().unwrap();
            for transfer in ["kind = \"phong\"\nexponent = 20.0", "kind = \"lambert\""] {
                let surface =
                    Material::from_toml_str(&format!("[transfer]\n{transfer}\n")).unwrap();
                for shadowing in [true, false] {
                    let a = NdfMapped::new(&pyr, &surface, 32.0, shadowing).unwrap();
                    assert_eq!(a.tiles_built(), pyr.levels.len());
                    let l0 = &pyr.levels[0];
                    assert!(l0.lobes.len() > l0.texels(), "two lobes a texel somewhere");
                    for (k, (l, tl)) in pyr.levels.iter().zip(&a.levels).enumerate() {
                        let nl = tl.tiles[0].get().unwrap();
                        let nl = &*nl;
                        assert_eq!(nl.cells.is_some(), k == 0 && shadowing);
                        for t in 0..l.texels() {
                            let (s, e) = (nl.lobe_start[t] as usize, nl.lobe_start[t + 1] as usize);
                            for sg in &nl.lobes[s..e] {
                                let got = nl.lobe_horizon(t, sg.src);
                                if !shadowing {
                                    assert!(got.is_none());
                                    continue;
                                }
                                let want = if sg.src == NO_LOBE {
                                    LobeHorizon::Texel(l.horizon.as_ref().unwrap().get(t))
                                } else if k == 0 {
                                    LobeHorizon::Cell(cells.get(t).unwrap())
                                } else {
                                    LobeHorizon::Lobe(&hz[k][sg.src as usize])
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

    /// [`NdfMapped::from_pyramid`] (tables built tile by tile as they are read) shades every
    /// point bit for bit as [`NdfMapped::new`] (all built up front): over footprints from
    /// below level 0 to the whole map (every level read), both filters, Phong, Lambert and
    /// general facets, with and without shadowing, on a map of several tiles a level
    /// (128², tiles of 64²: level 0 four tiles). A small footprint builds few tiles.
    #[test]
    fn lazy_tiles_shade_as_the_eager_tables() {
        let map = fixtures::gaussian(128, 4.0, 0.1, 3, 0.01).unwrap();
        let params = ExtractParams {
            compact_texels: 64 * 64,
            ..ExtractParams::default()
        };
        let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
        assert!(pyr.levels[0].lobes.len() > pyr.levels[0].texels());
        let total_tiles: usize = pyr
            .levels
            .iter()
            .map(|l| l.cols.div_ceil(TILE_TEXELS) * l.rows.div_ceil(TILE_TEXELS))
            .sum();
        assert_eq!(total_tiles, 4 + 1 + 1 + 1 + 1 + 1 + 1 + 1);
        let transfers = [
            "kind = \"phong\"\nexponent = 20.0",
            "kind = \"lambert\"",
            "kind = \"microfacet\"\nalpha = 0.3",
        ];
        let wi: Vec<DVec3> = [(0.3, 0.4), (-0.6, 0.1), (0.05, -0.8), (0.9, 0.2)]
            .iter()
            .map(|&(x, y)| DVec3::new(x, y, (1.0f64 - x * x - y * y).sqrt()))
            .collect();
        let wo = DVec3::new(-0.2, 0.3, 0.93).normalize();
        let tpu = 128.0;
        for transfer in transfers {
            let surface = Material::from_toml_str(&format!("[transfer]\n{transfer}\n")).unwrap();
            for shadowing in [true, false] {
                for box_filter in [true, false] {
                    // Box detail 0 on all three: under a table cap a finer detail reads no
                    // finer than the cap allows, by design (`with_box_detail`).
                    let eager = NdfMapped::new(&pyr, &surface, tpu, shadowing)
                        .unwrap()
                        .with_box_filter(box_filter)
                        .with_box_detail(0.0);
                    let lazy = NdfMapped::from_pyramid(pyr.clone(), &surface, tpu, shadowing)
                        .unwrap()
                        .with_box_filter(box_filter)
                        .with_box_detail(0.0);
                    // Capped at 1 byte: every tile dropped as soon as another is built (bar
                    // those read since the last pass), rebuilt when read again.
                    let capped = NdfMapped::from_pyramid(pyr.clone(), &surface, tpu, shadowing)
                        .unwrap()
                        .with_box_filter(box_filter)
                        .with_box_detail(0.0)
                        .with_table_cap(1);
                    let mut c = vec![[0.0f32; 3]; 4];
                    assert_eq!(lazy.tiles_built(), 0);
                    // One point, a footprint under a cell: level 0 (and 1) only.
                    let sp = local_point(DVec2::new(0.1, 0.2), 0.3 / tpu);
                    let (mut a, mut b) = (vec![[0.0f32; 3]; 4], vec![[0.0f32; 3]; 4]);
                    eager.eval_many(&sp, wo, &wi, &mut a);
                    lazy.eval_many(&sp, wo, &wi, &mut b);
                    assert_eq!(a, b);
                    let few = lazy.tiles_built();
                    assert!((1..=3).contains(&few), "{few} tiles built");
                    // Every level-0 tile's centre under a cell, the whole map, then a sweep.
                    let mut points: Vec<(DVec2, f64)> = [0.25, 0.75]
                        .iter()
                        .flat_map(|&u| [0.25, 0.75].map(|v| (DVec2::new(u, v), 0.5 / tpu)))
                        .collect();
                    points.push((DVec2::new(0.5, 0.5), 1000.0 / tpu));
                    for i in 0..200u32 {
                        let f = f64::from(i);
                        let uv = DVec2::new(
                            (f * 0.618_034).fract() * 1.3 - 0.1,
                            (f * 0.414_214).fract(),
                        );
                        // Footprints 2⁻³ … 2⁸ cells.
                        points.push((uv, (2.0f64).powf(-3.0 + 11.0 * (f * 0.7548).fract()) / tpu));
                    }
                    for (i, &(uv, fp)) in points.iter().enumerate() {
                        let sp = local_point(uv, fp);
                        eager.eval_many(&sp, wo, &wi, &mut a);
                        lazy.eval_many(&sp, wo, &wi, &mut b);
                        // (Rebuilding the coarse tiles visits all of level 0 each time: the
                        // capped material only over the first points.)
                        let check_capped = transfer.contains("phong");
                        if i < 40 && check_capped {
                            capped.eval_many(&sp, wo, &wi, &mut c);
                        } else {
                            c.copy_from_slice(&a);
                        }
                        for ((x, y), z) in a.iter().zip(&b).zip(&c) {
                            for ch in 0..3 {
                                assert_eq!(x[ch].to_bits(), y[ch].to_bits(), "{transfer} {i}");
                                assert_eq!(x[ch].to_bits(), z[ch].to_bits(), "{transfer} {i}");
                            }
                        }
                    }
                    assert_eq!(lazy.tiles_built(), total_tiles);
                    let (bytes, peak, dropped) = lazy.table_cache_stats();
                    assert_eq!((bytes, dropped), (peak, 0));
                    assert!(bytes > 0);
                    if transfer.contains("phong") {
                        let (_, _, dropped) = capped.table_cache_stats();
                        assert!(dropped > 10, "{dropped} tiles dropped");
                        assert!(capped.tiles_built() < total_tiles);
                    }
                    assert_eq!(eager.table_cache_stats(), (0, 0, 0));
                }
            }
        }
    }

    /// View weighting reads the same from tiles built on demand as from the eager tables, bit
    /// for bit: set before any tile is built, or after some were built without it (which drops
    /// them: they hold nothing of it). Tiles built without it hold less.
    #[test]
    fn lazy_tiles_with_view_weighting_shade_as_the_eager_tables() {
        let map = fixtures::gaussian(128, 4.0, 0.3, 5, 0.01).unwrap();
        let pyr = extract(
            Source::Heights(&map),
            &ExtractParams::default(),
            &mut |_| {},
        )
        .unwrap();
        let wi: Vec<DVec3> = [(0.3, 0.4), (-0.6, 0.1), (0.05, -0.8)]
            .iter()
            .map(|&(x, y)| DVec3::new(x, y, (1.0f64 - x * x - y * y).sqrt()))
            .collect();
        let wo = DVec3::new(-0.2, -0.5, 0.84).normalize();
        let tpu = 128.0;
        for transfer in [
            "kind = \"phong\"\nexponent = 20.0",
            "kind = \"lambert\"",
            "kind = \"microfacet\"\nalpha = 0.3",
        ] {
            let surface = Material::from_toml_str(&format!("[transfer]\n{transfer}\n")).unwrap();
            // On by default with shadowing, off without.
            let eager = NdfMapped::new(&pyr, &surface, tpu, true).unwrap();
            assert!(eager.view_weighting());
            assert!(!NdfMapped::new(&pyr, &surface, tpu, false)
                .unwrap()
                .view_weighting());
            let plain = eager.clone().with_view_weighting(false);
            let lazy = NdfMapped::from_pyramid(pyr.clone(), &surface, tpu, true).unwrap();
            assert!(lazy.view_weighting());
            let lazy_plain = NdfMapped::from_pyramid(pyr.clone(), &surface, tpu, true)
                .unwrap()
                .with_view_weighting(false);
            let points: Vec<crate::ShadingPoint> = (0..60u32)
                .map(|i| {
                    let f = f64::from(i);
                    let uv = DVec2::new((f * 0.618_034).fract(), (f * 0.414_214).fract());
                    local_point(uv, (2.0f64).powf(-2.0 + 10.0 * (f * 0.7548).fract()) / tpu)
                })
                .collect();
            let shade = |m: &NdfMapped| -> Vec<[f32; 3]> {
                let mut all = Vec::new();
                let mut out = vec![[0.0f32; 3]; wi.len()];
                for sp in &points {
                    m.eval_many(sp, wo, &wi, &mut out);
                    all.extend_from_slice(&out);
                }
                all
            };
            let want = shade(&eager);
            assert_eq!(shade(&lazy), want, "{transfer}");
            assert_ne!(
                shade(&plain),
                want,
                "{transfer}: view weighting changes nothing"
            );
            // Tiles built without view weighting hold less, and are dropped when it is turned on.
            assert_eq!(shade(&lazy_plain), shade(&plain), "{transfer}");
            let (without, _, _) = lazy_plain.table_cache_stats();
            let (with, _, _) = lazy.table_cache_stats();
            assert!(without < with, "{transfer}: {without} vs {with} bytes");
            assert!(lazy_plain.tiles_built() > 0);
            let turned = lazy_plain.with_view_weighting(true);
            assert_eq!((turned.tiles_built(), turned.table_cache_stats().0), (0, 0));
            assert_eq!(shade(&turned), want, "{transfer}");
        }
    }

    /// The bound a budget is checked against holds every level's tables as built (with
    /// shadowing and view weighting: the cells on level 0, the lobes' distributions above and
    /// their joints and facets turned towards each azimuth from `JOINT_FROM_LEVEL` on), Phong
    /// and Lambert facets.
    #[test]
    fn level_tables_bytes_bound_the_tables_built() {
        let map = fixtures::gaussian(32, 4.0, 0.1, 3, 0.01).unwrap();
        let pyr = extract(
            Source::Heights(&map),
            &ExtractParams::default(),
            &mut |_| {},
        )
        .unwrap();
        for transfer in ["kind = \"phong\"\nexponent = 20.0", "kind = \"lambert\""] {
            let surface = Material::from_toml_str(&format!("[transfer]\n{transfer}\n")).unwrap();
            let facet = Facet::new(&surface.transfer);
            for shadowing in [true, false] {
                let a = NdfMapped::new(&pyr, &surface, 32.0, shadowing).unwrap();
                for (k, tl) in a.levels.iter().enumerate() {
                    let built = tl.tiles[0].get().unwrap().bytes() as u64;
                    let bound = level_tables_bytes(&pyr, k, &facet, shadowing, true);
                    assert!(
                        built <= bound,
                        "level {k}: {built} B built, bound {bound} B"
                    );
                }
            }
        }
    }
}
