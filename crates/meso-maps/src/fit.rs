//! Fitting a sum of Phong peaks (Eq. 12, [`PhongLobe`]) to a weighted set of meso-normals.
//!
//! # Method
//! The normals of a footprint are first merged per bin of a fine equal-area grid
//! ([`ENTRY_GRID_RES`]² bins, ≈ 0.8° wide) into [`Entry`]s that keep the *sum* of their weighted
//! normals, so the within-bin spread survives in the length of the mean vector.
//!
//! * If there are no more entries than `max_lobes`, every entry becomes its own lobe (exact):
//!   axis = its mean direction, exponent from its spread (a set of identical normals gets
//!   [`ETA_MAX`], a delta-like lobe).
//! * Otherwise the mixture of K lobes is fitted by maximum likelihood with EM. With
//!   `t = ln((1 + a·m)/2)` the log-density of a lobe is `ln((η+2)/(8π)) + (η/2)·t`, so the
//!   exponent's M-step is closed-form, `η + 2 = −2 / E_r[t]` (clamped to `[0, ETA_MAX]`), and
//!   the axis satisfies `a ∝ Σ r_n m_n / (1 + a·m_n)`, iterated once per EM step.
//!   K grows from 1; each K starts from a spherical k-means (greedy weighted k-means++ seeds);
//!   K lobes are kept only if they raise the mean log-likelihood (per unit weight) over K − 1
//!   lobes by more than `min_gain` nats.
//!   Footprints with more than `max_em_points` entries are fitted on a strided subset; footprints
//!   with at most 4 entries per lobe use the k-means clusters directly (no EM).
//!
//! The quality of a fit is measured by [`ndf_l2_error`]: the relative L2 distance between the
//! lobes' probability per bin of a [`RESIDUAL_GRID_RES`]² equal-area grid and the histogram of
//! the footprint's normals.

use crate::sphgrid::SphereGrid;
use glam::DVec3;
use meso_core::ndf::PhongLobe;
use std::f64::consts::PI;

/// Largest Phong exponent η on cos(α/2); footprints of identical normals get exactly this.
pub const ETA_MAX: f64 = 1.0e6;
/// Largest number of lobes per texel.
pub const MAX_LOBES: usize = 8;
/// Resolution of the equal-area grid used to merge normals into [`Entry`]s (≈ 0.8° bins).
pub const ENTRY_GRID_RES: usize = 256;
/// Resolution of the equal-area grid of the NDF residual (1024 bins of ≈ 6.3°).
pub const RESIDUAL_GRID_RES: usize = 32;

/// Normals of one bin of the entry grid: `w` = total weight, `m` = Σ weight·normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Entry {
    /// Bin index in the [`ENTRY_GRID_RES`] grid (entries are kept sorted by it).
    pub bin: u32,
    /// Total microsurface-area weight (Eq. 1 convention, see `crate::facets`).
    pub w: f64,
    /// Sum of weight × unit normal.
    pub m: DVec3,
}

impl Entry {
    /// The entry of a single normal.
    #[must_use]
    pub fn new(n: DVec3, w: f64) -> Entry {
        Entry {
            bin: SphereGrid {
                res: ENTRY_GRID_RES,
            }
            .bin(n) as u32,
            w,
            m: n * w,
        }
    }
    /// Mean vector `m / w` (length ≤ 1; shorter when the bin's normals spread).
    #[inline]
    #[must_use]
    pub fn mean(&self) -> DVec3 {
        self.m / self.w
    }
}

/// Merge sorted entry lists into `out` (cleared first), summing entries of equal bins.
pub fn merge_entries(lists: &[&[Entry]], out: &mut Vec<Entry>) {
    out.clear();
    for l in lists {
        out.extend_from_slice(l);
    }
    out.sort_unstable_by_key(|e| e.bin);
    let mut k = 0;
    for r in 0..out.len() {
        if k > 0 && out[k - 1].bin == out[r].bin {
            let e = out[r];
            out[k - 1].w += e.w;
            out[k - 1].m += e.m;
        } else {
            out[k] = out[r];
            k += 1;
        }
    }
    out.truncate(k);
}

/// Parameters of the lobe fit.
#[derive(Clone, Debug, PartialEq)]
pub struct FitParams {
    /// Largest number of lobes per texel, 1..=[`MAX_LOBES`] (default 4).
    pub max_lobes: usize,
    /// Smallest gain in mean log-likelihood (nats per unit weight) that justifies one more
    /// lobe (default 0.001).
    pub min_gain: f64,
    /// EM iterations per K (default 30; stops earlier when the likelihood settles).
    pub em_iterations: usize,
    /// Entries used by EM; larger footprints are fitted on a strided subset (default 512).
    pub max_em_points: usize,
    /// EM entries per pyramid level: a level of T texels fits each on at most
    /// `clamp(level_em_points / T, 64, max_em_points)` entries (default 2¹⁸), so that the big
    /// fine levels cost no more than the coarse ones; levels of ≤ 512 texels get the full
    /// `max_em_points`.
    pub level_em_points: usize,
    /// Levels with at most this many texels (the coarse ones) are fitted thoroughly: full
    /// `em_iterations` for every start (default 64; see `fit_lobes_with`).
    pub thorough_texels: usize,
}

impl Default for FitParams {
    fn default() -> Self {
        FitParams {
            max_lobes: 4,
            min_gain: 0.001,
            em_iterations: 30,
            max_em_points: 512,
            level_em_points: 1 << 18,
            thorough_texels: 64,
        }
    }
}

#[inline]
fn log_t(a: DVec3, m: DVec3) -> f64 {
    (0.5 * (1.0 + a.dot(m))).max(1e-300).ln()
}

#[inline]
fn eta_from_mean_t(t: f64) -> f64 {
    if t >= -1.0 / ETA_MAX {
        ETA_MAX
    } else {
        (-2.0 / t - 2.0).clamp(0.0, ETA_MAX)
    }
}

#[derive(Clone, Copy)]
struct L {
    a: DVec3,
    w: f64,
    eta: f64,
}

/// Spherical k-means with a greedy weighted k-means++ start (first centre: the heaviest entry;
/// then the entry maximising weight × squared chord distance to the nearest centre), 5 Lloyd
/// steps, then lobes with the cluster shares and the closed-form exponent of each cluster.
fn kmeans_init(pts: &[Pt], k: usize) -> Vec<L> {
    let mut centres: Vec<DVec3> = Vec::with_capacity(k);
    let first = pts
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|e| e.0.normalize())
        .unwrap_or(DVec3::Z);
    centres.push(first);
    while centres.len() < k {
        let mut best = (-1.0, DVec3::Z);
        for e in pts {
            let d = e.0.normalize();
            let dist = centres
                .iter()
                .map(|c| 2.0 - 2.0 * c.dot(d))
                .fold(f64::INFINITY, f64::min);
            if e.1 * dist > best.0 {
                best = (e.1 * dist, d);
            }
        }
        centres.push(best.1);
    }
    let mut sums = vec![(DVec3::ZERO, 0.0f64, 0.0f64); k];
    for _ in 0..5 {
        sums.iter_mut().for_each(|s| *s = (DVec3::ZERO, 0.0, 0.0));
        for &(d, w) in pts {
            let j = (0..k)
                .max_by(|&a, &b| centres[a].dot(d).total_cmp(&centres[b].dot(d)))
                .unwrap_or(0);
            sums[j].0 += d * w;
            sums[j].1 += w;
        }
        for j in 0..k {
            if sums[j].0.length_squared() > 0.0 {
                centres[j] = sums[j].0.normalize();
            }
        }
    }
    for &(d, w) in pts {
        let j = (0..k)
            .max_by(|&a, &b| centres[a].dot(d).total_cmp(&centres[b].dot(d)))
            .unwrap_or(0);
        sums[j].2 += w * log_t(centres[j], d);
    }
    let total: f64 = sums.iter().map(|s| s.1).sum();
    (0..k)
        .filter(|&j| sums[j].1 > 0.0)
        .map(|j| L {
            a: centres[j],
            w: sums[j].1 / total,
            eta: eta_from_mean_t(sums[j].2 / sums[j].1).min(1e4),
        })
        .collect()
}

/// `ln x` for finite `x > 0` to ~1e-9 absolute: exponent split, mantissa folded into
/// `[√½, √2)`, then the atanh series `2(s + s³/3 + … + s⁹/9)` with `s = (m−1)/(m+1)`. EM's inner
/// loop spends most of its time in `ln` and `exp`; libm's full-precision versions are not needed.
#[inline]
fn fast_ln(x: f64) -> f64 {
    let bits = x.to_bits();
    let mut e = ((bits >> 52) & 0x7ff) as i64 - 1023;
    let mut m = f64::from_bits((bits & 0x000f_ffff_ffff_ffff) | 0x3ff0_0000_0000_0000);
    if e == -1023 {
        // Subnormal: rare (x < 2.2e-308); fall back.
        return x.ln();
    }
    if m > std::f64::consts::SQRT_2 {
        m *= 0.5;
        e += 1;
    }
    let s = (m - 1.0) / (m + 1.0);
    let s2 = s * s;
    let p = s * (2.0 + s2 * (2.0 / 3.0 + s2 * (0.4 + s2 * (2.0 / 7.0 + s2 * (2.0 / 9.0)))));
    e as f64 * std::f64::consts::LN_2 + p
}

/// `exp y` for `y ≤ 0` to ~1e-9 relative (0 below −700): `2^k · e^r`, `|r| ≤ ln2/2`, degree-8
/// Taylor polynomial for `e^r`.
#[inline]
fn fast_exp_neg(y: f64) -> f64 {
    if y < -700.0 {
        return 0.0;
    }
    // Nearest integer to y·log₂e (≤ 0) by truncation, one instruction (`round` is a libm call).
    let ki = (y * std::f64::consts::LOG2_E - 0.5) as i64;
    let k = ki as f64;
    let r = y - k * std::f64::consts::LN_2;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0
                    + r * (1.0 / 24.0
                        + r * (1.0 / 120.0
                            + r * (1.0 / 720.0 + r * (1.0 / 5040.0 + r * (1.0 / 40320.0))))))));
    p * f64::from_bits(((ki + 1023) as u64) << 52)
}

/// A point of EM: the mean vector of an entry (length ≤ 1) and its weight.
type Pt = (DVec3, f64);

/// Mean log-likelihood per unit weight of the mixture.
fn loglik(pts: &[Pt], lobes: &[L], total: f64) -> f64 {
    let k = lobes.len();
    let mut c = [0.0f64; MAX_LOBES];
    for (j, l) in lobes.iter().enumerate() {
        c[j] = l.w.max(1e-300).ln() + ((l.eta + 2.0) / (8.0 * PI)).ln();
    }
    let mut logd = [0.0f64; MAX_LOBES];
    let mut ll = 0.0;
    for &(m, w) in pts {
        let mut mx = f64::NEG_INFINITY;
        for j in 0..k {
            let x = (0.5 * (1.0 + lobes[j].a.dot(m))).max(1e-300);
            logd[j] = c[j] + 0.5 * lobes[j].eta * fast_ln(x);
            mx = mx.max(logd[j]);
        }
        let s: f64 = logd[..k].iter().map(|v| fast_exp_neg(v - mx)).sum();
        ll += w * (mx + fast_ln(s));
    }
    ll / total
}

/// EM on the mixture (module docs), at most `iters` iterations; returns the mean
/// log-likelihood per unit weight of the last E-step. One `ln` and one `exp` per point and lobe.
fn em(pts: &[Pt], lobes: &mut Vec<L>, total: f64, iters: usize) -> f64 {
    let mut prev = f64::NEG_INFINITY;
    let mut acc_w = [0.0f64; MAX_LOBES];
    let mut acc_a = [DVec3::ZERO; MAX_LOBES];
    let mut acc_t = [0.0f64; MAX_LOBES];
    let mut logd = [0.0f64; MAX_LOBES];
    let mut lt = [0.0f64; MAX_LOBES];
    let mut inv = [0.0f64; MAX_LOBES];
    let mut c = [0.0f64; MAX_LOBES];
    for _ in 0..iters.max(1) {
        let k = lobes.len();
        if k == 0 {
            break;
        }
        for j in 0..k {
            c[j] = lobes[j].w.max(1e-300).ln() + ((lobes[j].eta + 2.0) / (8.0 * PI)).ln();
        }
        acc_w[..k].fill(0.0);
        acc_a[..k].fill(DVec3::ZERO);
        acc_t[..k].fill(0.0);
        let mut ll = 0.0;
        for &(m, w) in pts {
            let mut mx = f64::NEG_INFINITY;
            for j in 0..k {
                let x = (0.5 * (1.0 + lobes[j].a.dot(m))).max(1e-300);
                lt[j] = fast_ln(x);
                inv[j] = 0.5 / x.max(0.5e-6);
                logd[j] = c[j] + 0.5 * lobes[j].eta * lt[j];
                mx = mx.max(logd[j]);
            }
            if k == 1 {
                ll += w * logd[0];
                acc_w[0] += w;
                acc_a[0] += m * (w * inv[0]);
                acc_t[0] += w * lt[0];
                continue;
            }
            let mut s = 0.0;
            for v in logd.iter_mut().take(k) {
                *v = fast_exp_neg(*v - mx);
                s += *v;
            }
            ll += w * (mx + fast_ln(s));
            let ws = w / s;
            for j in 0..k {
                let r = ws * logd[j];
                acc_w[j] += r;
                acc_a[j] += m * (r * inv[j]);
                acc_t[j] += r * lt[j];
            }
        }
        for j in 0..k {
            if acc_w[j] <= 1e-12 * total {
                lobes[j].w = 0.0;
                continue;
            }
            lobes[j].w = acc_w[j] / total;
            if acc_a[j].length_squared() > 0.0 {
                lobes[j].a = acc_a[j].normalize();
            }
            lobes[j].eta = eta_from_mean_t(acc_t[j] / acc_w[j]);
        }
        lobes.retain(|l| l.w > 0.0);
        let ll = ll / total;
        let converged = (ll - prev).abs() < 1e-6 * (1.0 + ll.abs());
        prev = ll;
        if converged || lobes.len() < k {
            break;
        }
    }
    prev
}

fn to_phong(lobes: &[L]) -> Vec<PhongLobe> {
    let s: f64 = lobes.iter().map(|l| l.w).sum();
    lobes
        .iter()
        .map(|l| PhongLobe {
            axis: l.a,
            weight: l.w / s,
            exponent: l.eta,
        })
        .collect()
}

/// Split the heaviest lobe of `lobes` into a concentric pair (same axis, exponents ×2.5 and
/// ÷2.5): the start that lets EM model a peak sharper and tails heavier than one Phong peak
/// (e.g. the Gaussian slopes of a random surface), which k-means starts cannot.
fn split_heaviest(lobes: &[L]) -> Vec<L> {
    let mut out = lobes.to_vec();
    if let Some(j) = (0..out.len()).max_by(|&a, &b| out[a].w.total_cmp(&out[b].w)) {
        let l = out[j];
        out[j] = L {
            a: l.a,
            w: 0.5 * l.w,
            eta: (l.eta * 2.5).min(ETA_MAX),
        };
        out.push(L {
            a: l.a,
            w: 0.5 * l.w,
            eta: l.eta / 2.5,
        });
    }
    out
}

/// Fit up to `params.max_lobes` Phong peaks to the merged normals `entries` (see module docs).
/// Writes the lobes into `out` (cleared first); weights sum to 1.
pub fn fit_lobes(entries: &[Entry], params: &FitParams, out: &mut Vec<PhongLobe>) {
    let mut pts = Vec::new();
    fit_lobes_with(entries, params, params.max_em_points, true, &mut pts, out);
}

/// [`fit_lobes`] with the EM subset capped at `max_points` entries (≤ `params.max_em_points`)
/// and a caller-owned buffer (no allocation per call once it has grown). `thorough` runs every
/// EM for `em_iterations`; otherwise K is chosen after 5 EM iterations per start and the chosen
/// K polished with at most 10 more (the cheap path of the big, fine pyramid levels).
pub fn fit_lobes_with(
    entries: &[Entry],
    params: &FitParams,
    max_points: usize,
    thorough: bool,
    pts: &mut Vec<(DVec3, f64)>,
    out: &mut Vec<PhongLobe>,
) {
    out.clear();
    let total: f64 = entries.iter().map(|e| e.w).sum();
    if entries.is_empty() || total <= 0.0 {
        return;
    }
    let kmax = params.max_lobes.clamp(1, MAX_LOBES);
    if entries.len() <= kmax {
        for e in entries {
            let mean = e.mean();
            let a = mean.normalize();
            out.push(PhongLobe {
                axis: a,
                weight: e.w / total,
                exponent: eta_from_mean_t(log_t(a, mean)),
            });
        }
        return;
    }
    // Strided subset for EM.
    let cap = max_points.min(params.max_em_points).max(8);
    let stride = entries.len().div_ceil(cap);
    pts.clear();
    pts.extend(entries.iter().step_by(stride).map(|e| (e.mean(), e.w)));
    let pts: &[Pt] = pts;
    let ptotal: f64 = pts.iter().map(|p| p.1).sum();
    let iters = params.em_iterations.max(3);
    // With the full point budget (small levels) every EM runs `em_iterations`; on budget-capped
    // levels, selection runs short EM (5 iterations) and the chosen K is polished with ≤ 10 more.
    let full = thorough;
    let sel_iters = if full { iters } else { iters.min(5) };
    // K = 1: mean direction, then the fixed point and the closed-form η.
    let a = pts.iter().map(|p| p.0 * p.1).sum::<DVec3>();
    let a = if a.length_squared() > 0.0 {
        a.normalize()
    } else {
        DVec3::Z
    };
    let mut lobes = vec![L {
        a,
        w: 1.0,
        eta: 0.0,
    }];
    let mut ll = em(
        pts,
        &mut lobes,
        ptotal,
        if full { iters } else { iters.min(10) },
    );
    // Nearly identical normals: one delta-like lobe, nothing to gain from more.
    if lobes.len() == 1 && lobes[0].eta >= ETA_MAX {
        out.extend(to_phong(&lobes));
        return;
    }
    let small = pts.len() <= 4 * kmax;
    let mut improved = false;
    for k in 2..=kmax {
        let mut best: Option<(f64, Vec<L>)> = None;
        // Thorough fits try both starts at every K, the cheap path both at K = 2 and k-means
        // after; small footprints (no EM) only k-means (a split start needs EM to move).
        let starts: &[usize] = if small {
            &[0]
        } else if full || k == 2 {
            &[0, 1]
        } else {
            &[0]
        };
        for &start in starts {
            let mut trial = if start == 0 {
                kmeans_init(pts, k)
            } else {
                split_heaviest(&lobes)
            };
            // Small footprints (≤ 4 entries per lobe): the starts are used as they are.
            let l2 = if small {
                loglik(pts, &trial, ptotal)
            } else {
                em(pts, &mut trial, ptotal, sel_iters)
            };
            if trial.len() == k && best.as_ref().is_none_or(|b| l2 > b.0) {
                best = Some((l2, trial));
            }
        }
        match best {
            Some((l2, trial)) if l2 - ll > params.min_gain => {
                lobes = trial;
                ll = l2;
                improved = true;
            }
            _ => break,
        }
    }
    if improved && !small && iters > sel_iters {
        em(pts, &mut lobes, ptotal, (iters - sel_iters).min(10));
    }
    out.extend(to_phong(&lobes));
}

/// Probability of each bin of `grid` under a lobe set (weights summing to 1): lobes narrower
/// than a quarter of a bin put all their mass in the bin of their axis; others are integrated
/// with 3×3 points per bin. `out` has `grid.bins()` entries.
pub fn lobe_bin_mass(lobes: &[PhongLobe], grid: SphereGrid, out: &mut [f64]) {
    out.fill(0.0);
    let da = grid.bin_solid_angle();
    let bin_angle = da.sqrt();
    for l in lobes {
        let width = 2.0 / (l.exponent + 1.0).sqrt();
        if width < 0.25 * bin_angle {
            out[grid.bin(l.axis)] += l.weight;
            continue;
        }
        // Bins whose nearest point (centre minus a bin diagonal) is where the lobe has fallen
        // below e⁻³⁰ of its peak get nothing.
        let margin = 1.5 * bin_angle;
        for (k, o) in out.iter_mut().enumerate() {
            let c = grid.point(k, 0.5, 0.5);
            let alpha = (l.axis.dot(c).clamp(-1.0, 1.0).acos() - margin).max(0.0);
            if 0.5 * l.exponent * (0.5 * (1.0 + alpha.cos())).ln() < -30.0 {
                continue;
            }
            let mut s = 0.0;
            for a in 0..3 {
                for b in 0..3 {
                    let m = grid.point(k, (a as f64 + 0.5) / 3.0, (b as f64 + 0.5) / 3.0);
                    s += l.unit_density(m);
                }
            }
            let v = s / 9.0 * da * l.weight;
            *o += v;
        }
    }
}

/// Relative L2 error `‖P_fit − P_hist‖ / ‖P_hist‖` between the lobes' bin probabilities and the
/// histogram of `(normal, weight)` pairs on a [`RESIDUAL_GRID_RES`]² equal-area grid. Because
/// the bins have equal solid angle this equals the relative L2 error of the bin-averaged NDFs.
#[must_use]
pub fn ndf_l2_error(
    normals: impl Iterator<Item = (DVec3, f64)>,
    fit_mass: impl FnOnce(SphereGrid, &mut [f64]),
) -> f64 {
    let grid = SphereGrid {
        res: RESIDUAL_GRID_RES,
    };
    let mut hist = vec![0.0; grid.bins()];
    let mut tot = 0.0;
    for (n, w) in normals {
        hist[grid.bin(n)] += w;
        tot += w;
    }
    if tot <= 0.0 {
        return 0.0;
    }
    hist.iter_mut().for_each(|h| *h /= tot);
    let mut fit = vec![0.0; grid.bins()];
    fit_mass(grid, &mut fit);
    let num: f64 = hist.iter().zip(&fit).map(|(h, f)| (h - f) * (h - f)).sum();
    let den: f64 = hist.iter().map(|h| h * h).sum();
    (num / den).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fast_ln_and_exp_match_libm() {
        let mut x: f64 = 1e-300;
        while x < 1e3 {
            assert!(
                (fast_ln(x) - x.ln()).abs() < 1e-9 * (1.0 + x.ln().abs()),
                "ln {x}"
            );
            x *= 1.37;
        }
        let mut y: f64 = 0.0;
        while y > -745.0 {
            let e = y.exp();
            assert!((fast_exp_neg(y) - e).abs() <= 1e-9 * e + 1e-300, "exp {y}");
            y -= 0.173;
        }
    }
}
