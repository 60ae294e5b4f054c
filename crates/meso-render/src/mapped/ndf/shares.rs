//! The projected area of a texel's lobes: [`peak_projected_area`], the `E[m_z⁺]` of one Phong
//! peak (the part below the horizon covers nothing), and [`projected_shares`], each lobe's
//! share of its texel's projected area, handed down from the level-0 normals it stands for
//! (the module docs of [`crate::mapped`], "Steep maps").
//!
//! # Conventions
//! * Shares are per level, indexed like the pyramid level's lobes; a texel's shares sum to 1,
//!   or are all 0 when nothing faces up.

use meso_core::sg;
use meso_maps::Pyramid;

/// The projected area `E[m_z⁺]` of a Phong peak `((1 + a·m)/2)^(η/2)` (normalised over the
/// sphere) whose axis has `z = a_z`: the part of the lobe below the horizon covers nothing.
/// `η/(η + 4) · a_z` (which counts that part negatively) when the lobe lies above the horizon
/// to within 12 of its standard deviations `2/√η`; otherwise a quadrature over the angle α
/// from the axis with the azimuth integrated in closed form,
/// `∫₀^{2π} max(0, c + s cos φ) dφ = 2(c·acos(−c/s) + √(s² − c²))` for `|c| < s`.
pub(super) fn peak_projected_area(a_z: f64, eta: f64) -> f64 {
    let a_z = a_z.clamp(-1.0, 1.0);
    let reach = 24.0 / eta.max(1e-9).sqrt();
    if a_z.acos() + reach < std::f64::consts::FRAC_PI_2 {
        return sg::phong_peak_mean_cos(eta) * a_z;
    }
    let s_a = (1.0 - a_z * a_z).max(0.0).sqrt();
    let amax = reach.min(std::f64::consts::PI);
    const N: usize = 512;
    let (mut num, mut den) = (0.0, 0.0);
    for k in 0..N {
        let a = (k as f64 + 0.5) / N as f64 * amax;
        let (sa, ca) = a.sin_cos();
        let d = (0.5 * (1.0 + ca)).powf(0.5 * eta) * sa;
        let (c, s) = (a_z * ca, s_a * sa);
        let g = if c >= s {
            std::f64::consts::TAU * c
        } else if c <= -s {
            0.0
        } else {
            2.0 * (c * (-c / s).acos() + (s * s - c * c).sqrt())
        };
        num += d * g;
        den += d * std::f64::consts::TAU;
    }
    if den > 0.0 {
        num / den
    } else {
        a_z.max(0.0)
    }
}

/// Per level and lobe of `pyramid`, the lobe's share of its texel's projected area (the
/// shares of a texel sum to 1, or are all 0 when nothing faces up).
///
/// Level 0 takes `w·E[m_z⁺]` per lobe ([`peak_projected_area`]): exact for its lobes, which are
/// the map's own normals (one cell of projected area per texel). A coarser texel collects the
/// level-0 lobes of its footprint and hands each one's projected area to its own lobes by
/// responsibility, `∝ w_l · peak_l(a_j)` (the mixture's posterior at the level-0 normal). So a
/// lobe gets the projected area of the normals it stands for, not `w·E[m_z⁺]` of its own
/// shape: a fit can make the two very different near the horizon, where a texel's area weight
/// `1/n_z` is large (100 for a normal-map texel tilted up to `n_z = 0.01`) but its projected
/// area one cell, and any spread or axis lift of the lobe that stands for it multiplies that
/// (see the module docs, "Steep maps"). Cost: one log-density per level-0 lobe, level and
/// lobe of the covering texel; the levels run in parallel.
pub(super) fn projected_shares(pyramid: &Pyramid) -> Vec<Vec<f64>> {
    use rayon::prelude::*;
    let Some(l0) = pyramid.levels.first() else {
        return Vec::new();
    };
    let per_texel = |l: &meso_maps::Level, mut mass: Vec<f64>| -> Vec<f64> {
        for t in 0..l.texels() {
            let (a, b) = (l.lobe_start[t] as usize, l.lobe_start[t + 1] as usize);
            let total: f64 = mass[a..b].iter().sum();
            for m in &mut mass[a..b] {
                *m = if total > 0.0 { *m / total } else { 0.0 };
            }
        }
        mass
    };
    // Level 0: projected area per lobe, one cell per texel.
    let base = per_texel(
        l0,
        l0.lobes
            .iter()
            .map(|p| p.weight * peak_projected_area(p.axis.z, p.exponent))
            .collect(),
    );
    let mut out = vec![base.clone()];
    out.par_extend(pyramid.levels[1..].par_iter().enumerate().map(|(k1, l)| {
        let k = k1 + 1;
        let mut mass = vec![0.0f64; l.lobes.len()];
        let mut logr = Vec::with_capacity(8);
        for row in 0..l0.rows {
            for col in 0..l0.cols {
                let ct = row * l0.cols + col;
                let pt = (row >> k).min(l.rows - 1) * l.cols + (col >> k).min(l.cols - 1);
                let (pa, pb) = (l.lobe_start[pt] as usize, l.lobe_start[pt + 1] as usize);
                if pa == pb {
                    continue;
                }
                let (ca, cb) = (l0.lobe_start[ct] as usize, l0.lobe_start[ct + 1] as usize);
                for (lobe, &mj) in l0.lobes.range(ca, cb).zip(&base[ca..cb]) {
                    let m = lobe.axis;
                    if mj <= 0.0 {
                        continue;
                    }
                    // Log responsibilities (log-sum-exp: sharp lobes underflow).
                    logr.clear();
                    let mut best = f64::NEG_INFINITY;
                    for p in l.lobes.range(pa, pb) {
                        let x = 0.5 * (1.0 + p.axis.dot(m));
                        let v = if x > 0.0 && p.weight > 0.0 {
                            p.weight.ln() + (p.exponent + 2.0).ln() + 0.5 * p.exponent * x.ln()
                        } else {
                            f64::NEG_INFINITY
                        };
                        best = best.max(v);
                        logr.push(v);
                    }
                    if best == f64::NEG_INFINITY {
                        // Opposite every lobe: the nearest axis takes it.
                        let near = (pa..pb)
                            .max_by(|&x, &y| {
                                l.lobes
                                    .get(x)
                                    .axis
                                    .dot(m)
                                    .total_cmp(&l.lobes.get(y).axis.dot(m))
                            })
                            .unwrap_or(pa);
                        mass[near] += mj;
                        continue;
                    }
                    let z: f64 = logr.iter().map(|v| (v - best).exp()).sum();
                    for (i, v) in logr.iter().enumerate() {
                        mass[pa + i] += mj * (v - best).exp() / z;
                    }
                }
            }
        }
        per_texel(l, mass)
    }));
    out
}

#[cfg(test)]
mod tests {
    use super::super::peak_quadrature::for_each_peak_node;
    use super::*;
    use glam::DVec3;

    /// `E[m_z⁺]` of a Phong peak: the closed form above the horizon and the quadrature across
    /// it agree with a brute-force quadrature of the peak over the sphere (in the lobe's frame),
    /// and a lobe at the horizon covers far more than `μ a_z` says.
    #[test]
    fn peak_projected_area_matches_quadrature() {
        for (a_z, eta) in [
            (0.9f64, 40.0f64),
            (0.5, 4.0),
            (0.3, 40.0),
            (0.05, 4.0),
            (0.05, 100.0),
            (0.05, 1e4),
            (0.2, 1e6),
        ] {
            let axis = DVec3::new((1.0 - a_z * a_z).sqrt(), 0.0, a_z);
            let amax = (40.0 / f64::sqrt(eta)).min(std::f64::consts::PI);
            let (mut num, mut den) = (0.0, 0.0);
            for_each_peak_node(axis, DVec3::Y, eta, amax, (4000, 720), |d, m| {
                num += d * m.z.max(0.0);
                den += d;
            });
            let want = num / den;
            let got = peak_projected_area(a_z, eta);
            assert!(
                (got - want).abs() < 2e-3 * want,
                "a_z {a_z}, η {eta}: {got} vs {want}"
            );
        }
        // A lobe of η = 100 at a_z = 0.05: several times μ a_z.
        assert!(peak_projected_area(0.05, 100.0) > 2.0 * 0.05 * 100.0 / 104.0);
    }
}
