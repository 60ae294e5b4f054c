//! What each lobe of a pyramid stands for, handed down from the level-0 normals: its share of
//! its texel's projected area and the horizon statistics of the cells whose normals it stands
//! for ([`lobe_stats`]; one texel's: [`texel_lobe_stats`]), and the projected area `E[m_z⁺]` of one Phong peak
//! ([`peak_projected_area`]).
//!
//! A coarse texel's lobes are a fit of the normals of its footprint; which cells a lobe stands
//! for is the mixture's posterior at each level-0 normal. Weighting each cell's horizon
//! distribution ([`HorizonCdf`]) by the projected area it hands to a lobe gives that lobe's own visibility
//! `V_j(ω)`: the visibility conditioned on the normal, per lobe (issue #11, item 1). On touching
//! half-cylinders the flat lobe stands for the tops (low horizons) and the steep lobes for the
//! creases (high horizons); on their negative (grooves: the same NDF) the other way round.
//!
//! # Conventions
//! * Everything is per level and indexed like the level's lobes (`Level::lobes`).
//! * A texel's shares sum to 1, or are all 0 when nothing faces up.
//! * A lobe's horizon distribution has as weight the projected area handed to it (level-0
//!   cells; 0 = it stands for nothing: visible from everywhere, [`HorizonCdf::visibility`]).
//! * A cell's distribution is that of its surface, approximately: its four corner samples'
//!   angles interpolated bilinearly at 4 × 4 points of the cell ([`cell_cdf`]), rounded to
//!   1/255 as stored and pooled as such (so a whole level reuses level 0's cells, and a tile
//!   computes the same values). Level 0's lobes take their cell's.
//! * Level 0 keeps its cells' horizons point by point too ([`LobeStats::cells`],
//!   [`CellHorizon`]): the renderer shades level 0 with them, reading the light and the viewer
//!   together per sub-cell, since one cell's distribution cannot say which of its points see
//!   both (its joint grid degenerates to the product there).
//!
//! Until 2026-12-07 a lobe pooled its cells' horizon angles as a mean and a variance and read
//! them through the ramp of [`crate::HorizonStats::visibility`]; on the steep facade map a
//! lobe holding wall tops (horizon 0) and window floors (horizons high) then hid nearly all of
//! a grazing light its tops see (0.29 of the bump map's radiance at 16 cells a pixel;
//! docs/heightmaps.md, "Horizon distributions per lobe").

use super::{Level, Progress, ProgressTask, Pyramid};
use crate::compact::Horizons;
use crate::horizon::{
    CellHorizon, HorizonCdf, HorizonCdfSum, HorizonJoint, HorizonJointSum, HorizonToward,
    HorizonTowardSum, HORIZON_DIRECTIONS,
};
use meso_core::sg;

/// The projected area `E[m_z⁺]` of a Phong peak `((1 + a·m)/2)^(η/2)` (normalised over the
/// sphere) whose axis has `z = a_z`: the part of the lobe below the horizon covers nothing.
/// `η/(η + 4) · a_z` (which counts that part negatively) when the lobe lies above the horizon
/// to within 12 of its standard deviations `2/√η`; otherwise a quadrature over the angle α
/// from the axis with the azimuth integrated in closed form,
/// `∫₀^{2π} max(0, c + s cos φ) dφ = 2(c·acos(−c/s) + √(s² − c²))` for `|c| < s`:
/// Gauss–Legendre of 16 nodes (`PROJECTED_AREA_NODES`) on each piece of `[0, 12 deviations]`
/// between the kinks `α = |π/2 − θ_a|` and `π − |π/2 − θ_a|` of that integral (where the
/// horizon starts and stops cutting the ring).
#[must_use]
pub fn peak_projected_area(a_z: f64, eta: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI, TAU};
    static GL: std::sync::OnceLock<(Vec<f64>, Vec<f64>)> = std::sync::OnceLock::new();
    let a_z = a_z.clamp(-1.0, 1.0);
    let reach = 24.0 / eta.max(1e-9).sqrt();
    let theta = a_z.acos();
    if theta + reach < FRAC_PI_2 {
        return sg::phong_peak_mean_cos(eta) * a_z;
    }
    let (xs, ws) = GL.get_or_init(|| meso_core::quadrature::gauss_legendre(PROJECTED_AREA_NODES));
    let s_a = (1.0 - a_z * a_z).max(0.0).sqrt();
    let amax = reach.min(PI);
    // |c| = s where tan α = ±a_z/s_a: α = |π/2 − θ| and π − |π/2 − θ|.
    let k1 = (FRAC_PI_2 - theta).abs();
    let cuts = [0.0, k1.min(amax), (PI - k1).min(amax), amax];
    let (mut num, mut den) = (0.0, 0.0);
    for piece in cuts.windows(2) {
        let (lo, hi) = (piece[0], piece[1]);
        if hi <= lo {
            continue;
        }
        let (half, mid) = (0.5 * (hi - lo), 0.5 * (hi + lo));
        for (x, w) in xs.iter().zip(ws) {
            let a = mid + half * x;
            let (sa, ca) = a.sin_cos();
            let d = w * half * (0.5 * (1.0 + ca)).powf(0.5 * eta) * sa;
            let (c, s) = (a_z * ca, s_a * sa);
            let g = if c >= s {
                TAU * c
            } else if c <= -s {
                0.0
            } else {
                2.0 * (c * (-c / s).acos() + (s * s - c * c).sqrt())
            };
            num += d * g;
            den += d * TAU;
        }
    }
    if den > 0.0 {
        num / den
    } else {
        a_z.max(0.0)
    }
}

/// The first level whose lobes get a joint horizon distribution ([`HorizonJoint`]): below it
/// a texel spans at most 2 × 2 cells, whose horizons the product reads well (on the steep
/// facade map the product of the joint's pairs errs by 2 % of the exact at level 2 on
/// average, by 10–25 % from level 4 on; docs/heightmaps.md, "Light and viewer together per
/// lobe").
pub const JOINT_FROM_LEVEL: usize = 2;

/// A texel's joint horizon distributions are pooled from at most this many cells a side of
/// its footprint: one cell of each of `JOINT_CELLS_SIDE²` blocks, at a place hashed from the
/// texel and block (a regular stride would alias with a periodic map). What they estimate is
/// how two directions go together, not how much sees each (the lobe's [`HorizonCdf`], of every
/// cell); 16 cells of 16 points each.
pub const JOINT_CELLS_SIDE: usize = 8;

/// Gauss–Legendre nodes per piece of [`peak_projected_area`]'s quadrature.
const PROJECTED_AREA_NODES: usize = 16;

/// Per level of a pyramid, what each lobe stands for (module docs): [`lobe_stats`].
#[derive(Clone, Debug, PartialEq)]
pub struct LobeStats {
    /// Per level and lobe, the lobe's share of its texel's projected area (a texel's shares
    /// sum to 1, or are all 0 when nothing faces up).
    pub shares: Vec<Vec<f64>>,
    /// Per level and lobe, the horizon distribution of the cells the lobe stands for,
    /// weighted by the projected area handed to it (weight in level-0 cells). `None` for
    /// pyramids without horizon statistics (normal maps), or when not asked for.
    pub horizon: Option<Vec<Vec<HorizonCdf>>>,
    /// Per level and lobe, from level [`JOINT_FROM_LEVEL`] on (empty below), the joint
    /// horizon distribution of the cells the lobe stands for ([`HorizonJoint`]: along pairs of
    /// azimuths 90°–180° apart, of a sample of [`JOINT_CELLS_SIDE`]² cells a texel, weighted
    /// by the projected area handed over). `None` with `horizon`.
    pub joint: Option<Vec<Vec<HorizonJoint>>>,
    /// Per level and lobe, from level [`JOINT_FROM_LEVEL`] on (empty below), the horizon
    /// distributions of the facets the lobe stands for that are turned towards each stored
    /// azimuth ([`HorizonToward`]: visibility conditioned on the normal within the lobe),
    /// weighted by the projected area handed over. `None` with `horizon`.
    pub toward: Option<Vec<Vec<HorizonToward>>>,
    /// Level 0's cells' horizons kept point by point, per texel (`row · cols + col`): what
    /// the renderer shades level 0 with, seeing the light and the viewer together
    /// ([`CellHorizon`]). `None` with `horizon`.
    pub cells: Option<Vec<CellHorizon>>,
}

/// What each lobe of `pyramid` stands for: its share of its texel's projected area and, when
/// `horizons` is true and the pyramid has horizon statistics, the horizon statistics of the
/// cells it stands for.
///
/// Level 0 takes `w·E[m_z⁺]` per lobe ([`peak_projected_area`]): exact for its lobes, which are
/// the map's own normals (one cell of projected area per texel), and each lobe its cell's
/// horizon statistics (its four corner samples'). A coarser texel collects the level-0 lobes of its footprint and hands
/// each one's projected area to its own lobes by responsibility, `∝ w_l · peak_l(a_j)` (the
/// mixture's posterior at the level-0 normal), and with it the level-0 cell's horizon
/// distribution (pooled, [`HorizonCdfSum::add`], weighted by the area handed over). So a lobe
/// gets the projected area of the normals it stands for, not `w·E[m_z⁺]` of its own shape (a
/// fit can make the two very different near the horizon, where a texel's area weight `1/n_z`
/// is large but its projected area one cell), and the horizons of where those normals are.
///
/// Cost: level 0's shares and cells' distributions once (4 × 4 points and 8 directions a
/// cell), then one log-density per level-0 lobe, level and lobe of the covering texel, plus
/// one pooled sum per lobe it hands area to; the levels run in parallel. Memory: the shares (8 bytes per
/// lobe) and the horizon distributions (132 bytes per lobe; 520 per lobe of the texel row
/// being summed).
#[must_use]
pub fn lobe_stats(pyramid: &Pyramid, horizons: bool) -> LobeStats {
    stats(pyramid, horizons, false, None)
}

/// [`lobe_stats`] with level 0's horizon statistics stored once per level-0 texel rather than
/// once per lobe: `horizon[0]` is indexed like level 0's texels (`row · cols + col`), each its
/// cell's statistics, which every lobe of the texel takes in [`lobe_stats`] (the same values,
/// about half the memory on a height map's level 0, whose texels hold two lobes). The other
/// levels and the shares are [`lobe_stats`]'s.
#[must_use]
pub fn lobe_stats_by_cell(pyramid: &Pyramid, horizons: bool) -> LobeStats {
    stats(pyramid, horizons, true, None)
}

/// [`lobe_stats_by_cell`], reporting its progress to `report` ([`ProgressTask::Tables`]):
/// once before any work (at 0, the totals set), after each coarse row of each level (the
/// levels run in parallel, so the reports come from several threads, `work_done` growing), and
/// at the end (`work_done = work_total`). What a renderer building its tables up front shows
/// while it does: seconds on a 1024² height map.
#[must_use]
pub fn lobe_stats_by_cell_reporting(
    pyramid: &Pyramid,
    horizons: bool,
    report: &(dyn Fn(Progress) + Sync),
) -> LobeStats {
    stats(pyramid, horizons, true, Some(report))
}

/// The work of [`lobe_stats_by_cell_reporting`]'s coarse level `k` per level-0 cell visited:
/// 2 where every cell also gives a joint horizon distribution (the levels from
/// [`JOINT_FROM_LEVEL`] that pool every cell's, [`joint_every_cell`]: about twice the time a
/// cell), else 1.
fn tables_work_per_cell(pyramid: &Pyramid, k: usize, horizons: bool) -> u64 {
    let joint_every_cell = horizons
        && pyramid.levels[0].horizon.is_some()
        && k >= JOINT_FROM_LEVEL
        && joint_every_cell(pyramid.levels[k].span);
    if joint_every_cell {
        2
    } else {
        1
    }
}

/// [`lobe_stats`] (`by_cell` false) or [`lobe_stats_by_cell`], reporting to `report` when
/// given ([`lobe_stats_by_cell_reporting`]).
fn stats(
    pyramid: &Pyramid,
    horizons: bool,
    by_cell: bool,
    report: Option<&(dyn Fn(Progress) + Sync)>,
) -> LobeStats {
    use rayon::prelude::*;
    use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};
    let Some(l0) = pyramid.levels.first() else {
        return LobeStats {
            shares: Vec::new(),
            horizon: None,
            joint: None,
            toward: None,
            cells: None,
        };
    };
    let h0 = l0.horizon.as_ref().filter(|_| horizons);
    // Progress: level 0's own pass over its cells, then the level-0 cells each coarse level
    // visits, weighted by their cost.
    let cells0 = l0.rows as u64 * l0.cols as u64;
    let work_total: u64 = (cells0
        + (1..pyramid.levels.len())
            .map(|k| cells0 * tables_work_per_cell(pyramid, k, horizons))
            .sum::<u64>())
    .max(1);
    let (work_done, levels_done) = (AtomicU64::new(0), AtomicUsize::new(1));
    let progress = |work: u64| Progress {
        task: ProgressTask::Tables,
        levels_done: levels_done.load(Ordering::Relaxed),
        levels: pyramid.levels.len(),
        texels_done: work,
        texels_total: work_total,
        work_done: work,
        work_total,
    };
    // The work last reported: the rows finish on several threads, each report is made only
    // when it is past the last one, so `work_done` never goes back.
    let reported = std::sync::Mutex::new(0u64);
    let report_work = |w: u64| {
        if let Some(r) = report {
            let mut last = reported
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner);
            if w > *last {
                *last = w;
                r(progress(w));
            }
        }
    };
    if let Some(r) = report {
        r(Progress {
            levels_done: 0,
            ..progress(0)
        });
    }
    // Level 0's cells' horizons, and their distributions (`cell_cdf`'s) from them.
    let cells: Option<Vec<CellHorizon>> = h0.map(|h| {
        (0..l0.texels())
            .into_par_iter()
            .map(|t| cell_horizon(pyramid, h, t))
            .collect()
    });
    let base_horizon: Option<Vec<HorizonCdf>> = cells
        .as_ref()
        .map(|c| c.par_iter().map(CellHorizon::cdf).collect());
    // Level 0: projected area per lobe, one cell per texel.
    let mut base = Vec::with_capacity(l0.lobes.len());
    for t in 0..l0.texels() {
        cell_shares(l0, t, &mut base);
    }
    if report.is_some() {
        let w = work_done.fetch_add(cells0, Ordering::Relaxed) + cells0;
        report_work(w.min(work_total));
    }
    // The coarse levels as whole rectangles: a row of texels' sums at a time (520 bytes a lobe
    // of the row), not a level's.
    #[allow(clippy::type_complexity)]
    let coarse: Vec<(
        Vec<f64>,
        Option<Vec<HorizonCdf>>,
        Option<Vec<HorizonJoint>>,
        Option<Vec<HorizonToward>>,
    )> = pyramid.levels[1..]
        .par_iter()
        .enumerate()
        .map(|(k1, l)| {
            let level0 = Level0 {
                shares: &base,
                cdfs: base_horizon.as_deref(),
            };
            let per_cell = tables_work_per_cell(pyramid, k1 + 1, horizons);
            let row_done = |cells: u64| {
                if report.is_some() {
                    let w = work_done.fetch_add(cells * per_cell, Ordering::Relaxed);
                    report_work((w + cells * per_cell).min(work_total));
                }
            };
            let st = rect_stats(
                pyramid,
                k1 + 1,
                0..l.rows,
                0..l.cols,
                horizons,
                Some(&level0),
                Some(&row_done),
            );
            levels_done.fetch_add(1, Ordering::Relaxed);
            (st.shares, st.horizon, st.joint, st.toward)
        })
        .collect();
    if let Some(r) = report {
        // The end, once (every row's report is at most this).
        let _last = reported
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        r(Progress {
            levels_done: pyramid.levels.len(),
            ..progress(work_total)
        });
    }
    let base_horizon = base_horizon.map(|h| {
        if by_cell {
            return h;
        }
        let mut out = Vec::with_capacity(l0.lobes.len());
        for (t, s) in h.iter().enumerate() {
            for _ in l0.lobe_start[t]..l0.lobe_start[t + 1] {
                out.push(*s);
            }
        }
        out
    });
    let mut shares = vec![base];
    let mut joint = base_horizon.as_ref().map(|_| vec![Vec::new()]);
    let mut toward = base_horizon.as_ref().map(|_| vec![Vec::new()]);
    let mut horizon = base_horizon.map(|h| vec![h]);
    for (s, h, j, tw) in coarse {
        shares.push(s);
        if let (Some(v), Some(h)) = (&mut horizon, h) {
            v.push(h);
        }
        if let Some(v) = &mut joint {
            v.push(j.unwrap_or_default());
        }
        if let Some(v) = &mut toward {
            v.push(tw.unwrap_or_default());
        }
    }
    LobeStats {
        shares,
        horizon,
        joint,
        toward,
        cells,
    }
}

/// [`lobe_stats_by_cell`] of the texels of a rectangle of one level: rows `rows` and columns
/// `cols` of level `level`, row-major. `shares` holds the rectangle's lobes' shares in order
/// (texel by texel, each texel's lobes as in [`Level::lobes`]); when `horizons` is true and
/// the pyramid has horizon statistics, on level 0 `cells`, one per texel of the rectangle
/// (its cell's, as [`LobeStats::cells`]), on coarser levels `horizon` (and from
/// [`JOINT_FROM_LEVEL`] on `joint`), one per lobe. The very values (same bits) of
/// [`lobe_stats_by_cell`]'s entries for
/// those texels: a coarse texel's cells are visited in the same order (row by row of its
/// footprint) and their shares and horizons computed alike; level 0's rows are visited in
/// order, a coarse row of the rectangle at a time, so that a level 0 held by band
/// ([`crate::Pyramid::read_lazy`]) decodes each band once a rectangle (with a cache of two
/// bands). Cost: the level-0 cells under the
/// rectangle (a whole coarse level's rectangle visits all of level 0, as [`lobe_stats`] does
/// per level); what a renderer building its tables on demand calls per tile.
///
/// # Panics
/// `level`, `rows` or `cols` out of range.
#[must_use]
pub fn rect_lobe_stats_by_cell(
    pyramid: &Pyramid,
    level: usize,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    horizons: bool,
) -> LevelStats {
    rect_stats(pyramid, level, rows, cols, horizons, None, None)
}

/// What a whole pyramid's stats hold of level 0 already, for the coarse levels to read instead
/// of computing it again per level: its lobes' shares (indexed like its lobes, [`cell_shares`]'s)
/// and its cells' horizon distributions (indexed like its texels, [`cell_cdf`]'s).
struct Level0<'a> {
    shares: &'a [f64],
    cdfs: Option<&'a [HorizonCdf]>,
}

/// [`rect_lobe_stats_by_cell`], reading level 0's shares and cells' distributions from
/// `level0` when given (the same values) instead of computing them, and telling `row_done`
/// (when given) the level-0 cells each coarse row visited once it is summed.
fn rect_stats(
    pyramid: &Pyramid,
    level: usize,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    horizons: bool,
    level0: Option<&Level0<'_>>,
    row_done: Option<&dyn Fn(u64)>,
) -> LevelStats {
    let l = &pyramid.levels[level];
    let l0 = &pyramid.levels[0];
    assert!(
        rows.end <= l.rows && cols.end <= l.cols,
        "rectangle out of level {level}"
    );
    let h0 = l0.horizon.as_ref().filter(|_| horizons);
    let with_joint = h0.is_some() && level >= JOINT_FROM_LEVEL;
    let mut shares = Vec::new();
    let mut hz: Option<Vec<HorizonCdf>> = h0.filter(|_| level > 0).map(|_| Vec::new());
    let mut cz: Option<Vec<CellHorizon>> = h0.filter(|_| level == 0).map(|_| Vec::new());
    let mut jz: Option<Vec<HorizonJoint>> = with_joint.then(Vec::new);
    let mut tz: Option<Vec<HorizonToward>> = with_joint.then(Vec::new);
    let (mut cell, mut logr, mut mass, mut acc) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut jacc: Vec<HorizonJointSum> = Vec::new();
    let mut tacc: Vec<HorizonTowardSum> = Vec::new();
    // A coarse row's texels: their lobes and, at `off[i]`, their accumulators and their lobes
    // as read to hand the cells' area out.
    let (mut lobes, mut off, mut hand) = (Vec::new(), Vec::new(), Vec::new());
    for row in rows {
        if level == 0 {
            for col in cols.clone() {
                let t = row * l.cols + col;
                cell_shares(l0, t, &mut shares);
                if let (Some(v), Some(h)) = (&mut cz, h0) {
                    v.push(cell_horizon(pyramid, h, t));
                }
            }
            continue;
        }
        lobes.clear();
        off.clear();
        hand.clear();
        off.push(0);
        for col in cols.clone() {
            let t = row * l.cols + col;
            let (pa, pb) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
            lobes.push((pa, pb));
            hand_lobes(l, pa, pb, &mut hand);
            off.push(off[off.len() - 1] + pb - pa);
        }
        let n = off[off.len() - 1];
        mass.clear();
        mass.resize(n, 0.0f64);
        acc.clear();
        acc.resize(if h0.is_some() { n } else { 0 }, HorizonCdfSum::default());
        jacc.clear();
        jacc.resize(if with_joint { n } else { 0 }, HorizonJointSum::default());
        tacc.clear();
        tacc.resize(if with_joint { n } else { 0 }, HorizonTowardSum::default());
        // Level 0's rows in order (a level held by band decodes each band once), each texel's
        // cells row by row of its footprint as before: the same sums in the same order.
        for r in row * l.span..((row + 1) * l.span).min(l0.rows) {
            for (i, col) in cols.clone().enumerate() {
                let (pa, _) = lobes[i];
                let hand = &hand[off[i]..off[i + 1]];
                let mass = &mut mass[off[i]..off[i + 1]];
                let acc = if h0.is_some() {
                    &mut acc[off[i]..off[i + 1]]
                } else {
                    &mut acc[..]
                };
                let (jacc, tacc) = if with_joint {
                    (&mut jacc[off[i]..off[i + 1]], &mut tacc[off[i]..off[i + 1]])
                } else {
                    (&mut jacc[..], &mut tacc[..])
                };
                for c in col * l.span..((col + 1) * l.span).min(l0.cols) {
                    let ct = r * l0.cols + c;
                    let (ca, cb) = (l0.lobe_start[ct] as usize, l0.lobe_start[ct + 1] as usize);
                    let cell_s: &[f64] = match level0 {
                        Some(z) => &z.shares[ca..cb],
                        None => {
                            cell.clear();
                            cell_shares(l0, ct, &mut cell);
                            &cell
                        }
                    };
                    let cell_h = h0.map(|h| match level0.and_then(|z| z.cdfs) {
                        Some(c) => HorizonCdfSum::of(&c[ct]),
                        None => HorizonCdfSum::of(&cell_cdf(pyramid, h, ct)),
                    });
                    let cell_j = match h0 {
                        Some(h) if with_joint && joint_sampled(l.span, row, col, r, c) => Some(
                            HorizonJointSum::of_bilinear_cell(&cell_corners(pyramid, h, ct), 1.0),
                        ),
                        _ => None,
                    };
                    hand_cell(
                        l0.lobes.range(ca, cb).map(|p| p.axis),
                        cell_s,
                        hand,
                        pa,
                        &mut logr,
                        |j, m, normal| {
                            mass[j - pa] += m;
                            if let Some(s) = &cell_h {
                                acc[j - pa].add(s, m);
                                if with_joint {
                                    tacc[j - pa].add(s, normal, m);
                                }
                            }
                            if let Some(s) = &cell_j {
                                jacc[j - pa].add(s, m);
                            }
                        },
                    );
                }
            }
        }
        for i in 0..lobes.len() {
            let mass = &mass[off[i]..off[i + 1]];
            let total: f64 = mass.iter().sum();
            shares.extend(
                mass.iter()
                    .map(|&m| if total > 0.0 { m / total } else { 0.0 }),
            );
            if let Some(v) = &mut hz {
                v.extend(acc[off[i]..off[i + 1]].iter().map(HorizonCdfSum::finish));
            }
            if let Some(v) = &mut jz {
                v.extend(jacc[off[i]..off[i + 1]].iter().map(HorizonJointSum::finish));
            }
            if let Some(v) = &mut tz {
                v.extend(
                    tacc[off[i]..off[i + 1]]
                        .iter()
                        .map(HorizonTowardSum::finish),
                );
            }
        }
        if let Some(done) = row_done {
            let r = (row * l.span).min(l0.rows)..((row + 1) * l.span).min(l0.rows);
            let c = (cols.start * l.span).min(l0.cols)..(cols.end * l.span).min(l0.cols);
            done(r.len() as u64 * c.len() as u64);
        }
    }
    LevelStats {
        shares,
        horizon: hz,
        joint: jz,
        toward: tz,
        cells: cz,
    }
}

/// What the lobes of part of one level stand for: [`rect_lobe_stats_by_cell`].
#[derive(Clone, Debug, PartialEq)]
pub struct LevelStats {
    /// Per lobe, its share of its texel's projected area (as [`LobeStats::shares`]).
    pub shares: Vec<f64>,
    /// The horizon distributions per lobe, on levels above 0 (as [`lobe_stats_by_cell`]'s);
    /// `None` without, and on level 0, which has `cells`.
    pub horizon: Option<Vec<HorizonCdf>>,
    /// Per lobe, the joint horizon distributions (as [`LobeStats::joint`]'s), from level
    /// [`JOINT_FROM_LEVEL`] on with `horizon`; `None` otherwise.
    pub joint: Option<Vec<HorizonJoint>>,
    /// Per lobe, the distributions of its facets turned towards each stored azimuth (as
    /// [`LobeStats::toward`]'s), from level [`JOINT_FROM_LEVEL`] on with `horizon`; `None`
    /// otherwise.
    pub toward: Option<Vec<HorizonToward>>,
    /// On level 0 (with horizon statistics), per texel its cell's horizons kept point by
    /// point ([`CellHorizon`], as [`LobeStats::cells`]); `None` otherwise.
    pub cells: Option<Vec<CellHorizon>>,
}

/// What one lobe of a texel stands for ([`texel_lobe_stats`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LobeStat {
    /// Its share of the texel's projected area (the texel's shares sum to 1, or are all 0).
    pub share: f64,
    /// The horizon distribution of the cells it stands for (weight: the projected area handed
    /// to it, in level-0 cells); `None` without horizon statistics.
    pub horizon: Option<HorizonCdf>,
}

/// [`lobe_stats`] of one texel, `(row, col)` of level `level`: per lobe, in the order of
/// [`Level::texel_lobes`], what it stands for. Visits only the level-0 cells of the texel's
/// footprint (for the editor's texel view).
///
/// # Errors
/// The level, row or column out of range.
pub fn texel_lobe_stats(
    pyramid: &Pyramid,
    level: usize,
    row: usize,
    col: usize,
) -> crate::error::Result<Vec<LobeStat>> {
    let l = pyramid.level(level)?;
    // Checks the row and column.
    l.texel_lobes(row, col)?;
    let l0 = &pyramid.levels[0];
    let t = row * l.cols + col;
    let (pa, pb) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
    let mut mass = vec![0.0f64; pb - pa];
    let h0 = l0.horizon.as_ref();
    let mut hz = h0.map(|_| vec![HorizonCdfSum::default(); pb - pa]);
    let (mut shares, mut logr, mut hand) = (Vec::new(), Vec::new(), Vec::new());
    hand_lobes(l, pa, pb, &mut hand);
    for r in row * l.span..((row + 1) * l.span).min(l0.rows) {
        for c in col * l.span..((col + 1) * l.span).min(l0.cols) {
            let ct = r * l0.cols + c;
            shares.clear();
            cell_shares(l0, ct, &mut shares);
            let cell_h = h0.map(|h| HorizonCdfSum::of(&cell_cdf(pyramid, h, ct)));
            let (ca, cb) = (l0.lobe_start[ct] as usize, l0.lobe_start[ct + 1] as usize);
            let axes = l0.lobes.range(ca, cb).map(|p| p.axis);
            hand_cell(axes, &shares, &hand, pa, &mut logr, |j, m, _| {
                mass[j - pa] += m;
                if let (Some(hz), Some(s)) = (&mut hz, &cell_h) {
                    hz[j - pa].add(s, m);
                }
            });
        }
    }
    let total: f64 = mass.iter().sum();
    Ok(mass
        .iter()
        .enumerate()
        .map(|(j, &m)| LobeStat {
            share: if total > 0.0 { m / total } else { 0.0 },
            horizon: hz.as_ref().map(|v| v[j].finish()),
        })
        .collect())
}

/// The horizon distribution of level-0 cell `t` (row-major), weight 1: its four corner
/// samples' angles (from level 0's texels `h`, which hold the samples' own: texel `(r, c)` is
/// sample `(r, c)`, the cell's top-left corner; the far corners wrap, or on clamped maps repeat
/// the last row and column), per direction interpolated bilinearly at the centres of 4 × 4
/// sub-cells: the continuous surface's horizons, approximately (on the facade height map the
/// bilinear points' visibility is 0.86–1.03 of rays on the displaced surface where the corners'
/// own is 0.71–0.82; `examples/horizon_models.rs`).
pub(crate) fn cell_cdf(pyramid: &Pyramid, h: &Horizons, t: usize) -> HorizonCdf {
    cell_horizon(pyramid, h, t).cdf()
}

/// Level-0 cell `t`'s horizons kept point by point: its corners' angles ([`cell_cdf`]'s).
pub(crate) fn cell_horizon(pyramid: &Pyramid, h: &Horizons, t: usize) -> CellHorizon {
    CellHorizon::new(&cell_corners(pyramid, h, t))
}

/// Level-0 cell `t`'s four corner samples' horizon angles per direction, at `(x, y)` = (0, 0),
/// (1, 0), (0, 1), (1, 1) ([`cell_cdf`]).
fn cell_corners(pyramid: &Pyramid, h: &Horizons, t: usize) -> [[f64; 4]; HORIZON_DIRECTIONS] {
    let l0 = &pyramid.levels[0];
    let wrap = pyramid.border == crate::heightmap::Border::Wrap;
    let next = |i: usize, n: usize| {
        if i + 1 < n {
            i + 1
        } else if wrap {
            0
        } else {
            i
        }
    };
    let (r, c) = (t / l0.cols, t % l0.cols);
    let (r1, c1) = (next(r, l0.rows), next(c, l0.cols));
    let corner = |rr: usize, cc: usize| h.get(rr * l0.cols + cc).mean;
    let (a00, a01, a10, a11) = (corner(r, c), corner(r, c1), corner(r1, c), corner(r1, c1));
    std::array::from_fn(|d| [a00[d], a01[d], a10[d], a11[d]])
}

/// Whether a texel of a level `span` cells a side pools the joint horizon distributions of
/// every cell of its footprint (at most [`JOINT_CELLS_SIDE`] blocks a side), not one of each
/// block ([`joint_sampled`]).
fn joint_every_cell(span: usize) -> bool {
    span / JOINT_CELLS_SIDE <= 1
}

/// Whether level-0 cell `(r, c)` is one of those texel `(row, col)` of a level `span` cells a
/// side pools its joint horizon distributions from ([`JOINT_CELLS_SIDE`]): every cell of a
/// texel of at most that many a side, else one of each block of the footprint, at a place
/// hashed from the texel and the block.
fn joint_sampled(span: usize, row: usize, col: usize, r: usize, c: usize) -> bool {
    if joint_every_cell(span) {
        return true;
    }
    let block = span / JOINT_CELLS_SIDE;
    let (lr, lc) = (r - row * span, c - col * span);
    let (br, bc) = (lr / block, lc / block);
    // SplitMix64's finaliser of the texel and the block.
    let mut x = (row as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (col as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F)
        ^ ((br * JOINT_CELLS_SIDE + bc) as u64).wrapping_mul(0x1656_67B1_9E37_79F9);
    x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    x ^= x >> 31;
    lr % block == (x % block as u64) as usize && lc % block == ((x >> 32) % block as u64) as usize
}

/// Appends to `out` the shares of level-0 texel `t`'s lobes: `w·E[m_z⁺]` each
/// ([`peak_projected_area`]) over their sum, or 0 when that is 0.
fn cell_shares(l0: &Level, t: usize, out: &mut Vec<f64>) {
    let (a, b) = (l0.lobe_start[t] as usize, l0.lobe_start[t + 1] as usize);
    let start = out.len();
    out.extend(
        l0.lobes
            .range(a, b)
            .map(|p| p.weight * peak_projected_area(p.axis.z, p.exponent)),
    );
    let total: f64 = out[start..].iter().sum();
    for m in &mut out[start..] {
        *m = if total > 0.0 { *m / total } else { 0.0 };
    }
}

/// A lobe of a coarse texel as [`hand_cell`] reads it, decoded once per texel instead of once
/// per level-0 cell under it: its axis, and the two terms of its log-density
/// `ln w + ln(η + 2) + ½η · ln x` that do not depend on the normal (`log_norm`, the first two
/// summed as the density sums them, and `half_eta`), or `log_norm` = −∞ for a lobe of no
/// weight.
#[derive(Clone, Copy, Debug)]
struct HandLobe {
    axis: glam::DVec3,
    log_norm: f64,
    half_eta: f64,
}

impl HandLobe {
    fn new(p: &meso_core::ndf::PhongLobe) -> HandLobe {
        HandLobe {
            axis: p.axis,
            log_norm: if p.weight > 0.0 {
                p.weight.ln() + (p.exponent + 2.0).ln()
            } else {
                f64::NEG_INFINITY
            },
            half_eta: 0.5 * p.exponent,
        }
    }
}

/// Appends to `out` the lobes `pa..pb` of level `l` as [`hand_cell`] reads them.
fn hand_lobes(l: &Level, pa: usize, pb: usize, out: &mut Vec<HandLobe>) {
    out.extend(l.lobes.range(pa, pb).map(|p| HandLobe::new(&p)));
}

/// Hands a level-0 cell's projected area (its lobes' `shares`, of axes `axes`) to a coarse
/// texel's lobes `lobes` (its lobes `pa..`, [`hand_lobes`]) by the mixture's posterior:
/// `give(j, m, normal)` for each lobe `j` (counted from `pa`) and area `m` > 0, `normal` the
/// axis of the level-0 lobe it comes from. `logr` is scratch. A texel of one lobe takes all of
/// it.
fn hand_cell(
    axes: impl Iterator<Item = glam::DVec3>,
    shares: &[f64],
    lobes: &[HandLobe],
    pa: usize,
    logr: &mut Vec<f64>,
    mut give: impl FnMut(usize, f64, glam::DVec3),
) {
    if lobes.is_empty() {
        return;
    }
    for (m, &mj) in axes.zip(shares) {
        if mj <= 0.0 {
            continue;
        }
        if lobes.len() == 1 {
            // Its posterior is 1 (or, opposite it, the nearest axis is its own).
            give(pa, mj, m);
            continue;
        }
        // Log responsibilities (log-sum-exp: sharp lobes underflow).
        logr.clear();
        let mut best = f64::NEG_INFINITY;
        for p in lobes {
            let x = 0.5 * (1.0 + p.axis.dot(m));
            let v = if x > 0.0 && p.log_norm > f64::NEG_INFINITY {
                p.log_norm + p.half_eta * x.ln()
            } else {
                f64::NEG_INFINITY
            };
            best = best.max(v);
            logr.push(v);
        }
        if best == f64::NEG_INFINITY {
            // Opposite every lobe: the nearest axis takes it.
            let near = (0..lobes.len())
                .max_by(|&x, &y| lobes[x].axis.dot(m).total_cmp(&lobes[y].axis.dot(m)))
                .unwrap_or(0);
            give(pa + near, mj, m);
            continue;
        }
        // The exponentials once: kept in `logr` for the shares.
        let mut z = 0.0;
        for v in logr.iter_mut() {
            *v = (*v - best).exp();
            z += *v;
        }
        for (i, e) in logr.iter().enumerate() {
            let r = e / z;
            if r > 0.0 {
                give(pa + i, mj * r, m);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures;
    use crate::pyramid::{extract, ExtractParams, Source};

    /// [`peak_projected_area`]'s pieces of Gauss–Legendre agree with a 20 000-point midpoint
    /// rule of the same integral over the peak's reach, from axes pointing down to up and from
    /// broad (η = 4) to sharp (η = 4·10⁶) peaks: within 10⁻³ of the value (or of 10⁻³ where it
    /// is smaller). Measured: 2.0·10⁻⁴ (16 nodes a piece; 6·10⁻⁶ with 32). Without the cuts
    /// at the kinks (one piece) the same rule is up to 0.14 off.
    #[test]
    fn projected_area_pieces_match_a_fine_midpoint_rule() {
        let reference = |a_z: f64, eta: f64| {
            let reach = (24.0 / eta.sqrt()).min(std::f64::consts::PI);
            let s_a = (1.0 - a_z * a_z).max(0.0).sqrt();
            let n = 20_000;
            let (mut num, mut den) = (0.0, 0.0);
            for k in 0..n {
                let a = (k as f64 + 0.5) / n as f64 * reach;
                let d = (0.5 * (1.0 + a.cos())).powf(0.5 * eta) * a.sin();
                let (c, s) = (a_z * a.cos(), s_a * a.sin());
                let g = if c >= s {
                    c
                } else if c <= -s {
                    0.0
                } else {
                    (c * (-c / s).acos() + (s * s - c * c).sqrt()) / std::f64::consts::PI
                };
                num += d * g;
                den += d;
            }
            num / den
        };
        let mut worst = 0.0f64;
        for i in 0..=40 {
            let a_z = -1.0 + i as f64 / 20.0;
            for j in 0..=12 {
                let eta = 4.0 * 10f64.powf(j as f64 / 2.0);
                if a_z.acos() + 24.0 / eta.sqrt() < std::f64::consts::FRAC_PI_2 {
                    continue; // the closed form above the horizon
                }
                let (want, got) = (reference(a_z, eta), peak_projected_area(a_z, eta));
                worst = worst.max((got - want).abs() / want.abs().max(1e-3));
            }
        }
        assert!(worst < 1e-3, "worst {worst}");
    }

    /// The pyramid of touching half-cylinders (32², period 16; `sign` −1: grooves), default
    /// extraction.
    fn half_cylinder_pyramid(sign: f64) -> Pyramid {
        let map = fixtures::half_cylinders(32, 16, 1.0, sign).unwrap();
        extract(
            Source::Heights(&map),
            &ExtractParams::default(),
            &mut |_| {},
        )
        .unwrap()
    }

    /// Each lobe's facets turned towards a stored azimuth are a part of it: their share and
    /// distribution never claim more than the lobe's own (to rounding), on bumps and grooves;
    /// levels below `JOINT_FROM_LEVEL` have none.
    #[test]
    fn facets_turned_towards_an_azimuth_are_part_of_their_lobe() {
        for sign in [1.0, -1.0] {
            let pyr = half_cylinder_pyramid(sign);
            let st = lobe_stats(&pyr, true);
            let (hz, tw) = (st.horizon.as_ref().unwrap(), st.toward.as_ref().unwrap());
            let mut some = false;
            for (k, (hl, tl)) in hz.iter().zip(tw).enumerate() {
                if k < JOINT_FROM_LEVEL {
                    assert!(tl.is_empty(), "level {k}");
                    continue;
                }
                assert_eq!(tl.len(), hl.len(), "level {k}");
                for (c, t) in hl.iter().zip(tl) {
                    for d in 0..HORIZON_DIRECTIONS {
                        let s = f64::from(t.share[d]) / 255.0;
                        some |= s > 0.1;
                        for n in 0..crate::CDF_NODES {
                            let f = f64::from(c.frac[d][n]) / 255.0;
                            let g = f64::from(t.frac[d][n]) / 255.0;
                            assert!(s * g <= f + 2.0 / 255.0, "level {k}: {s} · {g} > {f}");
                            assert!(f - s * g <= 1.0 - s + 2.0 / 255.0, "level {k}");
                        }
                    }
                }
            }
            assert!(some, "the cylinders' flanks are turned towards ±x");
        }
    }

    /// On touching half-cylinders the flattest lobe of a coarse texel stands for the tops
    /// (low horizons along +x) and the one tilted towards +x for the creases (high horizons);
    /// on the same heights upside down (grooves: the same NDF) the other way round. Level 0's
    /// lobes take their cell's distribution (its four corners interpolated bilinearly), and
    /// each texel's shares sum to 1; one texel's [`texel_lobe_stats`] agrees with the whole
    /// pyramid's. Median horizons along +x, measured (32², period 16, level 4): bumps 0.321
    /// rad for the flat lobe (it also stands for the normals tilted towards −x, which see their
    /// own cylinder's top along +x) and 0.589 for the steep one; grooves 0.979 and 0.250.
    #[test]
    fn lobe_horizons_tell_bumps_from_grooves() {
        for sign in [1.0, -1.0] {
            let pyr = half_cylinder_pyramid(sign);
            let st = lobe_stats(&pyr, true);
            let hz = st.horizon.as_ref().unwrap();
            let l0 = &pyr.levels[0];
            let h0 = l0.horizon.as_ref().unwrap();
            // Level 0: each lobe its cell's distribution, the corners' angles interpolated
            // bilinearly at 4 × 4 points (recomputed here point by point), to 1/255.
            let nodes = crate::CDF_ELEVATIONS_DEG.map(f64::to_radians);
            for t in 0..l0.texels() {
                let (r, c) = (t / l0.cols, t % l0.cols);
                let a = |rr: usize, cc: usize| h0.get((rr % l0.rows) * l0.cols + cc % l0.cols).mean;
                let (a00, a01, a10, a11) = (a(r, c), a(r, c + 1), a(r + 1, c), a(r + 1, c + 1));
                for d in 0..HORIZON_DIRECTIONS {
                    for (k, &e) in nodes.iter().enumerate() {
                        let mut below = 0;
                        for y in [0.125, 0.375, 0.625, 0.875] {
                            for x in [0.125, 0.375, 0.625, 0.875] {
                                let h = a00[d] * (1.0 - x) * (1.0 - y)
                                    + a01[d] * x * (1.0 - y)
                                    + a10[d] * (1.0 - x) * y
                                    + a11[d] * x * y;
                                below += usize::from(h <= e);
                            }
                        }
                        let want = below as f64 / 16.0 * 255.0;
                        let lobes = l0.lobe_start[t] as usize..l0.lobe_start[t + 1] as usize;
                        for got in &hz[0][lobes] {
                            let got = f64::from(got.frac[d][k]);
                            assert!((got - want).abs() <= 0.5 + 1e-9, "texel {t} {d} {k}");
                        }
                    }
                }
            }
            for (k, l) in pyr.levels.iter().enumerate() {
                for t in 0..l.texels() {
                    let (a, b) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
                    let s: f64 = st.shares[k][a..b].iter().sum();
                    assert!((s - 1.0).abs() < 1e-9, "level {k} texel {t}: {s}");
                }
            }
            // One texel's query agrees with the whole pyramid's.
            for (k, l) in pyr.levels.iter().enumerate() {
                let t = l.texels() / 2;
                let one = texel_lobe_stats(&pyr, k, t / l.cols, t % l.cols).unwrap();
                let a = l.lobe_start[t] as usize;
                for (j, s) in one.iter().enumerate() {
                    assert!((s.share - st.shares[k][a + j]).abs() < 1e-9);
                    let (x, y) = (s.horizon.unwrap(), hz[k][a + j]);
                    assert!((x.weight - y.weight).abs() <= 1e-6 * y.weight, "level {k}");
                    for d in 0..HORIZON_DIRECTIONS {
                        for n in 0..crate::CDF_NODES {
                            let (p, q) = (x.frac[d][n], y.frac[d][n]);
                            assert!(p.abs_diff(q) <= 1, "level {k}");
                        }
                    }
                }
            }
            // Level 4: one texel per period (16 cells).
            let (k, l) = (4, &pyr.levels[4]);
            assert!(l.lobe_start[1] - l.lobe_start[0] >= 2);
            let (a, b) = (l.lobe_start[0] as usize, l.lobe_start[1] as usize);
            // The flattest lobe, and the one tilted furthest towards +x.
            let best = |key: &dyn Fn(usize) -> f64| {
                (a..b)
                    .filter(|&j| st.shares[k][j] > 0.0)
                    .max_by(|&x, &y| key(x).total_cmp(&key(y)))
                    .unwrap()
            };
            let flat = best(&|j| l.lobes.get(j).axis.z);
            let steep = best(&|j| l.lobes.get(j).axis.x);
            assert!(l.lobes.get(steep).axis.x > 0.3);
            // Median horizon along +x, the side the steep lobe faces.
            let (hf, hs) = (hz[k][flat].quantile(0, 0.5), hz[k][steep].quantile(0, 0.5));
            eprintln!("sign {sign}: +x horizon of the flat lobe {hf:.3}, of the steep {hs:.3}");
            if sign > 0.0 {
                assert!(hf < 0.7 * hs, "bumps: flat {hf} steep {hs}");
            } else {
                assert!(hs < 0.5 * hf, "grooves: flat {hf} steep {hs}");
            }
        }
    }

    /// [`lobe_stats_by_cell`] holds level 0's horizon distributions once per texel, each the
    /// very one (same bits) that every lobe of the texel gets from [`lobe_stats`]; the other
    /// levels and all shares are identical. Compact (`f32`) and `f64` levels both.
    #[test]
    #[allow(clippy::needless_range_loop)] // `j` indexes two tables' lobes
    fn lobe_stats_by_cell_is_lobe_stats_with_level_0_per_texel() {
        // Rough enough that level-0 texels hold two lobes (their triangles' normals).
        let map = fixtures::gaussian(32, 4.0, 0.1, 3, 0.01).unwrap();
        for compact_texels in [usize::MAX, 64] {
            let params = ExtractParams {
                compact_texels,
                ..ExtractParams::default()
            };
            let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
            let (a, b) = (lobe_stats(&pyr, true), lobe_stats_by_cell(&pyr, true));
            assert_eq!(a.shares, b.shares);
            let (ha, hb) = (a.horizon.unwrap(), b.horizon.unwrap());
            assert_eq!(ha[1..], hb[1..]);
            let l0 = &pyr.levels[0];
            assert_eq!(hb[0].len(), l0.texels());
            assert!(l0.lobes.len() > l0.texels(), "two lobes a texel somewhere");
            for (t, cell) in hb[0].iter().enumerate() {
                for j in l0.lobe_start[t] as usize..l0.lobe_start[t + 1] as usize {
                    assert_eq!(ha[0][j], *cell, "texel {t} lobe {j}");
                }
            }
            // Without horizons: no statistics either way.
            assert!(lobe_stats_by_cell(&pyr, false).horizon.is_none());
        }
    }

    /// [`rect_lobe_stats_by_cell`] of any rectangle gives the very bits of
    /// [`lobe_stats_by_cell`]'s entries for its texels, on every level, compact or not.
    #[test]
    #[allow(clippy::needless_range_loop)] // `j` indexes two tables' lobes
    fn rect_lobe_stats_are_lobe_stats_by_cell() {
        let map = fixtures::gaussian(32, 4.0, 0.1, 3, 0.01).unwrap();
        for compact_texels in [usize::MAX, 64] {
            let params = ExtractParams {
                compact_texels,
                ..ExtractParams::default()
            };
            let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).unwrap();
            let all = lobe_stats_by_cell(&pyr, true);
            let hz = all.horizon.as_ref().unwrap();
            let cells = all.cells.as_ref().unwrap();
            assert_eq!(cells.len(), pyr.levels[0].texels());
            for (k, l) in pyr.levels.iter().enumerate() {
                let (r0, c0) = (l.rows / 3, l.cols / 2);
                let (r1, c1) = ((r0 + 5).min(l.rows), (c0 + 3).min(l.cols));
                let got = rect_lobe_stats_by_cell(&pyr, k, r0..r1, c0..c1, true);
                // Level 0 has its cells' horizons, the others their lobes' distributions.
                assert_eq!(got.cells.is_some(), k == 0);
                assert_eq!(got.horizon.is_some(), k > 0);
                let (mut i, mut n) = (0, 0);
                for r in r0..r1 {
                    for c in c0..c1 {
                        let t = r * l.cols + c;
                        if k == 0 {
                            let gc = got.cells.as_ref().unwrap();
                            assert_eq!(gc[n], cells[t], "level 0 texel {t}");
                            // The cell's distribution is its horizons' distribution.
                            assert_eq!(gc[n].cdf(), hz[0][t], "level 0 texel {t}");
                        }
                        n += 1;
                        for j in l.lobe_start[t] as usize..l.lobe_start[t + 1] as usize {
                            assert_eq!(got.shares[i].to_bits(), all.shares[k][j].to_bits());
                            if k > 0 {
                                let gh = got.horizon.as_ref().unwrap();
                                assert_eq!(gh[i], hz[k][j], "level {k} lobe {j}");
                                if k >= JOINT_FROM_LEVEL {
                                    let gj = got.joint.as_ref().unwrap();
                                    let aj = &all.joint.as_ref().unwrap()[k];
                                    assert_eq!(gj[i], aj[j], "joint, level {k} lobe {j}");
                                    assert!(gj[i].weight > 0.0 || gh[i].weight <= 0.0);
                                }
                            }
                            i += 1;
                        }
                    }
                }
                assert_eq!(got.shares.len(), i);
                assert!(i > 0);
                // Joint distributions from level JOINT_FROM_LEVEL on, one a lobe.
                assert_eq!(got.joint.is_some(), k >= JOINT_FROM_LEVEL);
                assert_eq!(
                    all.joint.as_ref().unwrap()[k].len(),
                    if k >= JOINT_FROM_LEVEL {
                        l.lobes.len()
                    } else {
                        0
                    }
                );
            }
            let none = rect_lobe_stats_by_cell(&pyr, 1, 0..1, 0..1, false);
            assert!(none.horizon.is_none());
            assert!(none.joint.is_none());
            let none0 = rect_lobe_stats_by_cell(&pyr, 0, 0..1, 0..1, false);
            assert!(none0.cells.is_none() && none0.horizon.is_none());
        }
    }
}
