//! Horizon angles (Max 1988, "Horizon mapping"): for every sample of a height map, the elevation
//! angle of the horizon seen along eight azimuths — +x, +y, −x, −y (0°, 90°, 180°, 270°) and
//! the four diagonals (45°, 135°, 225°, 315°) — in radians in `[0, π/2)`; 0 means nothing
//! rises above the horizontal plane through the sample (the macro surface's tangent plane).
//!
//! The piecewise-linear surface along a grid line is linear between samples, so the horizon is
//! the largest slope from the sample to any later sample on its line: found for a whole line in
//! O(n) with the upper convex hull of the samples ahead. Wrapped maps look one full period ahead
//! (enough: farther copies are seen under smaller angles); clamped maps stop at the border.
//! Along the diagonals the line also crosses the cells' split diagonals ([`diagonal_angles`]).
//!
//! [`HorizonStats`] filters the angles over a footprint as a mean and a variance per direction;
//! [`HorizonStats::visibility`] turns them into the fraction of the footprint that sees a
//! direction: the horizon angle is modelled as uniformly distributed with that mean and variance
//! (a ramp of half-width √3·σ around the mean) and the ramp is smoothed by a smoothstep. A
//! direction between two of the eight azimuths interpolates their means and variances.
//!
//! Until 2026-12-07 only the four axes were kept and the diagonals interpolated from them: on
//! the facade height map under a light at 45° that left the NDF-mapped shadows 0.52–0.68 of
//! the bump map's (docs/heightmaps.md, "Eight azimuths").

use crate::heightmap::{Border, HeightMap};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::FRAC_PI_2;

mod cell;
mod toward;
pub use cell::CellHorizon;
pub use toward::{HorizonToward, HorizonTowardSum, TowardReading, TOWARD_TILT};

/// Number of horizon directions kept per sample and footprint.
pub const HORIZON_DIRECTIONS: usize = 8;

/// Azimuths (degrees, from +x towards +y) of the horizon directions, in the order of
/// [`HorizonMap::angles`] and [`HorizonStats`]: the four axes +x, +y, −x, −y, then the four
/// diagonals +x+y, −x+y, −x−y, +x−y ([`DIAGONAL_AZIMUTHS_DEG`]).
pub const HORIZON_AZIMUTHS_DEG: [f64; HORIZON_DIRECTIONS] =
    [0.0, 90.0, 180.0, 270.0, 45.0, 135.0, 225.0, 315.0];

/// The slot (order of [`HORIZON_AZIMUTHS_DEG`]) of the direction at azimuth `k · 45°`.
const SLOT_OF_OCTANT: [usize; HORIZON_DIRECTIONS] = [0, 4, 1, 5, 2, 6, 3, 7];

/// The step of a stored horizon angle ([`HorizonMap::angles`]): `[0, π/2]` in 65 535 steps,
/// ≈ 2.4·10⁻⁵ rad (a stored angle is within half a step of the exact one). The map file keeps
/// the angles' statistics to 12 bits (≈ 3.8·10⁻⁴ rad), sixteen times coarser.
pub const ANGLE_STEP: f64 = std::f64::consts::FRAC_PI_2 / 65_535.0;

/// Horizon elevation angles of every sample, quantised to 16 bits: `angles[d][i·width + j]`
/// for direction `d` (order of [`HORIZON_AZIMUTHS_DEG`]) is the angle in units of
/// [`ANGLE_STEP`] ([`HorizonMap::angle`] gives radians). Two bytes a sample and direction: the
/// extraction holds every sample's eight angles until level 2 is fitted (at 8192², 1 GB).
#[derive(Clone, Debug, PartialEq)]
pub struct HorizonMap {
    /// Samples along x.
    pub width: usize,
    /// Samples along y.
    pub height: usize,
    /// Per direction, per sample (row-major) horizon elevation angle in units of
    /// [`ANGLE_STEP`] (0 = the horizontal, 65 535 = π/2).
    pub angles: [Vec<u16>; HORIZON_DIRECTIONS],
}

/// The stored code of a horizon angle in radians (`[0, π/2]`, rounded to [`ANGLE_STEP`]).
fn angle_code(a: f64) -> u16 {
    (a / ANGLE_STEP).round().clamp(0.0, 65_535.0) as u16
}

/// Horizon angles along one line towards increasing index; `s` = sample spacing.
fn horizon_line(h: &[f64], s: f64, wrap: bool, out: &mut [f64], stack: &mut Vec<(f64, f64)>) {
    let n = h.len();
    let len = if wrap { 2 * n } else { n };
    stack.clear();
    for idx in (0..len).rev() {
        let p = (idx as f64 * s, h[idx % n]);
        let slope = |q: (f64, f64)| (q.1 - p.1) / (q.0 - p.0);
        while stack.len() >= 2 && slope(stack[stack.len() - 1]) <= slope(stack[stack.len() - 2]) {
            stack.pop();
        }
        if idx < n {
            out[idx] = match stack.last() {
                Some(&q) => slope(q).max(0.0).atan(),
                None => 0.0,
            };
        }
        stack.push(p);
    }
}

/// Columns whose ±y angles [`HorizonMap::compute`] finds at a time (its buffers: 4 bytes a
/// sample of the block).
const COLUMN_BLOCK: usize = 256;

/// One thread's buffers for [`horizon_line`] along both directions of a line.
#[derive(Default)]
struct Lines {
    line: Vec<f64>,
    out: Vec<f64>,
    stack: Vec<(f64, f64)>,
}

impl Lines {
    /// The horizon angle codes of the line of heights `heights`, `s` apart, towards increasing
    /// index (`ahead`) and towards decreasing index (`behind`), both in the line's order, of
    /// every `stride`-th entry from the first (1: every entry; 2 along the diagonals that cross
    /// the cells' split diagonals, whose midpoints lie between the samples).
    fn both_ways(
        &mut self,
        heights: impl Iterator<Item = f64>,
        s: f64,
        wrap: bool,
        stride: usize,
        ahead: &mut [u16],
        behind: &mut [u16],
    ) {
        self.line.clear();
        self.line.extend(heights);
        let n = self.line.len();
        self.out.resize(n, 0.0);
        horizon_line(&self.line, s, wrap, &mut self.out, &mut self.stack);
        for (j, a) in ahead.iter_mut().enumerate() {
            *a = angle_code(self.out[stride * j]);
        }
        self.line.reverse();
        horizon_line(&self.line, s, wrap, &mut self.out, &mut self.stack);
        for (j, a) in behind.iter_mut().enumerate() {
            *a = angle_code(self.out[n - 1 - stride * j]);
        }
    }
}

impl HorizonMap {
    /// Horizon angles of every sample of `map` along ±x, ±y and the diagonals
    /// ([`diagonal_angles`]). Lines are independent: rows (±x) and columns (±y, 256 at a
    /// time) are computed in parallel on rayon's pool, each line exactly as one after the other
    /// would (the same angles, bit for bit, whatever the threads), with no more memory than the
    /// eight angle arrays and one block.
    #[must_use]
    pub fn compute(map: &HeightMap) -> HorizonMap {
        let (w, h) = (map.width(), map.height());
        let s = map.texel_size();
        let wrap = map.border() == Border::Wrap;
        let hs = map.heights();
        let (mut east, mut west) = (vec![0u16; w * h], vec![0u16; w * h]);
        if w > 0 && h > 0 {
            // ±x along the rows, row by row in parallel.
            east.par_chunks_mut(w)
                .zip(west.par_chunks_mut(w))
                .zip(hs.par_chunks(w))
                .for_each_init(Lines::default, |ln, ((e, wst), row)| {
                    ln.both_ways(row.iter().copied(), s, wrap, 1, e, wst);
                });
        }
        // ±y along the columns: a block of columns at a time in parallel into column-major
        // buffers (a few MB), then copied into the rows in parallel, so that no more than the
        // four angle arrays and one block are held.
        let (mut north, mut south) = (vec![0u16; w * h], vec![0u16; w * h]);
        if w > 0 && h > 0 {
            let block = COLUMN_BLOCK.min(w);
            let (mut up, mut down) = (vec![0u16; block * h], vec![0u16; block * h]);
            for j0 in (0..w).step_by(block) {
                let nb = block.min(w - j0);
                up[..nb * h]
                    .par_chunks_mut(h)
                    .zip(down[..nb * h].par_chunks_mut(h))
                    .enumerate()
                    .for_each_init(Lines::default, |ln, (jj, (u, d))| {
                        let j = j0 + jj;
                        ln.both_ways((0..h).map(|i| hs[i * w + j]), s, wrap, 1, u, d);
                    });
                north
                    .par_chunks_mut(w)
                    .zip(south.par_chunks_mut(w))
                    .enumerate()
                    .for_each(|(i, (n, so))| {
                        for jj in 0..nb {
                            n[j0 + jj] = up[jj * h + i];
                            so[j0 + jj] = down[jj * h + i];
                        }
                    });
            }
        }
        let [ne, nw, sw, se] = diagonal_angles(map);
        HorizonMap {
            width: w,
            height: h,
            angles: [east, north, west, south, ne, nw, sw, se],
        }
    }

    /// The horizon angle (radians, within half an [`ANGLE_STEP`] of the exact one) of sample
    /// `k` (row-major) along direction `d` (order of [`HORIZON_AZIMUTHS_DEG`]).
    #[must_use]
    pub fn angle(&self, d: usize, k: usize) -> f64 {
        f64::from(self.angles[d][k]) * ANGLE_STEP
    }

    /// The statistics of the single sample `(row, col)`.
    #[must_use]
    pub fn sample_stats(&self, row: usize, col: usize) -> HorizonStats {
        let k = row * self.width + col;
        HorizonStats {
            weight: 1.0,
            mean: std::array::from_fn(|d| self.angle(d, k)),
            var: [0.0; HORIZON_DIRECTIONS],
        }
    }

    /// Statistics over all samples.
    #[must_use]
    pub fn total_stats(&self) -> HorizonStats {
        let mut s = HorizonStats::default();
        for r in 0..self.height {
            for c in 0..self.width {
                s.merge(&self.sample_stats(r, c));
            }
        }
        s
    }
}

/// Directions of the four diagonal horizon angles ([`diagonal_angles`]): azimuths 45°
/// (+x+y), 135° (−x+y), 225° (−x−y) and 315° (+x−y).
pub const DIAGONAL_AZIMUTHS_DEG: [f64; 4] = [45.0, 135.0, 225.0, 315.0];

/// Greatest common divisor.
fn gcd(a: usize, b: usize) -> usize {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Samples whose diagonal lines [`diagonal_angles`] hands to rayon at a time (its buffers: 12
/// bytes a sample of the batch).
const DIAGONAL_BATCH: usize = 1 << 20;

/// Horizon angles of every sample of `map` along the four diagonals, in the codes of
/// [`HorizonMap::angles`] and the order of [`DIAGONAL_AZIMUTHS_DEG`], of the same surface:
/// the two triangles a cell split along its `(i, j)–(i + 1, j + 1)` diagonal (row, column).
///
/// Along +x+y (and back) the line through the samples runs on those split diagonals, so the
/// surface is linear between samples, `√2` texels apart. Along +x−y it crosses each cell's
/// split diagonal at its midpoint, where the height is the mean of that diagonal's two ends:
/// the line is linear between samples and midpoints, half as far apart. Either way the horizon
/// is exact, found in O(n) a line by the convex hull of the samples ahead (as along the axes). On a wrapped map a diagonal line closes
/// after `lcm(width, height)` samples (`gcd(width, height)` lines a direction) and is looked
/// along for one whole turn; on a clamped map the lines stop at the border.
#[must_use]
pub fn diagonal_angles(map: &HeightMap) -> [Vec<u16>; 4] {
    let (w, h) = (map.width(), map.height());
    let s = map.texel_size() * std::f64::consts::SQRT_2;
    let wrap = map.border() == Border::Wrap;
    let hs = map.heights();
    let mut out: [Vec<u16>; 4] = std::array::from_fn(|_| vec![0u16; w * h]);
    if w == 0 || h == 0 {
        return out;
    }
    // (+x+y, −x−y) with rows stepping +1, then (+x−y, −x+y) with rows stepping −1.
    for (down, ahead_dir, behind_dir) in [(false, 0usize, 2usize), (true, 3, 1)] {
        // Each line: its first sample and its number of samples.
        let lines: Vec<(usize, usize, usize)> = if wrap {
            let g = gcd(w, h);
            (0..g).map(|c| (0, c, w / g * h)).collect()
        } else if down {
            (0..h)
                .map(|r| (r, 0, (r + 1).min(w)))
                .chain((1..w).map(|c| (h - 1, c, h.min(w - c))))
                .collect()
        } else {
            (0..w)
                .map(|c| (0, c, h.min(w - c)))
                .chain((1..h).map(|r| (r, 0, (h - r).min(w))))
                .collect()
        };
        let step = |r: usize, c: usize| -> (usize, usize) {
            let c1 = if c + 1 == w { 0 } else { c + 1 };
            let r1 = if down {
                if r == 0 {
                    h - 1
                } else {
                    r - 1
                }
            } else if r + 1 == h {
                0
            } else {
                r + 1
            };
            (r1, c1)
        };
        let mut start = 0;
        while start < lines.len() {
            let mut end = start;
            let mut n = 0;
            while end < lines.len() && (end == start || n + lines[end].2 <= DIAGONAL_BATCH) {
                n += lines[end].2;
                end += 1;
            }
            let done: Vec<(Vec<u32>, Vec<u16>, Vec<u16>)> = lines[start..end]
                .par_iter()
                .map_init(Lines::default, |ln, &(r0, c0, len)| {
                    let mut idx = Vec::with_capacity(len);
                    let (mut r, mut c) = (r0, c0);
                    for _ in 0..len {
                        idx.push((r * w + c) as u32);
                        (r, c) = step(r, c);
                    }
                    let (mut a, mut b) = (vec![0u16; len], vec![0u16; len]);
                    if down {
                        // Samples and the midpoints of the split diagonals between them.
                        let mid = |k: usize| {
                            let (r, c) = ((idx[k] as usize) / w, (idx[k] as usize) % w);
                            let (r1, c1) = step(r, c);
                            0.5 * (hs[r1 * w + c] + hs[r * w + c1])
                        };
                        let steps = if wrap { 2 * len } else { 2 * len - 1 };
                        let line = (0..steps).map(|k| {
                            if k % 2 == 0 {
                                hs[idx[k / 2] as usize]
                            } else {
                                mid(k / 2)
                            }
                        });
                        ln.both_ways(line, 0.5 * s, wrap, 2, &mut a, &mut b);
                    } else {
                        let line = idx.iter().map(|&k| hs[k as usize]);
                        ln.both_ways(line, s, wrap, 1, &mut a, &mut b);
                    }
                    (idx, a, b)
                })
                .collect();
            for (idx, a, b) in done {
                for ((&k, &x), &y) in idx.iter().zip(&a).zip(&b) {
                    out[ahead_dir][k as usize] = x;
                    out[behind_dir][k as usize] = y;
                }
            }
            start = end;
        }
    }
    out
}

/// Mean and variance (radians, radians²) of the horizon angles of a footprint along the eight
/// directions of [`HORIZON_AZIMUTHS_DEG`], with the weight (number of samples) they summarise.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct HorizonStats {
    /// Number of samples summarised (0 = no information: everything is visible).
    pub weight: f64,
    /// Mean horizon elevation angle per direction (radians).
    pub mean: [f64; HORIZON_DIRECTIONS],
    /// Variance of the horizon angle per direction (radians²).
    pub var: [f64; HORIZON_DIRECTIONS],
}

impl HorizonStats {
    /// Statistics of the four axes only (+x, +y, −x, −y: map files before version 5), the
    /// diagonals filled in as the model before 2026-12-07 saw them: each the mean of its two
    /// neighbours' means and of their variances (its interpolation at 45°).
    #[must_use]
    pub fn from_axes(weight: f64, mean: [f64; 4], var: [f64; 4]) -> HorizonStats {
        let mut s = HorizonStats {
            weight,
            ..HorizonStats::default()
        };
        s.mean[..4].copy_from_slice(&mean);
        s.var[..4].copy_from_slice(&var);
        for k in 0..4 {
            let (a, b) = (k, (k + 1) % 4);
            s.mean[4 + k] = 0.5 * (mean[a] + mean[b]);
            s.var[4 + k] = 0.5 * (var[a] + var[b]);
        }
        s
    }

    /// Merge another footprint's statistics into this one (exact pooled mean and variance).
    pub fn merge(&mut self, o: &HorizonStats) {
        if o.weight <= 0.0 {
            return;
        }
        let n = self.weight + o.weight;
        for d in 0..HORIZON_DIRECTIONS {
            let delta = o.mean[d] - self.mean[d];
            let mean = self.mean[d] + delta * o.weight / n;
            let m2 = self.var[d] * self.weight
                + o.var[d] * o.weight
                + delta * delta * self.weight * o.weight / n;
            self.mean[d] = mean;
            self.var[d] = m2 / n;
        }
        self.weight = n;
    }

    /// Fraction of the footprint from which the direction `w` (local frame, z up) is above the
    /// horizon, in `[0, 1]`. Mean and variance are interpolated in azimuth between the two
    /// nearest of the eight directions, `φ` from the first of them, with weights cos²2φ and
    /// sin²2φ.
    #[must_use]
    pub fn visibility(&self, w: DVec3) -> f64 {
        self.visibility_along(&HorizonDirection::new(w))
    }

    /// [`HorizonStats::visibility`] of a direction prepared once ([`HorizonDirection::new`]),
    /// for many statistics seen from the same direction (one shading call's lobes).
    #[inline]
    #[must_use]
    pub fn visibility_along(&self, d: &HorizonDirection) -> f64 {
        // Below the horizon nothing sees, straight up everything: whatever the statistics.
        if let Some(v) = d.fixed {
            return v;
        }
        if self.weight <= 0.0 {
            return 1.0;
        }
        let mu = d.c2 * self.mean[d.ix] + d.s2 * self.mean[d.iy];
        let var = d.c2 * self.var[d.ix] + d.s2 * self.var[d.iy];
        let half = 3f64.sqrt() * var.max(0.0).sqrt();
        if half < 1e-9 {
            return if d.elev > mu { 1.0 } else { 0.0 };
        }
        let x = ((d.elev - (mu - half)) / (2.0 * half)).clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    }
}

/// Elevations (degrees) at which a [`HorizonCdf`] keeps the fraction of its footprint whose
/// horizon lies at or below them, per direction; with 0 at 0° and 1 at 90° (every horizon
/// angle is below 90°), the nodes of a piecewise-linear distribution function. Denser near the
/// horizontal plane, where the horizons of gentle maps and the lights that graze them lie.
pub const CDF_ELEVATIONS_DEG: [f64; CDF_NODES] = [
    0.5, 3.0, 6.0, 9.0, 12.0, 15.0, 18.0, 21.0, 25.0, 29.0, 34.0, 40.0, 47.0, 55.0, 65.0, 77.0,
];

/// Number of stored nodes of a [`HorizonCdf`] per direction.
pub const CDF_NODES: usize = 16;

/// The distribution of the horizon angles of a footprint, per direction of
/// [`HORIZON_AZIMUTHS_DEG`]: at each elevation of [`CDF_ELEVATIONS_DEG`] the fraction of the
/// footprint whose horizon is at or below it, to 1/255 (132 bytes). Unlike a mean and a
/// variance ([`HorizonStats`]), fractions pool exactly ([`HorizonCdfSum`]) and keep a
/// two-peaked distribution two-peaked: the texel of a facade that holds window floors
/// (horizons high) and wall tops (horizons 0) sees a grazing light from its tops, where a ramp
/// of the pooled mean and variance hides nearly all of it (docs/heightmaps.md, "Horizon
/// distributions per lobe").
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct HorizonCdf {
    /// The footprint's weight (level-0 cells or projected area handed over; 0 = it stands for
    /// nothing: visible from everywhere).
    pub weight: f32,
    /// Per direction, per node, the fraction in units of 1/255.
    pub frac: [[u8; CDF_NODES]; HORIZON_DIRECTIONS],
}

impl HorizonCdf {
    /// The fraction of the footprint from which the direction `w` (local frame, z up) is
    /// above the horizon, in `[0, 1]` ([`HorizonCdf::visibility_along`]).
    #[must_use]
    pub fn visibility(&self, w: DVec3) -> f64 {
        self.visibility_along(&HorizonDirection::new(w))
    }

    /// The fraction of the footprint from which the direction prepared as `d` is above the
    /// horizon: along each of the two directions nearest its azimuth the distribution read
    /// at its elevation (linear between the nodes), interpolated with the weights of
    /// [`HorizonStats::visibility_along`].
    #[inline]
    #[must_use]
    pub fn visibility_along(&self, d: &HorizonDirection) -> f64 {
        // Below the horizon nothing sees, straight up everything: whatever the distribution
        // (also one of no weight, which sees every other direction).
        if let Some(v) = d.fixed {
            return v;
        }
        if self.weight <= 0.0 {
            return 1.0;
        }
        d.c2 * self.at(d.ix, d) + d.s2 * self.at(d.iy, d)
    }

    /// The fraction of the footprint whose horizon along direction `slot` lies below the
    /// elevation of `d` (the distribution linear between its nodes).
    #[inline]
    fn at(&self, slot: usize, d: &HorizonDirection) -> f64 {
        fraction_at(&self.frac[slot], d)
    }

    /// The fraction of the footprint from which both directions prepared as `a` and `b` are
    /// above the horizon: shadowing and masking together. Each direction is read along the
    /// two stored azimuths nearest its own, with the weights of
    /// [`HorizonCdf::visibility_along`]; of each pair of stored azimuths, those 0° or 45° apart
    /// count the smaller of the two fractions (exact along one azimuth: a horizon below the
    /// lower elevation is below the higher too; a point that sees along one azimuth mostly
    /// sees along its neighbour), those farther apart the footprint's `joint` fractions where
    /// given ([`HorizonJoint::copula`], of the same cells), else their product (as if
    /// independent). Hence `joint(a, a) = visibility(a)`, within the Fréchet bounds
    /// `max(0, V(a) + V(b) − 1) ≤ joint ≤ min(V(a), V(b))`, and continuous in both azimuths.
    ///
    /// On the steep facade map (16–256 cells a texel, elevations 7.5°–60°) the product for
    /// every pair (the model before 2026-12-07) errs by 9–25 % of the truth per lobe, 25 % too
    /// low with light and viewer along one azimuth; the smaller fraction by none there and 2–7 %
    /// at 45°, the joint fractions by 2–5 % farther apart (docs/heightmaps.md, "Light and
    /// viewer together per lobe"; `examples/joint_models.rs`).
    #[must_use]
    pub fn joint_visibility_along(
        &self,
        joint: Option<&HorizonJoint>,
        a: &HorizonDirection,
        b: &HorizonDirection,
    ) -> f64 {
        match (a.fixed, b.fixed) {
            (Some(va), _) => return va * self.visibility_along(b),
            (_, Some(vb)) => return vb * self.visibility_along(a),
            _ => {}
        }
        if self.weight <= 0.0 {
            return 1.0;
        }
        self.both(joint.filter(|j| j.weight > 0.0), a, b, near_pairs(a, b))
            .0
    }

    /// The fraction of what sees the view of `pair` that also sees its light:
    /// [`HorizonCdf::joint_visibility_along`] over the view's visibility (the light's alone
    /// where nothing sees the view, and, without `joint`, where no two of their stored
    /// azimuths that carry weight are read together, which the rule then counts as
    /// independent).
    #[inline]
    #[must_use]
    pub fn visibility_given(&self, joint: Option<&HorizonJoint>, pair: &HorizonPair) -> f64 {
        let (light, view) = (&pair.light, &pair.view);
        let joint =
            joint.filter(|j| j.weight > 0.0 && light.fixed.is_none() && view.fixed.is_none());
        if self.weight <= 0.0 || (joint.is_none() && !pair.together) {
            return self.visibility_along(light);
        }
        let (both, seen, lit) = self.both(joint, light, view, pair.near);
        Self::light_given_view([lit, seen, both])
    }

    /// The rule of [`HorizonCdf::visibility_given`] from a footprint's three fractions in
    /// [`HorizonCdf::pair_fractions`]' order (those that see the light, the viewer, both): the
    /// share of what sees the viewer that also sees the light, `both / viewer` (at most 1), or
    /// the light's own fraction where nothing sees the viewer.
    #[inline]
    #[must_use]
    pub fn light_given_view([light, seen, both]: [f64; 3]) -> f64 {
        if seen > 0.0 {
            (both / seen).min(1.0)
        } else {
            light
        }
    }

    /// The fractions of the footprint that see the light of `pair`, its viewer, and both
    /// ([`HorizonCdf::joint_visibility_along`]'s rule, with `joint` as there), in one pass.
    #[inline]
    #[must_use]
    pub fn pair_fractions(&self, joint: Option<&HorizonJoint>, pair: &HorizonPair) -> [f64; 3] {
        let (l, v) = (&pair.light, &pair.view);
        let joint = joint.filter(|j| j.weight > 0.0);
        if self.weight <= 0.0
            || l.fixed.is_some()
            || v.fixed.is_some()
            || (joint.is_none() && !pair.together)
        {
            let (a, b) = (self.visibility_along(l), self.visibility_along(v));
            return [a, b, a * b];
        }
        let (both, seen, light) = self.both(joint, l, v, pair.near);
        [light, seen, both]
    }

    /// The rule of [`HorizonCdf::joint_visibility_along`] for two directions of no fixed
    /// visibility whose pairs of stored azimuths `near` are 0° or 45° apart ([`near_pairs`]),
    /// the second's visibility and the first's ([`HorizonCdf::visibility_along`]'s, from the
    /// fractions the rule reads).
    #[inline]
    fn both(
        &self,
        joint: Option<&HorizonJoint>,
        a: &HorizonDirection,
        b: &HorizonDirection,
        near: [bool; 4],
    ) -> (f64, f64, f64) {
        let fa = [self.at(a.ix, a), self.at(a.iy, a)];
        let fb = [self.at(b.ix, b), self.at(b.iy, b)];
        let (sa, sb) = ([a.ix, a.iy], [b.ix, b.iy]);
        let (wa, wb) = ([a.c2, a.s2], [b.c2, b.s2]);
        let mut both = 0.0;
        for p in 0..2 {
            for q in 0..2 {
                let w = wa[p] * wb[q];
                if w <= 0.0 {
                    continue;
                }
                let v = if near[2 * p + q] {
                    fa[p].min(fb[q])
                } else if let Some(j) = joint {
                    j.copula(sa[p], fa[p], sb[q], fb[q])
                } else {
                    fa[p] * fb[q]
                };
                both += w * v;
            }
        }
        (
            both,
            wb[0] * fb[0] + wb[1] * fb[1],
            wa[0] * fa[0] + wa[1] * fa[1],
        )
    }
}

/// Elevations (degrees) of a [`HorizonJoint`]'s grid: nodes 1, 5, 9 and 13 of
/// [`CDF_ELEVATIONS_DEG`].
pub const JOINT_ELEVATIONS_DEG: [f64; JOINT_NODES] = [3.0, 15.0, 29.0, 55.0];

/// Nodes of a [`HorizonJoint`]'s grid per direction.
pub const JOINT_NODES: usize = 4;

/// Pairs of stored azimuths a [`HorizonJoint`] holds: those 90°, 135° and 180° apart (8 + 8 +
/// 4; nearer pairs are read by the rule of [`HorizonCdf::joint_visibility_along`]).
pub const JOINT_PAIRS: usize = 20;

/// Marks a transposed entry of [`PAIR_OF_SLOTS`].
const TRANSPOSED: u8 = 0x80;
/// Marks a pair of slots [`HorizonJoint`] does not hold.
const NO_PAIR: u8 = 0xFF;

/// The stored azimuths (slots of [`HORIZON_AZIMUTHS_DEG`]) of each pair a [`HorizonJoint`]
/// holds, the first's octant the lower.
const JOINT_PAIR_SLOTS: [(usize, usize); JOINT_PAIRS] = joint_pair_slots();

/// For two slots, the index of their pair in [`JOINT_PAIR_SLOTS`] (`| TRANSPOSED` when they
/// come in the other order), or [`NO_PAIR`] (less than 90° apart).
const PAIR_OF_SLOTS: [[u8; HORIZON_DIRECTIONS]; HORIZON_DIRECTIONS] = pair_of_slots();

const fn joint_pair_slots() -> [(usize, usize); JOINT_PAIRS] {
    let mut out = [(0, 0); JOINT_PAIRS];
    let (mut n, mut oa) = (0, 0);
    while oa < HORIZON_DIRECTIONS {
        let mut ob = oa + 1;
        while ob < HORIZON_DIRECTIONS {
            let d = ob - oa;
            if d >= 2 && d <= 6 {
                out[n] = (SLOT_OF_OCTANT[oa], SLOT_OF_OCTANT[ob]);
                n += 1;
            }
            ob += 1;
        }
        oa += 1;
    }
    out
}

const fn pair_of_slots() -> [[u8; HORIZON_DIRECTIONS]; HORIZON_DIRECTIONS] {
    let mut out = [[NO_PAIR; HORIZON_DIRECTIONS]; HORIZON_DIRECTIONS];
    let pairs = joint_pair_slots();
    let mut n = 0;
    while n < JOINT_PAIRS {
        let (a, b) = pairs[n];
        out[a][b] = n as u8;
        out[b][a] = n as u8 | TRANSPOSED;
        n += 1;
    }
    out
}

/// The joint distribution of a footprint's horizons along pairs of stored azimuths 90°–180°
/// apart, for light and viewer far apart in azimuth ([`HorizonCdf::joint_visibility_along`]):
/// per pair `(a, b)` of [`JOINT_PAIRS`], the fraction of the footprint whose horizon along `a`
/// lies at or below elevation `E_i` and along `b` at or below `E_j`, on the grid
/// [`JOINT_ELEVATIONS_DEG`]², and per direction the fraction at or below each `E_i` (of the same
/// points: the grid's own margins), all to 1/255 (356 bytes). Pooled exactly like
/// [`HorizonCdf`] ([`HorizonJointSum`]). Read as a copula ([`HorizonJoint::copula`]): a lobe's
/// own distributions ([`HorizonCdf`]) set how much sees each direction, and the grid how the two
/// go together, as each node's share of the way from the product to a Fréchet bound,
/// interpolated between the nodes.
///
/// On a facade, the points that see a grazing light and a grazing viewer on opposite sides are
/// the wall tops, open every way, and a recess floor sees neither: visibility along opposite
/// azimuths is strongly correlated, which a product cannot say (the facade seen 60° from the
/// normal with the light opposite: 0.14 of the truth with the product).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct HorizonJoint {
    /// The footprint's weight (0: no joint known; the product is read).
    pub weight: f32,
    /// Per direction, per node of [`JOINT_ELEVATIONS_DEG`], the fraction at or below it, in
    /// units of 1/255.
    pub margin: [[u8; JOINT_NODES]; HORIZON_DIRECTIONS],
    /// Per pair, `[i · 4 + j]`: the fraction at or below `E_i` along the pair's first azimuth
    /// and `E_j` along its second, in units of 1/255.
    pub both: [[u8; JOINT_NODES * JOINT_NODES]; JOINT_PAIRS],
}

impl HorizonJoint {
    /// The fraction that sees along stored azimuth `a` an elevation a fraction `u` of the
    /// footprint sees (the lobe's own distribution read there) and along `b` one a fraction
    /// `v` sees: the grid's copula at `(u, v)`. The cell of the grid is found by `u` among the
    /// grid's own fractions along `a` (0, the margins at the nodes, 1) and `v` along `b`
    /// (Sklar's combination of the grid's dependence with the lobe's margins, which may differ
    /// from the grid's: a coarse texel's grid pools a sample of its cells). Each node's
    /// dependence `θ` is its value's share of the way from the product `uv` to the upper
    /// Fréchet bound `min(u, v)` (or, below the product, minus its share of the way to the
    /// lower bound `max(0, u + v − 1)`); `θ` is interpolated bilinearly across the cell (a node
    /// on the unit square's edge, where every copula agrees, takes its nearest inner node's)
    /// and the copula read back at `(u, v)`. So it is exact at the nodes, and between them
    /// exact for sets whose two horizons go together, are independent, or go against each
    /// other. A grid read bilinearly in the fractions themselves (the reading before
    /// 2026-12-07) loses up to half the dependence between two nodes, which left the coarse
    /// levels' renders of a steep facade 0.33–0.93 of the truth at 16–64 cells a pixel with
    /// light and viewer 135°–180° apart in azimuth (0.42–1.03 now; docs/heightmaps.md, "The
    /// joint read between its nodes"). Within the Fréchet bounds; the product `u · v` for a
    /// pair it does not hold (less than 90° apart).
    #[must_use]
    pub fn copula(&self, a: usize, u: f64, b: usize, v: f64) -> f64 {
        let code = PAIR_OF_SLOTS[a][b];
        if code == NO_PAIR {
            return u * v;
        }
        let pair = &self.both[usize::from(code & !TRANSPOSED)];
        // In the pair's order: the first azimuth and its fraction, then the second.
        let ((a, u), (b, v)) = if code & TRANSPOSED == 0 {
            ((a, u), (b, v))
        } else {
            ((b, v), (a, u))
        };
        let q = unit_255;
        let (ma, mb) = (&self.margin[a], &self.margin[b]);
        // Node k of a direction's fractions: 0 below the grid, 1 above it.
        let node = |m: &[u8; JOINT_NODES], k: usize| match k {
            0 => 0.0,
            k if k > JOINT_NODES => 1.0,
            k => q(m[k - 1]),
        };
        let grid = |i: usize, j: usize| -> f64 {
            if i == 0 || j == 0 {
                0.0
            } else if i > JOINT_NODES {
                node(mb, j)
            } else if j > JOINT_NODES {
                node(ma, i)
            } else {
                q(pair[(i - 1) * JOINT_NODES + (j - 1)])
            }
        };
        // The cell holding `x` among a direction's fractions (the last of equal ones) and the
        // position in it.
        let cell = |m: &[u8; JOINT_NODES], x: f64| {
            let mut s = 0;
            while s < JOINT_NODES && node(m, s + 1) <= x {
                s += 1;
            }
            let (lo, hi) = (node(m, s), node(m, s + 1));
            let t = if hi - lo > 1e-9 {
                ((x - lo) / (hi - lo)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            (s, t)
        };
        let ((sa, tu), (sb, tv)) = (cell(ma, u), cell(mb, v));
        // The dependence at a node of the grid, moved onto the inner nodes (the edges of the
        // unit square hold every copula alike): where the grid lies between the product and
        // the upper Fréchet bound, the share of the way to it; below the product, minus the
        // share of the way to the lower bound. None where the bounds meet (a margin of 0 or 1).
        let theta = |i: usize, j: usize| -> Option<f64> {
            let (i, j) = (i.clamp(1, JOINT_NODES), j.clamp(1, JOINT_NODES));
            let (x, y, g) = (node(ma, i), node(mb, j), grid(i, j));
            dependence(x, y, g)
        };
        let corners = [
            (theta(sa, sb), (1.0 - tu) * (1.0 - tv)),
            (theta(sa + 1, sb), tu * (1.0 - tv)),
            (theta(sa, sb + 1), (1.0 - tu) * tv),
            (theta(sa + 1, sb + 1), tu * tv),
        ];
        let (mut sum, mut wsum) = (0.0, 0.0);
        for (t, w) in corners {
            if let Some(t) = t {
                sum += w * t;
                wsum += w;
            }
        }
        let t = if wsum > 1e-12 {
            sum / wsum
        } else {
            // On an edge of the cell whose corners there carry no dependence: the others'
            // mean (none: the product).
            let (s, n) = corners
                .iter()
                .filter_map(|c| c.0)
                .fold((0.0, 0.0), |(s, n), t| (s + t, n + 1.0));
            if n > 0.0 {
                s / n
            } else {
                0.0
            }
        };
        with_dependence(u, v, t)
    }
}

/// The dependence of a copula's value `c` at `(u, v)`, in [−1, 1]: `(c − uv)/(min(u, v) − uv)`
/// at or above the product, `−(uv − c)/(uv − max(0, u + v − 1))` below it, 0 where the two
/// Fréchet bounds meet (`u` or `v` 0 or 1). With [`with_frechet_dependence`], how a lobe's joint
/// visibility of two directions is carried to the fractions of a part of it.
#[must_use]
pub fn frechet_dependence(u: f64, v: f64, c: f64) -> f64 {
    dependence(u, v, c).unwrap_or(0.0)
}

/// The copula at `(u, v)` of dependence `t` in [−1, 1] ([`frechet_dependence`]): the product
/// moved a share `t` of the way to the upper Fréchet bound `min(u, v)`, or `−t` of the way to
/// the lower `max(0, u + v − 1)`.
#[must_use]
pub fn with_frechet_dependence(u: f64, v: f64, t: f64) -> f64 {
    with_dependence(u, v, t)
}

/// The dependence of a copula's value `c` at `(u, v)`: `(c − uv)/(min(u, v) − uv)` at or above
/// the product, `−(uv − c)/(uv − max(0, u + v − 1))` below it, in [−1, 1]; `None` where the two
/// Fréchet bounds meet (`u` or `v` 0 or 1).
fn dependence(u: f64, v: f64, c: f64) -> Option<f64> {
    let p = u * v;
    let (hi, lo) = (u.min(v), (u + v - 1.0).max(0.0));
    if hi - lo < 1e-9 {
        return None;
    }
    Some(if c >= p {
        if hi - p > 1e-12 {
            ((c - p) / (hi - p)).min(1.0)
        } else {
            0.0
        }
    } else if p - lo > 1e-12 {
        -((p - c) / (p - lo)).min(1.0)
    } else {
        0.0
    })
}

/// The copula at `(u, v)` of dependence `t` ([`dependence`]'s inverse): the product moved a
/// share `t` of the way to the upper Fréchet bound, or `−t` of the way to the lower.
fn with_dependence(u: f64, v: f64, t: f64) -> f64 {
    let p = u * v;
    if t >= 0.0 {
        p + t * (u.min(v) - p)
    } else {
        p + t * (p - (u + v - 1.0).max(0.0))
    }
}

/// Weighted sums of [`HorizonJoint`]s, pooled exactly: [`HorizonJointSum::finish`] gives the
/// fractions of everything added.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct HorizonJointSum {
    weight: f64,
    margin: [[f32; JOINT_NODES]; HORIZON_DIRECTIONS],
    both: [[f32; JOINT_NODES * JOINT_NODES]; JOINT_PAIRS],
}

impl HorizonJointSum {
    /// The joint distribution of one point set: per direction, `angles[d]` (radians) of 16
    /// points of equal weight, the whole set of weight `weight`.
    #[must_use]
    pub fn of_points(angles: &[[f64; 16]; HORIZON_DIRECTIONS], weight: f64) -> HorizonJointSum {
        HorizonJointSum::of_below(&angles.map(|a| Below::Points(joint_below(&a))), weight)
    }

    /// The joint distribution of a cell whose horizon angles are its corners' interpolated
    /// bilinearly at the centres of its 4 × 4 sub-cells (the points of
    /// [`HorizonCdfSum::of_bilinear_cell`]), weight `weight`. Where a direction's four corners
    /// lie between the same two nodes, so do all its points, and none is interpolated.
    #[must_use]
    pub fn of_bilinear_cell(
        corners: &[[f64; 4]; HORIZON_DIRECTIONS],
        weight: f64,
    ) -> HorizonJointSum {
        // Nodes this close to a corner's angle count the points one by one (an interpolated
        // point may round a hair beyond its corners).
        const MARGIN: f64 = 1e-9;
        let nodes = JOINT_ELEVATIONS_DEG.map(f64::to_radians);
        let below = corners.map(|a| {
            let lo = a.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let k = nodes.iter().filter(|&&e| e < lo - MARGIN).count();
            if k == nodes.iter().filter(|&&e| e < hi + MARGIN).count() {
                Below::All(k as u8)
            } else {
                Below::Points(joint_below(&bilinear_points(&a)))
            }
        });
        HorizonJointSum::of_below(&below, weight)
    }

    /// The joint distribution of 16 points of equal weight, the whole set of weight
    /// `weight`, from per direction the grid nodes strictly below each point's angle.
    fn of_below(below: &[Below; HORIZON_DIRECTIONS], weight: f64) -> HorizonJointSum {
        let mut s = HorizonJointSum {
            weight,
            ..HorizonJointSum::default()
        };
        let each = (weight / 16.0) as f32;
        const N: usize = JOINT_NODES;
        let all = 16.0 * each;
        for (m, k) in s.margin.iter_mut().zip(below) {
            match k {
                // Every point at or below the nodes from `k` on.
                Below::All(k) => {
                    for (i, x) in m.iter_mut().enumerate() {
                        *x = if i >= usize::from(*k) { all } else { 0.0 };
                    }
                }
                Below::Points(k) => {
                    // Per node, the points at or below it: a histogram of `k`, summed up.
                    let mut hist = [0u32; N + 1];
                    for &kp in k {
                        hist[usize::from(kp)] += 1;
                    }
                    let mut n = 0;
                    for (x, h) in m.iter_mut().zip(hist) {
                        n += h;
                        *x = n as f32 * each;
                    }
                }
            }
        }
        for (out, &(a, b)) in s.both.iter_mut().zip(&JOINT_PAIR_SLOTS) {
            if let (Below::All(ka), Below::All(kb)) = (&below[a], &below[b]) {
                // Every point in one cell of the grid: at or below the nodes from it on.
                let (ka, kb) = (usize::from(*ka), usize::from(*kb));
                for i in 0..N {
                    for j in 0..N {
                        out[i * N + j] = if i >= ka && j >= kb { all } else { 0.0 };
                    }
                }
                continue;
            }
            // A histogram of (k_a, k_b), then its two-dimensional running sums over the grid.
            let (pa, pb) = (below[a].points(), below[b].points());
            let mut hist = [[0u32; N + 1]; N + 1];
            for (&ka, &kb) in pa.iter().zip(&pb) {
                hist[usize::from(ka)][usize::from(kb)] += 1;
            }
            let mut cum = [[0u32; N]; N];
            for i in 0..N {
                let mut row = 0;
                for j in 0..N {
                    row += hist[i][j];
                    cum[i][j] = row + if i > 0 { cum[i - 1][j] } else { 0 };
                    out[i * N + j] = cum[i][j] as f32 * each;
                }
            }
        }
        s
    }

    /// Add footprint `o` (its sums) scaled by `scale`: the pooled distribution.
    pub fn add(&mut self, o: &HorizonJointSum, scale: f64) {
        if o.weight <= 0.0 || scale <= 0.0 {
            return;
        }
        self.weight += o.weight * scale;
        add_scaled(&mut self.margin, &o.margin, scale as f32);
        add_scaled(&mut self.both, &o.both, scale as f32);
    }

    /// The pooled footprints' joint distribution, rounded to 1/255 (weight 0 when nothing was
    /// added).
    #[must_use]
    pub fn finish(&self) -> HorizonJoint {
        let mut out = HorizonJoint {
            weight: self.weight as f32,
            ..HorizonJoint::default()
        };
        if self.weight <= 0.0 {
            return out;
        }
        let inv = 1.0 / self.weight;
        for (o, s) in out.margin.iter_mut().zip(&self.margin) {
            *o = s.map(|v| to_255(v, inv));
        }
        for (o, s) in out.both.iter_mut().zip(&self.both) {
            *o = s.map(|v| to_255(v, inv));
        }
        out
    }
}

/// A light and a viewer prepared together for [`HorizonCdf::visibility_given`] (once per
/// light and shading call, not per lobe): whether any of their stored azimuths are read
/// together by the rule of [`HorizonCdf::joint_visibility_along`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HorizonPair {
    light: HorizonDirection,
    view: HorizonDirection,
    /// Which of their pairs of stored azimuths are 0° or 45° apart ([`near_pairs`]).
    near: [bool; 4],
    /// Some pair of their stored azimuths, 0° or 45° apart, carries weight, and neither
    /// direction's visibility is fixed.
    together: bool,
}

impl HorizonPair {
    /// The light's direction and the viewer's, each prepared.
    #[must_use]
    pub fn new(light: &HorizonDirection, view: &HorizonDirection) -> HorizonPair {
        let near = near_pairs(light, view);
        let (wl, wv) = ([light.c2, light.s2], [view.c2, view.s2]);
        HorizonPair {
            light: *light,
            view: *view,
            near,
            together: light.fixed.is_none()
                && view.fixed.is_none()
                && (0..4).any(|k| near[k] && wl[k / 2] * wv[k % 2] > 0.0),
        }
    }

    /// The weight of the pairs of their stored azimuths 90° or more apart, in [0, 1]: where
    /// light and viewer are read apart (the rest, 0° or 45° apart, are read together as one
    /// event along nearly one azimuth). 0 where either direction's visibility is fixed.
    /// Continuous in both directions' azimuths.
    #[must_use]
    pub fn far_weight(&self) -> f64 {
        if self.light.fixed.is_some() || self.view.fixed.is_some() {
            return 0.0;
        }
        let (wl, wv) = ([self.light.c2, self.light.s2], [self.view.c2, self.view.s2]);
        (0..4)
            .filter(|&k| !self.near[k])
            .map(|k| wl[k / 2] * wv[k % 2])
            .sum()
    }
}

/// For the pairs (`a`'s nearest stored azimuths × `b`'s, in the order `(ix, ix)`, `(ix, iy)`,
/// `(iy, ix)`, `(iy, iy)`), whether they are 0° or 45° apart.
#[inline]
fn near_pairs(a: &HorizonDirection, b: &HorizonDirection) -> [bool; 4] {
    std::array::from_fn(|k| {
        let (p, q) = (k / 2, k % 2);
        // Octants apart, 0..8: 0, 1 or 7 are neighbours.
        let apart = (a.octant + p + HORIZON_DIRECTIONS - (b.octant + q) % HORIZON_DIRECTIONS)
            % HORIZON_DIRECTIONS;
        matches!(apart, 0 | 1 | 7)
    })
}

impl HorizonCdf {
    /// The horizon angle (radians) below which a fraction `p` (in `[0, 1]`) of the footprint's
    /// horizons along direction `d` (order of [`HORIZON_AZIMUTHS_DEG`]) lie: the inverse of the
    /// piecewise-linear distribution (the median at `p = 0.5`; 0 for a footprint of no
    /// weight).
    #[must_use]
    pub fn quantile(&self, d: usize, p: f64) -> f64 {
        if self.weight <= 0.0 {
            return 0.0;
        }
        let nodes = cdf_nodes_rad()
            .into_iter()
            .zip(self.frac[d].map(unit_255))
            .chain([(FRAC_PI_2, 1.0)]);
        let (mut e0, mut f0) = (0.0, 0.0);
        for (e1, f1) in nodes {
            if f1 >= p {
                return if f1 > f0 {
                    e0 + (p - f0) / (f1 - f0) * (e1 - e0)
                } else {
                    e0
                };
            }
            (e0, f0) = (e1, f1);
        }
        FRAC_PI_2
    }
}

/// Weighted sums of the horizon distributions of footprints ([`HorizonCdf`] before rounding):
/// add footprints, then [`HorizonCdfSum::finish`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HorizonCdfSum {
    weight: f64,
    sum: [[f32; CDF_NODES]; HORIZON_DIRECTIONS],
}

impl Default for HorizonCdfSum {
    fn default() -> HorizonCdfSum {
        HorizonCdfSum {
            weight: 0.0,
            sum: [[0.0; CDF_NODES]; HORIZON_DIRECTIONS],
        }
    }
}

impl HorizonCdfSum {
    /// The distribution of one point set: per direction, `angles[d]` (radians) of 16 points
    /// of equal weight, the whole set of weight `weight`.
    #[must_use]
    pub fn of_points(angles: &[[f64; 16]; HORIZON_DIRECTIONS], weight: f64) -> HorizonCdfSum {
        let mut s = HorizonCdfSum {
            weight,
            ..HorizonCdfSum::default()
        };
        let each = (weight / 16.0) as f32;
        for (v, h) in s.sum.iter_mut().zip(angles) {
            count_points(v, h, each, || *h);
        }
        s
    }

    /// The distribution of a cell whose horizon angles are its corners' interpolated
    /// bilinearly, at the centres of its 4 × 4 sub-cells (the points [`HorizonCdfSum::of_points`]
    /// would take), weight `weight`: `corners[d]` per direction are the angles (radians) at
    /// `(x, y)` = (0, 0), (1, 0), (0, 1), (1, 1). Where the four corners lie between the same
    /// two nodes, so do all the points, and none is interpolated.
    #[must_use]
    pub fn of_bilinear_cell(
        corners: &[[f64; 4]; HORIZON_DIRECTIONS],
        weight: f64,
    ) -> HorizonCdfSum {
        let mut s = HorizonCdfSum {
            weight,
            ..HorizonCdfSum::default()
        };
        let each = (weight / 16.0) as f32;
        for (v, a) in s.sum.iter_mut().zip(corners) {
            count_points(v, a, each, || bilinear_points(a));
        }
        s
    }

    /// The sums of a finished distribution (its fractions times its weight): what
    /// [`HorizonCdfSum::finish`] rounded, pooled again.
    #[must_use]
    pub fn of(c: &HorizonCdf) -> HorizonCdfSum {
        let w = f64::from(c.weight);
        let k = (w / 255.0) as f32;
        HorizonCdfSum {
            weight: w,
            sum: c.frac.map(|f| f.map(|q| f32::from(q) * k)),
        }
    }

    /// Add footprint `o` (its sums) scaled by `scale`: the pooled distribution.
    pub fn add(&mut self, o: &HorizonCdfSum, scale: f64) {
        if o.weight <= 0.0 || scale <= 0.0 {
            return;
        }
        self.weight += o.weight * scale;
        add_scaled(&mut self.sum, &o.sum, scale as f32);
    }

    /// The pooled footprints' distribution, rounded to 1/255 (weight 0 when nothing was added).
    #[must_use]
    pub fn finish(&self) -> HorizonCdf {
        let mut out = HorizonCdf {
            weight: self.weight as f32,
            ..HorizonCdf::default()
        };
        if self.weight <= 0.0 {
            return out;
        }
        let inv = 1.0 / self.weight;
        for (o, s) in out.frac.iter_mut().zip(&self.sum) {
            *o = s.map(|v| to_255(v, inv));
        }
        out
    }
}

/// One direction's distribution `f` (fractions at the nodes of [`CDF_ELEVATIONS_DEG`], to
/// 1/255; 0 at 0° and 1 at 90°) read at the elevation of `d`, linear between the nodes.
#[inline]
fn fraction_at(f: &[u8; CDF_NODES], d: &HorizonDirection) -> f64 {
    let node = |k: usize| match k {
        0 => 0.0,
        k if k > CDF_NODES => 1.0,
        k => unit_255(f[k - 1]),
    };
    node(d.node) + d.node_t * (node(d.node + 1) - node(d.node))
}

/// A fraction stored to 1/255 ([`HorizonCdf`], [`HorizonJoint`], [`HorizonToward`]) as a
/// number, `x / 255`: read from a table of the 256 quotients (the same values as the division,
/// which the shading reads dozens of times a lobe).
#[inline]
pub(crate) fn unit_255(x: u8) -> f64 {
    UNIT_255[usize::from(x)]
}

/// `k / 255` for every `k` of a byte ([`unit_255`]).
static UNIT_255: [f64; 256] = {
    let mut t = [0.0; 256];
    let mut k = 0;
    while k < 256 {
        t[k] = k as f64 / 255.0;
        k += 1;
    }
    t
};

/// `dst += k · src`, row by row: the sums of [`HorizonCdfSum`] and [`HorizonJointSum`] pooled.
fn add_scaled<const N: usize>(dst: &mut [[f32; N]], src: &[[f32; N]], k: f32) {
    for (a, b) in dst.iter_mut().zip(src) {
        for (x, y) in a.iter_mut().zip(b) {
            *x += k * y;
        }
    }
}

/// A pooled sum `v` as a fraction of the weight (`inv` its inverse), to 1/255, rounded half
/// up: what [`HorizonCdf`] and [`HorizonJoint`] store.
#[inline]
fn to_255(v: f32, inv: f64) -> u8 {
    // Non-negative: `as` truncates after the half is added (saturating at 255).
    (f64::from(v) * inv * 255.0 + 0.5) as u8
}

/// Per point of a set of 16, the nodes of a [`HorizonJoint`]'s grid strictly below its angle
/// (the point lies at or below nodes `k..`): all the same, or each its own.
#[derive(Clone, Copy, Debug)]
enum Below {
    All(u8),
    Points([u8; 16]),
}

impl Below {
    /// Per point, its count.
    fn points(&self) -> [u8; 16] {
        match self {
            Below::All(k) => [*k; 16],
            Below::Points(p) => *p,
        }
    }
}

/// [`Below::Points`] of 16 angles (radians).
fn joint_below(angles: &[f64; 16]) -> [u8; 16] {
    let nodes = JOINT_ELEVATIONS_DEG.map(f64::to_radians);
    std::array::from_fn(|p| nodes.iter().filter(|&&e| e < angles[p]).count() as u8)
}

/// A cell's corner values `a` (at `(x, y)` = (0, 0), (1, 0), (0, 1), (1, 1)) interpolated
/// bilinearly at the centres of its 4 × 4 sub-cells, row by row.
fn bilinear_points(a: &[f64; 4]) -> [f64; 16] {
    std::array::from_fn(|k| {
        let (x, y) = ((k % 4) as f64 * 0.25 + 0.125, (k / 4) as f64 * 0.25 + 0.125);
        a[0] * (1.0 - x) * (1.0 - y) + a[1] * x * (1.0 - y) + a[2] * (1.0 - x) * y + a[3] * x * y
    })
}

/// One direction's sums `v` of 16 points of weight `each`: per node, the weight of the points
/// at or below it. `bounds` holds values whose range contains the points' (the points
/// themselves, or a cell's corners around their bilinear points); the nodes outside that range
/// count none or all of them, and `points` is asked for only when a node lies inside it (a
/// fixed-size loop a node, which the compiler vectorises).
fn count_points(
    v: &mut [f32; CDF_NODES],
    bounds: &[f64],
    each: f32,
    points: impl FnOnce() -> [f64; 16],
) {
    let lo = bounds.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = bounds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let (blo, bhi) = (usize::from(nodes_below(lo)), usize::from(nodes_below(hi)));
    let h = if blo < bhi { points() } else { [0.0; 16] };
    let nodes = cdf_nodes_rad();
    for (n, x) in v.iter_mut().enumerate() {
        *x = if n < blo {
            0.0
        } else if n >= bhi {
            16.0 * each
        } else {
            let e = nodes[n];
            h.iter().map(|&p| u32::from(p <= e)).sum::<u32>() as f32 * each
        };
    }
}

/// The step of [`CDF_ELEVATIONS_DEG`]'s nodes (all are multiples of it): 0.5°.
const CDF_GRID_DEG: f64 = 0.5;

/// How many nodes of [`CDF_ELEVATIONS_DEG`] lie strictly below the angle `h` (radians), by a
/// table of the 0.5° steps (the nodes lie on them), checked against the nearest nodes.
#[inline]
fn nodes_below(h: f64) -> u8 {
    const STEPS: usize = 180;
    static TABLE: std::sync::OnceLock<[u8; STEPS + 1]> = std::sync::OnceLock::new();
    let table = TABLE.get_or_init(|| {
        // Entry k: the nodes strictly below any angle in (k, k + 1] steps.
        std::array::from_fn(|k| {
            let lo = k as f64 * CDF_GRID_DEG;
            CDF_ELEVATIONS_DEG.iter().filter(|&&e| e <= lo).count() as u8
        })
    });
    let x = (h.to_degrees() / CDF_GRID_DEG).clamp(0.0, STEPS as f64);
    let mut n = usize::from(table[(x as usize).min(STEPS)]);
    // Exact in radians near a node (the conversion may land a hair either side of a step).
    let nodes = cdf_nodes_rad();
    while n > 0 && nodes[n - 1] >= h {
        n -= 1;
    }
    while n < CDF_NODES && nodes[n] < h {
        n += 1;
    }
    n as u8
}

/// [`CDF_ELEVATIONS_DEG`] in radians.
fn cdf_nodes_rad() -> [f64; CDF_NODES] {
    static NODES: std::sync::OnceLock<[f64; CDF_NODES]> = std::sync::OnceLock::new();
    *NODES.get_or_init(|| CDF_ELEVATIONS_DEG.map(f64::to_radians))
}

/// A direction prepared for [`HorizonStats::visibility_along`]: its elevation (radians) and
/// the two of the eight horizon directions nearest its azimuth, with their weights cos²2φ and
/// sin²2φ (`φ` from the first).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HorizonDirection {
    elev: f64,
    ix: usize,
    iy: usize,
    /// The octant (45° sector counted from +x) of `ix`; `iy`'s is the next.
    octant: usize,
    c2: f64,
    s2: f64,
    /// The elevation's segment among 0°, [`CDF_ELEVATIONS_DEG`] and 90° (0 = below the first
    /// node) and its position in it, for [`HorizonCdf::visibility_along`].
    node: usize,
    node_t: f64,
    /// The visibility when it does not depend on the statistics: 0 below the horizon, 1 at
    /// the zenith.
    fixed: Option<f64>,
}

impl HorizonDirection {
    /// The direction `w` (local frame, z up; need not be unit).
    #[must_use]
    pub fn new(w: DVec3) -> HorizonDirection {
        let rxy = (w.x * w.x + w.y * w.y).sqrt();
        let mut d = HorizonDirection {
            elev: w.z.atan2(rxy),
            ix: 0,
            iy: 4,
            octant: 0,
            c2: 1.0,
            s2: 0.0,
            node: 0,
            node_t: 0.0,
            fixed: None,
        };
        let nodes = cdf_nodes_rad();
        let e = d.elev.max(0.0);
        let k = nodes.iter().position(|&x| e < x).unwrap_or(CDF_NODES);
        let lo = if k == 0 { 0.0 } else { nodes[k - 1] };
        let hi = if k == CDF_NODES { FRAC_PI_2 } else { nodes[k] };
        d.node = k;
        d.node_t = ((e - lo) / (hi - lo)).clamp(0.0, 1.0);
        if w.z <= 0.0 {
            d.fixed = Some(0.0);
        } else if rxy < 1e-12 {
            d.fixed = Some(1.0);
        } else {
            // The octant and the azimuth within it, in units of 45°.
            let a = w.y.atan2(w.x).rem_euclid(std::f64::consts::TAU) / std::f64::consts::FRAC_PI_4;
            let k = (a.floor() as usize).min(HORIZON_DIRECTIONS - 1);
            let (s, c) = ((a - k as f64) * std::f64::consts::FRAC_PI_2).sin_cos();
            d.ix = SLOT_OF_OCTANT[k];
            d.octant = k;
            d.iy = SLOT_OF_OCTANT[(k + 1) % HORIZON_DIRECTIONS];
            d.c2 = c * c;
            d.s2 = s * s;
        }
        d
    }
}

/// The horizon masking–shadowing model of one texel: `G(i, o) = V(i)·V(o)` with
/// [`HorizonStats::visibility`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HorizonVisibility(pub HorizonStats);

impl meso_core::material::VisibilityModel for HorizonVisibility {
    fn g(&self, i: DVec3, o: DVec3) -> f64 {
        self.0.visibility(i) * self.0.visibility(o)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The horizon angle by brute force: the largest slope from sample `(i, j)` to any sample
    /// ahead along `(di, dj)` (one period ahead on a wrapped map, to the border on a clamped
    /// one), as an angle in `[0, π/2)`.
    fn brute(map: &HeightMap, i: usize, j: usize, di: isize, dj: isize) -> f64 {
        let (w, h) = (map.width() as isize, map.height() as isize);
        let n = if di == 0 { w } else { h };
        let wrap = map.border() == Border::Wrap;
        let h0 = map.heights()[i * map.width() + j];
        let mut best = 0.0f64;
        for k in 1..=n {
            let (ii, jj) = (i as isize + di * k, j as isize + dj * k);
            let inside = (0..h).contains(&ii) && (0..w).contains(&jj);
            if !wrap && !inside {
                break;
            }
            let (ii, jj) = (ii.rem_euclid(h) as usize, jj.rem_euclid(w) as usize);
            let slope = (map.heights()[ii * map.width() + jj] - h0) / (k as f64 * map.texel_size());
            best = best.max(slope);
        }
        best.atan()
    }

    #[test]
    fn every_direction_of_a_non_square_map_matches_brute_force() {
        // Bumpy 13 × 7 and 300 × 7 maps (rows and columns of different lengths, so that a
        // transposition or a swapped direction shows; the second wider than a block of
        // columns), wrapped and clamped.
        for (border, w) in [
            (Border::Wrap, 13),
            (Border::Clamp, 13),
            (Border::Wrap, COLUMN_BLOCK + 44),
            (Border::Clamp, COLUMN_BLOCK + 44),
        ] {
            let map = HeightMap::from_fn(w, 7, 0.1, border, |x, y| {
                0.05 * (7.3 * x).sin() * (3.1 * y + 0.4).cos() + 0.02 * (11.0 * x * y).sin()
            })
            .unwrap();
            let hz = HorizonMap::compute(&map);
            let half = 0.5 * ANGLE_STEP + 1e-12;
            let mut rising = 0;
            for i in 0..7 {
                for j in 0..w {
                    let k = i * w + j;
                    for (d, (di, dj)) in [(0, 1), (1, 0), (0, -1), (-1, 0)].into_iter().enumerate()
                    {
                        let want = brute(&map, i, j, di, dj);
                        let got = hz.angle(d, k);
                        assert!(
                            (got - want).abs() < half,
                            "{border:?} ({i}, {j}) direction {d}: {got} vs {want}"
                        );
                        rising += usize::from(want > 0.01);
                    }
                }
            }
            assert!(
                rising > 100,
                "{rising} angles above 0.01 rad: the map is too flat"
            );
        }
    }

    /// The height of the triangulated surface at `(x, y)` (columns, rows; cells split along
    /// `(i, j)–(i + 1, j + 1)`), `None` off a clamped map.
    fn surface(map: &HeightMap, x: f64, y: f64) -> Option<f64> {
        let (w, h) = (map.width() as i64, map.height() as i64);
        let wrap = map.border() == Border::Wrap;
        let eps = 1e-9;
        if !wrap && (x < -eps || y < -eps || x > (w - 1) as f64 + eps || y > (h - 1) as f64 + eps) {
            return None;
        }
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let z = |r: i64, c: i64| {
            let (r, c) = if wrap {
                (r.rem_euclid(h), c.rem_euclid(w))
            } else {
                (r.min(h - 1), c.min(w - 1))
            };
            map.heights()[(r * w + c) as usize]
        };
        let (r, c) = (fy as i64, fx as i64);
        let (z00, z11) = (z(r, c), z(r + 1, c + 1));
        Some(if ty <= tx {
            z00 + tx * (z(r, c + 1) - z00) + ty * (z11 - z(r, c + 1))
        } else {
            z00 + ty * (z(r + 1, c) - z00) + tx * (z11 - z(r + 1, c))
        })
    }

    #[test]
    fn diagonal_angles_match_the_surface_marched_finely() {
        // The surface sampled 8 times a diagonal step (every breakpoint of the line: samples,
        // and the split diagonals' midpoints across them), one whole turn of a wrapped line.
        for (border, w, h) in [
            (Border::Wrap, 13, 7),
            (Border::Clamp, 13, 7),
            (Border::Wrap, 12, 8),
            (Border::Clamp, 6, 11),
        ] {
            let map = HeightMap::from_fn(w, h, 0.1, border, |x, y| {
                0.05 * (7.3 * x).sin() * (3.1 * y + 0.4).cos() + 0.02 * (11.0 * x * y).sin()
            })
            .unwrap();
            let got = diagonal_angles(&map);
            let turn = w / gcd(w, h) * h;
            let half = 0.5 * ANGLE_STEP + 1e-12;
            let mut rising = 0;
            for i in 0..h {
                for j in 0..w {
                    let h0 = map.heights()[i * w + j];
                    for (d, az) in DIAGONAL_AZIMUTHS_DEG.iter().enumerate() {
                        let (sa, ca) = az.to_radians().sin_cos();
                        let (dx, dy) = (ca.signum(), sa.signum());
                        let mut best = 0.0f64;
                        for k in 1..=8 * turn {
                            let t = k as f64 / 8.0;
                            let (x, y) = (j as f64 + dx * t, i as f64 + dy * t);
                            let Some(z) = surface(&map, x, y) else { break };
                            best = best.max((z - h0) / (t * std::f64::consts::SQRT_2 * 0.1));
                        }
                        let want = best.atan();
                        let got = f64::from(got[d][i * w + j]) * ANGLE_STEP;
                        assert!(
                            (got - want).abs() < half,
                            "{border:?} {w}×{h} ({i}, {j}) azimuth {az}: {got} vs {want}"
                        );
                        rising += usize::from(want > 0.01);
                    }
                }
            }
            assert!(rising > 50, "{rising} angles above 0.01 rad");
        }
    }

    #[test]
    fn visibility_reads_each_of_the_eight_azimuths_and_interpolates_between_them() {
        // A distinct sharp horizon per direction (no variance): the visibility at a direction's
        // own azimuth is the step at its angle; halfway between two, at their mean.
        let mean: [f64; HORIZON_DIRECTIONS] = std::array::from_fn(|d| 0.1 + 0.08 * d as f64);
        let s = HorizonStats {
            weight: 1.0,
            mean,
            var: [0.0; HORIZON_DIRECTIONS],
        };
        let dir = |az: f64, elev: f64| {
            let (sa, ca) = az.to_radians().sin_cos();
            DVec3::new(elev.cos() * ca, elev.cos() * sa, elev.sin())
        };
        for (d, az) in HORIZON_AZIMUTHS_DEG.iter().enumerate() {
            assert_eq!(s.visibility(dir(*az, mean[d] + 1e-6)), 1.0, "azimuth {az}");
            assert_eq!(s.visibility(dir(*az, mean[d] - 1e-6)), 0.0, "azimuth {az}");
        }
        for k in 0..HORIZON_DIRECTIONS {
            let (a, b) = (
                SLOT_OF_OCTANT[k],
                SLOT_OF_OCTANT[(k + 1) % HORIZON_DIRECTIONS],
            );
            let mid = 0.5 * (mean[a] + mean[b]);
            let az = 45.0 * k as f64 + 22.5;
            assert_eq!(s.visibility(dir(az, mid + 1e-6)), 1.0, "azimuth {az}");
            assert_eq!(s.visibility(dir(az, mid - 1e-6)), 0.0, "azimuth {az}");
        }
        // Old files' statistics: the diagonals are the axes' interpolation at 45°.
        let old = HorizonStats::from_axes(2.0, [0.1, 0.3, 0.5, 0.7], [0.01, 0.02, 0.03, 0.04]);
        let want = [(0.2, 0.015), (0.4, 0.025), (0.6, 0.035), (0.4, 0.025)];
        for (k, (m, v)) in want.into_iter().enumerate() {
            assert!((old.mean[4 + k] - m).abs() < 1e-15 && (old.var[4 + k] - v).abs() < 1e-15);
        }
        assert_eq!(old.mean[..4], [0.1, 0.3, 0.5, 0.7]);
    }

    #[test]
    fn horizon_distributions_pool_exactly_and_read_back_their_fractions() {
        // Two footprints of 16 points each along +x (the other directions flat): one with a
        // two-peaked set (half at 0, half at 50°), one spread evenly over 0–60°. Their pooled
        // distribution, weighted 3 : 1, is the fraction of all the points (weighted) at or
        // below each node; read at a node's elevation, the visibility is that fraction; the
        // median inverts it.
        let deg = |x: f64| x.to_radians();
        let mut a = [[0.0f64; 16]; HORIZON_DIRECTIONS];
        let mut b = [[0.0f64; 16]; HORIZON_DIRECTIONS];
        for k in 0..16 {
            a[0][k] = if k < 8 { 0.0 } else { deg(50.0) };
            b[0][k] = deg(60.0 * k as f64 / 15.0);
        }
        let mut sum = HorizonCdfSum::default();
        sum.add(&HorizonCdfSum::of_points(&a, 1.0), 3.0);
        sum.add(&HorizonCdfSum::of_points(&b, 1.0), 1.0);
        let cdf = sum.finish();
        assert_eq!(cdf.weight, 4.0);
        for (n, &e) in CDF_ELEVATIONS_DEG.iter().enumerate() {
            let below = |p: &[f64; 16]| p.iter().filter(|&&h| h <= deg(e)).count() as f64 / 16.0;
            let want = (3.0 * below(&a[0]) + below(&b[0])) / 4.0;
            assert!(
                (f64::from(cdf.frac[0][n]) / 255.0 - want).abs() <= 0.5 / 255.0,
                "node {n}"
            );
            // Every other direction is flat: all visible from the first node on.
            assert_eq!(cdf.frac[1][n], 255);
            // A light along +x at the node's elevation (a hair above: the node counts the
            // horizons at or below it).
            let el = deg(e) + 1e-9;
            let w = DVec3::new(el.cos(), 0.0, el.sin());
            let v = cdf.visibility(w);
            assert!(
                (v - f64::from(cdf.frac[0][n]) / 255.0).abs() < 1e-6,
                "node {n}: {v}"
            );
        }
        // Two-peaked: the tops (3/8 + 1/4 · 1/16 of the weight at 0) see any light above the
        // first node; a ramp of the pooled mean and variance would not.
        assert!(cdf.visibility(DVec3::new(0.94, 0.0, 0.34)) > 0.39);
        let median = cdf.quantile(0, 0.5);
        let back = cdf.visibility(DVec3::new(median.cos(), 0.0, median.sin()));
        assert!((back - 0.5).abs() < 1e-9, "{median} {back}");
        // Nothing pooled: visible from everywhere above the horizon.
        assert_eq!(
            HorizonCdfSum::default()
                .finish()
                .visibility(DVec3::new(1.0, 0.0, 0.1)),
            1.0
        );
    }

    #[test]
    fn light_and_viewer_together_within_the_frechet_bounds_exact_along_one_azimuth() {
        // 16 points whose horizons differ by direction: along each azimuth a spread of
        // angles, shifted per direction, so that no two directions share one distribution.
        let mut pts = [[0.0f64; 16]; HORIZON_DIRECTIONS];
        for (d, row) in pts.iter_mut().enumerate() {
            for (k, h) in row.iter_mut().enumerate() {
                *h = (((k * 7 + d * 5) % 16) as f64 * 4.5).to_radians();
            }
        }
        let cdf = HorizonCdfSum::of_points(&pts, 1.0).finish();
        let dir = |az: f64, el: f64| {
            let (a, e) = (az.to_radians(), el.to_radians());
            HorizonDirection::new(DVec3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin()))
        };
        for az in (0..72).map(|k| f64::from(k) * 5.0) {
            for el in [2.0, 10.0, 20.0, 35.0, 50.0] {
                let a = dir(az, el);
                let va = cdf.visibility_along(&a);
                // One direction twice: shadowing and masking are one event.
                assert!((cdf.joint_visibility_along(None, &a, &a) - va).abs() < 1e-12);
                // Along one azimuth, the higher elevation sees from all that the lower does
                // (exact on stored azimuths, where one distribution is read).
                let same = dir(az, el + 20.0);
                let on_slot = az % 45.0 == 0.0;
                if on_slot {
                    let j = cdf.joint_visibility_along(None, &a, &same);
                    assert!((j - va).abs() < 1e-12, "{az}° {el}°: {j} vs {va}");
                }
                for az_b in (0..24).map(|k| f64::from(k) * 15.0) {
                    for el_b in [5.0, 25.0, 60.0] {
                        let b = dir(az_b, el_b);
                        let vb = cdf.visibility_along(&b);
                        let j = cdf.joint_visibility_along(None, &a, &b);
                        let jr = cdf.joint_visibility_along(None, &b, &a);
                        assert!((j - jr).abs() < 1e-12, "symmetric");
                        assert!(j <= va.min(vb) + 1e-12, "{az}° {az_b}°: {j} > min");
                        assert!(j >= (va + vb - 1.0).max(0.0) - 1e-12, "{az}° {az_b}°");
                        // Stored azimuths 90° or more apart: as if independent.
                        let apart = (az - az_b).rem_euclid(360.0);
                        if on_slot && az_b % 45.0 == 0.0 && (90.0..=270.0).contains(&apart) {
                            assert!((j - va * vb).abs() < 1e-12);
                        }
                        let pair = HorizonPair::new(&a, &b);
                        let given = cdf.visibility_given(None, &pair);
                        if vb > 0.0 {
                            assert!((given * vb - j).abs() < 1e-12);
                        }
                        // The three fractions in one pass, and the rule of them the renderer
                        // reads with its per-normal light.
                        let f = cdf.pair_fractions(None, &pair);
                        for (got, want) in f.iter().zip([va, vb, j]) {
                            assert!((got - want).abs() < 1e-12, "{az}° {az_b}°: {f:?}");
                        }
                        assert!((HorizonCdf::light_given_view(f) - given).abs() < 1e-12);
                    }
                }
            }
        }
        // Continuous in azimuth: a sweep of the viewer's azimuth moves the joint by little per
        // step (the rule changes only where a stored azimuth's weight is 0).
        let a = dir(10.0, 20.0);
        let mut last = cdf.joint_visibility_along(None, &a, &dir(0.0, 30.0));
        for k in 1..=3600 {
            let j = cdf.joint_visibility_along(None, &a, &dir(f64::from(k) * 0.1, 30.0));
            assert!(
                (j - last).abs() < 0.01,
                "at {}°: {last} -> {j}",
                f64::from(k) * 0.1
            );
            last = j;
        }
        // A direction at the zenith or below the horizon: the other's visibility, or none.
        let up = HorizonDirection::new(DVec3::Z);
        assert!(
            (cdf.joint_visibility_along(None, &up, &a) - cdf.visibility_along(&a)).abs() < 1e-12
        );
        let below = HorizonDirection::new(DVec3::new(1.0, 0.0, -0.1));
        assert_eq!(cdf.joint_visibility_along(None, &below, &a), 0.0);
    }

    /// The direction along stored azimuth `slot` at elevation `el` (radians), prepared.
    fn stored_dir(slot: usize, el: f64) -> HorizonDirection {
        let az = HORIZON_AZIMUTHS_DEG[slot].to_radians();
        HorizonDirection::new(DVec3::new(
            el.cos() * az.cos(),
            el.cos() * az.sin(),
            el.sin(),
        ))
    }

    #[test]
    fn nothing_sees_below_the_horizon_whatever_the_statistics() {
        // A distribution of no weight (a lobe handed no cell) sees every direction above the
        // horizon, none below it or along it; straight up is seen by all.
        let (empty, stats) = (HorizonCdf::default(), HorizonStats::default());
        assert_eq!(empty.weight, 0.0);
        let dir = |w: DVec3| HorizonDirection::new(w);
        for w in [
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::X,
            DVec3::new(0.3, -0.2, -0.5),
        ] {
            let d = dir(w);
            assert_eq!(empty.visibility_along(&d), 0.0, "{w}");
            assert_eq!(stats.visibility_along(&d), 0.0, "{w}");
            let up = dir(DVec3::new(0.2, 0.1, 0.9));
            assert_eq!(empty.joint_visibility_along(None, &d, &up), 0.0);
            let pair = HorizonPair::new(&d, &up);
            assert_eq!(empty.pair_fractions(None, &pair)[0], 0.0);
            assert_eq!(empty.visibility_given(None, &pair), 0.0);
        }
        let up = dir(DVec3::new(0.2, 0.1, 0.9));
        assert_eq!(empty.visibility_along(&up), 1.0);
        assert_eq!(empty.visibility_along(&dir(DVec3::Z)), 1.0);
    }

    #[test]
    fn the_table_of_fractions_is_the_division() {
        for k in 0..=255u8 {
            assert_eq!(
                unit_255(k).to_bits(),
                (f64::from(k) / 255.0).to_bits(),
                "{k}"
            );
        }
    }

    #[test]
    fn a_cells_joint_is_its_bilinear_points_joint_to_the_bit() {
        // Corners within one interval of the grid (the points skipped), straddling a node,
        // on a node exactly and a hair either side of one, below the first node and above
        // the last, mixed across the directions: the cell's joint is that of its 16 points.
        let nodes = JOINT_ELEVATIONS_DEG.map(f64::to_radians);
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut kinds_seen = [0usize; 2];
        for case in 0..4000 {
            let corners: [[f64; 4]; HORIZON_DIRECTIONS] = std::array::from_fn(|d| {
                let pick = (case + d) % 6;
                std::array::from_fn(|_| match pick {
                    // Inside one interval: between nodes 1 and 2.
                    0 => nodes[1] + (nodes[2] - nodes[1]) * (0.05 + 0.9 * uniform()),
                    // Anywhere from 0° to 70°.
                    1 => 70f64.to_radians() * uniform(),
                    // On a node, or a hair either side of it.
                    2 => nodes[case % JOINT_NODES] + [0.0, 1e-12, -1e-12, 1e-10][case % 4],
                    // Below the first node, above the last.
                    3 => nodes[0] * uniform(),
                    4 => nodes[3] + 0.3 * uniform(),
                    // A narrow spread around a node.
                    _ => nodes[2] + 1e-3 * (uniform() - 0.5),
                })
            });
            let points = corners.map(|a| bilinear_points(&a));
            let w = 0.25 + uniform();
            assert_eq!(
                HorizonJointSum::of_bilinear_cell(&corners, w),
                HorizonJointSum::of_points(&points, w),
                "case {case}: {corners:?}"
            );
            for a in &corners {
                let lo = a.iter().copied().fold(f64::INFINITY, f64::min);
                let hi = a.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let same = nodes.iter().filter(|&&e| e < lo).count()
                    == nodes.iter().filter(|&&e| e < hi).count();
                kinds_seen[usize::from(same)] += 1;
            }
        }
        // Both ways of reading a direction were exercised.
        assert!(kinds_seen.iter().all(|&n| n > 1000), "{kinds_seen:?}");
    }

    #[test]
    fn joint_fractions_pool_exactly_and_give_the_fraction_that_sees_both() {
        // Two point sets (weights 3 : 1) whose horizons along opposite azimuths go together in
        // the first (a wall top sees both ways, a floor neither) and against each other in the
        // second. Every pair the joint holds reads back, at its grid's nodes and on stored
        // azimuths, the weighted fraction of the points that see both directions; between the
        // nodes it stays within the Fréchet bounds, and without the joint the product is read.
        let deg = |x: f64| x.to_radians();
        let mut a = [[0.0f64; 16]; HORIZON_DIRECTIONS];
        let mut b = [[0.0f64; 16]; HORIZON_DIRECTIONS];
        for k in 0..16 {
            let hi = deg(2.0 + 4.0 * k as f64);
            for d in 0..HORIZON_DIRECTIONS {
                a[d][k] = hi;
                b[d][k] = if d % 2 == 0 { hi } else { deg(62.0) - hi };
            }
        }
        let mut cdf = HorizonCdfSum::default();
        cdf.add(&HorizonCdfSum::of_points(&a, 1.0), 3.0);
        cdf.add(&HorizonCdfSum::of_points(&b, 1.0), 1.0);
        let cdf = cdf.finish();
        let mut sum = HorizonJointSum::default();
        sum.add(&HorizonJointSum::of_points(&a, 1.0), 3.0);
        sum.add(&HorizonJointSum::of_points(&b, 1.0), 1.0);
        let joint = sum.finish();
        assert_eq!(joint.weight, 4.0);
        let exact = |da: usize, ea: f64, db: usize, eb: f64| {
            let f = |p: &[[f64; 16]; HORIZON_DIRECTIONS]| {
                (0..16)
                    .filter(|&k| p[da][k] <= ea && p[db][k] <= eb)
                    .count() as f64
                    / 16.0
            };
            (3.0 * f(&a) + f(&b)) / 4.0
        };
        let dir = stored_dir;
        for (p, &(sa, sb)) in JOINT_PAIR_SLOTS.iter().enumerate() {
            for (i, &ei) in JOINT_ELEVATIONS_DEG.iter().enumerate() {
                for (j, &ej) in JOINT_ELEVATIONS_DEG.iter().enumerate() {
                    let want = exact(sa, deg(ei), sb, deg(ej));
                    let got = f64::from(joint.both[p][i * JOINT_NODES + j]) / 255.0;
                    assert!((got - want).abs() <= 0.5 / 255.0, "pair {p} ({i}, {j})");
                    // Read through the lobe's distributions, a hair above the nodes (they
                    // count the horizons at or below them), both orders.
                    let (da, db) = (dir(sa, deg(ei) + 1e-9), dir(sb, deg(ej) + 1e-9));
                    for v in [
                        cdf.joint_visibility_along(Some(&joint), &da, &db),
                        cdf.joint_visibility_along(Some(&joint), &db, &da),
                    ] {
                        assert!((v - want).abs() < 2.0 / 255.0, "pair {p}: {v} vs {want}");
                    }
                }
            }
            // Between the nodes and off the grid: within the bounds.
            for ea in [1.0, 8.0, 22.0, 40.0, 70.0] {
                for eb in [1.5, 10.0, 33.0, 60.0] {
                    let (da, db) = (dir(sa, deg(ea)), dir(sb, deg(eb)));
                    let (va, vb) = (cdf.visibility_along(&da), cdf.visibility_along(&db));
                    let v = cdf.joint_visibility_along(Some(&joint), &da, &db);
                    assert!(v <= va.min(vb) + 1e-12 && v >= (va + vb - 1.0).max(0.0) - 1e-12);
                    let none = cdf.joint_visibility_along(None, &da, &db);
                    assert!((none - va * vb).abs() < 1e-12);
                }
            }
        }
        // The opposite pairs of the first set go together: far more than the product sees both.
        let (l, o) = (dir(1, deg(21.0)), dir(3, deg(30.0)));
        let (vl, vo) = (cdf.visibility_along(&l), cdf.visibility_along(&o));
        let both = cdf.joint_visibility_along(Some(&joint), &l, &o);
        assert!(both > 1.3 * vl * vo, "{both} vs {}", vl * vo);
        let want = exact(1, deg(21.0), 3, deg(30.0));
        assert!((both - want).abs() < 0.05, "{both} vs {want}");
        let given = cdf.visibility_given(Some(&joint), &HorizonPair::new(&l, &o));
        assert!((given * vo - both).abs() < 1e-12);
        // The pairs held are the 20 stored azimuths 90°-180° apart, each once.
        let mut seen = std::collections::HashSet::new();
        for &(sa, sb) in &JOINT_PAIR_SLOTS {
            let apart = (HORIZON_AZIMUTHS_DEG[sa] - HORIZON_AZIMUTHS_DEG[sb]).abs();
            let apart = apart.min(360.0 - apart);
            assert!((90.0..=180.0).contains(&apart));
            assert!(seen.insert((sa.min(sb), sa.max(sb))));
        }
    }

    #[test]
    fn between_the_nodes_the_copula_keeps_its_nodes_dependence() {
        // Three point sets whose horizons along two stored azimuths go together (equal), are
        // independent (every pair of 16 angles) and go against each other. Off the grid's
        // nodes the joint reads, from the set's own distributions, the upper Fréchet bound,
        // the product and the lower bound. A grid read bilinearly in the two fractions (the
        // reading before 2026-12-07) loses up to half the dependence between two nodes.
        let deg = |x: f64| x.to_radians();
        let angle = |k: usize| deg(2.0 + 4.0 * k as f64);
        let dir = stored_dir;
        type Rule = fn(f64, f64) -> f64;
        let upper: Rule = |u, v| u.min(v);
        let product: Rule = |u, v| u * v;
        let lower: Rule = |u, v| (u + v - 1.0).max(0.0);
        // Pairs 180° and 90° apart.
        for (sa, sb) in [(1, 3), (0, 1)] {
            let sets: [(Vec<[[f64; 16]; HORIZON_DIRECTIONS]>, Rule); 3] = [
                (
                    vec![std::array::from_fn(|_| std::array::from_fn(angle))],
                    upper,
                ),
                (
                    (0..16)
                        .map(|i| {
                            let mut p: [[f64; 16]; HORIZON_DIRECTIONS] =
                                std::array::from_fn(|_| std::array::from_fn(angle));
                            p[sa] = [angle(i); 16];
                            p
                        })
                        .collect(),
                    product,
                ),
                (
                    vec![std::array::from_fn(|d| {
                        std::array::from_fn(|k| if d == sb { angle(15 - k) } else { angle(k) })
                    })],
                    lower,
                ),
            ];
            for (points, rule) in &sets {
                let (mut cdf, mut joint) = (HorizonCdfSum::default(), HorizonJointSum::default());
                for p in points {
                    cdf.add(&HorizonCdfSum::of_points(p, 1.0), 1.0);
                    joint.add(&HorizonJointSum::of_points(p, 1.0), 1.0);
                }
                let (cdf, joint) = (cdf.finish(), joint.finish());
                for (ea, eb) in [
                    (8.0, 8.0),
                    (21.0, 21.0),
                    (21.0, 40.0),
                    (10.0, 35.0),
                    (40.0, 60.0),
                ] {
                    let (da, db) = (dir(sa, deg(ea)), dir(sb, deg(eb)));
                    let (va, vb) = (cdf.visibility_along(&da), cdf.visibility_along(&db));
                    let want = rule(va, vb);
                    let got = cdf.joint_visibility_along(Some(&joint), &da, &db);
                    assert!(
                        (got - want).abs() < 0.01,
                        "slots {sa}, {sb} at {ea}°, {eb}°: {got} vs {want}"
                    );
                }
            }
        }
    }

    #[test]
    fn nodes_below_counts_the_nodes_strictly_below_an_angle() {
        for k in 0..=2000 {
            let deg = 90.0 * k as f64 / 2000.0;
            for h in [deg.to_radians(), (deg + 1e-9).to_radians()] {
                let want = CDF_ELEVATIONS_DEG
                    .iter()
                    .filter(|&&e| e.to_radians() < h)
                    .count();
                assert_eq!(usize::from(nodes_below(h)), want, "{deg}°");
            }
        }
        for e in CDF_ELEVATIONS_DEG {
            let h = e.to_radians();
            let want = CDF_ELEVATIONS_DEG
                .iter()
                .filter(|&&x| x.to_radians() < h)
                .count();
            assert_eq!(usize::from(nodes_below(h)), want, "on the node {e}°");
        }
    }
}
