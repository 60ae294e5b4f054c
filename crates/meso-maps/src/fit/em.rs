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

#[derive(Clone, Copy, Debug)]
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
    /// Each point's squared chord distance to its nearest seed so far (the running
    /// `f64::min`, in the seeds' order, of the seeding pass).
    near: Vec<f64>,
    /// The Lloyd steps' cluster of each point ([`kmeans_from`]'s buffer).
    assign: Vec<u8>,
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
        let near = vec![f64::INFINITY; pts.len()];
        KmeansSeeds {
            dirs,
            centres,
            near,
            assign: Vec::new(),
        }
    }

    /// The first `k` seeds of `pts` (the points `new` was given), seeded as far as needed.
    fn seeds(&mut self, pts: &[Pt], k: usize) -> &[DVec3] {
        while self.centres.len() < k {
            // The distance to the newest seed folded into each point's running minimum: the
            // same `f64::min` fold over the seeds as recomputing it from the first.
            let last = *self.centres.last().unwrap();
            let mut best = (-1.0, DVec3::Z);
            for ((e, &d), near) in pts.iter().zip(&self.dirs).zip(&mut self.near) {
                *near = near.min(2.0 - 2.0 * last.dot(d));
                let dist = *near;
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
    // Each point's cluster in the last Lloyd step. When a step assigns every point as the one
    // before, its sums, hence its centres, are those of the step before (an empty cluster keeps
    // its centre either way), and so are every later step's: the steps left are skipped, with
    // the same centres to the last bit.
    let mut assign = std::mem::take(&mut seeds.assign);
    assign.clear();
    assign.resize(pts.len(), u8::MAX);
    let mut settled = false;
    for _ in 0..5 {
        sums.iter_mut().for_each(|s| *s = (DVec3::ZERO, 0.0, 0.0));
        let mut same = true;
        for (&(d, w), a) in pts.iter().zip(assign.iter_mut()) {
            let j = nearest(centres, d);
            same &= usize::from(*a) == j;
            *a = j as u8;
            sums[j].0 += d * w;
            sums[j].1 += w;
        }
        if same {
            settled = true;
            break;
        }
        for j in 0..k {
            if sums[j].0.length_squared() > 0.0 {
                centres[j] = sums[j].0.normalize();
            }
        }
    }
    for (&(d, w), a) in pts.iter().zip(&assign) {
        // Settled: the last step's clusters are those of the final centres.
        let j = if settled {
            usize::from(*a)
        } else {
            nearest(centres, d)
        };
        sums[j].2 += w * log_t(centres[j], d);
    }
    seeds.assign = assign;
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
/// log-likelihood is [`loglik_scalar`]'s sum (with one lobe `ln` of the sum `e⁰ = 1` adds
/// exactly 0), bit for bit with 5–8 lobes, with 1–4 in the lanes' order ([`e_step_lanes`]).
pub(super) fn loglik(pts: &[Pt], lanes: &PtLanes, lobes: &[L], total: f64) -> f64 {
    if lobes.is_empty() || lobes.len() > MAX_LOBES {
        return loglik_scalar(pts, lobes, total);
    }
    e_step_k(pts, lanes, lobes, &mut Acc::default()) / total
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
pub(super) fn em(pts: &[Pt], lanes: &PtLanes, lobes: &mut Vec<L>, total: f64, iters: usize) -> f64 {
    let mut prev = f64::NEG_INFINITY;
    let mut acc = Acc::default();
    for _ in 0..iters.max(1) {
        let k = lobes.len();
        if k == 0 {
            break;
        }
        let ll = e_step_k(pts, lanes, lobes, &mut acc);
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

/// One E-step over `lobes` (1..=[`MAX_LOBES`] of them; `lanes` laid out from `pts`): fills
/// `acc` and returns the summed log-likelihood (not yet divided by the total weight). The lobe
/// count a constant (its loops unrolled, the per-lobe values in registers); 1–4 lobes over the
/// points in lanes ([`e_step_lanes`], in SIMD registers where the CPU has them, the same bits on
/// every path), 5–8 point by point ([`e_step`]).
fn e_step_k(pts: &[Pt], lanes: &PtLanes, lobes: &[L], acc: &mut Acc) -> f64 {
    match lobes.len() {
        1 => e_step_lanes::<1>(lanes, lobes, acc),
        2 => e_step_lanes::<2>(lanes, lobes, acc),
        3 => e_step_lanes::<3>(lanes, lobes, acc),
        4 => e_step_lanes::<4>(lanes, lobes, acc),
        5 => e_step::<5>(pts, lobes, acc),
        6 => e_step::<6>(pts, lobes, acc),
        7 => e_step::<7>(pts, lobes, acc),
        _ => e_step::<MAX_LOBES>(pts, lobes, acc),
    }
}

/// Points per lane group of [`PtLanes`]: the E-step of 1–4 lobes sums point `i` into lane
/// `i mod LANES` (the lanes of one AVX-512 register), the lanes added in order at the end.
const LANES: usize = 8;

/// EM's points by component (x, y, z of the mean vectors, weights), padded with weightless
/// points at the pole to a multiple of [`LANES`]: the layout of [`e_step_lanes`].
pub(super) struct PtLanes {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    w: Vec<f64>,
}

impl PtLanes {
    /// The points `pts` by component, padded.
    pub(super) fn new(pts: &[Pt]) -> PtLanes {
        let n = pts.len().div_ceil(LANES) * LANES;
        let mut l = PtLanes {
            x: Vec::with_capacity(n),
            y: Vec::with_capacity(n),
            z: Vec::with_capacity(n),
            w: Vec::with_capacity(n),
        };
        for &(m, w) in pts {
            l.x.push(m.x);
            l.y.push(m.y);
            l.z.push(m.z);
            l.w.push(w);
        }
        l.x.resize(n, 0.0);
        l.y.resize(n, 0.0);
        l.z.resize(n, 1.0);
        l.w.resize(n, 0.0);
        l
    }
}

/// The sum of the lanes of one E-step sum, in lane order (`((v₀ + v₁) + v₂) + …`).
#[inline]
fn lane_sum(v: &[f64; LANES]) -> f64 {
    v[1..].iter().fold(v[0], |s, x| s + x)
}

/// The per-lobe constant of the E-step: ln-weight plus ln-normaliser.
#[inline]
fn lobe_c(l: &L) -> f64 {
    l.w.max(1e-300).ln() + ((l.eta + 2.0) / (8.0 * PI)).ln()
}

/// One E-step of [`em`] over `K` ∈ 1..=4 lobes, the points in lanes ([`PtLanes`]): fills `acc`
/// and returns the summed log-likelihood (not yet divided by the total weight). Each point's
/// arithmetic is [`e_step`]'s (`fast_ln`, `fast_exp_neg`, no fused multiply-adds); the sums over
/// the points are kept per lane (point `i` in lane `i mod 8`) and the lanes added in order, so
/// the order of the sums is fixed by the layout, not by the CPU: eight lanes of one AVX-512
/// register, two AVX2 registers, or [`e_step_lanes_scalar`] give the same bits.
fn e_step_lanes<const K: usize>(p: &PtLanes, lobes: &[L], acc: &mut Acc) -> f64 {
    #[cfg(target_arch = "x86_64")]
    {
        if quads::avx512() {
            // SAFETY: the CPU has AVX-512F (checked).
            return unsafe { lanes8::e_step_512::<K>(p, lobes, acc) };
        }
        if quads::available() {
            // SAFETY: the CPU has AVX2 (checked).
            return unsafe { lanes8::e_step_256::<K>(p, lobes, acc) };
        }
    }
    e_step_lanes_scalar::<K>(p, lobes, acc)
}

/// [`e_step_lanes`] written out lane by lane (the reference of its SIMD forms).
fn e_step_lanes_scalar<const K: usize>(p: &PtLanes, lobes: &[L], acc: &mut Acc) -> f64 {
    debug_assert_eq!(lobes.len(), K);
    let mut c = [0.0f64; K];
    let mut a = [DVec3::ZERO; K];
    let mut he = [0.0f64; K];
    for j in 0..K {
        c[j] = lobe_c(&lobes[j]);
        a[j] = lobes[j].a;
        he[j] = 0.5 * lobes[j].eta;
    }
    let z = [0.0f64; LANES];
    let (mut sw, mut sx, mut sy, mut sz, mut st) = ([z; K], [z; K], [z; K], [z; K], [z; K]);
    let mut sll = z;
    for g in (0..p.w.len()).step_by(LANES) {
        for l in 0..LANES {
            let i = g + l;
            let m = DVec3::new(p.x[i], p.y[i], p.z[i]);
            let w = p.w[i];
            let mut logd = [0.0f64; K];
            let mut lt = [0.0f64; K];
            let mut inv = [0.0f64; K];
            let mut top = f64::NEG_INFINITY;
            for j in 0..K {
                let x = (0.5 * (1.0 + a[j].dot(m))).max(1e-300);
                lt[j] = fast_ln(x);
                inv[j] = 0.5 / x.max(0.5e-6);
                logd[j] = c[j] + he[j] * lt[j];
                // As the SIMD max: the first operand only when it is greater.
                top = if top > logd[j] { top } else { logd[j] };
            }
            if K == 1 {
                sll[l] += w * logd[0];
                sw[0][l] += w;
                let q = w * inv[0];
                sx[0][l] += m.x * q;
                sy[0][l] += m.y * q;
                sz[0][l] += m.z * q;
                st[0][l] += w * lt[0];
                continue;
            }
            let mut s = 0.0;
            let mut e = [0.0f64; K];
            for j in 0..K {
                e[j] = fast_exp_neg(logd[j] - top);
                s += e[j];
            }
            sll[l] += w * (top + fast_ln(s));
            let ws = w / s;
            for j in 0..K {
                let r = ws * e[j];
                sw[j][l] += r;
                let q = r * inv[j];
                sx[j][l] += m.x * q;
                sy[j][l] += m.y * q;
                sz[j][l] += m.z * q;
                st[j][l] += r * lt[j];
            }
        }
    }
    for j in 0..K {
        acc.w[j] = lane_sum(&sw[j]);
        acc.a[j] = DVec3::new(lane_sum(&sx[j]), lane_sum(&sy[j]), lane_sum(&sz[j]));
        acc.t[j] = lane_sum(&st[j]);
    }
    lane_sum(&sll)
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

/// `fast_exp_neg` and the lane helpers on two lanes per SSE2 register (every x86-64 CPU has
/// SSE2), for the smoothed refinement's target (`smoothed::target_pairs`): each lane exactly
/// the scalar operations.
#[cfg(target_arch = "x86_64")]
pub(super) mod pairs {
    use std::arch::x86_64::{
        __m128d, _mm_add_pd, _mm_andnot_pd, _mm_castpd_si128, _mm_castsi128_pd, _mm_cmplt_pd,
        _mm_cvtepi32_pd, _mm_cvtsd_f64, _mm_cvttpd_epi32, _mm_mul_pd, _mm_set1_pd, _mm_slli_epi64,
        _mm_sub_pd, _mm_unpackhi_pd,
    };
    use std::f64::consts::{LN_2, LOG2_E};

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
}

/// `fast_exp_neg` and the lane helpers on four lanes per AVX2 register, and the run-time
/// checks for AVX2 and AVX-512F, for the E-step in lanes ([`lanes8`]) and the smoothed
/// refinement: each lane exactly the scalar operations.
#[cfg(target_arch = "x86_64")]
pub(super) mod quads {
    use std::arch::x86_64::{
        __m256d, _mm256_add_pd, _mm256_andnot_pd, _mm256_castpd_si256, _mm256_castsi256_pd,
        _mm256_cmp_pd, _mm256_cvtepi32_pd, _mm256_cvttpd_epi32, _mm256_mul_pd, _mm256_set1_pd,
        _mm256_slli_epi64, _mm256_storeu_pd, _mm256_sub_pd, _CMP_LT_OQ,
    };
    use std::f64::consts::{LN_2, LOG2_E};

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

    /// Whether this CPU has AVX-512F (cached by the standard library).
    #[inline]
    pub(in super::super) fn avx512() -> bool {
        std::arch::is_x86_feature_detected!("avx512f")
    }
}

/// [`e_step_lanes`] in SIMD registers: eight points per AVX-512 register, or per pair of AVX2
/// registers, each lane the scalar operations of its point ([`e_step_lanes_scalar`]:
/// `fast_ln` and `fast_exp_neg` written out lane-wise, no fused multiply-adds).
#[cfg(target_arch = "x86_64")]
mod lanes8 {
    use super::{lane_sum, lobe_c, Acc, PtLanes, EXP_TAYLOR, L, LANES};
    use glam::DVec3;
    use std::f64::consts::{LN_2, LOG2_E, SQRT_2};

    /// 2^52: or-ed onto a small integer's bits, the double `2^52 + n`.
    const TWO52: f64 = 4_503_599_627_370_496.0;

    /// The E-step on one vector type `$v` of `$n` lanes (`$n` × registers = [`LANES`]).
    macro_rules! e_step_body {
        ($p:expr, $lobes:expr, $acc:expr, $K:expr, $R:expr,
         $v:ty, $set:expr, $load:expr, $store:expr, $add:expr, $sub:expr, $mul:expr,
         $div:expr, $max:expr, $ln:expr, $exp:expr) => {{
            const R: usize = $R;
            const W: usize = LANES / R;
            let (p, lobes, acc): (&PtLanes, &[L], &mut Acc) = ($p, $lobes, $acc);
            let z: $v = $set(0.0);
            let mut ax = [z; $K];
            let mut ay = [z; $K];
            let mut az = [z; $K];
            let mut he = [z; $K];
            let mut c = [z; $K];
            for j in 0..$K {
                ax[j] = $set(lobes[j].a.x);
                ay[j] = $set(lobes[j].a.y);
                az[j] = $set(lobes[j].a.z);
                he[j] = $set(0.5 * lobes[j].eta);
                c[j] = $set(lobe_c(&lobes[j]));
            }
            let (mut sw, mut sx, mut sy, mut sz, mut st) = (
                [[z; R]; $K],
                [[z; R]; $K],
                [[z; R]; $K],
                [[z; R]; $K],
                [[z; R]; $K],
            );
            let mut sll = [z; R];
            for g in (0..p.w.len()).step_by(LANES) {
                for h in 0..R {
                    let i = g + h * W;
                    let (mx, my, mz, w) = (
                        $load(&p.x[i..i + W]),
                        $load(&p.y[i..i + W]),
                        $load(&p.z[i..i + W]),
                        $load(&p.w[i..i + W]),
                    );
                    let mut logd = [z; $K];
                    let mut lt = [z; $K];
                    let mut inv = [z; $K];
                    let mut top = $set(f64::NEG_INFINITY);
                    for j in 0..$K {
                        let d = $add($add($mul(ax[j], mx), $mul(ay[j], my)), $mul(az[j], mz));
                        let x = $max($mul($set(0.5), $add($set(1.0), d)), $set(1e-300));
                        lt[j] = $ln(x);
                        inv[j] = $div($set(0.5), $max(x, $set(0.5e-6)));
                        logd[j] = $add(c[j], $mul(he[j], lt[j]));
                        top = $max(top, logd[j]);
                    }
                    if $K == 1 {
                        sll[h] = $add(sll[h], $mul(w, logd[0]));
                        sw[0][h] = $add(sw[0][h], w);
                        let q = $mul(w, inv[0]);
                        sx[0][h] = $add(sx[0][h], $mul(mx, q));
                        sy[0][h] = $add(sy[0][h], $mul(my, q));
                        sz[0][h] = $add(sz[0][h], $mul(mz, q));
                        st[0][h] = $add(st[0][h], $mul(w, lt[0]));
                        continue;
                    }
                    let mut s = z;
                    let mut e = [z; $K];
                    for j in 0..$K {
                        e[j] = $exp($sub(logd[j], top));
                        s = $add(s, e[j]);
                    }
                    sll[h] = $add(sll[h], $mul(w, $add(top, $ln(s))));
                    let ws = $div(w, s);
                    for j in 0..$K {
                        let r = $mul(ws, e[j]);
                        sw[j][h] = $add(sw[j][h], r);
                        let q = $mul(r, inv[j]);
                        sx[j][h] = $add(sx[j][h], $mul(mx, q));
                        sy[j][h] = $add(sy[j][h], $mul(my, q));
                        sz[j][h] = $add(sz[j][h], $mul(mz, q));
                        st[j][h] = $add(st[j][h], $mul(r, lt[j]));
                    }
                }
            }
            let all = |v: &[$v; R]| {
                let mut o = [0.0; LANES];
                for h in 0..R {
                    $store(&mut o[h * W..(h + 1) * W], v[h]);
                }
                lane_sum(&o)
            };
            for j in 0..$K {
                acc.w[j] = all(&sw[j]);
                acc.a[j] = DVec3::new(all(&sx[j]), all(&sy[j]), all(&sz[j]));
                acc.t[j] = all(&st[j]);
            }
            all(&sll)
        }};
    }

    /// [`super::e_step_lanes`] on AVX-512 (the CPU must have AVX-512F).
    #[target_feature(enable = "avx512f")]
    pub(super) fn e_step_512<const K: usize>(p: &PtLanes, lobes: &[L], acc: &mut Acc) -> f64 {
        use std::arch::x86_64::{
            __m512d, _mm512_add_pd, _mm512_and_si512, _mm512_castpd_si512, _mm512_castsi512_pd,
            _mm512_cmp_pd_mask, _mm512_cvtepi32_pd, _mm512_cvttpd_epi32, _mm512_div_pd,
            _mm512_loadu_pd, _mm512_mask_add_pd, _mm512_mask_mul_pd, _mm512_maskz_mov_pd,
            _mm512_max_pd, _mm512_mul_pd, _mm512_or_si512, _mm512_set1_epi64, _mm512_set1_pd,
            _mm512_slli_epi64, _mm512_srli_epi64, _mm512_storeu_pd, _mm512_sub_pd, _CMP_GT_OQ,
            _CMP_LT_OQ,
        };
        let set8 = _mm512_set1_pd;
        // SAFETY: eight doubles in the slice (unaligned load / store).
        let load = |s: &[f64]| unsafe { _mm512_loadu_pd(s.as_ptr()) };
        let store = |o: &mut [f64], v: __m512d| unsafe { _mm512_storeu_pd(o.as_mut_ptr(), v) };
        // `fast_ln` on eight lanes of normal positive numbers.
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
        // `fast_exp_neg` on eight lanes (`y ≤ 0`).
        let exp8 = |y: __m512d| {
            let under = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(y, set8(-700.0));
            let ki = _mm512_cvttpd_epi32(_mm512_sub_pd(_mm512_mul_pd(y, set8(LOG2_E)), set8(0.5)));
            let k = _mm512_cvtepi32_pd(ki);
            let r = _mm512_sub_pd(y, _mm512_mul_pd(k, set8(LN_2)));
            let mut q = _mm512_mul_pd(r, set8(1.0 / 40320.0));
            for cf in EXP_TAYLOR {
                q = _mm512_mul_pd(r, _mm512_add_pd(set8(cf), q));
            }
            let q = _mm512_add_pd(set8(1.0), q);
            let kb =
                _mm512_castpd_si512(_mm512_add_pd(_mm512_add_pd(k, set8(1023.0)), set8(TWO52)));
            let scale = _mm512_castsi512_pd(_mm512_slli_epi64::<52>(kb));
            _mm512_maskz_mov_pd(!under, _mm512_mul_pd(q, scale))
        };
        e_step_body!(
            p,
            lobes,
            acc,
            K,
            1,
            __m512d,
            set8,
            load,
            store,
            _mm512_add_pd,
            _mm512_sub_pd,
            _mm512_mul_pd,
            _mm512_div_pd,
            _mm512_max_pd,
            ln8,
            exp8
        )
    }

    /// [`super::e_step_lanes`] on AVX2, the eight lanes in two registers (the CPU must have
    /// AVX2).
    #[target_feature(enable = "avx2")]
    pub(super) fn e_step_256<const K: usize>(p: &PtLanes, lobes: &[L], acc: &mut Acc) -> f64 {
        use super::quads::{exp_neg, set};
        use std::arch::x86_64::{
            __m256d, _mm256_add_pd, _mm256_and_pd, _mm256_and_si256, _mm256_andnot_pd,
            _mm256_castpd_si256, _mm256_castsi256_pd, _mm256_cmp_pd, _mm256_div_pd,
            _mm256_loadu_pd, _mm256_max_pd, _mm256_mul_pd, _mm256_or_pd, _mm256_or_si256,
            _mm256_set1_epi64x, _mm256_srli_epi64, _mm256_storeu_pd, _mm256_sub_pd, _CMP_GT_OQ,
        };
        // SAFETY: four doubles in the slice (unaligned load / store).
        let load = |s: &[f64]| unsafe { _mm256_loadu_pd(s.as_ptr()) };
        let store = |o: &mut [f64], v: __m256d| unsafe { _mm256_storeu_pd(o.as_mut_ptr(), v) };
        // `fast_ln` on four lanes of normal positive numbers.
        let ln4 = |x: __m256d| {
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
            let mut q = _mm256_mul_pd(s2, set(2.0 / 9.0));
            q = _mm256_mul_pd(s2, _mm256_add_pd(set(2.0 / 7.0), q));
            q = _mm256_mul_pd(s2, _mm256_add_pd(set(0.4), q));
            q = _mm256_mul_pd(s2, _mm256_add_pd(set(2.0 / 3.0), q));
            let q = _mm256_mul_pd(s, _mm256_add_pd(set(2.0), q));
            _mm256_add_pd(_mm256_mul_pd(e, set(LN_2)), q)
        };
        let exp4 = |y: __m256d| exp_neg(y);
        let set4 = |v: f64| set(v);
        e_step_body!(
            p,
            lobes,
            acc,
            K,
            2,
            __m256d,
            set4,
            load,
            store,
            _mm256_add_pd,
            _mm256_sub_pd,
            _mm256_mul_pd,
            _mm256_div_pd,
            _mm256_max_pd,
            ln4,
            exp4
        )
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

    /// The k-means fits from seeds shared between K (in any order) are those seeded afresh.
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

    /// The log-likelihood from the E-step is the one written out: bit for bit with 5–8 lobes
    /// (the same sum), to 1e-12 with 1–4 (the lanes' sums, [`e_step_lanes`], in another order).
    #[test]
    fn loglik_is_the_scalar_one() {
        for (seed, n) in [(37u64, 257usize), (41, 64), (43, 5), (47, 1)] {
            for k in 1..=MAX_LOBES {
                let (pts, lobes) = random_case(seed + k as u64, n, k);
                let total: f64 = pts.iter().map(|p| p.1).sum();
                let (a, b) = (
                    loglik(&pts, &PtLanes::new(&pts), &lobes, total),
                    loglik_scalar(&pts, &lobes, total),
                );
                if k > 4 {
                    assert_eq!(a.to_bits(), b.to_bits(), "K {k}, n {n}");
                } else {
                    assert!(
                        (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
                        "K {k}, n {n}: {a} {b}"
                    );
                }
            }
        }
    }

    /// The E-step of 1–4 lobes in lanes ([`e_step_lanes`]) gives the same bits on every path
    /// (AVX-512, AVX2, the scalar lanes), and the sums of the point-by-point E-step
    /// ([`e_step`]) up to the order of the sums.
    #[test]
    fn lane_e_step_is_the_same_on_every_path() {
        fn check<const K: usize>(pts: &[Pt], lobes: &[L]) {
            let lanes = PtLanes::new(pts);
            let mut r = Acc::default();
            let ll = e_step_lanes_scalar::<K>(&lanes, lobes, &mut r);
            let same = |name: &str, ll2: f64, o: &Acc| {
                assert_eq!(
                    ll.to_bits(),
                    ll2.to_bits(),
                    "{name} K {K} n {}: ll",
                    pts.len()
                );
                for j in 0..K {
                    assert_eq!(r.w[j].to_bits(), o.w[j].to_bits(), "{name}: w");
                    assert_eq!(r.t[j].to_bits(), o.t[j].to_bits(), "{name}: t");
                    for c in 0..3 {
                        assert_eq!(r.a[j][c].to_bits(), o.a[j][c].to_bits(), "{name}: a");
                    }
                }
            };
            let mut o = Acc::default();
            same("dispatch", e_step_lanes::<K>(&lanes, lobes, &mut o), &o);
            if quads::avx512() {
                let mut o = Acc::default();
                // SAFETY: the CPU has AVX-512F (checked).
                let ll2 = unsafe { lanes8::e_step_512::<K>(&lanes, lobes, &mut o) };
                same("AVX-512", ll2, &o);
            }
            if quads::available() {
                let mut o = Acc::default();
                // SAFETY: the CPU has AVX2 (checked).
                let ll2 = unsafe { lanes8::e_step_256::<K>(&lanes, lobes, &mut o) };
                same("AVX2", ll2, &o);
            }
            let mut q = Acc::default();
            let llq = e_step::<K>(pts, lobes, &mut q);
            let close = |a: f64, b: f64, scale: f64| {
                assert!((a - b).abs() <= 1e-12 * scale, "K {K}: {a} against {b}");
            };
            let wsum: f64 = pts.iter().map(|p| p.1).sum();
            close(ll, llq, 1.0 + llq.abs() + wsum);
            for j in 0..K {
                close(r.w[j], q.w[j], 1.0 + wsum);
                close(r.t[j], q.t[j], 1.0 + q.t[j].abs() + wsum * 50.0);
                for c in 0..3 {
                    close(r.a[j][c], q.a[j][c], 1.0 + wsum * 1e6);
                }
            }
        }
        for (seed, n) in [
            (7u64, 257usize),
            (11, 1000),
            (13, 64),
            (17, 63),
            (19, 5),
            (23, 1),
        ] {
            let (pts, l) = random_case(seed, n, 4);
            check::<1>(&pts, &l[..1]);
            check::<2>(&pts, &l[..2]);
            check::<3>(&pts, &l[..3]);
            check::<4>(&pts, &l[..4]);
        }
    }
}
