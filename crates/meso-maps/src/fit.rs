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
    /// lobe (default 0.01).
    pub min_gain: f64,
    /// EM iterations per K (default 30; stops earlier when the likelihood settles).
    pub em_iterations: usize,
    /// Entries used by EM; larger footprints are fitted on a strided subset (default 512).
    pub max_em_points: usize,
}

impl Default for FitParams {
    fn default() -> Self {
        FitParams {
            max_lobes: 4,
            min_gain: 0.01,
            em_iterations: 30,
            max_em_points: 512,
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

impl L {
    #[inline]
    fn log_density(&self, m: DVec3) -> f64 {
        self.w.max(1e-300).ln()
            + ((self.eta + 2.0) / (8.0 * PI)).ln()
            + 0.5 * self.eta * log_t(self.a, m)
    }
}

/// Spherical k-means with a greedy weighted k-means++ start (first centre: the heaviest entry;
/// then the entry maximising weight × squared chord distance to the nearest centre), 5 Lloyd
/// steps, then lobes with the cluster shares and the closed-form exponent of each cluster.
fn kmeans_init(pts: &[Entry], k: usize) -> Vec<L> {
    let mut centres: Vec<DVec3> = Vec::with_capacity(k);
    let first = pts
        .iter()
        .max_by(|a, b| a.w.total_cmp(&b.w))
        .map(|e| e.mean().normalize())
        .unwrap_or(DVec3::Z);
    centres.push(first);
    while centres.len() < k {
        let mut best = (-1.0, DVec3::Z);
        for e in pts {
            let d = e.mean().normalize();
            let dist = centres
                .iter()
                .map(|c| 2.0 - 2.0 * c.dot(d))
                .fold(f64::INFINITY, f64::min);
            if e.w * dist > best.0 {
                best = (e.w * dist, d);
            }
        }
        centres.push(best.1);
    }
    let mut sums = vec![(DVec3::ZERO, 0.0f64, 0.0f64); k];
    for _ in 0..5 {
        sums.iter_mut().for_each(|s| *s = (DVec3::ZERO, 0.0, 0.0));
        for e in pts {
            let d = e.mean();
            let j = (0..k)
                .max_by(|&a, &b| centres[a].dot(d).total_cmp(&centres[b].dot(d)))
                .unwrap_or(0);
            sums[j].0 += e.m;
            sums[j].1 += e.w;
        }
        for j in 0..k {
            if sums[j].0.length_squared() > 0.0 {
                centres[j] = sums[j].0.normalize();
            }
        }
    }
    for e in pts {
        let d = e.mean();
        let j = (0..k)
            .max_by(|&a, &b| centres[a].dot(d).total_cmp(&centres[b].dot(d)))
            .unwrap_or(0);
        sums[j].2 += e.w * log_t(centres[j], d);
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

/// Mean log-likelihood per unit weight of the mixture, and the worst-explained entry.
fn loglik(pts: &[Entry], lobes: &[L], total: f64) -> (f64, usize) {
    let mut ll = 0.0;
    let mut worst = (f64::INFINITY, 0);
    for (n, e) in pts.iter().enumerate() {
        let m = e.mean();
        let l = lse(lobes.iter().map(|l| l.log_density(m)));
        ll += e.w * l;
        if l < worst.0 {
            worst = (l, n);
        }
    }
    (ll / total, worst.1)
}

#[inline]
fn lse(it: impl Iterator<Item = f64> + Clone) -> f64 {
    let mx = it.clone().fold(f64::NEG_INFINITY, f64::max);
    if !mx.is_finite() {
        return mx;
    }
    mx + it.map(|v| (v - mx).exp()).sum::<f64>().ln()
}

fn em(pts: &[Entry], lobes: &mut Vec<L>, total: f64, iters: usize) -> f64 {
    let k = lobes.len();
    let mut prev = f64::NEG_INFINITY;
    let mut acc_w = [0.0f64; MAX_LOBES];
    let mut acc_a = [DVec3::ZERO; MAX_LOBES];
    let mut acc_t = [0.0f64; MAX_LOBES];
    let mut logd = [0.0f64; MAX_LOBES];
    for _ in 0..iters {
        acc_w[..k].fill(0.0);
        acc_a[..k].fill(DVec3::ZERO);
        acc_t[..k].fill(0.0);
        let mut ll = 0.0;
        for e in pts {
            let m = e.mean();
            let mut mx = f64::NEG_INFINITY;
            for j in 0..k {
                logd[j] = lobes[j].log_density(m);
                mx = mx.max(logd[j]);
            }
            let mut s = 0.0;
            for v in logd.iter_mut().take(k) {
                *v = (*v - mx).exp();
                s += *v;
            }
            ll += e.w * (mx + s.ln());
            for j in 0..k {
                let r = e.w * logd[j] / s;
                let c = lobes[j].a.dot(m);
                acc_w[j] += r;
                acc_a[j] += m * (r / (1.0 + c).max(1e-6));
                acc_t[j] += r * (0.5 * (1.0 + c)).max(1e-300).ln();
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
        if (ll - prev).abs() < 1e-7 * (1.0 + ll.abs()) || lobes.len() < k {
            prev = ll;
            break;
        }
        prev = ll;
    }
    loglik(pts, lobes, total).0.max(prev.min(f64::MAX))
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

/// Fit up to `params.max_lobes` Phong peaks to the merged normals `entries` (see module docs).
/// Writes the lobes into `out` (cleared first); weights sum to 1.
pub fn fit_lobes(entries: &[Entry], params: &FitParams, out: &mut Vec<PhongLobe>) {
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
    let stride = entries.len().div_ceil(params.max_em_points.max(8));
    let sub: Vec<Entry>;
    let pts: &[Entry] = if stride > 1 {
        sub = entries.iter().step_by(stride).copied().collect();
        &sub
    } else {
        entries
    };
    let ptotal: f64 = pts.iter().map(|e| e.w).sum();
    // K = 1: mean direction, then the fixed point and the closed-form η.
    let mut a = pts.iter().map(|e| e.m).sum::<DVec3>();
    a = if a.length_squared() > 0.0 {
        a.normalize()
    } else {
        DVec3::Z
    };
    let mut lobes = vec![L {
        a,
        w: 1.0,
        eta: 0.0,
    }];
    let mut ll = em(pts, &mut lobes, ptotal, params.em_iterations.max(3));
    for k in 2..=kmax {
        let mut trial = kmeans_init(pts, k);
        // Small footprints (≤ 4 entries per lobe): the k-means clusters are used as they are.
        let ll2 = if pts.len() <= 4 * kmax {
            loglik(pts, &trial, ptotal).0
        } else {
            em(pts, &mut trial, ptotal, params.em_iterations)
        };
        if ll2 - ll > params.min_gain && trial.len() == k {
            lobes = trial;
            ll = ll2;
        } else {
            break;
        }
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
        for (k, o) in out.iter_mut().enumerate() {
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
