//! The smoothed refinement of the lobe fit (parent module docs): each Phong peak stood in for by
//! the spherical Gaussian of the same mean cosine, the kernel-smoothed L2 objective in closed
//! form, and Levenberg–Marquardt over axes, `ln κ` and weight logits from the EM lobes and from
//! a greedy start.

use super::em::{Pt, L};
use crate::limits::{ETA_MAX, MAX_LOBES};
use crate::sphgrid::SphereGrid;
use glam::DVec3;
use meso_core::fastmath::fast_exp_neg;
use meso_core::lm::{self, LmOptions};
use meso_core::sg;
use std::f64::consts::PI;

/// The spherical Gaussian concentration of a Phong peak of exponent η: the same mean cosine,
/// `η/(η + 4)` ([`sg::kappa_same_mean_cos`]; the renderer's `NdfMapped` makes the same
/// substitution, and the fitted κ go back to exponents exactly by [`kappa_eta`]).
fn peak_kappa(eta: f64) -> f64 {
    sg::kappa_same_mean_cos(eta).clamp(KAPPA_MIN, KAPPA_MAX)
}

/// The Phong exponent of a spherical Gaussian of concentration κ (inverse of [`peak_kappa`]:
/// [`sg::eta_same_mean_cos`]).
fn kappa_eta(kappa: f64) -> f64 {
    sg::eta_same_mean_cos(kappa).clamp(0.0, ETA_MAX)
}

const KAPPA_MIN: f64 = 1e-3;
const KAPPA_MAX: f64 = 2.5e5;

/// Per-lobe constants of [`sg_response`] (a thin wrapper: the constants come from
/// [`meso_core::sg`]).
#[derive(Clone, Copy)]
struct SgLobe {
    a: DVec3,
    t1: DVec3,
    t2: DVec3,
    kappa: f64,
    /// `κ / (1 − e^{−2κ})`.
    norm: f64,
    /// `coth κ − 1/κ`.
    lang: f64,
}

impl SgLobe {
    fn new(a: DVec3, kappa: f64) -> SgLobe {
        let (t1, t2) = tangents(a);
        SgLobe {
            a,
            t1,
            t2,
            kappa,
            norm: sg::normaliser_2pi(kappa),
            lang: sg::mean_cos(kappa),
        }
    }
}

/// Response `G(h) = ∫ sg(m) exp(λ(h·m − 1)) dm` of the unit-weight spherical Gaussian
/// `sg(m) = κ/(2π(1 − e^{−2κ})) e^{κ(a·m − 1)}` (normalised on the sphere) to the kernel, exactly:
/// `G = κ/(1 − e^{−2κ}) · e^{r−κ−λ} (1 − e^{−2r})/r` with `r = |κa + λh|`; and its derivatives
/// with respect to `ln κ` and to the axis' offsets along its two tangents. With `grad == false`
/// only `G` is computed.
#[inline]
fn sg_response(l: &SgLobe, lambda: f64, h: DVec3, grad: bool) -> [f64; 4] {
    let ah = l.a.dot(h);
    let kappa = l.kappa;
    let r = (kappa * kappa + lambda * (lambda + 2.0 * kappa * ah))
        .max(0.0)
        .sqrt();
    // r − κ − λ without cancellation (sg::product's ln_scale, on unit axes, written out on the
    // a·h the derivatives need too).
    let expo = 2.0 * kappa * lambda * (ah - 1.0) / (r + kappa + lambda);
    let sr = sg::integral_per_2pi(r);
    let g = l.norm * sr * fast_exp_neg(expo.min(0.0));
    if !grad {
        return [g, 0.0, 0.0, 0.0];
    }
    let lr = sg::mean_cos(r) / r.max(1e-12);
    // ∂ln G/∂κ = 1/κ − coth κ + L(r)(u·a)/r, u = κa + λh; ∂ln G/∂a = L(r) κ u / r.
    let dk = g * kappa * (lr * (kappa + lambda * ah) - l.lang);
    let c = g * lr * kappa * lambda;
    [g, dk, c * h.dot(l.t1), c * h.dot(l.t2)]
}

/// `JᵀJ += row rowᵀ` on the lower triangle of the row-major `np × np` matrix `jtj` (`np` a
/// multiple of 4), four columns per AVX2 register (the CPU must have AVX2): each element the
/// scalar `v += row[a] · row[b]`, bit for bit; the upper-triangle elements of the diagonal's
/// blocks of four get theirs too (the caller overwrites the upper triangle from the lower).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn jtj_add_quads(jtj: &mut [f64], row: &[f64; 4 * MAX_LOBES], np: usize) {
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_loadu_pd, _mm256_mul_pd, _mm256_set1_pd, _mm256_storeu_pd,
    };
    debug_assert!(np.is_multiple_of(4) && np <= 4 * MAX_LOBES && jtj.len() >= np * np);
    for a in 0..np {
        let ra = _mm256_set1_pd(row[a]);
        let line = &mut jtj[a * np..a * np + (a / 4 + 1) * 4];
        for (v, r) in line.chunks_exact_mut(4).zip(row.chunks_exact(4)) {
            // SAFETY: `v` and `r` hold four doubles each (unaligned loads and store).
            unsafe {
                let sum = _mm256_add_pd(
                    _mm256_loadu_pd(v.as_ptr()),
                    _mm256_mul_pd(ra, _mm256_loadu_pd(r.as_ptr())),
                );
                _mm256_storeu_pd(v.as_mut_ptr(), sum);
            }
        }
    }
}

/// [`sg_response`] of each lobe of `ls` at the four half vectors `h4`, one per AVX2 lane (the
/// CPU must have AVX2), into `out[lobe][half vector]`: each lane the scalar operations of its
/// half vector where `r > 20` (the branch of `sg::integral_per_2pi` and `sg::mean_cos` written
/// out: `1/r` and `1 − 1/r`), the scalar [`sg_response`] itself in the lanes where not; so bit
/// for bit the scalar responses.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn responses_quad(
    ls: &[SgLobe],
    lambda: f64,
    h4: &[DVec3],
    grad: bool,
    out: &mut [[[f64; 4]; 4]; MAX_LOBES],
) {
    use super::em::quads::{exp_neg, lanes, set};
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_cmp_pd, _mm256_div_pd, _mm256_max_pd, _mm256_min_pd,
        _mm256_movemask_pd, _mm256_mul_pd, _mm256_set_pd, _mm256_setzero_pd, _mm256_sqrt_pd,
        _mm256_sub_pd, _CMP_GT_OQ,
    };
    let hx = _mm256_set_pd(h4[3].x, h4[2].x, h4[1].x, h4[0].x);
    let hy = _mm256_set_pd(h4[3].y, h4[2].y, h4[1].y, h4[0].y);
    let hz = _mm256_set_pd(h4[3].z, h4[2].z, h4[1].z, h4[0].z);
    let zero = _mm256_setzero_pd();
    let dot = |v: DVec3| {
        _mm256_add_pd(
            _mm256_add_pd(_mm256_mul_pd(set(v.x), hx), _mm256_mul_pd(set(v.y), hy)),
            _mm256_mul_pd(set(v.z), hz),
        )
    };
    for (l, o) in ls.iter().zip(out.iter_mut()) {
        let kappa = l.kappa;
        let ah = dot(l.a);
        // r = √max(κ² + λ(λ + 2κ a·h), 0), in the scalar order.
        let r2 = _mm256_add_pd(
            set(kappa * kappa),
            _mm256_mul_pd(
                set(lambda),
                _mm256_add_pd(set(lambda), _mm256_mul_pd(set(2.0 * kappa), ah)),
            ),
        );
        let r = _mm256_sqrt_pd(_mm256_max_pd(r2, zero));
        let fast = _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_GT_OQ>(r, set(20.0)));
        let expo = _mm256_div_pd(
            _mm256_mul_pd(set(2.0 * kappa * lambda), _mm256_sub_pd(ah, set(1.0))),
            _mm256_add_pd(_mm256_add_pd(r, set(kappa)), set(lambda)),
        );
        let inv_r = _mm256_div_pd(set(1.0), r);
        let g = _mm256_mul_pd(
            _mm256_mul_pd(set(l.norm), inv_r),
            exp_neg(_mm256_min_pd(expo, zero)),
        );
        let gl = lanes(g);
        if grad {
            let lr = _mm256_div_pd(_mm256_sub_pd(set(1.0), inv_r), r);
            let dk = _mm256_mul_pd(
                _mm256_mul_pd(g, set(kappa)),
                _mm256_sub_pd(
                    _mm256_mul_pd(
                        lr,
                        _mm256_add_pd(set(kappa), _mm256_mul_pd(set(lambda), ah)),
                    ),
                    set(l.lang),
                ),
            );
            let c = _mm256_mul_pd(_mm256_mul_pd(_mm256_mul_pd(g, lr), set(kappa)), set(lambda));
            let d1 = lanes(_mm256_mul_pd(c, dot(l.t1)));
            let d2 = lanes(_mm256_mul_pd(c, dot(l.t2)));
            let dk = lanes(dk);
            for q in 0..4 {
                o[q] = [gl[q], dk[q], d1[q], d2[q]];
            }
        } else {
            for q in 0..4 {
                o[q] = [gl[q], 0.0, 0.0, 0.0];
            }
        }
        if fast != 0b1111 {
            for q in (0..4).filter(|q| fast & (1 << q) == 0) {
                o[q] = sg_response(l, lambda, h4[q], grad);
            }
        }
    }
}

/// Two unit tangents orthogonal to `a` and to each other.
fn tangents(a: DVec3) -> (DVec3, DVec3) {
    let t = if a.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t1 = (t - a * a.dot(t)).normalize();
    (t1, a.cross(t1))
}

/// The data smoothed by the kernel at each sample half vector: `Σ w K(h·m)` over the unit
/// normals `unit` (weights summing to 1), the terms with `h·m ≤ cut` left out. Two half vectors
/// per pass over the normals, one per SSE2 lane on x86-64 (each lane the scalar operations of
/// its half vector, `fast_exp_neg` lane-wise, the terms added in the normals' order: the sums
/// are bit for bit the scalar ones).
fn smoothed_target(hs: &[DVec3], unit: &[(DVec3, f64)], lambda: f64, cut: f64) -> Vec<f64> {
    let mut target = vec![0.0; hs.len()];
    #[cfg(target_arch = "x86_64")]
    let done = {
        // Eight half vectors per AVX-512 register where the CPU has AVX-512F, four per AVX2
        // register where it has AVX2, the rest in pairs.
        let octs = if std::arch::is_x86_feature_detected!("avx512f") {
            // SAFETY: AVX-512F is available (checked just above).
            unsafe { target_octs(hs, unit, lambda, cut, &mut target) };
            hs.len() / 8 * 8
        } else {
            0
        };
        let quads = if super::em::quads::available() {
            // SAFETY: AVX2 is available (checked just above).
            unsafe { target_quads(&hs[octs..], unit, lambda, cut, &mut target[octs..]) };
            octs + (hs.len() - octs) / 4 * 4
        } else {
            octs
        };
        // SAFETY: SSE2 is part of every x86-64 CPU (the target's baseline).
        unsafe { target_pairs(&hs[quads..], unit, lambda, cut, &mut target[quads..]) };
        quads + (hs.len() - quads) / 2 * 2
    };
    #[cfg(not(target_arch = "x86_64"))]
    let done = 0;
    for (&h, o) in hs.iter().zip(target.iter_mut()).skip(done) {
        let mut s = 0.0;
        for &(m, w) in unit {
            let c = h.dot(m);
            if c > cut {
                s += w * fast_exp_neg(lambda * (c - 1.0));
            }
        }
        *o = s;
    }
    target
}

/// [`smoothed_target`] for the half vectors in pairs (an odd last one is left to the caller).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "sse2")]
fn target_pairs(hs: &[DVec3], unit: &[(DVec3, f64)], lambda: f64, cut: f64, out: &mut [f64]) {
    use super::em::pairs::{exp_neg, lanes, set};
    use std::arch::x86_64::{
        _mm_add_pd, _mm_and_pd, _mm_cmpgt_pd, _mm_mul_pd, _mm_set_pd, _mm_setzero_pd, _mm_sub_pd,
    };
    for (hp, o) in hs.chunks_exact(2).zip(out.chunks_exact_mut(2)) {
        let hx = _mm_set_pd(hp[1].x, hp[0].x);
        let hy = _mm_set_pd(hp[1].y, hp[0].y);
        let hz = _mm_set_pd(hp[1].z, hp[0].z);
        let mut s = _mm_setzero_pd();
        for &(m, w) in unit {
            let c = _mm_add_pd(
                _mm_add_pd(_mm_mul_pd(hx, set(m.x)), _mm_mul_pd(hy, set(m.y))),
                _mm_mul_pd(hz, set(m.z)),
            );
            let term = _mm_mul_pd(
                set(w),
                exp_neg(_mm_mul_pd(set(lambda), _mm_sub_pd(c, set(1.0)))),
            );
            // Terms at or below the cut add +0 (the sums are ≥ +0, so exactly nothing).
            s = _mm_add_pd(s, _mm_and_pd(_mm_cmpgt_pd(c, set(cut)), term));
        }
        let [s0, s1] = lanes(s);
        o[0] = s0;
        o[1] = s1;
    }
}

/// [`smoothed_target`] for the half vectors four at a time, one per AVX2 lane (the CPU must have
/// AVX2; the last `hs.len() % 4` are left to the caller), each lane the scalar operations of
/// its half vector as in [`target_pairs`]: bit for bit the scalar sums.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn target_quads(hs: &[DVec3], unit: &[(DVec3, f64)], lambda: f64, cut: f64, out: &mut [f64]) {
    use super::em::quads::{exp_neg, lanes, set};
    use std::arch::x86_64::{
        _mm256_add_pd, _mm256_and_pd, _mm256_cmp_pd, _mm256_movemask_pd, _mm256_mul_pd,
        _mm256_set_pd, _mm256_setzero_pd, _mm256_sub_pd, _CMP_GT_OQ,
    };
    for (hq, o) in hs.chunks_exact(4).zip(out.chunks_exact_mut(4)) {
        let hx = _mm256_set_pd(hq[3].x, hq[2].x, hq[1].x, hq[0].x);
        let hy = _mm256_set_pd(hq[3].y, hq[2].y, hq[1].y, hq[0].y);
        let hz = _mm256_set_pd(hq[3].z, hq[2].z, hq[1].z, hq[0].z);
        let mut s = _mm256_setzero_pd();
        for &(m, w) in unit {
            let c = _mm256_add_pd(
                _mm256_add_pd(_mm256_mul_pd(hx, set(m.x)), _mm256_mul_pd(hy, set(m.y))),
                _mm256_mul_pd(hz, set(m.z)),
            );
            let keep = _mm256_cmp_pd::<_CMP_GT_OQ>(c, set(cut));
            // A normal beyond the cut of all four half vectors adds nothing (+0 to each lane).
            if _mm256_movemask_pd(keep) == 0 {
                continue;
            }
            let term = _mm256_mul_pd(
                set(w),
                exp_neg(_mm256_mul_pd(set(lambda), _mm256_sub_pd(c, set(1.0)))),
            );
            // Terms at or below the cut add +0 (the sums are ≥ +0, so exactly nothing).
            s = _mm256_add_pd(s, _mm256_and_pd(keep, term));
        }
        o.copy_from_slice(&lanes(s));
    }
}

/// [`smoothed_target`] for the half vectors eight at a time, one per AVX-512 lane (the CPU must
/// have AVX-512F; the last `hs.len() % 8` are left to the caller), each lane the scalar
/// operations of its half vector as in [`target_pairs`] (`fast_exp_neg` written out lane-wise):
/// bit for bit the scalar sums.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn target_octs(hs: &[DVec3], unit: &[(DVec3, f64)], lambda: f64, cut: f64, out: &mut [f64]) {
    use std::arch::x86_64::{
        _mm512_add_pd, _mm512_castpd_si512, _mm512_castsi512_pd, _mm512_cmp_pd_mask,
        _mm512_cvtepi32_pd, _mm512_cvttpd_epi32, _mm512_loadu_pd, _mm512_mask_add_pd,
        _mm512_maskz_mov_pd, _mm512_mul_pd, _mm512_set1_pd, _mm512_setzero_pd, _mm512_slli_epi64,
        _mm512_storeu_pd, _mm512_sub_pd, _CMP_GT_OQ, _CMP_LT_OQ,
    };
    use std::f64::consts::{LN_2, LOG2_E};
    const TWO52: f64 = 4_503_599_627_370_496.0;
    let set = _mm512_set1_pd;
    for (ho, o) in hs.chunks_exact(8).zip(out.chunks_exact_mut(8)) {
        let comp = |f: fn(&DVec3) -> f64| {
            let a: [f64; 8] = std::array::from_fn(|i| f(&ho[i]));
            // SAFETY: `a` holds eight doubles (unaligned load).
            unsafe { _mm512_loadu_pd(a.as_ptr()) }
        };
        let (hx, hy, hz) = (comp(|h| h.x), comp(|h| h.y), comp(|h| h.z));
        let mut s = _mm512_setzero_pd();
        for &(m, w) in unit {
            let c = _mm512_add_pd(
                _mm512_add_pd(_mm512_mul_pd(hx, set(m.x)), _mm512_mul_pd(hy, set(m.y))),
                _mm512_mul_pd(hz, set(m.z)),
            );
            // Terms at or below the cut are left out (the scalar adds nothing for them): a
            // normal beyond the cut of all eight half vectors adds nothing at all.
            let keep = _mm512_cmp_pd_mask::<_CMP_GT_OQ>(c, set(cut));
            if keep == 0 {
                continue;
            }
            // fast_exp_neg(λ(c − 1)), lane-wise (as `em::quads::exp_neg`).
            let y = _mm512_mul_pd(set(lambda), _mm512_sub_pd(c, set(1.0)));
            let under = _mm512_cmp_pd_mask::<_CMP_LT_OQ>(y, set(-700.0));
            let ki = _mm512_cvttpd_epi32(_mm512_sub_pd(_mm512_mul_pd(y, set(LOG2_E)), set(0.5)));
            let k = _mm512_cvtepi32_pd(ki);
            let r = _mm512_sub_pd(y, _mm512_mul_pd(k, set(LN_2)));
            let mut p = _mm512_mul_pd(r, set(1.0 / 40320.0));
            for cf in super::em::EXP_TAYLOR {
                p = _mm512_mul_pd(r, _mm512_add_pd(set(cf), p));
            }
            let p = _mm512_add_pd(set(1.0), p);
            let kb = _mm512_castpd_si512(_mm512_add_pd(_mm512_add_pd(k, set(1023.0)), set(TWO52)));
            let scale = _mm512_castsi512_pd(_mm512_slli_epi64::<52>(kb));
            let e = _mm512_maskz_mov_pd(!under, _mm512_mul_pd(p, scale));
            let term = _mm512_mul_pd(set(w), e);
            s = _mm512_mask_add_pd(s, keep, s, term);
        }
        // SAFETY: `o` holds eight doubles (unaligned store).
        unsafe { _mm512_storeu_pd(o.as_mut_ptr(), s) };
    }
}

/// Lobe parameters of the smoothed fit: axes, `ln κ`, softmax logits of the weights (so the
/// weights always sum to 1).
#[derive(Clone)]
pub(super) struct SgState {
    k: usize,
    axes: [DVec3; MAX_LOBES],
    lk: [f64; MAX_LOBES],
    sl: [f64; MAX_LOBES],
}

impl SgState {
    fn from_lobes(lobes: &[L]) -> SgState {
        let mut st = SgState {
            k: lobes.len(),
            axes: [DVec3::Z; MAX_LOBES],
            lk: [0.0; MAX_LOBES],
            sl: [0.0; MAX_LOBES],
        };
        for (j, l) in lobes.iter().enumerate() {
            st.axes[j] = l.a;
            st.lk[j] = peak_kappa(l.eta).ln();
            st.sl[j] = l.w.max(1e-12).ln();
        }
        st
    }
    fn weights(&self) -> [f64; MAX_LOBES] {
        let k = self.k;
        let mx = self.sl[..k]
            .iter()
            .copied()
            .fold(f64::NEG_INFINITY, f64::max);
        let mut w = [0.0; MAX_LOBES];
        for (wj, sl) in w.iter_mut().zip(&self.sl[..k]) {
            *wj = (sl - mx).exp();
        }
        let s: f64 = w[..k].iter().sum();
        w[..k].iter_mut().for_each(|v| *v /= s);
        w
    }
    fn lobes(&self) -> [SgLobe; MAX_LOBES] {
        let mut out = [SgLobe::new(DVec3::Z, 1.0); MAX_LOBES];
        for ((o, &a), &lk) in out.iter_mut().zip(&self.axes).zip(&self.lk).take(self.k) {
            *o = SgLobe::new(a, lk.exp());
        }
        out
    }
    fn to_lobes(&self) -> Vec<L> {
        let w = self.weights();
        (0..self.k)
            .map(|j| L {
                a: self.axes[j],
                w: w[j],
                eta: kappa_eta(self.lk[j].exp()),
            })
            .collect()
    }
    fn remove(&mut self, j: usize) {
        let k = self.k;
        self.axes.copy_within(j + 1..k, j);
        self.lk.copy_within(j + 1..k, j);
        self.sl.copy_within(j + 1..k, j);
        self.k -= 1;
    }
}

thread_local! {
    /// The LM solver's buffers, reused by every refinement on this thread.
    static LM_WORKSPACE: std::cell::RefCell<lm::Workspace> =
        std::cell::RefCell::new(lm::Workspace::new(4 * MAX_LOBES));
    /// Upper-hemisphere centres of the sample grid, per grid resolution.
    static SAMPLE_GRID: std::cell::RefCell<(usize, Vec<DVec3>)> =
        const { std::cell::RefCell::new((0, Vec::new())) };
}

/// The smoothed objective of one footprint (module docs): the sample half vectors `hs` (centres
/// of an equal-area grid with spacing ≈ the kernel's width, upper hemisphere, within reach of the
/// data) and the data smoothed by the kernel at them.
pub(super) struct Smoothed<'a> {
    lambda: f64,
    pts: &'a [Pt],
    total: f64,
    hs: Vec<DVec3>,
    target: Vec<f64>,
}

impl<'a> Smoothed<'a> {
    /// The smoothed objective of the points `pts` under the kernel of exponent `lambda`.
    pub(super) fn new(pts: &'a [Pt], lambda: f64) -> Smoothed<'a> {
        let total: f64 = pts.iter().map(|p| p.1).sum();
        // Kernel width ≈ 1/√λ rad; grid spacing √(4π)/res ≈ that width.
        let sigma = 1.0 / lambda.sqrt();
        let res = ((3.55 / sigma).ceil() as usize).clamp(8, 512);
        let c = pts.iter().map(|p| p.0 * p.1).sum::<DVec3>();
        let c = c.try_normalize().unwrap_or(DVec3::Z);
        let cmin = pts
            .iter()
            .map(|p| p.0.normalize_or_zero().dot(c))
            .fold(1.0f64, f64::min)
            .clamp(-1.0, 1.0);
        let cap = (cmin.acos() + 3.5 * sigma).min(PI).cos();
        let hs: Vec<DVec3> = SAMPLE_GRID.with(|g| {
            let mut g = g.borrow_mut();
            if g.0 != res {
                let grid = SphereGrid { res };
                g.1 = (0..grid.bins())
                    .map(|b| grid.point(b, 0.5, 0.5))
                    .filter(|h| h.z > 0.0)
                    .collect();
                g.0 = res;
            }
            g.1.iter().copied().filter(|h| h.dot(c) >= cap).collect()
        });
        // Unit normals, weights over the total, the kernel's cut-off (e^−20) as a cosine.
        let unit: Vec<(DVec3, f64)> = pts
            .iter()
            .map(|&(m, w)| (m.normalize_or_zero(), w / total))
            .collect();
        let cut = 1.0 - 20.0 / lambda;
        let target = smoothed_target(&hs, &unit, lambda, cut);
        Smoothed {
            lambda,
            pts,
            total,
            hs,
            target,
        }
    }

    /// The kernel's exponent λ.
    pub(super) fn lambda(&self) -> f64 {
        self.lambda
    }

    /// The data points.
    pub(super) fn points(&self) -> &'a [Pt] {
        self.pts
    }

    /// The shading error of `lobes` (weights summing to 1) against the data: the RMS over the
    /// sample half vectors of the blurred difference, over the largest blurred value of the
    /// data (the measure of the parent module's [`super::shading_error`]); `None` without
    /// sample half vectors or a positive peak.
    pub(super) fn rms_of_peak(&self, lobes: &[L]) -> Option<f64> {
        let peak = self.target.iter().copied().fold(0.0, f64::max);
        if self.hs.is_empty() || peak <= 0.0 || lobes.is_empty() {
            return None;
        }
        Some((self.objective_of(lobes) / self.hs.len() as f64).sqrt() / peak)
    }

    /// The objective of `lobes` (weights summing to 1): each Phong peak as the spherical
    /// Gaussian of the same mean cosine.
    pub(super) fn objective_of(&self, lobes: &[L]) -> f64 {
        if lobes.is_empty() || lobes.len() > MAX_LOBES {
            return f64::INFINITY;
        }
        self.eval(&SgState::from_lobes(lobes), None)
    }

    /// Sum of squared residuals; with `jac`, also `JᵀJ` (lower triangle) and `Jᵀr` added in.
    fn eval(&self, st: &SgState, mut jac: Option<(&mut [f64], &mut [f64])>) -> f64 {
        let k = st.k;
        let np = 4 * k;
        let ws = st.weights();
        let ls = st.lobes();
        let grad = jac.is_some();
        let mut obj = 0.0;
        let mut row = [0.0; 4 * MAX_LOBES];
        let mut gs = [[0.0; 4]; MAX_LOBES];
        // The responses of every lobe at up to four half vectors: [lobe][half vector][part].
        let mut block = [[[0.0; 4]; 4]; MAX_LOBES];
        #[cfg(target_arch = "x86_64")]
        let quads = super::em::quads::available();
        #[cfg(not(target_arch = "x86_64"))]
        let quads = false;
        let n = self.hs.len();
        let mut i0 = 0;
        while i0 < n {
            let len = if quads && i0 + 4 <= n {
                #[cfg(target_arch = "x86_64")]
                // SAFETY: AVX2 is available (`quads`).
                unsafe {
                    responses_quad(
                        &ls[..k],
                        self.lambda,
                        &self.hs[i0..i0 + 4],
                        grad,
                        &mut block,
                    );
                }
                4
            } else {
                for (b, l) in block.iter_mut().zip(&ls[..k]) {
                    b[0] = sg_response(l, self.lambda, self.hs[i0], grad);
                }
                1
            };
            for (q, &t) in self.target[i0..i0 + len].iter().enumerate() {
                let mut m = 0.0;
                for j in 0..k {
                    gs[j] = block[j][q];
                    m += ws[j] * gs[j][0];
                }
                let r = m - t;
                obj += r * r;
                if let Some((jtj, jtr)) = jac.as_mut() {
                    for j in 0..k {
                        row[4 * j] = ws[j] * (gs[j][0] - m);
                        row[4 * j + 1] = ws[j] * gs[j][1];
                        row[4 * j + 2] = ws[j] * gs[j][2];
                        row[4 * j + 3] = ws[j] * gs[j][3];
                    }
                    for a in 0..np {
                        jtr[a] += row[a] * r;
                    }
                    #[cfg(target_arch = "x86_64")]
                    if quads {
                        // SAFETY: AVX2 is available (`quads`).
                        unsafe { jtj_add_quads(jtj, &row, np) };
                        continue;
                    }
                    for a in 0..np {
                        let ra = row[a];
                        for (b, v) in jtj[a * np..=a * np + a].iter_mut().enumerate() {
                            *v += ra * row[b];
                        }
                    }
                }
            }
            i0 += len;
        }
        obj
    }

    /// Levenberg–Marquardt ([`meso_core::lm`]) from `st`, at most `iters` steps, until a step
    /// lowers the objective by less than the fraction `tol` or none is found in 10 tries;
    /// returns the objective.
    fn lm(&self, st: &mut SgState, iters: usize, tol: f64) -> f64 {
        let opts = LmOptions {
            max_iterations: iters,
            rel_tolerance: tol,
            small_steps_to_stop: 1,
            initial_lambda: 1e-3,
            lambda_min: 1e-9,
            lambda_max: f64::INFINITY,
            max_tries: 10,
        };
        LM_WORKSPACE.with(|ws| lm::minimize(self, st, &opts, &mut ws.borrow_mut()).cost)
    }

    /// Add a lobe of weight `share` (the others scaled by `1 − share`) where the data most
    /// exceed the lobes: at the kernel-weighted mean of the data around the sample of largest
    /// excess (so that it lies in the span of the data), concentration λ.
    fn add_lobe(&self, st: &mut SgState, share: f64) {
        let ws = st.weights();
        let ls = st.lobes();
        let mut best = (DVec3::Z, f64::NEG_INFINITY);
        for (&h, &t) in self.hs.iter().zip(&self.target) {
            let m: f64 = (0..st.k)
                .map(|j| ws[j] * sg_response(&ls[j], self.lambda, h, false)[0])
                .sum();
            if t - m > best.1 {
                best = (h, t - m);
            }
        }
        let h = best.0;
        let mean: DVec3 = self
            .pts
            .iter()
            .map(|&(m, w)| {
                let e = self.lambda * (h.dot(m.normalize_or_zero()) - 1.0);
                m * (w * fast_exp_neg(e.max(-700.0)))
            })
            .sum();
        let j = st.k;
        for (sl, w) in st.sl.iter_mut().zip(&ws).take(j) {
            *sl = (w * (1.0 - share)).max(1e-12).ln();
        }
        st.sl[j] = share.ln();
        st.lk[j] = self.lambda.ln();
        st.axes[j] = mean.try_normalize().unwrap_or(h);
        st.k += 1;
    }

    /// Greedy fit: one lobe with the data's mean axis and mean cosine, then lobes added by
    /// [`Self::add_lobe`] while each lowers the objective by more than `min_drop` (relative),
    /// up to `kmax`.
    fn greedy(&self, kmax: usize, iters: usize, min_drop: f64) -> (SgState, f64) {
        let c = self.pts.iter().map(|p| p.0 * p.1).sum::<DVec3>() / self.total;
        let mc = c.length().clamp(0.0, 1.0 - 1e-9);
        let mut st = SgState {
            k: 1,
            axes: [c.try_normalize().unwrap_or(DVec3::Z); MAX_LOBES],
            lk: [sg::kappa_from_mean_cos(mc).clamp(KAPPA_MIN, KAPPA_MAX).ln(); MAX_LOBES],
            sl: [0.0; MAX_LOBES],
        };
        let mut obj = self.lm(&mut st, iters, SMOOTH_TOL_START);
        while st.k < kmax {
            let mut next = st.clone();
            self.add_lobe(&mut next, 1.0 / (st.k + 1) as f64);
            let o = self.lm(&mut next, iters, SMOOTH_TOL_START);
            if o > obj * (1.0 - min_drop) {
                break;
            }
            st = next;
            obj = o;
        }
        (st, obj)
    }

    /// LM from `st`; a lobe whose weight dies (< 10⁻³) or whose axis sinks below the horizon is
    /// re-seeded by [`Self::add_lobe`] (at most `k` times, kept only when that lowers the
    /// objective).
    fn polish(&self, st: &mut SgState, iters: usize) -> f64 {
        let mut obj = self.lm(st, iters, SMOOTH_TOL_START);
        for _ in 0..st.k {
            let w = st.weights();
            let Some(dead) = (0..st.k).find(|&j| w[j] < 1e-3 || st.axes[j].z < 0.0) else {
                break;
            };
            let k = st.k;
            let mut next = st.clone();
            next.remove(dead);
            self.add_lobe(&mut next, 1.0 / k as f64);
            let o = self.lm(&mut next, iters, SMOOTH_TOL_START);
            if o >= obj {
                break;
            }
            *st = next;
            obj = o;
        }
        obj
    }
}

/// The smoothed objective as a least-squares problem over lobe states: per lobe the weight
/// logit, `ln κ` and the axis' offsets along its two tangents; a step is retracted onto the
/// sphere (axis renormalised, at most 0.3 rad) with `ln κ` clamped to its range and the logit
/// and `ln κ` steps limited.
impl lm::LeastSquares for Smoothed<'_> {
    type Point = SgState;
    fn n_params(&self, st: &SgState) -> usize {
        4 * st.k
    }
    fn cost(&self, st: &SgState) -> f64 {
        self.eval(st, None)
    }
    fn normal_equations(&self, st: &SgState, jtj: &mut [f64], jtr: &mut [f64]) -> f64 {
        let np = 4 * st.k;
        let obj = self.eval(st, Some((jtj, jtr)));
        for i in 0..np {
            for j in 0..i {
                jtj[j * np + i] = jtj[i * np + j];
            }
        }
        obj
    }
    fn retract(&self, st: &SgState, d: &[f64], nst: &mut SgState) {
        nst.clone_from(st);
        for j in 0..st.k {
            let (t1, t2) = tangents(st.axes[j]);
            nst.sl[j] += d[4 * j].clamp(-3.0, 3.0);
            nst.lk[j] =
                (st.lk[j] + d[4 * j + 1].clamp(-1.5, 1.5)).clamp(KAPPA_MIN.ln(), KAPPA_MAX.ln());
            // Axis steps of at most 0.3 rad.
            let (s1, s2) = (d[4 * j + 2], d[4 * j + 3]);
            let step = (s1 * s1 + s2 * s2).sqrt();
            let scale = if step > 0.3 { 0.3 / step } else { 1.0 };
            nst.axes[j] = (st.axes[j] + (t1 * s1 + t2 * s2) * scale).normalize();
        }
    }
}

/// Where a final Levenberg–Marquardt polish started: the polished EM lobes of a given id, or
/// the greedy state of a given number of lobes less one.
#[derive(Clone, Copy, PartialEq)]
enum Start {
    Em(usize),
    Greedy(usize),
}

/// The smoothed refinement of the EM fits of one footprint at every K (module docs), with what
/// different K share computed once: the smoothed data, the LM polish of each distinct EM fit,
/// the greedy states (the greedy start with `kmax = K` is a prefix of the one with a larger
/// `kmax`) and the final polish of each distinct start. [`Refiner::refine`] returns exactly
/// what refining those EM lobes alone with `kmax = K` would.
pub(super) struct Refiner<'a> {
    pub(super) sm: Smoothed<'a>,
    energy: f64,
    polished: Vec<(usize, SgState, f64)>,
    greedy: Vec<(SgState, f64)>,
    greedy_done: bool,
    finals: Vec<(Start, Vec<L>)>,
}

impl<'a> Refiner<'a> {
    pub(super) fn new(pts: &'a [Pt], lambda: f64) -> Refiner<'a> {
        let sm = Smoothed::new(pts, lambda);
        let energy = sm.target.iter().map(|t| t * t).sum();
        Refiner {
            sm,
            energy,
            polished: Vec::new(),
            greedy: Vec::new(),
            greedy_done: false,
            finals: Vec::new(),
        }
    }

    /// Refine the EM fit `lobes` (identified by `em_id`: equal ids, equal lobes) on the smoothed
    /// L2 objective unless it is already within [`SMOOTH_KEEP`]: LM from the EM lobes and from
    /// a greedy start (up to `kmax` lobes); the lobes of the lower objective are returned.
    pub(super) fn refine(&mut self, em_id: usize, lobes: &[L], kmax: usize) -> Vec<L> {
        if lobes.is_empty() || self.sm.hs.len() < 4 * kmax {
            return lobes.to_vec();
        }
        // The EM fit is kept unless it is off by more than SMOOTH_KEEP (relative L2): the
        // refinement models the peaks as spherical Gaussians and ignores detail finer than the
        // kernel, which a sharper facet BRDF than the kernel would see.
        let a = SgState::from_lobes(lobes);
        if self.sm.eval(&a, None) <= SMOOTH_KEEP * SMOOTH_KEEP * self.energy {
            return lobes.to_vec();
        }
        let oa = if let Some(p) = self.polished.iter().find(|p| p.0 == em_id) {
            p.2
        } else {
            let mut a = a;
            let o = self.sm.polish(&mut a, SMOOTH_START_ITERATIONS);
            self.polished.push((em_id, a, o));
            o
        };
        // The greedy start only when the EM start leaves more than SMOOTH_GOOD (relative L2).
        let start = if oa <= SMOOTH_GOOD * SMOOTH_GOOD * self.energy {
            Start::Em(em_id)
        } else {
            let g = self.greedy_at(kmax);
            if self.greedy[g].1 < oa {
                Start::Greedy(g)
            } else {
                Start::Em(em_id)
            }
        };
        if let Some(f) = self.finals.iter().find(|f| f.0 == start) {
            return f.1.clone();
        }
        let mut best = match start {
            Start::Em(id) => self.polished.iter().find(|p| p.0 == id).unwrap().1.clone(),
            Start::Greedy(g) => self.greedy[g].0.clone(),
        };
        self.sm.lm(&mut best, SMOOTH_ITERATIONS, SMOOTH_TOL);
        let out = best.to_lobes();
        self.finals.push((start, out.clone()));
        out
    }

    /// The smoothed fit from the one start `lobes` (the children's lobes reduced to K, parent
    /// module's [`super::fit_lobes_seeded`]; no EM start, no greedy start): `lobes` as they are
    /// when within [`SMOOTH_KEEP`] (relative smoothed L2, as [`Self::refine`] keeps an EM fit);
    /// else LM-polished with dead lobes re-seeded ([`Smoothed::polish`], as each start of
    /// [`Self::refine`]); when that leaves more than [`SMOOTH_GOOD`] (where [`Self::refine`]
    /// would try its greedy start), the lightest lobe is moved once to where the data most
    /// exceed the fit ([`Smoothed::add_lobe`], LM-polished) and kept if that lowers the
    /// objective; then LM to convergence (as [`Self::refine`]'s better start). `None` when the
    /// data give fewer than `4 · lobes.len()` half vectors ([`Self::refine`] leaves its EM fit
    /// as it is there; the caller fits by EM instead).
    pub(super) fn refine_from(&self, lobes: &[L]) -> Option<Vec<L>> {
        if lobes.is_empty() || self.sm.hs.len() < 4 * lobes.len() {
            return None;
        }
        let mut st = SgState::from_lobes(lobes);
        if self.sm.eval(&st, None) <= SMOOTH_KEEP * SMOOTH_KEEP * self.energy {
            return Some(lobes.to_vec());
        }
        let o = self.sm.polish(&mut st, SMOOTH_START_ITERATIONS);
        if o > SMOOTH_GOOD * SMOOTH_GOOD * self.energy && st.k > 1 {
            // The children's lobes can sit where the children's (maximum-likelihood, on the
            // finest smoothed level) fits put them; one lobe moved where the fit is most short
            // recovers most of what the greedy start won there (docs/benchmarks.md, "Extraction
            // speed, 2026-12-04 (evening)").
            let w = st.weights();
            let j = (0..st.k)
                .min_by(|&a, &b| w[a].total_cmp(&w[b]))
                .unwrap_or(0);
            let mut t = st.clone();
            t.remove(j);
            self.sm.add_lobe(&mut t, 1.0 / st.k as f64);
            if self
                .sm
                .lm(&mut t, SMOOTH_START_ITERATIONS, SMOOTH_TOL_START)
                < o
            {
                st = t;
            }
        }
        self.sm.lm(&mut st, SMOOTH_ITERATIONS, SMOOTH_TOL);
        Some(st.to_lobes())
    }

    /// The greedy fit with at most `kmax` lobes ([`Smoothed::greedy`]), as an index into
    /// `self.greedy` (states of 1, 2, … lobes, computed as far as needed).
    fn greedy_at(&mut self, kmax: usize) -> usize {
        if self.greedy.is_empty() {
            let (st, o) = self.sm.greedy(1, SMOOTH_START_ITERATIONS, SMOOTH_MIN_DROP);
            self.greedy.push((st, o));
        }
        while self.greedy.len() < kmax && !self.greedy_done {
            let (st, obj) = self.greedy.last().unwrap().clone();
            let mut next = st.clone();
            self.sm.add_lobe(&mut next, 1.0 / (st.k + 1) as f64);
            let o = self
                .sm
                .lm(&mut next, SMOOTH_START_ITERATIONS, SMOOTH_TOL_START);
            if o > obj * (1.0 - SMOOTH_MIN_DROP) {
                self.greedy_done = true;
                break;
            }
            self.greedy.push((next, o));
        }
        self.greedy.len().min(kmax) - 1
    }

    /// The K-chain's own candidate (parent module docs): `lobes` (the fit at K − 1) plus one
    /// lobe of weight `1/k` where the data most exceed them, LM-polished on the smoothed
    /// objective.
    pub(super) fn plus_one(&self, lobes: &[L], k: usize) -> Vec<L> {
        let mut st = SgState::from_lobes(lobes);
        if st.k >= MAX_LOBES {
            return lobes.to_vec();
        }
        self.sm.add_lobe(&mut st, 1.0 / k as f64);
        self.sm
            .lm(&mut st, SMOOTH_START_ITERATIONS, SMOOTH_TOL_START);
        st.to_lobes()
    }
}

/// The shading error of `lobes` against the points `pts` under the kernel of exponent
/// `lambda` (parent module's [`super::shading_error`]): RMS over the sample half vectors of
/// [`Smoothed`] of the kernel-blurred difference, over the largest blurred value of the points.
pub(super) fn rms_of_peak(pts: &[Pt], lobes: &[L], lambda: f64) -> f64 {
    Smoothed::new(pts, lambda).rms_of_peak(lobes).unwrap_or(0.0)
}

/// Relative smoothed L2 error of the EM fit up to which it is kept as it is.
const SMOOTH_KEEP: f64 = 0.05;
/// Relative L2 error of the smoothed fit below which the EM start is not challenged by the
/// greedy one.
const SMOOTH_GOOD: f64 = 0.03;
/// Most entries the smoothed objective is computed from (a strided subset beyond).
pub(super) const SMOOTH_MAX_POINTS: usize = 1024;
/// Most LM steps per start (and per greedy stage) of the smoothed refinement; the starts stop
/// when a step gains less than [`SMOOTH_TOL_START`] (relative).
const SMOOTH_START_ITERATIONS: usize = 10;
const SMOOTH_TOL_START: f64 = 1e-3;
/// Most LM steps of the final polish of the better start; it stops when a step gains less than
/// [`SMOOTH_TOL`].
const SMOOTH_ITERATIONS: usize = 30;
const SMOOTH_TOL: f64 = 1e-5;
/// The greedy start adds a lobe only when it lowers the smoothed objective by more than this
/// fraction.
pub(super) const SMOOTH_MIN_DROP: f64 = 0.02;

#[cfg(test)]
mod tests {
    use super::*;

    /// The smoothed target, two half vectors per SSE2 register on x86-64, is the scalar sum
    /// bit for bit (odd and even counts; terms beyond the cut left out).
    #[test]
    fn smoothed_target_is_the_scalar_sum_bit_for_bit() {
        use super::super::test_dirs::random_dir;
        let mut rng = meso_testkit::rng(0x9e37_79b9);
        let unit: Vec<(DVec3, f64)> = (0..300)
            .map(|k| (random_dir(&mut rng, 2.0), 1.0 / 300.0 + 1e-5 * f64::from(k)))
            .collect();
        for n in [1usize, 2, 37, 128] {
            let hs: Vec<DVec3> = (0..n).map(|_| random_dir(&mut rng, 1.5)).collect();
            for (lambda, cut) in [(3.0, -1.0), (80.0, 0.5), (2000.0, 0.9)] {
                let got = smoothed_target(&hs, &unit, lambda, cut);
                for (h, g) in hs.iter().zip(&got) {
                    let mut want = 0.0;
                    for &(m, w) in &unit {
                        let c = h.dot(m);
                        if c > cut {
                            want += w * fast_exp_neg(lambda * (c - 1.0));
                        }
                    }
                    assert_eq!(
                        g.to_bits(),
                        want.to_bits(),
                        "n {n}, λ {lambda}: {g} vs {want}"
                    );
                }
            }
        }
    }

    /// The responses four half vectors at a time (AVX2) are the scalar ones bit for bit, the
    /// gradient's too, with lanes of `r ≤ 20` (broad lobes facing away) among them.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn quad_responses_are_the_scalar_ones_bit_for_bit() {
        use super::super::test_dirs::random_dir;
        if !super::super::em::quads::available() {
            return;
        }
        let mut rng = meso_testkit::rng(0x5eed_0003);
        let lambda = 40.0;
        let mut slow = 0;
        for kappa in [1e-3, 0.7, 5.0, 39.0, 41.0, 300.0, 2.5e5] {
            let ls: Vec<SgLobe> = (0..MAX_LOBES)
                .map(|_| SgLobe::new(random_dir(&mut rng, 1.2), kappa))
                .collect();
            for _ in 0..50 {
                let mut h4: Vec<DVec3> = (0..4).map(|_| random_dir(&mut rng, 3.0)).collect();
                // Some half vectors opposite a lobe: r = |κa + λh| small near κ = λ.
                h4[3] = -ls[0].a;
                for grad in [false, true] {
                    let mut out = [[[0.0; 4]; 4]; MAX_LOBES];
                    // SAFETY: AVX2 is available (checked above).
                    unsafe { responses_quad(&ls, lambda, &h4, grad, &mut out) };
                    for (l, o) in ls.iter().zip(&out) {
                        for (q, &h) in h4.iter().enumerate() {
                            let want = sg_response(l, lambda, h, grad);
                            let r = (kappa * kappa + lambda * (lambda + 2.0 * kappa * l.a.dot(h)))
                                .max(0.0)
                                .sqrt();
                            slow += usize::from(r <= 20.0);
                            for p in 0..if grad { 4 } else { 1 } {
                                assert_eq!(o[q][p].to_bits(), want[p].to_bits(), "κ {kappa}");
                            }
                        }
                    }
                }
            }
        }
        assert!(slow > 0, "no lane took the scalar branch");
    }

    /// The smoothed target four (AVX2) and eight (AVX-512) half vectors at a time is the scalar
    /// sum bit for bit.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn quad_target_is_the_scalar_sum_bit_for_bit() {
        use super::super::test_dirs::random_dir;
        if !super::super::em::quads::available() {
            return;
        }
        let mut rng = meso_testkit::rng(0x5eed_0004);
        let unit: Vec<(DVec3, f64)> = (0..200)
            .map(|k| (random_dir(&mut rng, 2.0), 1.0 / 200.0 + 1e-5 * f64::from(k)))
            .collect();
        let hs: Vec<DVec3> = (0..40).map(|_| random_dir(&mut rng, 1.5)).collect();
        for (lambda, cut) in [(3.0, -1.0), (40.0, 0.5), (2000.0, 0.9)] {
            let mut got = vec![0.0; hs.len()];
            // SAFETY: AVX2 is available (checked above).
            unsafe { target_quads(&hs, &unit, lambda, cut, &mut got) };
            let mut want = vec![0.0; hs.len()];
            // SAFETY: SSE2 is part of every x86-64 CPU.
            unsafe { target_pairs(&hs, &unit, lambda, cut, &mut want) };
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(g.to_bits(), w.to_bits(), "λ {lambda}");
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                let mut got = vec![0.0; hs.len()];
                // SAFETY: AVX-512F is available (checked just above).
                unsafe { target_octs(&hs, &unit, lambda, cut, &mut got) };
                for (g, w) in got.iter().zip(&want) {
                    assert_eq!(g.to_bits(), w.to_bits(), "AVX-512, λ {lambda}");
                }
            }
        }
    }

    #[test]
    fn sg_response_matches_quadrature_and_its_gradient() {
        let a = DVec3::new(0.3, -0.2, 0.9).normalize();
        let lambda = 40.0;
        for kappa in [0.5, 8.0, 150.0] {
            let l = SgLobe::new(a, kappa);
            let h = DVec3::new(-0.1, 0.25, 0.95).normalize();
            let g = sg_response(&l, lambda, h, true);
            // Midpoint quadrature of ∫ sg(m) exp(λ(h·m − 1)) dm on a fine equal-area grid.
            let grid = SphereGrid { res: 512 };
            let norm = sg::normaliser(kappa);
            let q: f64 = (0..grid.bins())
                .map(|b| {
                    let m = grid.point(b, 0.5, 0.5);
                    norm * (kappa * (a.dot(m) - 1.0)).exp() * (lambda * (h.dot(m) - 1.0)).exp()
                })
                .sum::<f64>()
                * grid.bin_solid_angle();
            assert!((g[0] - q).abs() < 2e-3 * q, "κ {kappa}: {} vs {q}", g[0]);
            // Derivatives against central differences.
            let e = 1e-6;
            let dk = (sg_response(&SgLobe::new(a, kappa * (1.0 + e)), lambda, h, false)[0]
                - sg_response(&SgLobe::new(a, kappa * (1.0 - e)), lambda, h, false)[0])
                / (2.0 * e);
            assert!(
                (g[1] - dk).abs() < 1e-5 * (1.0 + dk.abs()),
                "∂κ {} vs {dk}",
                g[1]
            );
            for (t, gi) in [(l.t1, g[2]), (l.t2, g[3])] {
                let gp = sg_response(
                    &SgLobe::new((a + t * e).normalize(), kappa),
                    lambda,
                    h,
                    false,
                );
                let gm = sg_response(
                    &SgLobe::new((a - t * e).normalize(), kappa),
                    lambda,
                    h,
                    false,
                );
                let d = (gp[0] - gm[0]) / (2.0 * e);
                assert!((gi - d).abs() < 1e-5 * (1.0 + d.abs()), "∂a {gi} vs {d}");
            }
        }
    }

    #[test]
    fn kappa_and_eta_round_trip() {
        for eta in [0.5, 4.0, 20.0, 300.0, 1e5] {
            let back = kappa_eta(peak_kappa(eta));
            assert!((back - eta).abs() < 1e-6 * eta, "{eta} -> {back}");
        }
    }
}
