//! Visibility conditioned on the normal: which facets of a height map are lit from `i` *and*
//! seen from `o`, per facet normal (the paper's §3.1 point: positive and negative cylinders share
//! an NDF and differ in BRDF by self-blocking).
//!
//! # Model
//! Every facet `f` of the triangulated surface (`crate::facets`) keeps its **horizon** at
//! [`POINTS_PER_FACET`] points `p` (the centroids of its midpoint subdivision): for
//! [`AZIMUTHS`] azimuths `φ_a = 2π a / A`, the tangent of the highest elevation at which the
//! surface, marched from the point along `φ_a`, rises above it (`tan h_p(φ_a) ≥ 0`).
//! A direction `ω` of elevation `e` and azimuth `φ` reaches the point when `tan e > h_p(φ)`,
//! with `h_p` interpolated linearly between the two nearest azimuths. For a set of facets `F`
//! (those of one normal bin of the NDF) the joint visibility is
//!
//! ```text
//! G(i, o | F) = Σ_{f∈F} Σ_p w_f/P · [i reaches p] · [o reaches p] / Σ_{f∈F} w_f,
//! ```
//!
//! with `w_f` the facets' microsurface areas: shadowing and masking correlated exactly as far as
//! the points stand for the facet (a shadow edge across a facet is resolved to a quarter of
//! it), and nothing assumed about the heights' statistics (Smith assumes uncorrelated heights
//! and normals, which creased and steep surfaces are not).
//!
//! # The march
//! The surface between samples is the piecewise-linear one the gonioreflectometer traces
//! (`crate::gonio`), evaluated exactly ([`surface_height`]) at every crossing of a cell edge
//! along the azimuth (exact: the surface is linear between crossings), up to two periods of a
//! wrapped map (or the border of a clamped one); the march stops early once even the map's
//! highest point could no longer rise above the horizon found.

use crate::facets::NormalMode;
use crate::heightmap::{Border, HeightMap};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// Azimuths at which each facet keeps its horizon (every 11.25°).
pub const AZIMUTHS: usize = 32;
/// The lowest horizon kept, `tan 1°`: directions within 1° of the macro surface's horizon
/// (θ > 89°) count as hidden everywhere, which lets the march stop after
/// `(h_max − h)/tan 1°` instead of crossing the whole map on gentle surfaces.
pub const HORIZON_FLOOR: f64 = 0.017_455_064_928_217_585;

/// Height of the piecewise-linear surface of `map` at `(x, y)` in **texel units** (sample
/// `(i, j)` at `(j, i)`), triangulated as `crate::facets` (diagonal `(i, j)–(i+1, j+1)`); wrapped
/// or clamped by the map's border.
#[must_use]
pub fn surface_height(map: &HeightMap, x: f64, y: f64) -> f64 {
    Samples::new(map).surface_height(x, y)
}

/// A height map's samples with a cheap border rule for the march (in-range indices, the
/// common case, skip the integer division of `HeightMap::at`).
struct Samples<'a> {
    h: &'a [f64],
    w: isize,
    rows: isize,
    wrap: bool,
}

impl<'a> Samples<'a> {
    fn new(map: &'a HeightMap) -> Samples<'a> {
        Samples {
            h: map.heights(),
            w: map.width() as isize,
            rows: map.height() as isize,
            wrap: map.border() == Border::Wrap,
        }
    }

    #[inline]
    fn at(&self, i: isize, j: isize) -> f64 {
        let fix = |k: isize, n: isize| {
            if (0..n).contains(&k) {
                k
            } else if self.wrap {
                k.rem_euclid(n)
            } else {
                k.clamp(0, n - 1)
            }
        };
        self.h[(fix(i, self.rows) * self.w + fix(j, self.w)) as usize]
    }

    /// [`surface_height`].
    #[inline]
    fn surface_height(&self, x: f64, y: f64) -> f64 {
        let (fj, fi) = (x.floor(), y.floor());
        let (fx, fy) = (x - fj, y - fi);
        let (i, j) = (fi as isize, fj as isize);
        let h00 = self.at(i, j);
        let h11 = self.at(i + 1, j + 1);
        if fy < fx {
            let h01 = self.at(i, j + 1);
            h00 + fx * (h01 - h00) + fy * (h11 - h01)
        } else {
            let h10 = self.at(i + 1, j);
            h00 + fy * (h10 - h00) + fx * (h11 - h10)
        }
    }
}

/// `x` wrapped into `[0, n)` (cheap when it is already there or one period off).
#[inline]
fn wrap_f(x: f64, n: f64) -> f64 {
    if (0.0..n).contains(&x) {
        x
    } else if (n..2.0 * n).contains(&x) {
        x - n
    } else if (-n..0.0).contains(&x) {
        x + n
    } else {
        x.rem_euclid(n)
    }
}

/// Maxima of the heights over aligned blocks of `2^k × 2^k` cells (their corner samples
/// included), for every level `k`: the bound that lets the horizon march skip a block whose
/// highest point cannot rise above the horizon already found. Blocks that run past the map's
/// last cell take the map's maximum.
struct MaxPyramid {
    /// `levels[k]` has `cols_k × rows_k` blocks, row-major.
    levels: Vec<(usize, usize, Vec<f64>)>,
    /// The map's highest sample.
    hmax: f64,
}

impl MaxPyramid {
    fn new(map: &HeightMap) -> MaxPyramid {
        let (cols, rows) = (map.cells_x(), map.cells_y());
        let hmax = map.range().1;
        let mut l0 = Vec::with_capacity(cols * rows);
        for i in 0..rows as isize {
            for j in 0..cols as isize {
                l0.push(
                    map.at(i, j)
                        .max(map.at(i, j + 1))
                        .max(map.at(i + 1, j))
                        .max(map.at(i + 1, j + 1)),
                );
            }
        }
        let mut levels = vec![(cols, rows, l0)];
        while {
            let (c, r, _) = &levels[levels.len() - 1];
            *c > 1 || *r > 1
        } {
            let (c, r, prev) = &levels[levels.len() - 1];
            let (c, r) = (*c, *r);
            let (nc, nr) = (c.div_ceil(2), r.div_ceil(2));
            let mut next = Vec::with_capacity(nc * nr);
            for bi in 0..nr {
                for bj in 0..nc {
                    let mut m = f64::NEG_INFINITY;
                    for (di, dj) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                        let (ci, cj) = (2 * bi + di, 2 * bj + dj);
                        m = m.max(if ci < r && cj < c {
                            prev[ci * c + cj]
                        } else {
                            hmax
                        });
                    }
                    next.push(m);
                }
            }
            levels.push((nc, nr, next));
        }
        MaxPyramid { levels, hmax }
    }
}

/// Tangent of the horizon elevation seen from `(x, y, h0)` (texel units, height in length
/// units) along the unit direction `(dx, dy)`, ≥ [`HORIZON_FLOOR`]. Along a straight line the
/// piecewise-linear surface is linear between its crossings of the cell edges (rows, columns
/// and the cells' diagonals), and so the rise over distance is monotonic between them: the
/// largest slope is found exactly by evaluating the surface at every crossing — except inside
/// blocks of cells ([`MaxPyramid`]) whose highest point cannot beat the slope already found,
/// which are skipped whole.
fn horizon_tan(map: &HeightMap, maxes: &MaxPyramid, x: f64, y: f64, h0: f64, d: (f64, f64)) -> f64 {
    let s = map.texel_size();
    let (w, h) = (map.width() as f64, map.height() as f64);
    let (cw, ch) = (map.cells_x() as f64, map.cells_y() as f64);
    let wrap = map.border() == Border::Wrap;
    let hmax = maxes.hmax;
    let samples = Samples::new(map);
    // Farther copies of a wrapped tile are seen under smaller angles.
    let reach = if wrap { 2.0 * w.max(h) } else { f64::INFINITY };
    let next_crossing = |t: f64, c0: f64, dc: f64| -> f64 {
        if dc.abs() < 1e-12 {
            return f64::INFINITY;
        }
        let c = c0 + dc * t;
        let target = if dc > 0.0 {
            (c + 1e-9).floor() + 1.0
        } else {
            (c - 1e-9).ceil() - 1.0
        };
        t + (target - c) / dc
    };
    // Horizons below the floor are not searched for (module docs).
    let mut best = HORIZON_FLOOR;
    let mut t = 0.0f64;
    loop {
        if t > 0.0 && (hmax - h0) / (t * s) <= best {
            break;
        }
        // Skip the largest block ahead whose maximum cannot rise above `best`.
        if t > 0.0 {
            let eps = 1e-7;
            let (px, py) = (x + d.0 * (t + eps), y + d.1 * (t + eps));
            let (qx, qy) = if wrap {
                (wrap_f(px, cw), wrap_f(py, ch))
            } else {
                (px, py)
            };
            let mut skip_to = None;
            if qx >= 0.0 && qy >= 0.0 && qx < cw && qy < ch {
                // The cell first (one test when it cannot be skipped), then ever larger blocks.
                let mut found = None;
                for (k, (bc, br, m)) in maxes.levels.iter().enumerate() {
                    let b = (1usize << k) as f64;
                    let (bj, bi) = ((qx / b) as usize, (qy / b) as usize);
                    if bj >= *bc || bi >= *br || (m[bi * bc + bj] - h0) / (t * s) > best {
                        break;
                    }
                    found = Some((b, bj, bi));
                }
                if let Some((b, bj, bi)) = found {
                    // Leave the block: its x and y boundaries ahead, in unwrapped units.
                    let (ox, oy) = (px - qx, py - qy);
                    let exit = |lo: f64, c0: f64, dc: f64| -> f64 {
                        if dc > 1e-12 {
                            (lo + b - c0) / dc
                        } else if dc < -1e-12 {
                            (lo - c0) / dc
                        } else {
                            f64::INFINITY
                        }
                    };
                    let tx = exit(ox + bj as f64 * b, x, d.0);
                    let ty = exit(oy + bi as f64 * b, y, d.1);
                    skip_to = Some(tx.min(ty).max(t + eps));
                }
            }
            if let Some(t2) = skip_to {
                t = t2;
                if t > reach {
                    break;
                }
                continue;
            }
        }
        let t2 = next_crossing(t, x, d.0)
            .min(next_crossing(t, y, d.1))
            .min(next_crossing(t, x - y, d.0 - d.1));
        if t2.is_nan() || t2 > reach {
            break;
        }
        t = t2;
        let (px, py) = (x + d.0 * t, y + d.1 * t);
        if !wrap && (px < -1e-9 || py < -1e-9 || px > w - 1.0 + 1e-9 || py > h - 1.0 + 1e-9) {
            break;
        }
        let rise = (samples.surface_height(px, py) - h0) / (t * s);
        best = best.max(rise);
    }
    best
}

/// Points at which each facet of a small map keeps its horizon: one in each of the four
/// triangles of its midpoint subdivision (or each quarter of a cell with one central-difference
/// normal), placed at random in it ([`jitter`]: a fixed pseudo-random point per facet). Maps
/// with at least [`FINE_FACETS`] facets use one random point in the facet.
///
/// A facet's visibility is the share of its area that the light reaches and the viewer sees;
/// a random point estimates it without bias, and the estimates of a bin's many facets average.
/// Fixed points (the sub-triangles' centroids, the centroid of a large map's facet) did not:
/// on a periodic surface every groove's shadow edge falls at the same place against them, so
/// their error repeats instead of averaging (V-grooves of 45° walls one cell wide: 6.8 % off
/// `meso gonio` at 64², 27 % at 128² with the centroid alone; docs/heightmaps.md).
pub const POINTS_PER_FACET: usize = 4;
/// Facet count from which one point per facet is kept (see [`POINTS_PER_FACET`]).
pub const FINE_FACETS: usize = 32_768;

/// The number of points per facet [`facet_horizons`] uses for `facets` facets.
#[must_use]
pub fn points_per_facet(facets: usize) -> usize {
    if facets >= FINE_FACETS {
        1
    } else {
        POINTS_PER_FACET
    }
}

/// Two pseudo-random numbers in `[0, 1)` for point `p` of facet `f` (SplitMix64 of both): the
/// same for every run, independent from facet to facet.
#[must_use]
pub fn jitter(f: usize, p: usize) -> (f64, f64) {
    let mut z = (f as u64)
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add((p as u64 + 1).wrapping_mul(0xD1B5_4A32_D192_ED03));
    let mut next = || {
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut x = z;
        x = (x ^ (x >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        x = (x ^ (x >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        x ^= x >> 31;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    (next(), next())
}

/// A uniformly distributed point of triangle `v` for the two numbers `(u, w)` in `[0, 1)`.
fn in_triangle(v: [(f64, f64); 3], (mut u, mut w): (f64, f64)) -> (f64, f64) {
    if u + w > 1.0 {
        (u, w) = (1.0 - u, 1.0 - w);
    }
    (
        v[0].0 + u * (v[1].0 - v[0].0) + w * (v[2].0 - v[0].0),
        v[0].1 + u * (v[1].1 - v[0].1) + w * (v[2].1 - v[0].1),
    )
}

/// The sample points of facet `f`, triangle `v` (texel units): with `np` = 4 one random point
/// ([`jitter`]) in each triangle of its midpoint subdivision (stratified), with `np` = 1 one
/// in the whole triangle (the first entry).
fn triangle_points(v: [(f64, f64); 3], f: usize, np: usize) -> [(f64, f64); POINTS_PER_FACET] {
    if np == 1 {
        return [in_triangle(v, jitter(f, 0)); POINTS_PER_FACET];
    }
    let mid = |a: (f64, f64), b: (f64, f64)| (0.5 * (a.0 + b.0), 0.5 * (a.1 + b.1));
    let (m01, m12, m20) = (mid(v[0], v[1]), mid(v[1], v[2]), mid(v[2], v[0]));
    [
        in_triangle([v[0], m01, m20], jitter(f, 0)),
        in_triangle([v[1], m12, m01], jitter(f, 1)),
        in_triangle([v[2], m20, m12], jitter(f, 2)),
        in_triangle([m01, m12, m20], jitter(f, 3)),
    ]
}

/// The sample points of facet `f`, the cell with corner `(x, y)` under one central-difference
/// normal: one random point in each quarter (`np` = 4) or in the cell (`np` = 1, the first).
fn cell_points(x: f64, y: f64, f: usize, np: usize) -> [(f64, f64); POINTS_PER_FACET] {
    let at = |k: usize, ox: f64, oy: f64, side: f64| {
        let (u, w) = jitter(f, k);
        (x + ox + side * u, y + oy + side * w)
    };
    if np == 1 {
        return [at(0, 0.0, 0.0, 1.0); POINTS_PER_FACET];
    }
    [
        at(0, 0.0, 0.0, 0.5),
        at(1, 0.5, 0.0, 0.5),
        at(2, 0.0, 0.5, 0.5),
        at(3, 0.5, 0.5, 0.5),
    ]
}

/// The horizons of every facet of a height map at its `P` = [`points_per_facet`] points:
/// `tan[(f · P + p) · AZIMUTHS + a]` for facet `f` (the order of
/// [`crate::facets::FacetNormals::from_heightmap`] with the same mode), point `p` and azimuth `a`.
#[must_use]
pub fn facet_horizons(map: &HeightMap, mode: NormalMode) -> Vec<f32> {
    let per_cell = match mode {
        NormalMode::Triangles => 2,
        NormalMode::CentralDifferences => 1,
    };
    let all: Vec<u32> = (0..(map.cells_x() * map.cells_y() * per_cell) as u32).collect();
    facet_horizons_of(map, mode, &all, &|_, _| {})
}

/// The horizons of the listed facets (indices in the order of
/// [`crate::facets::FacetNormals::from_heightmap`] with the same mode) at the map's
/// [`points_per_facet`] points: `tan[(n · P + p) · AZIMUTHS + a]` for the `n`-th listed facet.
/// `done(chunks_done, chunks)` is called (from the worker threads) after each chunk of facets:
/// the progress of the horizon march, the long part of a facet NDF's visibility.
#[must_use]
pub fn facet_horizons_of(
    map: &HeightMap,
    mode: NormalMode,
    facets: &[u32],
    done: &(dyn Fn(usize, usize) + Sync),
) -> Vec<f32> {
    let (cols, rows) = (map.cells_x(), map.cells_y());
    let finished = std::sync::atomic::AtomicUsize::new(0);
    let maxes = MaxPyramid::new(map);
    let dirs: Vec<(f64, f64)> = (0..AZIMUTHS)
        .map(|a| {
            let p = TAU * a as f64 / AZIMUTHS as f64;
            (p.cos(), p.sin())
        })
        .collect();
    let per_cell = match mode {
        NormalMode::Triangles => 2,
        NormalMode::CentralDifferences => 1,
    };
    let np = points_per_facet(cols * rows * per_cell);
    let stride = np * AZIMUTHS;
    let mut out = vec![0.0f32; facets.len() * stride];
    const CHUNK: usize = 256;
    let chunks = facets.len().div_ceil(CHUNK);
    out.par_chunks_mut(CHUNK * stride)
        .zip(facets.par_chunks(CHUNK))
        .for_each(|(dst, list)| {
            for (n, &f) in list.iter().enumerate() {
                let f = f as usize;
                let (cell, k) = (f / per_cell, f % per_cell);
                let (x, y) = ((cell % cols) as f64, (cell / cols) as f64);
                // Triangle A (i,j),(i,j+1),(i+1,j+1); B (i,j),(i+1,j+1),(i+1,j).
                let pts: [(f64, f64); POINTS_PER_FACET] = match mode {
                    NormalMode::Triangles if k == 0 => {
                        triangle_points([(x, y), (x + 1.0, y), (x + 1.0, y + 1.0)], f, np)
                    }
                    NormalMode::Triangles => {
                        triangle_points([(x, y), (x + 1.0, y + 1.0), (x, y + 1.0)], f, np)
                    }
                    NormalMode::CentralDifferences => cell_points(x, y, f, np),
                };
                let pts = &pts[..np];
                for (p, &(cx, cy)) in pts.iter().enumerate() {
                    let h0 = Samples::new(map).surface_height(cx, cy);
                    let base = (n * np + p) * AZIMUTHS;
                    for (a, &d) in dirs.iter().enumerate() {
                        dst[base + a] = horizon_tan(map, &maxes, cx, cy, h0, d) as f32;
                    }
                }
            }
            let n = finished.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            done(n, chunks);
        });
    out
}

/// The most facets of one normal bin whose horizons are marched (on average): a bin with more
/// (a flat plateau's, a groove wall's) keeps a pseudo-random subset of them, each standing for
/// its share of the bin's area. A random subset, not a stride: a stride through the facets in
/// map order keeps one of a cell's two triangles, or one column of a periodic pattern, and
/// biased the V-grooves' visibility by 6 %. The bins' visibilities move by a sampling error of
/// order `0.5/√MAX_FACETS_PER_BIN` each, averaged further over the bins a BRDF value sums.
pub const MAX_FACETS_PER_BIN: usize = 2048;

/// The facets whose horizons a [`BinnedVisibility`] keeps: from `bins[f]` (facet `f`'s bin, of
/// `nb`), every facet of bins with at most [`MAX_FACETS_PER_BIN`], and of larger bins each
/// facet with probability `MAX_FACETS_PER_BIN / count` (a hash of its index: deterministic).
/// Returns the chosen facets (ascending) and each one's weight factor (its bin's facet count
/// over the number chosen from it, so that a bin's total weight is kept).
#[must_use]
pub fn facets_to_march(bins: &[u32], nb: usize) -> (Vec<u32>, Vec<f64>) {
    let mut count = vec![0usize; nb];
    for &b in bins {
        count[b as usize] += 1;
    }
    // Keep facet f of bin b when its hash, as a fraction of 2^64, is below p_b.
    let threshold: Vec<u64> = count
        .iter()
        .map(|&c| {
            if c <= MAX_FACETS_PER_BIN {
                u64::MAX
            } else {
                (MAX_FACETS_PER_BIN as f64 / c as f64 * u64::MAX as f64) as u64
            }
        })
        .collect();
    let keep = |f: usize, b: usize| threshold[b] == u64::MAX || splitmix64(f as u64) < threshold[b];
    let mut kept = vec![0usize; nb];
    let mut chosen = Vec::new();
    for (f, &b) in bins.iter().enumerate() {
        if keep(f, b as usize) {
            chosen.push(f as u32);
            kept[b as usize] += 1;
        }
    }
    let factor = chosen
        .iter()
        .map(|&f| {
            let b = bins[f as usize] as usize;
            count[b] as f64 / kept[b] as f64
        })
        .collect();
    (chosen, factor)
}

/// A 64-bit mix of `x` (SplitMix64's finaliser): a deterministic pseudo-random value.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Gauss–Legendre nodes on [0, 1] for the elevation integral of [`sky_view`].
struct SkyRule {
    x: Vec<f64>,
    w: Vec<f64>,
    dirs: Vec<(f64, f64)>,
}

impl SkyRule {
    fn new() -> SkyRule {
        let (x, w) = meso_core::quadrature::gauss_legendre(8);
        SkyRule {
            x: x.iter().map(|x| 0.5 * (x + 1.0)).collect(),
            w: w.iter().map(|w| 0.5 * w).collect(),
            dirs: (0..AZIMUTHS)
                .map(|a| {
                    let p = TAU * a as f64 / AZIMUTHS as f64;
                    (p.cos(), p.sin())
                })
                .collect(),
        }
    }

    /// [`sky_view`] with this rule.
    fn view(&self, horizon_tan: &[f32], m: DVec3) -> f64 {
        let mut s = 0.0;
        for (&(c, sn), &t) in self.dirs.iter().zip(horizon_tan) {
            let e0 = f64::from(t).atan().max(0.0);
            let span = 0.5 * std::f64::consts::PI - e0;
            let tangential = c * m.x + sn * m.y;
            let mut acc = 0.0;
            for (x, w) in self.x.iter().zip(&self.w) {
                let e = e0 + span * x;
                let (se, ce) = e.sin_cos();
                acc += w * (ce * tangential + se * m.z).max(0.0) * ce;
            }
            s += acc * span;
        }
        // Azimuthal sectors of 2π/A, and the 1/π of the cosine weighting.
        (s * TAU / AZIMUTHS as f64 / std::f64::consts::PI).clamp(0.0, 1.0)
    }
}

/// The cosine-weighted share of the hemisphere about the facet normal `m` that sees the sky
/// from a point with the horizon `horizon_tan` (per azimuth, as stored): `(1/π) ∫ (ω·m)⁺ dω`
/// over the directions above the horizon, 1 for a flat facet under an open sky (less the 1°
/// horizon floor). Eight Gauss–Legendre nodes in elevation per stored azimuth.
#[must_use]
pub fn sky_view(horizon_tan: &[f32], m: DVec3) -> f64 {
    SkyRule::new().view(horizon_tan, m)
}

/// Where a direction falls among the stored azimuths: the two neighbours, the interpolation
/// weight of the second, and the tangent of its elevation.
#[derive(Clone, Copy, Debug)]
struct Probe {
    a0: usize,
    a1: usize,
    t: f32,
    tan_e: f32,
}

impl Probe {
    fn new(w: DVec3) -> Probe {
        let r = (w.x * w.x + w.y * w.y).sqrt();
        let tan_e = if r < 1e-12 { f64::INFINITY } else { w.z / r };
        let phi = w.y.atan2(w.x).rem_euclid(TAU);
        let u = phi / TAU * AZIMUTHS as f64;
        let a0 = (u.floor() as usize) % AZIMUTHS;
        Probe {
            a0,
            a1: (a0 + 1) % AZIMUTHS,
            t: (u - u.floor()) as f32,
            tan_e: tan_e as f32,
        }
    }
}

/// The visibility of a delta-sum NDF's normals: for each delta (one normal bin of the map), the
/// horizons and weights of the facets it stands for. Bin `k`'s horizons are stored azimuth by
/// azimuth (`AZIMUTHS` runs of its facets' tangents), so that a query streams through flat
/// arrays; each bin also keeps its largest horizon per azimuth, so that directions above all of
/// them are answered without visiting the facets.
#[derive(Clone, Debug, Default)]
pub struct BinnedVisibility {
    /// Bin `k` owns facets `start[k]..start[k+1]`; its horizons are
    /// `horizons[start[k]·A + a·len + f]` for azimuth `a` and its `f`-th facet.
    horizons: Vec<f32>,
    weights: Vec<f32>,
    start: Vec<u32>,
    /// Per bin and azimuth, the largest horizon of the bin's facets.
    max_horizon: Vec<f32>,
    /// Per bin, the total weight of its facets.
    total: Vec<f32>,
    /// Per bin, the weighted mean cosine-weighted sky view of its facets' points
    /// ([`sky_view`]).
    sky: Vec<f32>,
    /// Lookup from a delta's normal (its bits) to its bin.
    index: std::collections::HashMap<[u64; 3], u32>,
}

/// The key of a unit normal in [`BinnedVisibility`]'s lookup.
fn key(m: DVec3) -> [u64; 3] {
    [m.x.to_bits(), m.y.to_bits(), m.z.to_bits()]
}

impl BinnedVisibility {
    /// Group facets into bins. The `n`-th kept facet has weight `weights[n]` (its
    /// microsurface area, or the share of its bin it stands for), bin `bins[n]`
    /// (0..`normals.len()`) and horizons `horizons[n·P·A ..]` ([`facet_horizons_of`] over the
    /// same list); `normals[k]` is the exact normal the NDF's delta `k` carries.
    #[must_use]
    pub fn new(
        weights: &[f64],
        horizons: &[f32],
        bins: &[u32],
        normals: &[DVec3],
    ) -> BinnedVisibility {
        let nb = normals.len();
        let np = horizons.len() / (bins.len() * AZIMUTHS).max(1);
        let pp = np as u32;
        let mut count = vec![0u32; nb + 1];
        for &b in bins {
            count[b as usize + 1] += pp;
        }
        for k in 0..nb {
            count[k + 1] += count[k];
        }
        let start = count.clone();
        let mut fill = count;
        let n = bins.len() * np;
        let mut hz = vec![0.0f32; n * AZIMUTHS];
        let mut ws = vec![0.0f32; n];
        let mut max_horizon = vec![0.0f32; nb * AZIMUTHS];
        let mut total = vec![0.0f32; nb];
        let mut sky = vec![0.0f64; nb];
        let sky_rule = SkyRule::new();
        for (f, &b) in bins.iter().enumerate() {
            let b = b as usize;
            let (s0, len) = (start[b] as usize, (start[b + 1] - start[b]) as usize);
            let w = (weights[f] / np as f64) as f32;
            for p in 0..np {
                let src = (f * np + p) * AZIMUTHS;
                sky[b] += f64::from(w) * sky_rule.view(&horizons[src..src + AZIMUTHS], normals[b]);
            }
            for p in 0..np {
                let local = fill[b] as usize - s0;
                fill[b] += 1;
                let src = (f * np + p) * AZIMUTHS;
                for a in 0..AZIMUTHS {
                    let v = horizons[src + a];
                    hz[s0 * AZIMUTHS + a * len + local] = v;
                    let mh = &mut max_horizon[b * AZIMUTHS + a];
                    *mh = mh.max(v);
                }
                ws[s0 + local] = w;
                total[b] += w;
            }
        }
        let index = normals
            .iter()
            .enumerate()
            .map(|(k, m)| (key(*m), k as u32))
            .collect();
        let sky = sky
            .iter()
            .zip(&total)
            .map(|(&s, &t)| {
                if t > 0.0 {
                    (s / f64::from(t)) as f32
                } else {
                    1.0
                }
            })
            .collect();
        BinnedVisibility {
            horizons: hz,
            weights: ws,
            start,
            max_horizon,
            total,
            sky,
            index,
        }
    }

    /// Append this model to `out` (little-endian; [`BinnedVisibility::decode`] reads it back):
    /// the five arrays, each as a `u64` length and its values.
    pub fn encode(&self, out: &mut Vec<u8>) {
        fn put<T: Copy>(out: &mut Vec<u8>, v: &[T], bytes: impl Fn(T) -> [u8; 4]) {
            out.extend_from_slice(&(v.len() as u64).to_le_bytes());
            for &x in v {
                out.extend_from_slice(&bytes(x));
            }
        }
        put(out, &self.horizons, f32::to_le_bytes);
        put(out, &self.weights, f32::to_le_bytes);
        put(out, &self.start, u32::to_le_bytes);
        put(out, &self.max_horizon, f32::to_le_bytes);
        put(out, &self.total, f32::to_le_bytes);
        put(out, &self.sky, f32::to_le_bytes);
    }

    /// Read a model written by [`BinnedVisibility::encode`] for the deltas `normals` from the
    /// front of `bytes`, advancing it; `None` unless every length and offset is consistent
    /// with one bin per normal and every value is finite.
    #[must_use]
    pub fn decode(bytes: &mut &[u8], normals: &[DVec3]) -> Option<BinnedVisibility> {
        fn take<T>(bytes: &mut &[u8], limit: usize, f: impl Fn([u8; 4]) -> T) -> Option<Vec<T>> {
            let (len, rest) = bytes.split_first_chunk::<8>()?;
            let n = usize::try_from(u64::from_le_bytes(*len)).ok()?;
            if n > limit || rest.len() < n.checked_mul(4)? {
                return None;
            }
            let (data, rest) = rest.split_at(n * 4);
            *bytes = rest;
            Some(
                data.chunks_exact(4)
                    .map(|c| f([c[0], c[1], c[2], c[3]]))
                    .collect(),
            )
        }
        let limit = bytes.len() / 4;
        let horizons = take(bytes, limit, f32::from_le_bytes)?;
        let weights = take(bytes, limit, f32::from_le_bytes)?;
        let start = take(bytes, limit, u32::from_le_bytes)?;
        let max_horizon = take(bytes, limit, f32::from_le_bytes)?;
        let total = take(bytes, limit, f32::from_le_bytes)?;
        let sky = take(bytes, limit, f32::from_le_bytes)?;
        let nb = normals.len();
        let ok = start.len() == nb + 1
            && start[0] == 0
            && start.windows(2).all(|w| w[0] <= w[1])
            && start[nb] as usize == weights.len()
            && horizons.len() == weights.len() * AZIMUTHS
            && max_horizon.len() == nb * AZIMUTHS
            && total.len() == nb
            && sky.len() == nb
            && sky.iter().all(|s| (0.0..=1.0).contains(s))
            && horizons
                .iter()
                .chain(&weights)
                .chain(&max_horizon)
                .chain(&total)
                .all(|v| v.is_finite());
        if !ok {
            return None;
        }
        let index = normals
            .iter()
            .enumerate()
            .map(|(k, m)| (key(*m), k as u32))
            .collect();
        Some(BinnedVisibility {
            horizons,
            weights,
            start,
            max_horizon,
            total,
            sky,
            index,
        })
    }

    /// Per bin, the cosine-weighted share of its facets' hemisphere that sees the sky
    /// ([`sky_view`], weight-averaged over the bin's points).
    #[must_use]
    pub fn sky_views(&self) -> &[f32] {
        &self.sky
    }

    /// Number of bins.
    #[must_use]
    pub fn bins(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// `G(i, o | bin k)`: the weighted fraction of bin `k`'s facets that both `i` and `o` reach.
    #[must_use]
    pub fn joint(&self, k: usize, i: DVec3, o: DVec3) -> f64 {
        self.joint_probed(k, &Probe::new(i), &Probe::new(o))
    }

    /// [`BinnedVisibility::joint`] for many bins `ks` of one direction pair, written to
    /// `out[..ks.len()]`: the directions' azimuths and elevations are found once.
    pub fn joint_many(&self, i: DVec3, o: DVec3, ks: &[u32], out: &mut [f64]) {
        let (pi, po) = (Probe::new(i), Probe::new(o));
        for (v, &k) in out.iter_mut().zip(ks) {
            *v = self.joint_probed(k as usize, &pi, &po);
        }
    }

    fn joint_probed(&self, k: usize, pi: &Probe, po: &Probe) -> f64 {
        let mh = &self.max_horizon[k * AZIMUTHS..(k + 1) * AZIMUTHS];
        // Above every facet's horizon on both sides: all visible.
        if pi.tan_e > mh[pi.a0].max(mh[pi.a1]) && po.tan_e > mh[po.a0].max(mh[po.a1]) {
            return 1.0;
        }
        let (a, b) = (self.start[k] as usize, self.start[k + 1] as usize);
        let len = b - a;
        let all = self.total[k];
        if len == 0 || all <= 0.0 {
            return 1.0;
        }
        let base = a * AZIMUTHS;
        let run = |az: usize| &self.horizons[base + az * len..base + (az + 1) * len];
        let (i0, i1, o0, o1) = (run(pi.a0), run(pi.a1), run(po.a0), run(po.a1));
        let w = &self.weights[a..b];
        let mut vis = 0.0f32;
        for f in 0..len {
            let hi = i0[f] + pi.t * (i1[f] - i0[f]);
            let ho = o0[f] + po.t * (o1[f] - o0[f]);
            let ok = (pi.tan_e > hi) & (po.tan_e > ho);
            vis += if ok { w[f] } else { 0.0 };
        }
        f64::from(vis / all).min(1.0)
    }

    /// `G(i, o | m)` for a normal `m` that is one of the deltas' normals; 1 for any other.
    #[must_use]
    pub fn given_normal(&self, i: DVec3, o: DVec3, m: DVec3) -> f64 {
        match self.index.get(&key(m)) {
            Some(&k) => self.joint(k as usize, i, o),
            None => 1.0,
        }
    }

    /// `G(i, o)` over all facets (the visibility not conditioned on the normal): the
    /// weight-averaged [`BinnedVisibility::joint`].
    #[must_use]
    pub fn total(&self, i: DVec3, o: DVec3) -> f64 {
        let (mut vis, mut all) = (0.0f64, 0.0f64);
        for k in 0..self.bins() {
            let w = f64::from(self.total[k]);
            vis += w * self.joint(k, i, o);
            all += w;
        }
        if all > 0.0 {
            vis / all
        } else {
            1.0
        }
    }
}
