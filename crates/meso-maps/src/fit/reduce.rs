//! Mixture reduction: the lobes of a texel's children merged pairwise, preserving each merged
//! pair's weight and mean normal, down to K lobes (after Han et al. 2007, "Frequency domain
//! normal map filtering", who merge von Mises–Fisher lobes by their mean vectors).
//!
//! A Phong peak of axis `a` and exponent η (density `(η+2)/(8π) ((1 + a·m)/2)^(η/2)`, the fit's
//! Eq. 12 form) has the mean normal `E[m] = a · η/(η + 4)`. A weighted mixture's mean normal is
//! the weighted sum of its lobes'. Two lobes `(w₁, μ₁)`, `(w₂, μ₂)` (μ the mean normal) are
//! merged into the lobe of weight `w₁ + w₂` and mean normal `(w₁μ₁ + w₂μ₂)/(w₁ + w₂)`: axis its
//! direction, exponent `η = 4r/(1 − r)` from its length `r` (so the merged lobe keeps the pair's
//! spread about their common mean, the part of it between the two axes included). The pair
//! merged first is the one of least Ward cost `w₁w₂/(w₁ + w₂) · |μ₁ − μ₂|²` (the weighted squared
//! distance the merge moves the mean normals by), repeated until K lobes are left.
//!
//! Used as a start of the smoothed refinement on the coarse levels ([`super::fit_lobes_seeded`]):
//! a texel's NDF is the area-weighted mixture of its four children's, so the children's fitted
//! lobes, reduced to K, are a start near the texel's own fit without a greedy search.

use super::em::L;
use super::{bounded, ETA_MAX};
use glam::DVec3;

/// The mean normal of a lobe of axis `a` (unit) and exponent `eta` (≥ 0): `a · η/(η + 4)`.
fn mean_normal(a: DVec3, eta: f64) -> DVec3 {
    a * (eta / (eta + 4.0))
}

/// The lobe (axis, exponent) of mean normal `mu` (length < 1): axis its direction, exponent
/// `4r/(1 − r)` of its length `r` (capped at [`ETA_MAX`]); a zero mean normal gets the axis
/// `fallback` and exponent 0 (uniform).
fn lobe_of_mean(mu: DVec3, fallback: DVec3) -> (DVec3, f64) {
    let r = mu.length();
    if r <= 1e-300 {
        return (fallback, 0.0);
    }
    let r = r.min(1.0 - 1e-12);
    (mu / mu.length(), (4.0 * r / (1.0 - r)).min(ETA_MAX))
}

/// The Ward cost (per unit of the lobes' total weight) up to which two lobes are taken for
/// the same one and merged even below K: mean normals ≈ 10⁻⁵ apart at equal weights (a flat
/// footprint's children are K copies of one delta-like lobe).
const SAME_LOBE_COST: f64 = 1e-10;

/// Merge the weighted lobes `lobes` (weights > 0, any total) pairwise by least Ward cost of
/// their mean normals (module docs) until at most `k` (≥ 1) are left (fewer when some are the
/// same lobe, [`SAME_LOBE_COST`]). Weights are returned
/// normalised to sum to 1; each lobe's axis and exponent are clamped to the fit's bounds. Zero-
/// weight lobes are dropped first. Empty when no lobe has weight.
pub(super) fn reduce_lobes(lobes: &[L], k: usize) -> Vec<L> {
    reduce_lobes_within(lobes, k, SAME_LOBE_COST)
}

/// [`reduce_lobes`], merging on below `k` while the cheapest pair's Ward cost is at most
/// `same` (per unit of the lobes' total weight: the spread of the mean normals the merge adds,
/// rad² for sharp lobes; at least [`SAME_LOBE_COST`]). (A version with the pairs' costs kept
/// in a matrix, updated for the merged lobe only, took more time on a pyramid's texels of
/// 8–16 lobes: 1.16–1.23 s against 1.28–1.41 s for a 1024² extraction merging every level.)
pub(super) fn reduce_lobes_within(lobes: &[L], k: usize, same: f64) -> Vec<L> {
    let same = same.max(SAME_LOBE_COST);
    let k = k.max(1);
    // Per lobe: weight, mean normal, and the lobe itself while unmerged.
    let mut cur: Vec<(f64, DVec3, Option<L>)> = lobes
        .iter()
        .filter(|l| l.w > 0.0 && l.w.is_finite())
        .map(|l| (l.w, mean_normal(l.a, l.eta), Some(*l)))
        .collect();
    let total: f64 = cur.iter().map(|c| c.0).sum();
    if cur.is_empty() || total <= 0.0 {
        return Vec::new();
    }
    loop {
        if cur.len() <= 1 {
            break;
        }
        let mut best = (f64::INFINITY, 0, 1);
        for i in 0..cur.len() {
            for j in i + 1..cur.len() {
                let (wi, mi, _) = cur[i];
                let (wj, mj, _) = cur[j];
                let c = wi * wj / (wi + wj) * (mi - mj).length_squared();
                if c < best.0 {
                    best = (c, i, j);
                }
            }
        }
        let (cost, i, j) = best;
        // Down to `k`, and on while the pair is the same lobe (cost 0 up to rounding).
        if cur.len() <= k && cost > same * total {
            break;
        }
        let (wj, mj, _) = cur.swap_remove(j);
        let (wi, mi, _) = cur[i];
        let w = wi + wj;
        cur[i] = (w, (mi * wi + mj * wj) / w, None);
    }
    cur.into_iter()
        .map(|(w, mu, orig)| {
            let (a, eta) = match orig {
                // An unmerged lobe keeps its own axis and exponent (its mean normal's length
                // would round its exponent).
                Some(l) => (l.a, l.eta),
                None => lobe_of_mean(mu, DVec3::Z),
            };
            let (a, eta) = bounded(a, eta);
            L {
                a,
                w: w / total,
                eta,
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::test_dirs::random_dir;
    use super::*;

    fn random_lobes(rng: &mut meso_testkit::Rng, n: usize) -> Vec<L> {
        (0..n)
            .map(|_| {
                let [u, v] = meso_testkit::uniform2(rng);
                L {
                    a: random_dir(rng, 0.8),
                    w: 0.05 + u,
                    eta: 2.0 + 400.0 * v * v,
                }
            })
            .collect()
    }

    /// The merged lobes keep the children's total weight and their weighted mean normal (the
    /// first two moments a reduction must preserve), at every K.
    #[test]
    fn reduction_preserves_weight_and_mean_normal() {
        let mut rng = meso_testkit::rng(7);
        for n in [1usize, 3, 8, 16] {
            let lobes = random_lobes(&mut rng, n);
            let total: f64 = lobes.iter().map(|l| l.w).sum();
            let mean: DVec3 = lobes
                .iter()
                .map(|l| mean_normal(l.a, l.eta) * (l.w / total))
                .sum();
            for k in 1..=4 {
                let r = reduce_lobes(&lobes, k);
                assert_eq!(r.len(), n.min(k), "n {n} k {k}");
                let w: f64 = r.iter().map(|l| l.w).sum();
                assert!((w - 1.0).abs() < 1e-12, "weights sum {w}");
                let m: DVec3 = r.iter().map(|l| mean_normal(l.a, l.eta) * l.w).sum();
                assert!(
                    (m - mean).length() < 1e-9,
                    "n {n} k {k}: mean normal {m} against {mean}"
                );
                for l in &r {
                    assert!(l.a.z >= crate::limits::AXIS_MIN_Z && l.eta <= ETA_MAX);
                    assert!((l.a.length() - 1.0).abs() < 1e-12);
                }
            }
        }
    }

    /// Two lobes of one axis merge into a lobe of that axis whose mean cosine is the weighted
    /// mean of theirs: w = 0.25 at η = 4 (mean cosine 1/2) and w = 0.75 at η = 36 (9/10) give
    /// mean cosine 0.8, η = 4 · 0.8/0.2 = 16.
    #[test]
    fn same_axis_lobes_merge_to_the_mean_cosine() {
        let a = DVec3::new(0.3, -0.2, 1.0).normalize();
        let r = reduce_lobes(
            &[
                L {
                    a,
                    w: 0.25,
                    eta: 4.0,
                },
                L {
                    a,
                    w: 0.75,
                    eta: 36.0,
                },
            ],
            1,
        );
        assert_eq!(r.len(), 1);
        assert!((r[0].a - a).length() < 1e-12);
        assert!((r[0].eta - 16.0).abs() < 1e-9, "{}", r[0].eta);
        assert!((r[0].w - 1.0).abs() < 1e-15);
    }

    /// A unit normal drawn from the Phong peak of axis `a` and exponent `eta`: `u = (1 + a·m)/2`
    /// has density ∝ `u^(η/2)` on [0, 1], so `u = U^(1/(η/2 + 1))`; the azimuth is uniform.
    fn sample_peak(rng: &mut meso_testkit::Rng, a: DVec3, eta: f64) -> DVec3 {
        let [p, q] = meso_testkit::uniform2(rng);
        let u = p.powf(1.0 / (eta / 2.0 + 1.0));
        let c = (2.0 * u - 1.0).clamp(-1.0, 1.0);
        let s = (1.0 - c * c).sqrt();
        let phi = 2.0 * std::f64::consts::PI * q;
        let (t1, t2) = a.any_orthonormal_pair();
        a * c + (t1 * phi.cos() + t2 * phi.sin()) * s
    }

    /// Against the fit on the raw points: four children, each of two lobes drawn around four
    /// well-separated directions (a child's lobe a few degrees off the direction, its own
    /// exponent). Reducing the children's eight lobes (their known parameters, weighted by the
    /// children's shares) to four gives what EM fits to 200 000 normals drawn from the children's
    /// mixture: the same axes within 1°, weights within 0.01 and mean cosines within 0.005.
    #[test]
    fn reduction_matches_the_fit_on_the_raw_points() {
        let mut rng = meso_testkit::rng(11);
        let dirs = [
            DVec3::new(0.5, 0.0, 1.0).normalize(),
            DVec3::new(-0.5, 0.1, 1.0).normalize(),
            DVec3::new(0.0, 0.6, 1.0).normalize(),
            DVec3::new(0.05, -0.55, 1.0).normalize(),
        ];
        let shares = [0.2, 0.3, 0.25, 0.25];
        let mut children = Vec::new();
        for (c, share) in shares.iter().enumerate() {
            // Child c: two of the four directions, jittered by ≈ 2°, weights 0.4 / 0.6.
            for (d, w) in [(c, 0.4), ((c + 1) % 4, 0.6)] {
                let a = (dirs[d] + random_dir(&mut rng, 0.03) - DVec3::Z).normalize();
                let eta = 150.0 + 300.0 * meso_testkit::uniform2(&mut rng)[0];
                children.push(L {
                    a,
                    w: share * w,
                    eta,
                });
            }
        }
        let reduced = reduce_lobes(&children, 4);
        // The raw points: the children's mixture sampled.
        let n = 200_000;
        let mut entries = Vec::with_capacity(n);
        let cum: Vec<f64> = children
            .iter()
            .scan(0.0, |s, l| {
                *s += l.w;
                Some(*s)
            })
            .collect();
        for _ in 0..n {
            let u = meso_testkit::uniform2(&mut rng)[0] * cum[cum.len() - 1];
            let l = children[cum.iter().position(|&c| u <= c).unwrap_or(7)];
            entries.push(super::super::Entry::new(
                sample_peak(&mut rng, l.a, l.eta),
                1.0,
            ));
        }
        let mut merged = Vec::new();
        super::super::merge_entries(&[&entries], &mut merged);
        let params = super::super::FitParams {
            max_lobes: 4,
            smooth_exponent: 0.0,
            max_em_points: 1 << 16,
            em_iterations: 200,
            ..Default::default()
        };
        let mut fit = Vec::new();
        super::super::fit_lobes(&merged, &params, &mut fit);
        assert_eq!(fit.len(), 4);
        for r in &reduced {
            let f = fit
                .iter()
                .max_by(|a, b| a.axis.dot(r.a).total_cmp(&b.axis.dot(r.a)))
                .unwrap();
            let angle = f.axis.dot(r.a).clamp(-1.0, 1.0).acos().to_degrees();
            let (mr, mf) = (r.eta / (r.eta + 4.0), f.exponent / (f.exponent + 4.0));
            assert!(
                angle < 1.0 && (f.weight - r.w).abs() < 0.01 && (mr - mf).abs() < 0.005,
                "reduced {r:?} against fitted {f:?}: {angle:.3}°, mean cosines {mr:.4} / {mf:.4}"
            );
        }
    }
}
