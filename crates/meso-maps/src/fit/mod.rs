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
//!   lobes by more than `min_gain` nats. On the cheap path without the smoothed refinement
//!   (levels of more than `smooth_texels` texels, or every level with `smooth_exponent` 0; EM
//!   footprints of more than 4 points per lobe; `max_lobes` ≥ 3) K = `max_lobes` is tried
//!   first: its k-means start's EM fit is kept when it gains more than
//!   `(max_lobes − 1)·min_gain` over one lobe (what growing K one step at a time needs to get
//!   there); only otherwise does K grow from 1.
//!   Footprints with more than `max_em_points` entries are fitted on a strided subset; footprints
//!   with at most 4 entries per lobe use the k-means clusters directly (no EM), and there K
//!   goes on growing past a K that gains too little (hard clusters of a K that splits the
//!   footprint's groups badly can lose to one EM lobe where a larger K separates them: a
//!   brick facade's 4 × 4 texels of five groups of identical normals got one broad lobe, and a
//!   GGX α = 0.05 facet shaded that pyramid level 3.05× too bright, 1.16× with the fix).
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
//! * **Coarse levels from their children** ([`FitParams::smooth_from_children`], opt-in: the
//!   steep render test fails with it; [`fit_lobes_seeded`]). A texel's NDF is the
//!   weight-averaged mixture of its four children's, so on the pyramid's smoothed levels the
//!   children's lobes (each weight times its child's share of the facet weight) are merged
//!   pairwise down to `max_lobes` by a moment-preserving mixture reduction (`reduce`: least
//!   Ward cost of the lobes' mean normals `a·η/(η+4)`; a merged lobe keeps the pair's weight
//!   and mean normal), and that one start is refined on the smoothed objective as above (kept
//!   when within 5%, else LM with dead lobes re-seeded; when that leaves more than 3%, the
//!   lightest lobe moved once to where the data most exceed the fit, kept if better; then LM to
//!   convergence). No EM, no k-means, no greedy start: a 1024² extraction takes ≈ 11–16% less
//!   CPU. Footprints of at most `max_lobes` entries stay exact; the K chain ignores the
//!   children.
//!
//! * **The K chain** ([`FitParams::k_chain`], opt-in; issue #11 item 4). Everything above is the
//!   *single* fit at one `max_lobes`; its objective can rise with `max_lobes` (EM's choice of K
//!   and the refinement's starts change with it). The lobes returned for `max_lobes` = K are the
//!   end of a chain: at K = 1 the single fit; at each K ≥ 2 the candidates are the chain's fit
//!   at K − 1, the single fit at K, and — when that does not gain — the fit at K − 1 plus one
//!   lobe (smoothed levels: `smoothed`'s lobe where the data most exceed the fit, LM-polished;
//!   otherwise `split_heaviest`, EM-polished). The lowest [`fit_objective`] wins; a candidate
//!   with more lobes than the chain's fit must lower it by the gain (`min_gain` nats, or
//!   `SMOOTH_MIN_DROP` of the smoothed objective). So the objective never rises with
//!   `max_lobes` and is never above the single fit's at the same `max_lobes`. The objective is
//!   the fit's own: the smoothed L2 objective where the refinement runs, minus the mean
//!   log-likelihood of the EM points elsewhere. The single fits at K = 1, 2, … share their EM
//!   chain, the LM polish of each distinct EM fit and the greedy states (computed once:
//!   `Single`, `smoothed::Refiner`), so the chain costs the candidates it adds and little more.
//!
//! * **K by the shading error** ([`KChoice::Shading`], with the chain; opt-in; issue #11 item
//!   4). Each texel's lobes are the candidate with the fewest lobes whose shading error (the
//!   measure of [`shading_error`], under the kernel of the material's own facet transfer,
//!   [`FitParams::facet_exponent`] / [`facet_kernel_exponent`], λ = 40 when it is not known)
//!   is within a tolerance of the least; the candidates are every fit the chain considered
//!   (the single fits at K = 1, …, `max_lobes` and the chain's own). With tolerance 0 the
//!   shading error never rises with `max_lobes` (the candidates at K are among those at
//!   K + 1). It is measured on the fit's own data (the refinement's points, or the EM points
//!   on the big levels), not on the 64² grid of the report. Not the default: on the steep
//!   stone-wall render test it shaded worse than the single fit (Phong 20, box, 8 texels/px
//!   3.12 % at tolerance 0 against the 3 % bound, 3.45 % at 0.2 %; with the facet's own
//!   λ = 20, 3.33 %), and it costs ≈ 2× the single fit's extraction time (docs/heightmaps.md,
//!   "Lobe fits that cannot go wrong").
//!
//! The quality of a fit is measured by [`ndf_l2_error`]: the relative L2 distance between the
//! lobes' probability per bin of a [`RESIDUAL_GRID_RES`]² equal-area grid and the histogram of
//! the footprint's normals; and by [`shading_error`], the error a user can read: both seen
//! through a facet kernel, RMS over half vectors as a fraction of the peak.
//!
//! # Layout
//! The public fit API (entries, parameters, [`fit_lobes`]) lives here; the maximum-likelihood
//! start (k-means seeds and EM) in `em`, the smoothed Levenberg–Marquardt refinement in
//! `smoothed`, and the binned quality measure ([`ndf_l2_error`]) in `residual`. The arrows run
//! one way: this module uses the three, `smoothed` uses `em`'s lobe type and fast `exp`, and
//! `residual` reads the entries' bins (`entries_l2_error`).

mod em;
mod reduce;
mod residual;
mod smoothed;

use crate::sphgrid::SphereGrid;
use em::{
    em, eta_from_mean_t, kmeans_from, log_t, loglik, split_heaviest, KmeansSeeds, Pt, PtLanes, L,
};
use glam::DVec3;
use meso_core::ndf::PhongLobe;
use smoothed::{rms_of_peak, Refiner, Smoothed, SMOOTH_MAX_POINTS, SMOOTH_MIN_DROP};

// The lobe bounds live in `crate::limits` (other crates read them there); re-exported here.
pub use crate::limits::{AXIS_MIN_Z, ETA_MAX, ETA_MIN, MAX_LOBES};
pub use residual::{
    entries_l2_error, lobe_bin_mass, ndf_bin_mass, ndf_l2_error, RESIDUAL_GRID_RES,
};

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

/// Merge lists each sorted by bin with no bin twice (as [`merge_entries`] leaves them) into
/// `out` (cleared first), summing entries of equal bins in list order: a linear k-way merge,
/// O(n·lists) against the O(n log n) of sorting the concatenation (the pyramid's recomputed
/// merges, `level_fit::texel_entries`, ran mostly in that sort).
pub fn merge_sorted_entries(lists: &[&[Entry]], out: &mut Vec<Entry>) {
    out.clear();
    debug_assert!(lists
        .iter()
        .all(|l| l.windows(2).all(|p| p[0].bin < p[1].bin)));
    match lists {
        [] => {}
        [a] => out.extend_from_slice(a),
        _ => {
            out.reserve(lists.iter().map(|l| l.len()).max().unwrap_or(0));
            let mut pos = [0usize; MAX_MERGE_LISTS];
            assert!(lists.len() <= MAX_MERGE_LISTS, "at most four lists");
            loop {
                let mut bin = u32::MAX;
                for (l, &p) in lists.iter().zip(&pos) {
                    if let Some(e) = l.get(p) {
                        bin = bin.min(e.bin);
                    }
                }
                if bin == u32::MAX {
                    break;
                }
                let mut acc: Option<Entry> = None;
                for (l, p) in lists.iter().zip(&mut pos) {
                    if let Some(e) = l.get(*p) {
                        if e.bin == bin {
                            *p += 1;
                            match &mut acc {
                                None => acc = Some(*e),
                                Some(a) => {
                                    a.w += e.w;
                                    a.m += e.m;
                                }
                            }
                        }
                    }
                }
                out.extend(acc);
            }
        }
    }
}

/// The most lists [`merge_sorted_entries`] merges (a texel's four children).
const MAX_MERGE_LISTS: usize = 4;

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
    /// Whether the pyramid fits its smoothed levels (≤ `smooth_texels` texels, above level 0)
    /// from their children's lobes: each texel's four children's lobes merged down to
    /// `max_lobes` (moment-preserving mixture reduction) and refined on the smoothed objective
    /// from that one start, instead of EM and the refinement's EM and greedy starts (module
    /// docs, "Coarse levels from their children"; [`fit_lobes_seeded`]). Default `false`,
    /// **opt-in**: it takes 11 % less CPU on a 1024² Gaussian map and 16 % less on the facade
    /// texture, with the coarse levels' mean shading error within +0.5 % and +4 % of the default
    /// fit's, but the steep render test (`crates/meso-render/tests/steep.rs`) fails with it
    /// (Phong 20, box, 8 texels/px 3.08 % against the 3 % bound; Lambert, trilinear, 4
    /// texels/px 14.4 % and 15.9 % against 14 %) (docs/benchmarks.md, "Extraction speed,
    /// 2026-12-04 (evening)"). Not read with the K chain.
    pub smooth_from_children: bool,
    /// Which levels of a pyramid above level 0 are fitted by merging their children's lobes
    /// ([`merge_lobes`]: each texel's four children's lobes, weighted by the children's shares
    /// of the facet weight, merged pairwise down to `max_lobes`, keeping each merged pair's
    /// weight and mean normal) instead of EM on the texel's own facets (module docs, "Levels
    /// merged from their children"). Default [`MergeLevels::Plain`]: the levels without the
    /// smoothed refinement (more than `smooth_texels` texels). Not read with the K chain
    /// (`k_chain`) or [`KChoice::Shading`]: their candidates are each texel's own fits.
    pub merge_levels: MergeLevels,
    /// Whether the lobes come from the K chain (module docs, "The K chain"): the fit's
    /// objective never rises with `max_lobes`. Default `false`, the single fit at `max_lobes`
    /// (one of the chain's candidates): on the steep stone-wall render test
    /// (`crates/meso-render/tests/steep.rs`) the chain's lower smoothed objective shaded worse
    /// (Phong 20, box, 8 texels/px 3.15 % against the 3 % bound; Lambert, trilinear, 4 texels/px
    /// 15.3 % against 14 %), so it stays opt-in until its objective matches shading; nor did
    /// choosing K by the shading error ([`KChoice::Shading`]) pass it (module docs).
    pub k_chain: bool,
    /// How each texel's lobes are picked among the K chain's candidates (module docs, "K by the
    /// shading error"). Default [`KChoice::Objective`]: with `k_chain` the end of the chain,
    /// without it the single fit. [`KChoice::Shading`] runs the chain whatever `k_chain` says.
    pub k_choice: KChoice,
    /// Exponent λ of the kernel `exp(λ(h·m − 1))` of the material's own facet transfer
    /// ([`facet_kernel_exponent`]: Phong η → η, Beckmann/GGX α → 2/α², Lambert → 2), by which
    /// [`KChoice::Shading`] picks K and the pyramid reports each level's shading error
    /// ([`Self::shading_exponent`]); 0 (the default) when the transfer is not known: then
    /// `smooth_exponent`, or [`SHADING_KERNEL_EXPONENT`] when that is 0.
    pub facet_exponent: f64,
}

/// Which levels of a pyramid are fitted by merging their children's lobes
/// ([`FitParams::merge_levels`]). Level 0 is always fitted from its cells' facets; level 1
/// merges its cells' facets (each merged bin of the entry grid its own lobe), the levels above
/// it their children's fitted lobes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum MergeLevels {
    /// None: every level fitted from its own facets (EM; the smoothed refinement on the small
    /// levels). The fit before 2026-12-06.
    None,
    /// The plain levels (more than [`FitParams::smooth_texels`] texels: those EM alone fits
    /// otherwise); the smoothed levels keep their own fit. Default: on a 1024² Gaussian map
    /// the same shading error level by level within ±0.9 points of peak (levels 1 and 4
    /// better, 2 and 3 worse) at ≈ 0.6× the extraction time (docs/heightmaps.md, "Levels
    /// merged from their children").
    #[default]
    Plain,
    /// Every level above level 0, the smoothed ones too (no EM, no refinement): the fast fit,
    /// ≈ 0.35× the time, with the coarse levels' shading error up to 1.4× the default's.
    All,
}

impl MergeLevels {
    /// Every value with its name (`meso extract --merge-levels`, Python `merge_levels=`).
    pub const NAMES: [(MergeLevels, &'static str); 3] = [
        (MergeLevels::Plain, "plain"),
        (MergeLevels::None, "none"),
        (MergeLevels::All, "all"),
    ];

    /// Its name: `"plain"`, `"none"` or `"all"`.
    #[must_use]
    pub fn name(self) -> &'static str {
        Self::NAMES
            .iter()
            .find(|(m, _)| *m == self)
            .map_or("plain", |(_, n)| n)
    }

    /// The value of a name, if it is one of [`Self::NAMES`].
    #[must_use]
    pub fn from_name(name: &str) -> Option<MergeLevels> {
        Self::NAMES
            .iter()
            .find(|(_, n)| *n == name)
            .map(|(m, _)| *m)
    }
}

/// How the K chain ([`FitParams::k_chain`]) picks a texel's lobes among its candidates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum KChoice {
    /// The end of the chain: the lowest [`fit_objective`], which never rises with `max_lobes`.
    Objective,
    /// By the shading error ([`shading_error`]'s measure, kernel
    /// [`FitParams::shading_exponent`]): among the chain's fits and the single fits at
    /// K = 1, …, `max_lobes`, the one with the fewest lobes whose shading error is within
    /// `tolerance` (a fraction of the peak, 0.001 = 0.1 % of peak, added) of the least; equal
    /// counts go to the lower error. Measured on the fit's own data (the smoothed refinement's
    /// points where it runs, else the EM points), not on the 64² grid of the report.
    Shading {
        /// Shading error (fraction of the peak, ≥ 0) that one lobe less may cost.
        tolerance: f64,
    },
}

/// The exponent λ of the facet kernel `exp(λ(h·m − 1))` that stands for `transfer` in the
/// shading error ([`FitParams::facet_exponent`]): a Phong facet `(m·h)^η` (Eq. 10, bisector)
/// → η; the reflected form `(R·o)^η` turns twice as fast with m → 4η; a Beckmann or GGX facet
/// of roughness α (the geometric mean of `alpha_x` and `alpha_y`) → 2/α² (the Gaussian
/// `exp(−tan²θ/α²)` of Beckmann's slopes; GGX's core is twice as curved, 4/α², and its tails
/// far wider, so 2/α² is a compromise there, not measured); Lambert (`(i·m)(o·m)`, two cosines) → 2. `None` for a
/// mirror facet (it sees the NDF itself, no kernel) or a non-positive result. Each λ is
/// clamped to `[1, 10⁴]`.
#[must_use]
pub fn facet_kernel_exponent(transfer: &meso_core::transfer::Transfer) -> Option<f64> {
    use meso_core::transfer::{PhongVariant, Transfer};
    let l = match transfer {
        Transfer::Phong {
            exponent, variant, ..
        } => match variant {
            PhongVariant::Half => *exponent,
            PhongVariant::Reflect => 4.0 * exponent,
        },
        Transfer::Lambert { .. } => 2.0,
        Transfer::Mirror { .. } => return None,
        Transfer::Microfacet { distribution, .. } => {
            2.0 / (distribution.alpha_x * distribution.alpha_y)
        }
    };
    (l.is_finite() && l > 0.0).then(|| l.clamp(1.0, 1e4))
}

impl FitParams {
    /// The kernel exponent λ of the shading error (by which [`KChoice::Shading`] picks K, and
    /// which the pyramid's levels report): `facet_exponent` when > 0, else `smooth_exponent`
    /// when > 0, else [`SHADING_KERNEL_EXPONENT`].
    #[must_use]
    pub fn shading_exponent(&self) -> f64 {
        [self.facet_exponent, self.smooth_exponent]
            .into_iter()
            .find(|l| l.is_finite() && *l > 0.0)
            .unwrap_or(SHADING_KERNEL_EXPONENT)
    }
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
            smooth_from_children: false,
            merge_levels: MergeLevels::Plain,
            k_chain: false,
            k_choice: KChoice::Objective,
            facet_exponent: 0.0,
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
///
/// With `params.k_chain` the lobes come from the K chain (module docs, "The K chain"): their
/// [`fit_objective`] never rises with `params.max_lobes`, and is never above that of the single
/// fit at `params.max_lobes` (what `k_chain = false` returns).
pub fn fit_lobes_with(
    entries: &[Entry],
    params: &FitParams,
    max_points: usize,
    thorough: bool,
    smooth: bool,
    pts: &mut Vec<(DVec3, f64)>,
    out: &mut Vec<PhongLobe>,
) {
    fit_lobes_seeded(
        entries, params, max_points, thorough, smooth, None, pts, out,
    );
}

/// [`fit_lobes_with`] given the lobes of the footprint's children (`children`: each lobe's
/// weight times its child's share of the footprint's weight, so that they sum to 1; the
/// footprint's NDF is their mixture). Where the smoothed refinement runs (`smooth` and
/// `params.smooth_exponent > 0`) and the K chain does not (`params.k_chain` false, the
/// objective choice of K), the lobes are the children's merged down to `max_lobes` (`reduce`'s
/// moment-preserving reduction: weights and mean normal kept) and refined on the smoothed
/// objective from that one start: no EM, no greedy start (module docs, "Coarse levels from
/// their children"). Otherwise, or with `children` `None` or empty, or too few half vectors
/// for the refinement: exactly [`fit_lobes_with`].
#[allow(clippy::too_many_arguments)]
pub fn fit_lobes_seeded(
    entries: &[Entry],
    params: &FitParams,
    max_points: usize,
    thorough: bool,
    smooth: bool,
    children: Option<&[PhongLobe]>,
    pts: &mut Vec<(DVec3, f64)>,
    out: &mut Vec<PhongLobe>,
) {
    out.clear();
    let total: f64 = entries.iter().map(|e| e.w).sum();
    if entries.is_empty() || total <= 0.0 {
        return;
    }
    let kmax = params.max_lobes.clamp(1, MAX_LOBES);
    let n = entries.len();
    if n == 1 {
        out.extend(exact_lobes(entries, total));
        return;
    }
    // The shading choice picks among the chain's candidates, so it runs the chain.
    let chain = params.k_chain || params.k_choice != KChoice::Objective;
    if !chain && n <= kmax {
        // Every entry its own lobe: nothing of the EM fit is read (level 0's cells of two
        // facets, and every footprint of at most `max_lobes` bins).
        out.extend(exact_lobes(entries, total));
        return;
    }
    fill_em_points(entries, params, max_points, pts);
    let pts: &[Pt] = pts;
    let sdata = smooth_points(entries, pts, smooth, params);
    if let (false, Some(d), Some(c)) = (chain, &sdata, children) {
        // The children's lobes reduced to K, refined on the smoothed objective alone.
        let start = reduce::reduce_lobes(&to_l(c), kmax);
        if let Some(l) = Refiner::new(d, params.smooth_exponent).refine_from(&start) {
            out.extend(to_phong(&l));
            return;
        }
    }
    let mut single = Single::new(pts, params, thorough, sdata.as_deref());
    if !chain {
        out.extend(single.fit_top_down(kmax));
        return;
    }
    // The chain: the fit at K is the best (lowest objective) of the fit at K − 1, the single
    // fit at K, and the fit at K − 1 plus one lobe; a candidate with more lobes must lower the
    // objective by the gain (`min_gain` nats, or SMOOTH_MIN_DROP of the smoothed objective).
    // With the shading choice every distinct candidate is kept for it.
    let shading = matches!(params.k_choice, KChoice::Shading { .. });
    let mut cands: Vec<Vec<PhongLobe>> = Vec::new();
    let mut keep = |c: &Vec<PhongLobe>| {
        if shading && !cands.contains(c) {
            cands.push(c.clone());
        }
    };
    let mut cur = single.fit(1);
    keep(&cur);
    let mut o = single.objective(&cur);
    for k in 2..=kmax.min(n) {
        let prev = cur.clone();
        let cand = if n <= k {
            exact_lobes(entries, total)
        } else {
            single.fit(k)
        };
        keep(&cand);
        let oc = single.objective(&cand);
        let gained = oc < o - single.gain(o);
        if oc <= o {
            cur = cand;
            o = oc;
        }
        if !gained && n > k && !single.delta && pts.len() > 4 * k {
            let cand = single.plus_one(&prev, k);
            keep(&cand);
            let oc = single.objective(&cand);
            if oc < o - single.gain(o) {
                cur = cand;
                o = oc;
            }
        }
    }
    if let KChoice::Shading { tolerance } = params.k_choice {
        if let Some(i) = single.by_shading(&cands, params.shading_exponent(), tolerance) {
            cur = cands.swap_remove(i);
        }
    }
    out.extend(cur);
}

/// The objective the K chain never lets grow, of `lobes` (weights summing to 1) fitted to
/// `entries` by [`fit_lobes_with`] with the same `params`, `max_points` and `smooth`: with the
/// smoothed refinement (`smooth` and `params.smooth_exponent > 0`) the smoothed L2 objective
/// `Σ_h (∫ n_fit(m) K(h·m) dm − Σ_n w_n K(h·m_n))²` (module docs; dimensionless, the normals'
/// weights normalised to 1), otherwise minus the mean log-likelihood (nats per unit weight) of
/// the EM points. Footprints of one entry get 0 (their fit is exact at every K).
#[must_use]
pub fn fit_objective(
    entries: &[Entry],
    params: &FitParams,
    max_points: usize,
    smooth: bool,
    lobes: &[PhongLobe],
) -> f64 {
    let total: f64 = entries.iter().map(|e| e.w).sum();
    if entries.len() < 2 || total <= 0.0 {
        return 0.0;
    }
    let mut pts = Vec::new();
    fill_em_points(entries, params, max_points, &mut pts);
    let sdata = smooth_points(entries, &pts, smooth, params);
    let single = Single::new(&pts, params, true, sdata.as_deref());
    single.objective(lobes)
}

/// Exponent λ of the facet kernel `exp(λ(h·m − 1))` of [`shading_error`] when the fit's
/// `smooth_exponent` is 0 (the default `smooth_exponent`: ≈ 9° wide, about a Phong facet of
/// exponent 40 or a Beckmann facet of roughness α = √(2/λ) ≈ 0.22).
pub const SHADING_KERNEL_EXPONENT: f64 = 40.0;

/// Resolution of the equal-area grid the entries are merged onto for [`shading_error`] (4096
/// bins of ≈ 3.2°, a third of the kernel's width; each bin keeps its summed normals).
pub const SHADING_GRID_RES: usize = 64;

/// The shading error of `lobes` (weights summing to 1) against the merged normals `entries`,
/// as a fraction of the peak (0.01 = 1 %): both NDFs seen through the facet kernel
/// `K(h·m) = exp(λ(h·m − 1))` of exponent `lambda` (> 0; ≈ `1/√λ` rad wide, what a facet BRDF
/// of that width shades of the NDF at half vector `h`), the RMS of the difference over the
/// half vectors of an equal-area grid of spacing ≈ the kernel's width (the upper-hemisphere
/// ones within reach of the normals), divided by the largest blurred value of the normals.
/// Each Phong peak is taken as the spherical Gaussian of the same mean cosine (the renderer's
/// `NdfMapped` substitution, as the smoothed refinement does), so the blur is exact in closed
/// form; the normals are merged onto a [`SHADING_GRID_RES`]² grid first. 0 for no entries.
#[must_use]
pub fn shading_error(entries: &[Entry], lobes: &[PhongLobe], lambda: f64) -> f64 {
    if entries.is_empty() || lobes.is_empty() || !(lambda.is_finite() && lambda > 0.0) {
        return 0.0;
    }
    let grid = SphereGrid {
        res: SHADING_GRID_RES,
    };
    let pts: Vec<Pt> = if entries.len() <= 256 {
        entries.iter().map(|e| (e.mean(), e.w)).collect()
    } else {
        let mut bins = vec![(DVec3::ZERO, 0.0f64); grid.bins()];
        for e in entries {
            let b = &mut bins[grid.bin(e.mean().normalize_or(DVec3::Z))];
            b.0 += e.m;
            b.1 += e.w;
        }
        bins.into_iter()
            .filter(|b| b.1 > 0.0)
            .map(|(m, w)| (m / w, w))
            .collect()
    };
    rms_of_peak(&pts, &to_l(lobes), lambda)
}

/// The spread (rad², as a fraction of the shading kernel's own variance `1/λ`) that merging
/// two lobes may add to the mean normals and still be taken for one lobe below `max_lobes`
/// ([`merge_lobes`]): 1/250 of the kernel's variance. On the facade height map (1K, 8-bit)
/// with λ = 40, levels 1–3 kept 1.53 / 2.16 / 2.88 lobes per texel with a mean shading error of
/// 0.06 / 0.34 / 0.68 % of peak (EM: 1.66 / 2.34 / 3.02 lobes, 0.07 / 0.40 / 0.83 %); merging
/// only identical lobes kept 1.66 / 3.65 / 4.00 for the same error, 3× this spread
/// 1.51 / 2.12 / 2.80 for 0.06 / 0.36 / 0.71 % (docs/heightmaps.md, "Levels merged from their
/// children").
pub const MERGE_SAME_SPREAD: f64 = 0.004;

/// The lobes `children` (weights > 0, any total: a texel's children's lobes, each weight times
/// its child's share of their facet weight) merged pairwise by least Ward cost of their mean
/// normals, each merge keeping the pair's weight and mean normal (`reduce`), down to at most
/// `k` lobes and on below `k` while a merge adds less spread than [`MERGE_SAME_SPREAD`]`/λ`
/// (λ the exponent of the shading kernel, [`FitParams::shading_exponent`]), into `out`
/// (cleared first; weights summing to 1, axes and exponents in the fit's bounds). The fit of
/// the levels [`FitParams::merge_levels`] names.
pub fn merge_lobes(children: &[PhongLobe], k: usize, lambda: f64, out: &mut Vec<PhongLobe>) {
    out.clear();
    let same = MERGE_SAME_SPREAD / lambda.max(1.0);
    out.extend(to_phong(&reduce::reduce_lobes_within(
        &to_l(children),
        k,
        same,
    )));
}

/// Every entry its own lobe: axis = its mean direction, exponent from its spread (exact; also
/// [`merge_lobes`]' start on level 1).
pub(crate) fn exact_lobes(entries: &[Entry], total: f64) -> Vec<PhongLobe> {
    entries
        .iter()
        .map(|e| {
            let mean = e.mean();
            let a = mean.normalize();
            let (axis, exponent) = bounded(a, eta_from_mean_t(log_t(a, mean)));
            PhongLobe {
                axis,
                weight: e.w / total,
                exponent,
            }
        })
        .collect()
}

/// The EM points: a strided subset of at most `max_points` (≤ `params.max_em_points`, ≥ 8)
/// entries' mean vectors and weights.
fn fill_em_points(entries: &[Entry], params: &FitParams, max_points: usize, pts: &mut Vec<Pt>) {
    let cap = max_points.min(params.max_em_points).max(8);
    let stride = entries.len().div_ceil(cap);
    pts.clear();
    pts.extend(entries.iter().step_by(stride).map(|e| (e.mean(), e.w)));
}

/// The data of the smoothed objective (`None` without the refinement): up to
/// SMOOTH_MAX_POINTS entries (a strided subset of `max_em_points` aliases with periodic maps),
/// or the EM points when they are all the entries.
fn smooth_points(
    entries: &[Entry],
    pts: &[Pt],
    smooth: bool,
    params: &FitParams,
) -> Option<Vec<Pt>> {
    if !(smooth && params.smooth_exponent > 0.0) {
        return None;
    }
    Some(if entries.len() > pts.len() {
        let stride = entries.len().div_ceil(SMOOTH_MAX_POINTS);
        entries
            .iter()
            .step_by(stride)
            .map(|e| (e.mean(), e.w))
            .collect()
    } else {
        pts.to_vec()
    })
}

fn to_l(lobes: &[PhongLobe]) -> Vec<L> {
    lobes
        .iter()
        .map(|l| L {
            a: l.axis,
            w: l.weight,
            eta: l.exponent,
        })
        .collect()
}

/// The maximum-likelihood EM chain of the single fit for one value of its `small` flag: the
/// lobes after considering K = 1, 2, … (index K − 1) and the K at which they were last changed.
struct EmChain {
    states: Vec<(Vec<L>, usize)>,
    ll: f64,
    stopped: bool,
}

/// The single fit (the fitter before the K chain: EM with K grown by `min_gain`, then the
/// smoothed refinement) at any K, with what different K share computed once. `fit(k)` is
/// exactly the single fit with `max_lobes = k`.
struct Single<'a> {
    pts: &'a [Pt],
    /// `pts` in the E-step's lanes, laid out once for every EM run and likelihood.
    lanes: PtLanes,
    ptotal: f64,
    full: bool,
    iters: usize,
    sel_iters: usize,
    min_gain: f64,
    /// Nearly identical normals: one delta-like lobe at every K.
    delta: bool,
    chains: [EmChain; 2],
    /// The k-means points' directions and seeds, shared by the starts at every K (made at the
    /// first k-means start).
    seeds: Option<KmeansSeeds>,
    /// EM fits polished after the choice of K, by id.
    polished: Vec<(usize, Vec<L>)>,
    refiner: Option<Refiner<'a>>,
    smooth_exponent: f64,
}

impl<'a> Single<'a> {
    fn new(
        pts: &'a [Pt],
        params: &FitParams,
        thorough: bool,
        sdata: Option<&'a [Pt]>,
    ) -> Single<'a> {
        let ptotal: f64 = pts.iter().map(|p| p.1).sum();
        let iters = params.em_iterations.max(3);
        // With the full point budget (small levels) every EM runs `em_iterations`; on
        // budget-capped levels, selection runs short EM (5 iterations) and the chosen K is
        // polished with ≤ 10 more.
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
        let lanes = PtLanes::new(pts);
        let ll = em(
            pts,
            &lanes,
            &mut lobes,
            ptotal,
            if full { iters } else { iters.min(10) },
        );
        let delta = lobes.len() == 1 && lobes[0].eta >= ETA_MAX;
        let chain = || EmChain {
            states: vec![(lobes.clone(), 1)],
            ll,
            stopped: false,
        };
        Single {
            pts,
            lanes,
            ptotal,
            full,
            iters,
            sel_iters,
            min_gain: params.min_gain,
            delta,
            chains: [chain(), chain()],
            seeds: None,
            polished: Vec::new(),
            refiner: sdata.map(|d| Refiner::new(d, params.smooth_exponent)),
            smooth_exponent: params.smooth_exponent,
        }
    }

    /// The chain's objective of final lobes ([`fit_objective`]).
    fn objective(&self, lobes: &[PhongLobe]) -> f64 {
        match &self.refiner {
            Some(r) => r.sm.objective_of(&to_l(lobes)),
            None => -loglik(self.pts, &self.lanes, &to_l(lobes), self.ptotal),
        }
    }

    /// The index of the candidate [`KChoice::Shading`] picks (the fewest lobes whose shading
    /// error under the kernel of exponent `lambda` is within `tolerance` of the least; equal
    /// counts by the lower error), or `None` when the data give no peak to measure against.
    /// The measure is [`shading_error`]'s, on the refinement's data (its own smoothed data when
    /// its kernel is `lambda`) or the EM points.
    fn by_shading(&self, cands: &[Vec<PhongLobe>], lambda: f64, tolerance: f64) -> Option<usize> {
        let own;
        let sm = match &self.refiner {
            Some(r) if r.sm.lambda() == lambda => &r.sm,
            r => {
                own = Smoothed::new(r.as_ref().map_or(self.pts, |r| r.sm.points()), lambda);
                &own
            }
        };
        let errs: Vec<f64> = cands
            .iter()
            .map(|c| sm.rms_of_peak(&to_l(c)))
            .collect::<Option<_>>()?;
        let least = errs.iter().copied().fold(f64::INFINITY, f64::min);
        (0..cands.len())
            .filter(|&i| errs[i] <= least + tolerance)
            .min_by(|&a, &b| {
                cands[a]
                    .len()
                    .cmp(&cands[b].len())
                    .then(errs[a].total_cmp(&errs[b]))
            })
    }

    /// The drop of the objective below `o` that justifies one more lobe.
    fn gain(&self, o: f64) -> f64 {
        match &self.refiner {
            Some(_) => SMOOTH_MIN_DROP * o.abs(),
            None => self.min_gain,
        }
    }

    /// The EM chain of flag `small` up to K = `k`.
    fn extend(&mut self, small: bool, k: usize) {
        let (pts, ptotal, full, sel_iters) = (self.pts, self.ptotal, self.full, self.sel_iters);
        let lanes = &self.lanes;
        let ch = &mut self.chains[usize::from(small)];
        let seeds = &mut self.seeds;
        while ch.states.len() < k {
            let kk = ch.states.len() + 1;
            let (lobes, last) = ch.states.last().unwrap().clone();
            if ch.stopped {
                ch.states.push((lobes, last));
                continue;
            }
            let mut best: Option<(f64, Vec<L>)> = None;
            // Thorough fits try both starts at every K, the cheap path both at K = 2 and
            // k-means after; small footprints (no EM) only k-means (a split start needs EM to
            // move).
            let starts: &[usize] = if small {
                &[0]
            } else if full || kk == 2 {
                &[0, 1]
            } else {
                &[0]
            };
            for &start in starts {
                let mut trial = if start == 0 {
                    kmeans_from(pts, seeds.get_or_insert_with(|| KmeansSeeds::new(pts)), kk)
                } else {
                    split_heaviest(&lobes)
                };
                // Small footprints (≤ 4 entries per lobe): the starts are used as they are.
                let l2 = if small {
                    loglik(pts, lanes, &trial, ptotal)
                } else {
                    em(pts, lanes, &mut trial, ptotal, sel_iters)
                };
                if trial.len() == kk && best.as_ref().is_none_or(|b| l2 > b.0) {
                    best = Some((l2, trial));
                }
            }
            match best {
                Some((l2, trial)) if l2 - ch.ll > self.min_gain => {
                    ch.ll = l2;
                    ch.states.push((trial, kk));
                }
                // Small footprints: the k-means clusters are taken without EM, so a K that
                // splits the footprint's groups badly can lose to K − 1 where a larger K
                // separates them (five groups of identical normals: two clusters lose to one
                // EM lobe, four gain); the chain goes on to the next K.
                _ if small => ch.states.push((lobes, last)),
                _ => {
                    ch.stopped = true;
                    ch.states.push((lobes, last));
                }
            }
        }
    }

    /// The single fit with `max_lobes = k` (final, bounded lobes).
    fn fit(&mut self, k: usize) -> Vec<PhongLobe> {
        if self.delta {
            return to_phong(&self.chains[0].states[0].0);
        }
        let small = self.pts.len() <= 4 * k;
        self.extend(small, k);
        let (lobes, last) = self.chains[usize::from(small)].states[k - 1].clone();
        self.finish(lobes, last, small, k)
    }

    /// [`Self::fit`] at `k`, K chosen top-down on the cheap path (not `full`, no smoothed
    /// refinement, EM footprints of more than `4k` points, `k ≥ 3`): the k-means start at
    /// K = `k` is fitted first (what the chain's last step fits there: one start, k-means,
    /// independent of the chain's fits at smaller K) and kept when it has `k` lobes and raises
    /// the mean log-likelihood over the one lobe by more than `(k − 1)·min_gain` nats, which the
    /// chain needs to get there (more than `min_gain` at each of its `k − 1` steps); otherwise
    /// the chain runs as in `fit`. The same lobes as `fit(k)` wherever the chain ends at
    /// K = `k`, without its fits at 2 ≤ K < `k`; where the chain would stop earlier although
    /// the fit at `k` gains that much, the `k` lobes (1–2 % more lobes on levels 2–4 of a 1024²
    /// Gaussian map, 1–5 % on levels 3–4 of the facade texture; docs/benchmarks.md, "Extraction
    /// speed, 2026-12-05"). Not where the smoothed refinement runs: there the EM fit is the
    /// refinement's start, and the top-down one raised the facade's level-5 shading error by 8 %.
    fn fit_top_down(&mut self, k: usize) -> Vec<PhongLobe> {
        if self.delta || self.full || k < 3 || self.refiner.is_some() {
            return self.fit(k);
        }
        let small = self.pts.len() <= 4 * k;
        let ch = &self.chains[usize::from(small)];
        if small || ch.states.len() != 1 {
            return self.fit(k);
        }
        let ll1 = ch.ll;
        let mut trial = kmeans_from(
            self.pts,
            self.seeds.get_or_insert_with(|| KmeansSeeds::new(self.pts)),
            k,
        );
        let l = em(
            self.pts,
            &self.lanes,
            &mut trial,
            self.ptotal,
            self.sel_iters,
        );
        if trial.len() == k && l - ll1 > (k - 1) as f64 * self.min_gain {
            return self.finish(trial, k, false, k);
        }
        self.fit(k)
    }

    /// The final lobes of the chain state `lobes` last changed at K = `last` (chain of flag
    /// `small`) for `max_lobes = k`: EM-polished on the cheap path, then refined on the smoothed
    /// objective where that runs.
    fn finish(&mut self, lobes: Vec<L>, last: usize, small: bool, k: usize) -> Vec<PhongLobe> {
        let id = usize::from(small) * (MAX_LOBES + 1) + last;
        let improved = last > 1;
        let lobes = if improved && !small && self.iters > self.sel_iters {
            if let Some(p) = self.polished.iter().find(|p| p.0 == id) {
                p.1.clone()
            } else {
                let mut l = lobes;
                em(
                    self.pts,
                    &self.lanes,
                    &mut l,
                    self.ptotal,
                    (self.iters - self.sel_iters).min(10),
                );
                self.polished.push((id, l.clone()));
                l
            }
        } else {
            lobes
        };
        let lobes = match &mut self.refiner {
            Some(r) if self.smooth_exponent > 0.0 => r.refine(id, &lobes, k),
            _ => lobes,
        };
        to_phong(&lobes)
    }

    /// The chain's own candidate at K = `k`: the fit at K − 1 (`prev`) plus one lobe, polished
    /// on the chain's objective (smoothed: a lobe where the data most exceed the fit, LM;
    /// otherwise the heaviest lobe split in two, EM).
    fn plus_one(&self, prev: &[PhongLobe], k: usize) -> Vec<PhongLobe> {
        let lobes = to_l(prev);
        match &self.refiner {
            Some(r) => to_phong(&r.plus_one(&lobes, k)),
            None => {
                let mut l = split_heaviest(&lobes);
                em(self.pts, &self.lanes, &mut l, self.ptotal, self.sel_iters);
                to_phong(&l)
            }
        }
    }
}

/// Random directions for the tests of the fit's kernels.
#[cfg(test)]
mod test_dirs {
    use glam::DVec3;

    /// A unit vector with slopes uniform in `[−spread, spread]` along x and y.
    pub(super) fn random_dir(rng: &mut meso_testkit::Rng, spread: f64) -> DVec3 {
        let [u, v] = meso_testkit::uniform2(rng);
        DVec3::new(spread * (2.0 * u - 1.0), spread * (2.0 * v - 1.0), 1.0).normalize()
    }
}
