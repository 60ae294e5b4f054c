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
//! * **Smoothed refinement** (levels of at most `smooth_texels` texels, when
//!   `smooth_exponent` λ > 0). Maximum likelihood is the wrong objective for shading when K
//!   peaks cannot follow the normals: it is dominated by where the normals pile up (an
//!   egg crate's normals sit on the edges of a diamond, a ring 26–37° from the normal, densest
//!   at its corners) and puts narrow peaks there, leaving the rest of the ring dark: the coarse
//!   levels of the zoom bump map shaded 13–45% too dark at the bench's view
//!   (`docs/figures.md`, diagnosis). A renderer only sees the NDF through the facet BRDF, a
//!   kernel about 10° wide; so the lobes are refined to minimise
//!   `Σ_h (∫ n_fit(m) K(h·m) dm − Σ_n w_n K(h·m_n))²` with `K = exp(λ(h·m − 1))`, over the
//!   upper-hemisphere centres `h` of an equal-area grid of spacing ≈ the kernel's width `1/√λ`
//!   near the data (the data term from up to 1024 entries, weights normalised to 1). Each peak
//!   is treated as the spherical Gaussian of the same mean cosine `η/(η+4)` (as `NdfMapped`
//!   does; [`meso_core::sg::kappa_same_mean_cos`]), so the smoothed lobe is exact in closed form (`sg_response`). Levenberg–Marquardt
//!   over axes, `ln κ` and softmax weight logits (the weights stay a probability: Eq. 1) runs
//!   from two starts: the EM lobes (a lobe whose weight dies is re-seeded) and a greedy start
//!   (one lobe, then lobes added where the data most exceed the fit, while each lowers the
//!   objective by > 2%, up to `max_lobes`; tried only when the EM start leaves a relative
//!   smoothed L2 error above 3%); the lower objective wins. EM fits already within 5%
//!   (relative smoothed L2) are kept as they are: the spherical-Gaussian stand-in for a Phong
//!   peak (same mean cosine, a slightly narrower core) and the kernel's blindness to finer
//!   detail would cost a facet BRDF sharper than the kernel a few percent (a Beckmann α = 0.1
//!   facet on a random surface lost 4–5% when every fit was refined). It never raises the
//!   smoothed objective above the EM fit's; it can raise the binned L2 residual below (which
//!   rewards detail finer than any facet BRDF sees).
//!
//! The quality of a fit is measured by [`ndf_l2_error`]: the relative L2 distance between the
//! lobes' probability per bin of a [`RESIDUAL_GRID_RES`]² equal-area grid and the histogram of
//! the footprint's normals.

use crate::sphgrid::SphereGrid;
use glam::DVec3;
use meso_core::linalg::cholesky_solve;
use meso_core::ndf::PhongLobe;
use meso_core::sg;
use std::f64::consts::PI;

// The lobe bounds live in `crate::limits` (other crates read them there); re-exported here.
pub use crate::limits::{AXIS_MIN_Z, ETA_MAX, ETA_MIN, MAX_LOBES};

/// The bounds every fitted lobe satisfies: axis at `z ≥` [`AXIS_MIN_Z`], exponent in
/// `[`[`ETA_MIN`]`, `[`ETA_MAX`]`]`.
fn bounded(axis: DVec3, eta: f64) -> (DVec3, f64) {
    let a = if axis.z < AXIS_MIN_Z {
        let r = (axis.x * axis.x + axis.y * axis.y).sqrt();
        let (cx, cy) = if r > 1e-12 {
            (axis.x / r, axis.y / r)
        } else {
            (1.0, 0.0)
        };
        let s = (1.0 - AXIS_MIN_Z * AXIS_MIN_Z).sqrt();
        DVec3::new(cx * s, cy * s, AXIS_MIN_Z)
    } else {
        axis
    };
    let eta = if eta.is_finite() {
        eta.clamp(ETA_MIN, ETA_MAX)
    } else {
        ETA_MIN
    };
    (a, eta)
}
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
    /// Exponent λ of the smoothing kernel `exp(λ(h·m − 1))` of the smoothed refinement (module
    /// docs; the kernel is about as wide as a Phong facet `(h·m)^(λ−1)`, ≈ `1/√λ` rad); 0 turns
    /// the refinement off (maximum-likelihood EM only). Default 40.
    pub smooth_exponent: f64,
    /// Levels with at most this many texels get the smoothed refinement (default 1024; it
    /// costs ≈ 1 ms per texel, so the big fine levels keep the EM fit).
    pub smooth_texels: usize,
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
            smooth_exponent: 40.0,
            smooth_texels: 1024,
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

/// Two unit tangents orthogonal to `a` and to each other.
fn tangents(a: DVec3) -> (DVec3, DVec3) {
    let t = if a.x.abs() < 0.9 { DVec3::X } else { DVec3::Y };
    let t1 = (t - a * a.dot(t)).normalize();
    (t1, a.cross(t1))
}

/// Lobe parameters of the smoothed fit: axes, `ln κ`, softmax logits of the weights (so the
/// weights always sum to 1).
#[derive(Clone)]
struct SgState {
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
    /// Upper-hemisphere centres of the sample grid, per grid resolution.
    static SAMPLE_GRID: std::cell::RefCell<(usize, Vec<DVec3>)> =
        const { std::cell::RefCell::new((0, Vec::new())) };
}

/// The smoothed objective of one footprint (module docs): the sample half vectors `hs` (centres
/// of an equal-area grid with spacing ≈ the kernel's width, upper hemisphere, within reach of the
/// data) and the data smoothed by the kernel at them.
struct Smoothed<'a> {
    lambda: f64,
    pts: &'a [Pt],
    total: f64,
    hs: Vec<DVec3>,
    target: Vec<f64>,
}

impl<'a> Smoothed<'a> {
    fn new(pts: &'a [Pt], lambda: f64) -> Smoothed<'a> {
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
        let target = hs
            .iter()
            .map(|&h| {
                let mut s = 0.0;
                for &(m, w) in &unit {
                    let c = h.dot(m);
                    if c > cut {
                        s += w * fast_exp_neg(lambda * (c - 1.0));
                    }
                }
                s
            })
            .collect();
        Smoothed {
            lambda,
            pts,
            total,
            hs,
            target,
        }
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
        for (&h, &t) in self.hs.iter().zip(&self.target) {
            let mut m = 0.0;
            for j in 0..k {
                gs[j] = sg_response(&ls[j], self.lambda, h, grad);
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
                    let ra = row[a];
                    jtr[a] += ra * r;
                    for (b, v) in jtj[a * np..=a * np + a].iter_mut().enumerate() {
                        *v += ra * row[b];
                    }
                }
            }
        }
        obj
    }

    /// Levenberg–Marquardt from `st`, at most `iters` steps, until a step lowers the objective
    /// by less than the fraction `tol`; returns the objective.
    fn lm(&self, st: &mut SgState, iters: usize, tol: f64) -> f64 {
        let k = st.k;
        let np = 4 * k;
        let mut jtj = [0.0; 16 * MAX_LOBES * MAX_LOBES];
        let mut a = [0.0; 16 * MAX_LOBES * MAX_LOBES];
        let mut jtr = [0.0; 4 * MAX_LOBES];
        let mut d = [0.0; 4 * MAX_LOBES];
        let mut mu = 1e-3;
        let mut obj = self.eval(st, None);
        for _ in 0..iters {
            jtj[..np * np].fill(0.0);
            jtr[..np].fill(0.0);
            self.eval(st, Some((&mut jtj[..np * np], &mut jtr[..np])));
            for i in 0..np {
                for j in 0..i {
                    jtj[j * np + i] = jtj[i * np + j];
                }
            }
            let mut accepted = false;
            for _ in 0..10 {
                a[..np * np].copy_from_slice(&jtj[..np * np]);
                for i in 0..np {
                    d[i] = -jtr[i];
                    a[i * np + i] += mu * jtj[i * np + i] + 1e-18;
                }
                if !cholesky_solve(&mut a[..np * np], &mut d[..np], np) {
                    mu *= 4.0;
                    continue;
                }
                let mut nst = st.clone();
                for j in 0..k {
                    let (t1, t2) = tangents(st.axes[j]);
                    nst.sl[j] += d[4 * j].clamp(-3.0, 3.0);
                    nst.lk[j] = (st.lk[j] + d[4 * j + 1].clamp(-1.5, 1.5))
                        .clamp(KAPPA_MIN.ln(), KAPPA_MAX.ln());
                    // Axis steps of at most 0.3 rad.
                    let (s1, s2) = (d[4 * j + 2], d[4 * j + 3]);
                    let step = (s1 * s1 + s2 * s2).sqrt();
                    let scale = if step > 0.3 { 0.3 / step } else { 1.0 };
                    nst.axes[j] = (st.axes[j] + (t1 * s1 + t2 * s2) * scale).normalize();
                }
                let o = self.eval(&nst, None);
                if o < obj {
                    let drop = (obj - o) / obj.max(1e-300);
                    *st = nst;
                    obj = o;
                    mu = (mu / 3.0).max(1e-9);
                    accepted = drop > tol;
                    break;
                }
                mu *= 4.0;
            }
            if !accepted {
                break;
            }
        }
        obj
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

/// Refine the EM fit `lobes` on the smoothed L2 objective (module docs) unless it is already
/// within [`SMOOTH_KEEP`]: LM from the EM lobes and from a greedy start (up to `kmax` lobes);
/// the lobes of the lower objective are kept.
fn refine_smoothed(pts: &[Pt], lobes: &mut Vec<L>, lambda: f64, kmax: usize) {
    let sm = Smoothed::new(pts, lambda);
    if lobes.is_empty() || sm.hs.len() < 4 * kmax {
        return;
    }
    let mut a = SgState::from_lobes(lobes);
    let energy: f64 = sm.target.iter().map(|t| t * t).sum();
    // The EM fit is kept unless it is off by more than SMOOTH_KEEP (relative L2): the
    // refinement models the peaks as spherical Gaussians and ignores detail finer than the
    // kernel, which a sharper facet BRDF than the kernel would see.
    if sm.eval(&a, None) <= SMOOTH_KEEP * SMOOTH_KEEP * energy {
        return;
    }
    let oa = sm.polish(&mut a, SMOOTH_START_ITERATIONS);
    // The greedy start only when the EM start leaves more than SMOOTH_GOOD (relative L2).
    let mut best = if oa <= SMOOTH_GOOD * SMOOTH_GOOD * energy {
        a
    } else {
        let (b, ob) = sm.greedy(kmax, SMOOTH_START_ITERATIONS, SMOOTH_MIN_DROP);
        if ob < oa {
            b
        } else {
            a
        }
    };
    sm.lm(&mut best, SMOOTH_ITERATIONS, SMOOTH_TOL);
    *lobes = best.to_lobes();
}

/// Relative smoothed L2 error of the EM fit up to which it is kept as it is.
const SMOOTH_KEEP: f64 = 0.05;
/// Relative L2 error of the smoothed fit below which the EM start is not challenged by the
/// greedy one.
const SMOOTH_GOOD: f64 = 0.03;
/// Most entries the smoothed objective is computed from (a strided subset beyond).
const SMOOTH_MAX_POINTS: usize = 1024;
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
const SMOOTH_MIN_DROP: f64 = 0.02;

fn to_phong(lobes: &[L]) -> Vec<PhongLobe> {
    let s: f64 = lobes.iter().map(|l| l.w).sum();
    lobes
        .iter()
        .map(|l| {
            let (axis, exponent) = bounded(l.a, l.eta);
            PhongLobe {
                axis,
                weight: l.w / s,
                exponent,
            }
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
    fit_lobes_with(
        entries,
        params,
        params.max_em_points,
        true,
        true,
        &mut pts,
        out,
    );
}

/// [`fit_lobes`] with the EM subset capped at `max_points` entries (≤ `params.max_em_points`)
/// and a caller-owned buffer (no allocation per call once it has grown). `thorough` runs every
/// EM for `em_iterations`; otherwise K is chosen after 5 EM iterations per start and the chosen
/// K polished with at most 10 more (the cheap path of the big, fine pyramid levels). `smooth`
/// adds the smoothed refinement (module docs) when `params.smooth_exponent > 0`.
pub fn fit_lobes_with(
    entries: &[Entry],
    params: &FitParams,
    max_points: usize,
    thorough: bool,
    smooth: bool,
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
            let (axis, exponent) = bounded(a, eta_from_mean_t(log_t(a, mean)));
            out.push(PhongLobe {
                axis,
                weight: e.w / total,
                exponent,
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
    if smooth && params.smooth_exponent > 0.0 {
        // The smoothed objective sees up to SMOOTH_MAX_POINTS entries (a strided subset of
        // `max_em_points` aliases with periodic maps).
        let data: Vec<Pt>;
        let data = if entries.len() > pts.len() {
            let stride = entries.len().div_ceil(SMOOTH_MAX_POINTS);
            data = entries
                .iter()
                .step_by(stride)
                .map(|e| (e.mean(), e.w))
                .collect();
            &data[..]
        } else {
            pts
        };
        refine_smoothed(data, &mut lobes, params.smooth_exponent, kmax);
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

/// Probability of each bin of `grid` under any core NDF (`∫ n = 1`): Phong peaks by
/// [`lobe_bin_mass`], delta sums by their histogram, a vMF lobe narrower than a quarter of a bin
/// in the bin of its axis, other densities (vMF, tabulated) with 3×3 points per bin,
/// renormalised (a density the points all miss goes to the bin of its mean normal). `out` has
/// `grid.bins()` entries.
pub fn ndf_bin_mass(ndf: &meso_core::ndf::Ndf, grid: SphereGrid, out: &mut [f64]) {
    use meso_core::ndf::Ndf;
    out.fill(0.0);
    let da = grid.bin_solid_angle();
    match ndf {
        Ndf::PhongPeaks(p) => return lobe_bin_mass(p.lobes(), grid, out),
        Ndf::Deltas(d) => {
            for n in d.normals() {
                out[grid.bin(n.normal)] += n.weight;
            }
            return;
        }
        Ndf::VonMisesFisher(v) if 1.0 / (v.kappa + 1.0).sqrt() < 0.25 * da.sqrt() => {
            out[grid.bin(v.mu)] = 1.0;
            return;
        }
        _ => {}
    }
    let mut tot = 0.0;
    for (k, o) in out.iter_mut().enumerate() {
        let mut s = 0.0;
        for a in 0..3 {
            for b in 0..3 {
                s += ndf.eval(grid.point(k, (a as f64 + 0.5) / 3.0, (b as f64 + 0.5) / 3.0));
            }
        }
        *o = s / 9.0 * da;
        tot += *o;
    }
    if tot > 0.0 {
        out.iter_mut().for_each(|o| *o /= tot);
    } else {
        out[grid.bin(ndf.stats().mean_normal.normalize_or(DVec3::Z))] = 1.0;
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
