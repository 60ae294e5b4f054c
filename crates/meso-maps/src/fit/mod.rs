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
//!
//! # Layout
//! The public fit API (entries, parameters, [`fit_lobes`]) lives here; the maximum-likelihood
//! start (k-means seeds and EM) in `em`, the smoothed Levenberg–Marquardt refinement in
//! `smoothed`, and the binned quality measure ([`ndf_l2_error`]) in `residual`. The arrows run
//! one way: this module uses the three, `smoothed` uses `em`'s lobe type and fast `exp`.

mod em;
mod residual;
mod smoothed;

use crate::sphgrid::SphereGrid;
use em::{em, eta_from_mean_t, kmeans_init, log_t, loglik, split_heaviest, Pt, L};
use glam::DVec3;
use meso_core::ndf::PhongLobe;
use smoothed::{refine_smoothed, SMOOTH_MAX_POINTS};

// The lobe bounds live in `crate::limits` (other crates read them there); re-exported here.
pub use crate::limits::{AXIS_MIN_Z, ETA_MAX, ETA_MIN, MAX_LOBES};
pub use residual::{lobe_bin_mass, ndf_bin_mass, ndf_l2_error, RESIDUAL_GRID_RES};

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
