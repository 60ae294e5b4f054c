//! The maximum-likelihood start of the lobe fit (parent module docs): spherical k-means seeds,
//! EM on the mixture of Phong peaks with its closed-form M-step, the split start, and the fast
//! `ln` / `exp` of EM's inner loop.

use crate::limits::{ETA_MAX, MAX_LOBES};
use glam::DVec3;
use meso_core::fastmath::{fast_exp_neg, fast_ln};
use std::f64::consts::PI;

#[inline]
pub(super) fn log_t(a: DVec3, m: DVec3) -> f64 {
    (0.5 * (1.0 + a.dot(m))).max(1e-300).ln()
}

#[inline]
pub(super) fn eta_from_mean_t(t: f64) -> f64 {
    if t >= -1.0 / ETA_MAX {
        ETA_MAX
    } else {
        (-2.0 / t - 2.0).clamp(0.0, ETA_MAX)
    }
}

#[derive(Clone, Copy)]
/// A lobe while fitting: axis `a` (unit), weight `w`, Phong exponent `eta`.
pub(super) struct L {
    pub(super) a: DVec3,
    pub(super) w: f64,
    pub(super) eta: f64,
}

/// Spherical k-means with a greedy weighted k-means++ start (first centre: the heaviest entry;
/// then the entry maximising weight × squared chord distance to the nearest centre), 5 Lloyd
/// steps, then lobes with the cluster shares and the closed-form exponent of each cluster.
pub(super) fn kmeans_init(pts: &[Pt], k: usize) -> Vec<L> {
    // The unit directions of the points, normalised once (the seeding passes read them k − 1
    // times).
    let dirs: Vec<DVec3> = pts.iter().map(|e| e.0.normalize()).collect();
    let mut centres: Vec<DVec3> = Vec::with_capacity(k);
    let first = pts
        .iter()
        .zip(&dirs)
        .max_by(|a, b| a.0 .1.total_cmp(&b.0 .1))
        .map(|e| *e.1)
        .unwrap_or(DVec3::Z);
    centres.push(first);
    while centres.len() < k {
        let mut best = (-1.0, DVec3::Z);
        for (e, &d) in pts.iter().zip(&dirs) {
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
            let j = nearest(&centres, d);
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
        let j = nearest(&centres, d);
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

/// The index of the centre of largest `c·d` (the last of equal ones, as `Iterator::max_by`
/// with `total_cmp` picks it), each dot product computed once.
#[inline]
fn nearest(centres: &[DVec3], d: DVec3) -> usize {
    let mut best = (0, f64::NEG_INFINITY);
    for (j, c) in centres.iter().enumerate() {
        let v = c.dot(d);
        if j == 0 || v.total_cmp(&best.1) != std::cmp::Ordering::Less {
            best = (j, v);
        }
    }
    best.0
}

/// A point of EM: the mean vector of an entry (length ≤ 1) and its weight.
pub(super) type Pt = (DVec3, f64);

/// Mean log-likelihood per unit weight of the mixture.
pub(super) fn loglik(pts: &[Pt], lobes: &[L], total: f64) -> f64 {
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
pub(super) fn em(pts: &[Pt], lobes: &mut Vec<L>, total: f64, iters: usize) -> f64 {
    let mut prev = f64::NEG_INFINITY;
    let mut acc = Acc::default();
    for _ in 0..iters.max(1) {
        let k = lobes.len();
        if k == 0 {
            break;
        }
        // The E-step with the lobe count a constant (its loops unrolled, the per-lobe values
        // in registers); the same operations in the same order at every K.
        let ll = match k {
            1 => e_step::<1>(pts, lobes, &mut acc),
            2 => e_step::<2>(pts, lobes, &mut acc),
            3 => e_step::<3>(pts, lobes, &mut acc),
            4 => e_step::<4>(pts, lobes, &mut acc),
            5 => e_step::<5>(pts, lobes, &mut acc),
            6 => e_step::<6>(pts, lobes, &mut acc),
            7 => e_step::<7>(pts, lobes, &mut acc),
            _ => e_step::<MAX_LOBES>(pts, lobes, &mut acc),
        };
        for j in 0..k {
            if acc.w[j] <= 1e-12 * total {
                lobes[j].w = 0.0;
                continue;
            }
            lobes[j].w = acc.w[j] / total;
            if acc.a[j].length_squared() > 0.0 {
                lobes[j].a = acc.a[j].normalize();
            }
            lobes[j].eta = eta_from_mean_t(acc.t[j] / acc.w[j]);
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

/// The sums of one E-step per lobe: the responsibilities, the responsibility-weighted normals
/// over `1 + a·m` (the axis update) and the responsibility-weighted `t`.
#[derive(Default)]
struct Acc {
    w: [f64; MAX_LOBES],
    a: [DVec3; MAX_LOBES],
    t: [f64; MAX_LOBES],
}

/// One E-step of [`em`] over `K` = `lobes.len()` lobes: fills `acc` and returns the summed
/// log-likelihood (not yet divided by the total weight).
#[inline(always)]
fn e_step<const K: usize>(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
    debug_assert_eq!(lobes.len(), K);
    let mut c = [0.0f64; K];
    let mut a = [DVec3::ZERO; K];
    let mut eta = [0.0f64; K];
    for j in 0..K {
        c[j] = lobes[j].w.max(1e-300).ln() + ((lobes[j].eta + 2.0) / (8.0 * PI)).ln();
        a[j] = lobes[j].a;
        eta[j] = lobes[j].eta;
    }
    let mut acc_w = [0.0f64; K];
    let mut acc_a = [DVec3::ZERO; K];
    let mut acc_t = [0.0f64; K];
    let mut logd = [0.0f64; K];
    let mut lt = [0.0f64; K];
    let mut inv = [0.0f64; K];
    let mut ll = 0.0;
    for &(m, w) in pts {
        let mut mx = f64::NEG_INFINITY;
        for j in 0..K {
            let x = (0.5 * (1.0 + a[j].dot(m))).max(1e-300);
            lt[j] = fast_ln(x);
            inv[j] = 0.5 / x.max(0.5e-6);
            logd[j] = c[j] + 0.5 * eta[j] * lt[j];
            mx = mx.max(logd[j]);
        }
        if K == 1 {
            ll += w * logd[0];
            acc_w[0] += w;
            acc_a[0] += m * (w * inv[0]);
            acc_t[0] += w * lt[0];
            continue;
        }
        let mut s = 0.0;
        for v in &mut logd {
            *v = fast_exp_neg(*v - mx);
            s += *v;
        }
        ll += w * (mx + fast_ln(s));
        let ws = w / s;
        for j in 0..K {
            let r = ws * logd[j];
            acc_w[j] += r;
            acc_a[j] += m * (r * inv[j]);
            acc_t[j] += r * lt[j];
        }
    }
    acc.w[..K].copy_from_slice(&acc_w);
    acc.a[..K].copy_from_slice(&acc_a);
    acc.t[..K].copy_from_slice(&acc_t);
    ll
}

/// Split the heaviest lobe of `lobes` into a concentric pair (same axis, exponents ×2.5 and
/// ÷2.5): the start that lets EM model a peak sharper and tails heavier than one Phong peak
/// (e.g. the Gaussian slopes of a random surface), which k-means starts cannot.
pub(super) fn split_heaviest(lobes: &[L]) -> Vec<L> {
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
