//! The maximum-likelihood start of the lobe fit (parent module docs): spherical k-means seeds,
//! EM on the mixture of Phong peaks with its closed-form M-step, the split start, and the fast
//! `ln` / `exp` of EM's inner loop.

use crate::limits::{ETA_MAX, MAX_LOBES};
use glam::DVec3;
use meso_core::fastmath::{fast_exp_neg, fast_ln};
use std::f64::consts::PI;

/// The Horner coefficients after `1/8!` of the Taylor polynomial of `meso_core::fastmath::fast_exp_neg`,
/// shared by its two- and four-lane copies (`pairs::exp_neg`, `quads::exp_neg`).
#[cfg(target_arch = "x86_64")]
pub(super) const EXP_TAYLOR: [f64; 7] = [
    1.0 / 5040.0,
    1.0 / 720.0,
    1.0 / 120.0,
    1.0 / 24.0,
    1.0 / 6.0,
    0.5,
    1.0,
];

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
#[cfg(test)]
pub(super) fn kmeans_init(pts: &[Pt], k: usize) -> Vec<L> {
    kmeans_from(pts, &mut KmeansSeeds::new(pts), k)
}

/// The unit directions of a set of k-means points and their greedy k-means++ seeds
/// ([`kmeans_from`]), computed once for every K: the seeds of k centres are the first k of the
/// seeds of more (each seed depends only on those before it), so the fits at K = 2, 3, 4 share
/// the directions and the seeding passes (the same numbers as seeding each K afresh).
pub(super) struct KmeansSeeds {
    dirs: Vec<DVec3>,
    centres: Vec<DVec3>,
}

impl KmeansSeeds {
    /// The directions of `pts`, normalised once, and the first seed (the heaviest point's).
    pub(super) fn new(pts: &[Pt]) -> KmeansSeeds {
        let dirs: Vec<DVec3> = pts.iter().map(|e| e.0.normalize()).collect();
        let first = pts
            .iter()
            .zip(&dirs)
            .max_by(|a, b| a.0 .1.total_cmp(&b.0 .1))
            .map(|e| *e.1)
            .unwrap_or(DVec3::Z);
        let mut centres = Vec::with_capacity(MAX_LOBES);
        centres.push(first);
        KmeansSeeds { dirs, centres }
    }

    /// The first `k` seeds of `pts` (the points `new` was given), seeded as far as needed.
    fn seeds(&mut self, pts: &[Pt], k: usize) -> &[DVec3] {
        while self.centres.len() < k {
            let mut best = (-1.0, DVec3::Z);
            for (e, &d) in pts.iter().zip(&self.dirs) {
                let dist = self
                    .centres
                    .iter()
                    .map(|c| 2.0 - 2.0 * c.dot(d))
                    .fold(f64::INFINITY, f64::min);
                if e.1 * dist > best.0 {
                    best = (e.1 * dist, d);
                }
            }
            self.centres.push(best.1);
        }
        &self.centres[..k]
    }
}

/// Spherical k-means of `pts` into `k` ≤ [`MAX_LOBES`] clusters from the seeds of `seeds` (made
/// by [`KmeansSeeds::new`] from the same points): 5 Lloyd steps, then lobes with the cluster
/// shares and the closed-form exponent of each cluster.
pub(super) fn kmeans_from(pts: &[Pt], seeds: &mut KmeansSeeds, k: usize) -> Vec<L> {
    assert!(k <= MAX_LOBES, "at most MAX_LOBES clusters");
    let mut centres = [DVec3::Z; MAX_LOBES];
    centres[..k].copy_from_slice(seeds.seeds(pts, k));
    let centres = &mut centres[..k];
    let mut sums = [(DVec3::ZERO, 0.0f64, 0.0f64); MAX_LOBES];
    let sums = &mut sums[..k];
    for _ in 0..5 {
        sums.iter_mut().for_each(|s| *s = (DVec3::ZERO, 0.0, 0.0));
        for &(d, w) in pts {
            let j = nearest(centres, d);
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
        let j = nearest(centres, d);
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

/// Mean log-likelihood per unit weight of the mixture: the E-step's (`e_step_k`, SIMD), whose
/// log-likelihood is this sum bit for bit ([`loglik_scalar`]: with one lobe `ln` of the sum
/// `e⁰ = 1` adds exactly 0; Rust's `f64` sum starts at −0, which adds nothing to the
/// non-negative terms).
pub(super) fn loglik(pts: &[Pt], lobes: &[L], total: f64) -> f64 {
    if lobes.is_empty() || lobes.len() > MAX_LOBES {
        return loglik_scalar(pts, lobes, total);
    }
    e_step_k(pts, lobes, &mut Acc::default()) / total
}

/// [`loglik`] written out, one lobe at a time.
fn loglik_scalar(pts: &[Pt], lobes: &[L], total: f64) -> f64 {
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
        let ll = e_step_k(pts, lobes, &mut acc);
        for (j, l) in lobes.iter_mut().enumerate() {
            if acc.w[j] <= 1e-12 * total {
                l.w = 0.0;
                continue;
            }
            l.w = acc.w[j] / total;
            if acc.a[j].length_squared() > 0.0 {
                l.a = acc.a[j].normalize();
            }
            l.eta = eta_from_mean_t(acc.t[j] / acc.w[j]);
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

/// One E-step over `lobes` (1..=[`MAX_LOBES`] of them): fills `acc` and returns the summed
/// log-likelihood (not yet divided by the total weight). The lobe count a constant (its loops
/// unrolled, the per-lobe values in registers), in SIMD registers where the CPU has them; the
/// same operations in the same order at every K and on every path.
fn e_step_k(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
    match lobes.len() {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: AVX2 only where the CPU has it.
        1 if quads::available() => unsafe { quads::e_step_1(pts, lobes, acc) },
        1 => e_step::<1>(pts, lobes, acc),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: AVX2 only where the CPU has it; SSE2 is part of every x86-64 CPU.
        2 => unsafe {
            if quads::available() {
                quads::e_step_2(pts, lobes, acc)
            } else {
                pairs::e_step::<2, 1>(pts, lobes, acc)
            }
        },
        #[cfg(target_arch = "x86_64")]
        3 => e_step_3_4::<3>(pts, lobes, acc),
        #[cfg(target_arch = "x86_64")]
        4 => e_step_3_4::<4>(pts, lobes, acc),
        #[cfg(not(target_arch = "x86_64"))]
        2 => e_step::<2>(pts, lobes, acc),
        #[cfg(not(target_arch = "x86_64"))]
        3 => e_step::<3>(pts, lobes, acc),
        #[cfg(not(target_arch = "x86_64"))]
        4 => e_step::<4>(pts, lobes, acc),
        5 => e_step::<5>(pts, lobes, acc),
        6 => e_step::<6>(pts, lobes, acc),
        7 => e_step::<7>(pts, lobes, acc),
        _ => e_step::<MAX_LOBES>(pts, lobes, acc),
    }
}

/// [`e_step_k`] for `K` = 3 or 4 lobes on x86-64: two points per AVX-512 register where the CPU
/// has it, else one per AVX2 register, else two lobes per SSE2 register.
#[cfg(target_arch = "x86_64")]
fn e_step_3_4<const K: usize>(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
    // SAFETY: AVX-512 and AVX2 only where the CPU has them; SSE2 is part of every x86-64 CPU.
    unsafe {
        if quads::avx512() {
            quads::e_step_x2::<K>(pts, lobes, acc)
        } else if quads::available() {
            quads::e_step::<K>(pts, lobes, acc)
        } else {
            pairs::e_step::<K, 2>(pts, lobes, acc)
        }
    }
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

/// [`e_step`] for 2–4 lobes with the lobes in pairs, two per SSE2 register (every x86-64 CPU
/// has SSE2): each lane does exactly the scalar operations of its lobe (`fast_ln` and
/// `fast_exp_neg` written out lane-wise, the sums over the points and over the lobes in the
/// scalar order, no fused multiply-adds), so the results are bit for bit those of [`e_step`].
#[cfg(target_arch = "x86_64")]
pub(super) mod pairs {
    use super::{Acc, Pt, L};
    use glam::DVec3;
    use meso_core::fastmath::fast_ln;
    use std::arch::x86_64::{
        __m128d, _mm_add_pd, _mm_and_pd, _mm_and_si128, _mm_andnot_pd, _mm_castpd_si128,
        _mm_castsi128_pd, _mm_cmpgt_pd, _mm_cmplt_pd, _mm_cvtepi32_pd, _mm_cvtsd_f64,
        _mm_cvttpd_epi32, _mm_div_pd, _mm_max_pd, _mm_mul_pd, _mm_or_pd, _mm_or_si128,
        _mm_set1_epi64x, _mm_set1_pd, _mm_set_pd, _mm_setzero_pd, _mm_slli_epi64, _mm_srli_epi64,
        _mm_sub_pd, _mm_unpackhi_pd,
    };
    use std::f64::consts::{LN_2, LOG2_E, PI, SQRT_2};

    /// 2^52: or-ed onto a small integer's bits, the double `2^52 + n`.
    const TWO52: f64 = 4_503_599_627_370_496.0;

    #[inline]
    #[target_feature(enable = "sse2")]
    pub(in super::super) fn set(v: f64) -> __m128d {
        _mm_set1_pd(v)
    }

    #[inline]
    #[target_feature(enable = "sse2")]
    pub(in super::super) fn lanes(v: __m128d) -> [f64; 2] {
        [_mm_cvtsd_f64(v), _mm_cvtsd_f64(_mm_unpackhi_pd(v, v))]
    }

    /// `meso_core::fastmath::fast_ln` on two lanes of normal positive numbers (its subnormal
    /// fallback is never reached here: EM clamps its arguments to ≥ 1e-300).
    #[inline]
    #[target_feature(enable = "sse2")]
    pub(super) fn ln(x: __m128d) -> __m128d {
        let bits = _mm_castpd_si128(x);
        let eb = _mm_and_si128(_mm_srli_epi64::<52>(bits), _mm_set1_epi64x(0x7ff));
        // e = biased exponent − 1023, exactly, as a double.
        let e = _mm_sub_pd(
            _mm_castsi128_pd(_mm_or_si128(eb, _mm_castpd_si128(set(TWO52)))),
            set(TWO52 + 1023.0),
        );
        let m = _mm_castsi128_pd(_mm_or_si128(
            _mm_and_si128(bits, _mm_set1_epi64x(0x000f_ffff_ffff_ffff)),
            _mm_set1_epi64x(0x3ff0_0000_0000_0000),
        ));
        let big = _mm_cmpgt_pd(m, set(SQRT_2));
        let m = _mm_or_pd(
            _mm_and_pd(big, _mm_mul_pd(m, set(0.5))),
            _mm_andnot_pd(big, m),
        );
        let e = _mm_add_pd(e, _mm_and_pd(big, set(1.0)));
        let s = _mm_div_pd(_mm_sub_pd(m, set(1.0)), _mm_add_pd(m, set(1.0)));
        let s2 = _mm_mul_pd(s, s);
        let mut p = _mm_mul_pd(s2, set(2.0 / 9.0));
        p = _mm_mul_pd(s2, _mm_add_pd(set(2.0 / 7.0), p));
        p = _mm_mul_pd(s2, _mm_add_pd(set(0.4), p));
        p = _mm_mul_pd(s2, _mm_add_pd(set(2.0 / 3.0), p));
        let p = _mm_mul_pd(s, _mm_add_pd(set(2.0), p));
        _mm_add_pd(_mm_mul_pd(e, set(LN_2)), p)
    }

    /// `meso_core::fastmath::fast_exp_neg` on two lanes (`y ≤ 0`).
    #[inline]
    #[target_feature(enable = "sse2")]
    pub(in super::super) fn exp_neg(y: __m128d) -> __m128d {
        let under = _mm_cmplt_pd(y, set(-700.0));
        // The truncation of `y·log₂e − ½` (in i32 range wherever the result is used).
        let ki = _mm_cvttpd_epi32(_mm_sub_pd(_mm_mul_pd(y, set(LOG2_E)), set(0.5)));
        let k = _mm_cvtepi32_pd(ki);
        let r = _mm_sub_pd(y, _mm_mul_pd(k, set(LN_2)));
        let mut p = _mm_mul_pd(r, set(1.0 / 40320.0));
        for c in super::EXP_TAYLOR {
            p = _mm_mul_pd(r, _mm_add_pd(set(c), p));
        }
        let p = _mm_add_pd(set(1.0), p);
        // 2^k: the biased exponent k + 1023 (13..=1023 where used) shifted into place.
        let kb = _mm_castpd_si128(_mm_add_pd(_mm_add_pd(k, set(1023.0)), set(TWO52)));
        let scale = _mm_castsi128_pd(_mm_slli_epi64::<52>(kb));
        _mm_andnot_pd(under, _mm_mul_pd(p, scale))
    }

    /// [`super::e_step`] for `K` ∈ 2..=4 lobes in `NV` = ⌈K/2⌉ pairs.
    #[inline]
    #[target_feature(enable = "sse2")]
    pub(super) fn e_step<const K: usize, const NV: usize>(
        pts: &[Pt],
        lobes: &[L],
        acc: &mut Acc,
    ) -> f64 {
        debug_assert!(lobes.len() == K && K.div_ceil(2) == NV && (2..=4).contains(&K));
        // Per lobe: axis components, half the exponent, ln-weight plus ln-normaliser; a
        // missing fourth lobe has the density e^−∞ (its lane's responsibility is exactly 0, and
        // it is left out of the maximum and the sum over the lobes).
        let mut p = [[0.0f64; 4]; 5];
        p[4] = [f64::NEG_INFINITY; 4];
        for (j, l) in lobes.iter().enumerate() {
            p[0][j] = l.a.x;
            p[1][j] = l.a.y;
            p[2][j] = l.a.z;
            p[3][j] = 0.5 * l.eta;
            p[4][j] = l.w.max(1e-300).ln() + ((l.eta + 2.0) / (8.0 * PI)).ln();
        }
        let zero = _mm_setzero_pd();
        let (mut ax, mut ay, mut az, mut half_eta, mut c) =
            ([zero; NV], [zero; NV], [zero; NV], [zero; NV], [zero; NV]);
        for v in 0..NV {
            let pair = |q: &[f64; 4]| _mm_set_pd(q[2 * v + 1], q[2 * v]);
            ax[v] = pair(&p[0]);
            ay[v] = pair(&p[1]);
            az[v] = pair(&p[2]);
            half_eta[v] = pair(&p[3]);
            c[v] = pair(&p[4]);
        }
        let mut acc_w = [zero; NV];
        let mut acc_x = [zero; NV];
        let mut acc_y = [zero; NV];
        let mut acc_z = [zero; NV];
        let mut acc_t = [zero; NV];
        let mut ll = 0.0;
        for &(m, w) in pts {
            let (mx, my, mz) = (set(m.x), set(m.y), set(m.z));
            let mut lt = [zero; NV];
            let mut inv = [zero; NV];
            let mut logd = [zero; NV];
            let mut ld = [0.0f64; 4];
            for v in 0..NV {
                let d = _mm_add_pd(
                    _mm_add_pd(_mm_mul_pd(ax[v], mx), _mm_mul_pd(ay[v], my)),
                    _mm_mul_pd(az[v], mz),
                );
                let x = _mm_max_pd(_mm_mul_pd(set(0.5), _mm_add_pd(set(1.0), d)), set(1e-300));
                lt[v] = ln(x);
                inv[v] = _mm_div_pd(set(0.5), _mm_max_pd(x, set(0.5e-6)));
                logd[v] = _mm_add_pd(c[v], _mm_mul_pd(half_eta[v], lt[v]));
                let [l0, l1] = lanes(logd[v]);
                ld[2 * v] = l0;
                ld[2 * v + 1] = l1;
            }
            let mut top = f64::NEG_INFINITY;
            for &l in &ld[..K] {
                top = top.max(l);
            }
            let mut s = 0.0;
            let mut e = [zero; NV];
            for v in 0..NV {
                e[v] = exp_neg(_mm_sub_pd(logd[v], set(top)));
                let [e0, e1] = lanes(e[v]);
                s += e0;
                if 2 * v + 1 < K {
                    s += e1;
                }
            }
            ll += w * (top + fast_ln(s));
            let ws = set(w / s);
            for v in 0..NV {
                let r = _mm_mul_pd(ws, e[v]);
                acc_w[v] = _mm_add_pd(acc_w[v], r);
                let q = _mm_mul_pd(r, inv[v]);
                acc_x[v] = _mm_add_pd(acc_x[v], _mm_mul_pd(mx, q));
                acc_y[v] = _mm_add_pd(acc_y[v], _mm_mul_pd(my, q));
                acc_z[v] = _mm_add_pd(acc_z[v], _mm_mul_pd(mz, q));
                acc_t[v] = _mm_add_pd(acc_t[v], _mm_mul_pd(r, lt[v]));
            }
        }
        for v in 0..NV {
            let (w, x, y, z, t) = (
                lanes(acc_w[v]),
                lanes(acc_x[v]),
                lanes(acc_y[v]),
                lanes(acc_z[v]),
                lanes(acc_t[v]),
            );
            for i in 0..2 {
                let j = 2 * v + i;
                if j < K {
                    acc.w[j] = w[i];
                    acc.a[j] = DVec3::new(x[i], y[i], z[i]);
                    acc.t[j] = t[i];
                }
            }
        }
        ll
    }
}

/// [`e_step`] for 3 and 4 lobes in one AVX2 register (four lanes), where the CPU has AVX2
/// (detected at run time; otherwise [`pairs`]): each lane does exactly the scalar operations of
/// its lobe, as in [`pairs`] (no fused multiply-adds, the sums over the lobes in the scalar
/// order), so the results are bit for bit those of [`e_step`]; one register pass per point
/// instead of two halves EM's arithmetic at K = 3–4, most of the fine levels' EM.
#[cfg(target_arch = "x86_64")]
pub(super) mod quads {
    use super::{Acc, Pt, L};
    use glam::DVec3;
    use meso_core::fastmath::{fast_exp_neg, fast_ln};
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_and_pd, _mm256_and_si256, _mm256_andnot_pd,
        _mm256_castpd_si256, _mm256_castsi256_pd, _mm256_cmp_pd, _mm256_cvtepi32_pd,
        _mm256_cvttpd_epi32, _mm256_div_pd, _mm256_max_pd, _mm256_mul_pd, _mm256_or_pd,
        _mm256_or_si256, _mm256_set1_epi64x, _mm256_set1_pd, _mm256_set_pd, _mm256_setzero_pd,
        _mm256_slli_epi64, _mm256_srli_epi64, _mm256_storeu_pd, _mm256_sub_pd, _CMP_GT_OQ,
        _CMP_LT_OQ,
    };
    use std::f64::consts::{LN_2, LOG2_E, PI, SQRT_2};

    /// 2^52: or-ed onto a small integer's bits, the double `2^52 + n`.
    const TWO52: f64 = 4_503_599_627_370_496.0;

    /// Whether this CPU has AVX2 (cached by the standard library).
    #[inline]
    pub(in super::super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx2")
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    pub(in super::super) fn set(v: f64) -> __m256d {
        _mm256_set1_pd(v)
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    pub(in super::super) fn lanes(v: __m256d) -> [f64; 4] {
        let mut out = [0.0; 4];
        // SAFETY: `out` has room for four doubles (unaligned store).
        unsafe { _mm256_storeu_pd(out.as_mut_ptr(), v) };
        out
    }

    /// `meso_core::fastmath::fast_ln` on four lanes of normal positive numbers (as
    /// `pairs::ln`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn ln(x: __m256d) -> __m256d {
        let bits = _mm256_castpd_si256(x);
        let eb = _mm256_and_si256(_mm256_srli_epi64::<52>(bits), _mm256_set1_epi64x(0x7ff));
        let e = _mm256_sub_pd(
            _mm256_castsi256_pd(_mm256_or_si256(eb, _mm256_castpd_si256(set(TWO52)))),
            set(TWO52 + 1023.0),
        );
        let m = _mm256_castsi256_pd(_mm256_or_si256(
            _mm256_and_si256(bits, _mm256_set1_epi64x(0x000f_ffff_ffff_ffff)),
            _mm256_set1_epi64x(0x3ff0_0000_0000_0000),
        ));
        let big = _mm256_cmp_pd::<_CMP_GT_OQ>(m, set(SQRT_2));
        let m = _mm256_or_pd(
            _mm256_and_pd(big, _mm256_mul_pd(m, set(0.5))),
            _mm256_andnot_pd(big, m),
        );
        let e = _mm256_add_pd(e, _mm256_and_pd(big, set(1.0)));
        let s = _mm256_div_pd(_mm256_sub_pd(m, set(1.0)), _mm256_add_pd(m, set(1.0)));
        let s2 = _mm256_mul_pd(s, s);
        let mut p = _mm256_mul_pd(s2, set(2.0 / 9.0));
        p = _mm256_mul_pd(s2, _mm256_add_pd(set(2.0 / 7.0), p));
        p = _mm256_mul_pd(s2, _mm256_add_pd(set(0.4), p));
        p = _mm256_mul_pd(s2, _mm256_add_pd(set(2.0 / 3.0), p));
        let p = _mm256_mul_pd(s, _mm256_add_pd(set(2.0), p));
        _mm256_add_pd(_mm256_mul_pd(e, set(LN_2)), p)
    }

    /// `meso_core::fastmath::fast_exp_neg` on four lanes (`y ≤ 0`; as `pairs::exp_neg`).
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(in super::super) fn exp_neg(y: __m256d) -> __m256d {
        let under = _mm256_cmp_pd::<_CMP_LT_OQ>(y, set(-700.0));
        let ki = _mm256_cvttpd_epi32(_mm256_sub_pd(_mm256_mul_pd(y, set(LOG2_E)), set(0.5)));
        let k = _mm256_cvtepi32_pd(ki);
        let r = _mm256_sub_pd(y, _mm256_mul_pd(k, set(LN_2)));
        let mut p = _mm256_mul_pd(r, set(1.0 / 40320.0));
        for c in super::EXP_TAYLOR {
            p = _mm256_mul_pd(r, _mm256_add_pd(set(c), p));
        }
        let p = _mm256_add_pd(set(1.0), p);
        let kb = _mm256_castpd_si256(_mm256_add_pd(_mm256_add_pd(k, set(1023.0)), set(TWO52)));
        let scale = _mm256_castsi256_pd(_mm256_slli_epi64::<52>(kb));
        _mm256_andnot_pd(under, _mm256_mul_pd(p, scale))
    }

    /// [`super::e_step`] for one lobe with four points per register: each lane the scalar
    /// operations of its point (the dot product, `fast_ln`, the division), the sums over the
    /// points then added in the points' order, so the results are bit for bit the scalar ones.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn e_step_1(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
        debug_assert_eq!(lobes.len(), 1);
        let l = lobes[0];
        let c = l.w.max(1e-300).ln() + ((l.eta + 2.0) / (8.0 * PI)).ln();
        let half_eta = 0.5 * l.eta;
        let (ax, ay, az) = (set(l.a.x), set(l.a.y), set(l.a.z));
        let (mut acc_w, mut acc_a, mut acc_t, mut ll) = (0.0, DVec3::ZERO, 0.0, 0.0);
        let quads = pts.chunks_exact(4);
        let rest = quads.remainder();
        for q in quads {
            let comp = |f: fn(&Pt) -> f64| _mm256_set_pd(f(&q[3]), f(&q[2]), f(&q[1]), f(&q[0]));
            let (mx, my, mz, w) = (
                comp(|p| p.0.x),
                comp(|p| p.0.y),
                comp(|p| p.0.z),
                comp(|p| p.1),
            );
            let d = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(ax, mx), _mm256_mul_pd(ay, my)),
                _mm256_mul_pd(az, mz),
            );
            let x = _mm256_max_pd(
                _mm256_mul_pd(set(0.5), _mm256_add_pd(set(1.0), d)),
                set(1e-300),
            );
            let lt = ln(x);
            let inv = _mm256_div_pd(set(0.5), _mm256_max_pd(x, set(0.5e-6)));
            let logd = _mm256_add_pd(set(c), _mm256_mul_pd(set(half_eta), lt));
            let qv = _mm256_mul_pd(w, inv);
            let (wl, ww, wt) = (
                lanes(_mm256_mul_pd(w, logd)),
                lanes(w),
                lanes(_mm256_mul_pd(w, lt)),
            );
            let (qx, qy, qz) = (
                lanes(_mm256_mul_pd(mx, qv)),
                lanes(_mm256_mul_pd(my, qv)),
                lanes(_mm256_mul_pd(mz, qv)),
            );
            for i in 0..4 {
                ll += wl[i];
                acc_w += ww[i];
                acc_a += DVec3::new(qx[i], qy[i], qz[i]);
                acc_t += wt[i];
            }
        }
        for &(m, w) in rest {
            let x = (0.5 * (1.0 + l.a.dot(m))).max(1e-300);
            let lt = fast_ln(x);
            let inv = 0.5 / x.max(0.5e-6);
            let logd = c + half_eta * lt;
            ll += w * logd;
            acc_w += w;
            acc_a += m * (w * inv);
            acc_t += w * lt;
        }
        acc.w[0] = acc_w;
        acc.a[0] = acc_a;
        acc.t[0] = acc_t;
        ll
    }

    /// [`super::e_step`] for two lobes with two points per register (lanes: point 0's lobes,
    /// then point 1's): each lane the scalar operations of its point and lobe, the maximum, the
    /// sum over the lobes and the `ln` of each point in the scalar order, the sums over the
    /// points added in the points' order; bit for bit the scalar results.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn e_step_2(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
        use std::arch::x86_64::{
            _mm256_castpd256_pd128, _mm256_extractf128_pd, _mm_add_pd, _mm_setzero_pd,
            _mm_storeu_pd,
        };
        debug_assert_eq!(lobes.len(), 2);
        let cj = |l: &L| l.w.max(1e-300).ln() + ((l.eta + 2.0) / (8.0 * PI)).ln();
        let (l0, l1) = (lobes[0], lobes[1]);
        let (c0, c1) = (cj(&l0), cj(&l1));
        let two = |a: f64, b: f64| _mm256_set_pd(b, a, b, a);
        let (ax, ay, az) = (
            two(l0.a.x, l1.a.x),
            two(l0.a.y, l1.a.y),
            two(l0.a.z, l1.a.z),
        );
        let (half_eta, c) = (two(0.5 * l0.eta, 0.5 * l1.eta), two(c0, c1));
        let z = _mm_setzero_pd();
        let (mut acc_w, mut acc_x, mut acc_y, mut acc_z, mut acc_t) = (z, z, z, z, z);
        let mut ll = 0.0;
        let pairs = pts.chunks_exact(2);
        let rest = pairs.remainder();
        // Adds the low half (point 0) then the high half (point 1) of `v` onto `a`.
        let add2 = |a: &mut std::arch::x86_64::__m128d, v: __m256d| {
            *a = _mm_add_pd(*a, _mm256_castpd256_pd128(v));
            *a = _mm_add_pd(*a, _mm256_extractf128_pd::<1>(v));
        };
        for p in pairs {
            let ((m0, w0), (m1, w1)) = (p[0], p[1]);
            let (mx, my, mz) = (
                _mm256_set_pd(m1.x, m1.x, m0.x, m0.x),
                _mm256_set_pd(m1.y, m1.y, m0.y, m0.y),
                _mm256_set_pd(m1.z, m1.z, m0.z, m0.z),
            );
            let d = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(ax, mx), _mm256_mul_pd(ay, my)),
                _mm256_mul_pd(az, mz),
            );
            let x = _mm256_max_pd(
                _mm256_mul_pd(set(0.5), _mm256_add_pd(set(1.0), d)),
                set(1e-300),
            );
            let lt = ln(x);
            let inv = _mm256_div_pd(set(0.5), _mm256_max_pd(x, set(0.5e-6)));
            let logd = _mm256_add_pd(c, _mm256_mul_pd(half_eta, lt));
            let ld = lanes(logd);
            let top0 = f64::NEG_INFINITY.max(ld[0]).max(ld[1]);
            let top1 = f64::NEG_INFINITY.max(ld[2]).max(ld[3]);
            let e = exp_neg(_mm256_sub_pd(logd, _mm256_set_pd(top1, top1, top0, top0)));
            let el = lanes(e);
            let s0 = 0.0 + el[0] + el[1];
            let s1 = 0.0 + el[2] + el[3];
            ll += w0 * (top0 + fast_ln(s0));
            ll += w1 * (top1 + fast_ln(s1));
            let (ws0, ws1) = (w0 / s0, w1 / s1);
            let r = _mm256_mul_pd(_mm256_set_pd(ws1, ws1, ws0, ws0), e);
            add2(&mut acc_w, r);
            let q = _mm256_mul_pd(r, inv);
            add2(&mut acc_x, _mm256_mul_pd(mx, q));
            add2(&mut acc_y, _mm256_mul_pd(my, q));
            add2(&mut acc_z, _mm256_mul_pd(mz, q));
            add2(&mut acc_t, _mm256_mul_pd(r, lt));
        }
        let out = |v: std::arch::x86_64::__m128d| {
            let mut o = [0.0; 2];
            // SAFETY: `o` has room for two doubles (unaligned store).
            unsafe { _mm_storeu_pd(o.as_mut_ptr(), v) };
            o
        };
        let (w, x, y, zz, t) = (out(acc_w), out(acc_x), out(acc_y), out(acc_z), out(acc_t));
        let mut sums = Acc::default();
        for j in 0..2 {
            sums.w[j] = w[j];
            sums.a[j] = DVec3::new(x[j], y[j], zz[j]);
            sums.t[j] = t[j];
        }
        // The odd last point: the scalar E-step's body, continuing the sums.
        for &(m, w) in rest {
            let mut logd = [0.0f64; 2];
            let mut lt = [0.0f64; 2];
            let mut inv = [0.0f64; 2];
            let mut mx = f64::NEG_INFINITY;
            for (j, l) in [l0, l1].iter().enumerate() {
                let x = (0.5 * (1.0 + l.a.dot(m))).max(1e-300);
                lt[j] = fast_ln(x);
                inv[j] = 0.5 / x.max(0.5e-6);
                logd[j] = [c0, c1][j] + 0.5 * l.eta * lt[j];
                mx = mx.max(logd[j]);
            }
            let mut s = 0.0;
            for v in &mut logd {
                *v = fast_exp_neg(*v - mx);
                s += *v;
            }
            ll += w * (mx + fast_ln(s));
            let ws = w / s;
            for j in 0..2 {
                let r = ws * logd[j];
                sums.w[j] += r;
                sums.a[j] += m * (r * inv[j]);
                sums.t[j] += r * lt[j];
            }
        }
        acc.w[..2].copy_from_slice(&sums.w[..2]);
        acc.a[..2].copy_from_slice(&sums.a[..2]);
        acc.t[..2].copy_from_slice(&sums.t[..2]);
        ll
    }

    /// The per-lobe constants of [`e_step`]'s lanes: axis components, half the exponent, and
    /// ln-weight plus ln-normaliser (a missing fourth lobe has the density e^−∞, as in
    /// `pairs::e_step`: its lane's responsibility is exactly 0).
    fn lobe_lanes(lobes: &[L]) -> [[f64; 4]; 5] {
        let mut p = [[0.0f64; 4]; 5];
        p[4] = [f64::NEG_INFINITY; 4];
        for (j, l) in lobes.iter().enumerate() {
            p[0][j] = l.a.x;
            p[1][j] = l.a.y;
            p[2][j] = l.a.z;
            p[3][j] = 0.5 * l.eta;
            p[4][j] = l.w.max(1e-300).ln() + ((l.eta + 2.0) / (8.0 * PI)).ln();
        }
        p
    }

    /// The sums of [`e_step`] over the points so far, one lobe per lane.
    #[derive(Clone, Copy)]
    pub(super) struct Sums {
        w: __m256d,
        x: __m256d,
        y: __m256d,
        z: __m256d,
        t: __m256d,
        ll: f64,
    }

    impl Sums {
        #[inline]
        #[target_feature(enable = "avx2")]
        fn new() -> Sums {
            let zero = _mm256_setzero_pd();
            Sums {
                w: zero,
                x: zero,
                y: zero,
                z: zero,
                t: zero,
                ll: 0.0,
            }
        }

        #[inline]
        #[target_feature(enable = "avx2")]
        fn finish<const K: usize>(&self, acc: &mut Acc) -> f64 {
            let (w, x, y, z, t) = (
                lanes(self.w),
                lanes(self.x),
                lanes(self.y),
                lanes(self.z),
                lanes(self.t),
            );
            for j in 0..K {
                acc.w[j] = w[j];
                acc.a[j] = DVec3::new(x[j], y[j], z[j]);
                acc.t[j] = t[j];
            }
            self.ll
        }
    }

    /// One point of [`e_step`] added onto `sums` (lobe constants as [`lobe_lanes`] lays them
    /// out, in registers: `ax, ay, az, half_eta, c`).
    #[inline]
    #[target_feature(enable = "avx2")]
    fn point<const K: usize>(lob: &[__m256d; 5], m: DVec3, w: f64, sums: &mut Sums) {
        let [ax, ay, az, half_eta, c] = *lob;
        let (mx, my, mz) = (set(m.x), set(m.y), set(m.z));
        let d = _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(ax, mx), _mm256_mul_pd(ay, my)),
            _mm256_mul_pd(az, mz),
        );
        let x = _mm256_max_pd(
            _mm256_mul_pd(set(0.5), _mm256_add_pd(set(1.0), d)),
            set(1e-300),
        );
        let lt = ln(x);
        let inv = _mm256_div_pd(set(0.5), _mm256_max_pd(x, set(0.5e-6)));
        let logd = _mm256_add_pd(c, _mm256_mul_pd(half_eta, lt));
        let ld = lanes(logd);
        let mut top = f64::NEG_INFINITY;
        for &l in &ld[..K] {
            top = top.max(l);
        }
        let e = exp_neg(_mm256_sub_pd(logd, set(top)));
        let el = lanes(e);
        let mut s = 0.0;
        for &v in &el[..K] {
            s += v;
        }
        sums.ll += w * (top + fast_ln(s));
        let r = _mm256_mul_pd(set(w / s), e);
        sums.w = _mm256_add_pd(sums.w, r);
        let q = _mm256_mul_pd(r, inv);
        sums.x = _mm256_add_pd(sums.x, _mm256_mul_pd(mx, q));
        sums.y = _mm256_add_pd(sums.y, _mm256_mul_pd(my, q));
        sums.z = _mm256_add_pd(sums.z, _mm256_mul_pd(mz, q));
        sums.t = _mm256_add_pd(sums.t, _mm256_mul_pd(r, lt));
    }

    /// [`super::e_step`] for `K` ∈ 3..=4 lobes, one lobe per lane.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) fn e_step<const K: usize>(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
        debug_assert!(lobes.len() == K && (3..=4).contains(&K));
        let p = lobe_lanes(lobes);
        let quad = |q: &[f64; 4]| _mm256_set_pd(q[3], q[2], q[1], q[0]);
        let lob = [
            quad(&p[0]),
            quad(&p[1]),
            quad(&p[2]),
            quad(&p[3]),
            quad(&p[4]),
        ];
        let mut sums = Sums::new();
        for &(m, w) in pts {
            point::<K>(&lob, m, w, &mut sums);
        }
        sums.finish::<K>(acc)
    }

    /// Whether this CPU has AVX-512F (cached by the standard library).
    #[inline]
    pub(in super::super) fn avx512() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
    }

    /// [`e_step`] with two points per AVX-512 register (lanes 0–3 the first point's lobes, 4–7
    /// the second's; the CPU must have AVX-512F): each lane the scalar operations of its point
    /// and lobe (`fast_ln` and `fast_exp_neg` written out lane-wise, the `ln` of the two
    /// points' sums over the lobes in one SSE2 pair), the maximum and sum over the lobes in the
    /// scalar order, the sums over the points added point by point (the first point's half,
    /// then the second's); an odd last point by [`point`]. Bit for bit [`e_step`].
    #[inline]
    #[target_feature(enable = "avx512f")]
    pub(super) fn e_step_x2<const K: usize>(pts: &[Pt], lobes: &[L], acc: &mut Acc) -> f64 {
        use std::arch::x86_64::{
            __m512d, _mm512_add_pd, _mm512_and_si512, _mm512_castpd512_pd256, _mm512_castpd_si512,
            _mm512_castsi512_pd, _mm512_cmp_pd_mask, _mm512_cvtepi32_pd, _mm512_cvttpd_epi32,
            _mm512_div_pd, _mm512_extractf64x4_pd, _mm512_loadu_pd, _mm512_mask_add_pd,
            _mm512_mask_mul_pd, _mm512_maskz_mov_pd, _mm512_max_pd, _mm512_mul_pd, _mm512_or_si512,
            _mm512_set1_epi64, _mm512_set1_pd, _mm512_slli_epi64, _mm512_srli_epi64,
            _mm512_storeu_pd, _mm512_sub_pd,
        };
        debug_assert!(lobes.len() == K && (3..=4).contains(&K));
        let set8 = _mm512_set1_pd;
        let p = lobe_lanes(lobes);
        let quad = |q: &[f64; 4]| _mm256_set_pd(q[3], q[2], q[1], q[0]);
        let lob = [
            quad(&p[0]),
            quad(&p[1]),
            quad(&p[2]),
            quad(&p[3]),
            quad(&p[4]),
        ];
        let twice = |q: &[f64; 4]| {
            let a = [q[0], q[1], q[2], q[3], q[0], q[1], q[2], q[3]];
            // SAFETY: `a` holds eight doubles (unaligned load).
            unsafe { _mm512_loadu_pd(a.as_ptr()) }
        };
        let (ax, ay, az, half_eta, c) = (
            twice(&p[0]),
            twice(&p[1]),
            twice(&p[2]),
            twice(&p[3]),
            twice(&p[4]),
        );
        let halves = |a: f64, b: f64| {
            let v = [a, a, a, a, b, b, b, b];
            // SAFETY: `v` holds eight doubles (unaligned load).
            unsafe { _mm512_loadu_pd(v.as_ptr()) }
        };
        let lanes8 = |v: __m512d| {
            let mut o = [0.0; 8];
            // SAFETY: `o` has room for eight doubles (unaligned store).
            unsafe { _mm512_storeu_pd(o.as_mut_ptr(), v) };
            o
        };
        // `fast_ln` on eight lanes of normal positive numbers (as `ln`).
        let ln8 = |x: __m512d| {
            let bits = _mm512_castpd_si512(x);
            let eb = _mm512_and_si512(_mm512_srli_epi64::<52>(bits), _mm512_set1_epi64(0x7ff));
            let e = _mm512_sub_pd(
                _mm512_castsi512_pd(_mm512_or_si512(eb, _mm512_castpd_si512(set8(TWO52)))),
                set8(TWO52 + 1023.0),
            );
            let m = _mm512_castsi512_pd(_mm512_or_si512(
                _mm512_and_si512(bits, _mm512_set1_epi64(0x000f_ffff_ffff_ffff)),
                _mm512_set1_epi64(0x3ff0_0000_0000_0000),
            ));
            let big = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(m, set8(SQRT_2));
            let m = _mm512_mask_mul_pd(m, big, m, set8(0.5));
            let e = _mm512_mask_add_pd(e, big, e, set8(1.0));
            let s = _mm512_div_pd(_mm512_sub_pd(m, set8(1.0)), _mm512_add_pd(m, set8(1.0)));
            let s2 = _mm512_mul_pd(s, s);
            let mut q = _mm512_mul_pd(s2, set8(2.0 / 9.0));
            q = _mm512_mul_pd(s2, _mm512_add_pd(set8(2.0 / 7.0), q));
            q = _mm512_mul_pd(s2, _mm512_add_pd(set8(0.4), q));
            q = _mm512_mul_pd(s2, _mm512_add_pd(set8(2.0 / 3.0), q));
            let q = _mm512_mul_pd(s, _mm512_add_pd(set8(2.0), q));
            _mm512_add_pd(_mm512_mul_pd(e, set8(LN_2)), q)
        };
        // `fast_exp_neg` on eight lanes (`y ≤ 0`; as `exp_neg`).
        let exp8 = |y: __m512d| {
            let under = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(y, set8(-700.0));
            let ki = _mm512_cvttpd_epi32(_mm512_sub_pd(_mm512_mul_pd(y, set8(LOG2_E)), set8(0.5)));
            let k = _mm512_cvtepi32_pd(ki);
            let r = _mm512_sub_pd(y, _mm512_mul_pd(k, set8(LN_2)));
            let mut q = _mm512_mul_pd(r, set8(1.0 / 40320.0));
            for cf in super::EXP_TAYLOR {
                q = _mm512_mul_pd(r, _mm512_add_pd(set8(cf), q));
            }
            let q = _mm512_add_pd(set8(1.0), q);
            let kb =
                _mm512_castpd_si512(_mm512_add_pd(_mm512_add_pd(k, set8(1023.0)), set8(TWO52)));
            let scale = _mm512_castsi512_pd(_mm512_slli_epi64::<52>(kb));
            _mm512_maskz_mov_pd(!under, _mm512_mul_pd(q, scale))
        };
        // Adds the first point's half of `v` onto `a`, then the second's.
        let add2 = |a: &mut __m256d, v: __m512d| {
            *a = _mm256_add_pd(*a, _mm512_castpd512_pd256(v));
            *a = _mm256_add_pd(*a, _mm512_extractf64x4_pd::<1>(v));
        };
        let mut sums = Sums::new();
        let pairs = pts.chunks_exact(2);
        let rest = pairs.remainder();
        for pp in pairs {
            let ((m0, w0), (m1, w1)) = (pp[0], pp[1]);
            let (mx, my, mz) = (halves(m0.x, m1.x), halves(m0.y, m1.y), halves(m0.z, m1.z));
            let d = _mm512_add_pd(
                _mm512_add_pd(_mm512_mul_pd(ax, mx), _mm512_mul_pd(ay, my)),
                _mm512_mul_pd(az, mz),
            );
            let x = _mm512_max_pd(
                _mm512_mul_pd(set8(0.5), _mm512_add_pd(set8(1.0), d)),
                set8(1e-300),
            );
            let lt = ln8(x);
            let inv = _mm512_div_pd(set8(0.5), _mm512_max_pd(x, set8(0.5e-6)));
            let logd = _mm512_add_pd(c, _mm512_mul_pd(half_eta, lt));
            let ld = lanes8(logd);
            let (mut top0, mut top1) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
            for &l in &ld[..K] {
                top0 = top0.max(l);
            }
            for &l in &ld[4..4 + K] {
                top1 = top1.max(l);
            }
            let e = exp8(_mm512_sub_pd(logd, halves(top0, top1)));
            let el = lanes8(e);
            let (mut s0, mut s1) = (0.0, 0.0);
            for &v in &el[..K] {
                s0 += v;
            }
            for &v in &el[4..4 + K] {
                s1 += v;
            }
            let [ln0, ln1] =
                super::pairs::lanes(super::pairs::ln(std::arch::x86_64::_mm_set_pd(s1, s0)));
            sums.ll += w0 * (top0 + ln0);
            sums.ll += w1 * (top1 + ln1);
            let r = _mm512_mul_pd(halves(w0 / s0, w1 / s1), e);
            add2(&mut sums.w, r);
            let q = _mm512_mul_pd(r, inv);
            add2(&mut sums.x, _mm512_mul_pd(mx, q));
            add2(&mut sums.y, _mm512_mul_pd(my, q));
            add2(&mut sums.z, _mm512_mul_pd(mz, q));
            add2(&mut sums.t, _mm512_mul_pd(r, lt));
        }
        for &(m, w) in rest {
            point::<K>(&lob, m, w, &mut sums);
        }
        sums.finish::<K>(acc)
    }
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

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    /// Random unit normals with weights, and lobes with axes, shares and exponents from
    /// broad to sharp (points far from every lobe included: their log-densities underflow).
    fn random_case(seed: u64, n: usize, k: usize) -> (Vec<Pt>, Vec<L>) {
        use super::super::test_dirs::random_dir;
        let mut rng = meso_testkit::rng(seed);
        let pts: Vec<Pt> = (0..n)
            .map(|_| {
                let d = random_dir(&mut rng, 3.0);
                (d, 0.1 + meso_testkit::uniform2(&mut rng)[0])
            })
            .collect();
        let lobes: Vec<L> = (0..k)
            .map(|j| L {
                a: random_dir(&mut rng, 1.0),
                w: 1.0 / k as f64,
                eta: [2.0, 40.0, 800.0, 20_000.0][j % 4],
            })
            .collect();
        (pts, lobes)
    }

    /// The log-likelihood from the (SIMD) E-step is the one written out, bit for bit.
    #[test]
    fn shared_kmeans_seeds_give_each_k_its_own_fit_bit_for_bit() {
        for seed in 0..20 {
            let (pts, _) = random_case(seed, 5 + 7 * seed as usize, 1);
            for order in [[1, 2, 3, 4], [4, 2, 3, 1], [3, 1, 4, 2]] {
                let mut shared = KmeansSeeds::new(&pts);
                for k in order {
                    let a = kmeans_from(&pts, &mut shared, k);
                    let b = kmeans_init(&pts, k);
                    assert_eq!(a.len(), b.len());
                    for (x, y) in a.iter().zip(&b) {
                        assert_eq!(
                            x.a.to_array().map(f64::to_bits),
                            y.a.to_array().map(f64::to_bits)
                        );
                        assert_eq!(x.w.to_bits(), y.w.to_bits());
                        assert_eq!(x.eta.to_bits(), y.eta.to_bits());
                    }
                }
            }
        }
    }

    #[test]
    fn loglik_is_the_scalar_one_bit_for_bit() {
        for (seed, n) in [(37u64, 257usize), (41, 64), (43, 5), (47, 1)] {
            for k in 1..=MAX_LOBES {
                let (pts, lobes) = random_case(seed + k as u64, n, k);
                let total: f64 = pts.iter().map(|p| p.1).sum();
                assert_eq!(
                    loglik(&pts, &lobes, total).to_bits(),
                    loglik_scalar(&pts, &lobes, total).to_bits(),
                    "K {k}, n {n}"
                );
            }
        }
    }

    /// The AVX2 E-steps of one lobe (four points per register) and of two lobes (two points per
    /// register) are the scalar E-step bit for bit, with point counts that leave a remainder.
    #[test]
    fn avx2_points_e_step_is_the_scalar_one_bit_for_bit() {
        if !quads::available() {
            return;
        }
        for (seed, n) in [(17u64, 257usize), (19, 1000), (23, 63), (29, 3), (31, 1)] {
            for k in 1..=2 {
                let (pts, lobes) = random_case(seed + k as u64, n, k);
                let (mut scalar, mut quad) = (Acc::default(), Acc::default());
                let (ll_scalar, ll_quad) = if k == 1 {
                    // SAFETY: the CPU has AVX2 (checked).
                    (e_step::<1>(&pts, &lobes, &mut scalar), unsafe {
                        quads::e_step_1(&pts, &lobes, &mut quad)
                    })
                } else {
                    // SAFETY: the CPU has AVX2 (checked).
                    (e_step::<2>(&pts, &lobes, &mut scalar), unsafe {
                        quads::e_step_2(&pts, &lobes, &mut quad)
                    })
                };
                assert_eq!(ll_scalar.to_bits(), ll_quad.to_bits(), "K {k}, n {n}: ll");
                for j in 0..k {
                    assert_eq!(scalar.w[j].to_bits(), quad.w[j].to_bits(), "K {k} n {n} w");
                    assert_eq!(scalar.t[j].to_bits(), quad.t[j].to_bits(), "K {k} n {n} t");
                    for c in 0..3 {
                        assert_eq!(scalar.a[j][c].to_bits(), quad.a[j][c].to_bits());
                    }
                }
            }
        }
    }

    /// The SSE2 E-step (two lobes per register) is the scalar E-step bit for bit: the same
    /// responsibilities, axis and exponent sums and log-likelihood, K = 2, 3 and 4, with an
    /// odd and an even point count.
    #[test]
    fn sse2_e_step_is_the_scalar_one_bit_for_bit() {
        for (seed, n) in [(7u64, 257usize), (11, 1000), (13, 64)] {
            for k in 2..=4 {
                let (pts, lobes) = random_case(seed + k as u64, n, k);
                let (mut scalar, mut simd) = (Acc::default(), Acc::default());
                let ll_scalar = match k {
                    2 => e_step::<2>(&pts, &lobes, &mut scalar),
                    3 => e_step::<3>(&pts, &lobes, &mut scalar),
                    _ => e_step::<4>(&pts, &lobes, &mut scalar),
                };
                // SAFETY: SSE2 is part of every x86-64 CPU (the target's baseline).
                let ll_simd = unsafe {
                    match k {
                        2 => pairs::e_step::<2, 1>(&pts, &lobes, &mut simd),
                        3 => pairs::e_step::<3, 2>(&pts, &lobes, &mut simd),
                        _ => pairs::e_step::<4, 2>(&pts, &lobes, &mut simd),
                    }
                };
                assert_eq!(
                    ll_scalar.to_bits(),
                    ll_simd.to_bits(),
                    "K {k}, n {n}: log-likelihood"
                );
                if k >= 3 && quads::available() {
                    let mut quad = Acc::default();
                    // SAFETY: the CPU has AVX2 (checked).
                    let ll_quad = unsafe {
                        if k == 3 {
                            quads::e_step::<3>(&pts, &lobes, &mut quad)
                        } else {
                            quads::e_step::<4>(&pts, &lobes, &mut quad)
                        }
                    };
                    assert_eq!(ll_scalar.to_bits(), ll_quad.to_bits(), "K {k}, n {n}: AVX2");
                    for j in 0..k {
                        assert_eq!(scalar.w[j].to_bits(), quad.w[j].to_bits());
                        assert_eq!(scalar.t[j].to_bits(), quad.t[j].to_bits());
                        for c in 0..3 {
                            assert_eq!(scalar.a[j][c].to_bits(), quad.a[j][c].to_bits());
                        }
                    }
                }
                if k >= 3 && quads::avx512() {
                    for n2 in [n, n - 1] {
                        let (mut s2, mut x2) = (Acc::default(), Acc::default());
                        let pts = &pts[..n2];
                        let ll_s = match k {
                            3 => e_step::<3>(pts, &lobes, &mut s2),
                            _ => e_step::<4>(pts, &lobes, &mut s2),
                        };
                        // SAFETY: the CPU has AVX-512F (checked).
                        let ll_x = unsafe {
                            if k == 3 {
                                quads::e_step_x2::<3>(pts, &lobes, &mut x2)
                            } else {
                                quads::e_step_x2::<4>(pts, &lobes, &mut x2)
                            }
                        };
                        assert_eq!(ll_s.to_bits(), ll_x.to_bits(), "K {k}, n {n2}: AVX-512");
                        for j in 0..k {
                            assert_eq!(s2.w[j].to_bits(), x2.w[j].to_bits(), "AVX-512 w");
                            assert_eq!(s2.t[j].to_bits(), x2.t[j].to_bits(), "AVX-512 t");
                            for c in 0..3 {
                                assert_eq!(s2.a[j][c].to_bits(), x2.a[j][c].to_bits());
                            }
                        }
                    }
                }
                for j in 0..k {
                    assert_eq!(
                        scalar.w[j].to_bits(),
                        simd.w[j].to_bits(),
                        "K {k} lobe {j}: w"
                    );
                    assert_eq!(
                        scalar.t[j].to_bits(),
                        simd.t[j].to_bits(),
                        "K {k} lobe {j}: t"
                    );
                    for c in 0..3 {
                        assert_eq!(
                            scalar.a[j][c].to_bits(),
                            simd.a[j][c].to_bits(),
                            "K {k} lobe {j}: a[{c}]"
                        );
                    }
                }
            }
        }
    }
}
