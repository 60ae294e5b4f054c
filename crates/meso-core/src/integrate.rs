//! Integrals over the sphere of normals weighted by an NDF, `∫ n(m) g(m) dω`: the quadrature
//! behind the convolution of Eq. 2/8, Smith's projected areas and the NDF statistics.
//!
//! [`integrate`] computes `∫ n(m) g(m) dω` by a deterministic form of multiple importance
//! sampling: the integrand is split between a few *warps* — one Phong-peak warp per NDF lobe, one at
//! the transfer function's peak ([`Peak`]) and a uniform warp — with balance-heuristic weights, and
//! each part is integrated by a product rule (Gauss–Legendre in the warp's radial variable × the
//! periodic midpoint rule in azimuth). [`Accuracy`] sets the number of nodes; the error falls fast
//! with it (see the tests and `docs/benchmarks.md`). Delta sums are summed exactly and the cylinder
//! is integrated along its circle.
//!
//! This module depends on [`crate::ndf`] (it reads the NDF's lobes to place its warps) and not
//! the reverse: [`Ndf::integrate`] and [`Ndf::stats`] are defined here.

use crate::frame::Frame;
use crate::ndf::{Ndf, NdfStats, PhongLobe};
use crate::quadrature::gauss_legendre;
use glam::{DMat3, DVec3};
use std::f64::consts::PI;
use std::sync::OnceLock;

/// Number of quadrature nodes per warp: `radial × azimuth`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Accuracy {
    /// Gauss–Legendre nodes in the warp's radial variable (≤ 128).
    pub radial: usize,
    /// Midpoint nodes in azimuth.
    pub azimuth: usize,
}

impl Default for Accuracy {
    /// 32 × 48 nodes per warp: ~1e-4 relative error on typical Phong-peak materials.
    fn default() -> Self {
        Accuracy {
            radial: 32,
            azimuth: 48,
        }
    }
}

impl Accuracy {
    /// 16 × 24 nodes: fast, ~1e-3.
    #[must_use]
    pub fn fast() -> Accuracy {
        Accuracy {
            radial: 16,
            azimuth: 24,
        }
    }

    /// 64 × 96 nodes: reference quality.
    #[must_use]
    pub fn fine() -> Accuracy {
        Accuracy {
            radial: 64,
            azimuth: 96,
        }
    }
}

/// A peak of an integrand in the space of normals: a Phong-peak warp `cos^exponent(α/2)` about
/// `axis` that the quadrature adds to its warps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Peak {
    /// Unit axis of the peak.
    pub axis: DVec3,
    /// Phong-peak exponent on `cos(α/2)` (≈ 8/σ² for an angular width σ).
    pub exponent: f64,
}

/// Gauss–Legendre nodes on [0,1] for the counts used here, computed once.
fn gl01(n: usize) -> &'static (Vec<f64>, Vec<f64>) {
    static TABLES: OnceLock<Vec<(Vec<f64>, Vec<f64>)>> = OnceLock::new();
    let t = TABLES.get_or_init(|| {
        (0..=128)
            .map(|n| {
                if n == 0 {
                    return (vec![], vec![]);
                }
                let (x, w) = gauss_legendre(n);
                (
                    x.iter().map(|x| 0.5 * (x + 1.0)).collect(),
                    w.iter().map(|w| 0.5 * w).collect(),
                )
            })
            .collect()
    });
    &t[n.clamp(1, 128)]
}

/// One warp of the deterministic MIS rule: a Phong-peak density (exponent 0 = uniform sphere).
#[derive(Clone, Copy)]
struct Warp {
    frame: Frame,
    exponent: f64,
    share: f64,
}

impl Warp {
    fn density(&self, m: DVec3) -> f64 {
        let half_cos2 = (0.5 * (1.0 + self.frame.n.dot(m))).max(0.0);
        PhongLobe::normalization(self.exponent) * half_cos2.powf(0.5 * self.exponent)
    }
}

/// The warps for a continuous NDF and an optional transfer peak.
fn warps(ndf: &Ndf, hint: Option<Peak>) -> Vec<Warp> {
    let mut lobes: Vec<(DVec3, f64, f64)> = Vec::new(); // axis, exponent, weight
    match ndf {
        Ndf::PhongPeaks(p) => {
            for l in p.lobes() {
                if l.weight > 0.0 {
                    lobes.push((l.axis, l.exponent, l.weight));
                }
            }
        }
        Ndf::VonMisesFisher(v) => lobes.push((v.mu, 4.0 * v.kappa, 1.0)),
        Ndf::Microfacet(m) => {
            let a = m.alpha_x.min(m.alpha_y);
            // The core and, for long GGX tails, a lobe four times wider.
            lobes.push((DVec3::Z, 8.0 / (a * a), 0.7));
            lobes.push((DVec3::Z, 2.0 / (a * a), 0.3));
        }
        Ndf::Mixture(mx) => {
            for l in mx.lobes().iter().filter(|l| l.weight > 0.0) {
                let a = l.microfacet.alpha_x.min(l.microfacet.alpha_y);
                lobes.push((DVec3::Z, 8.0 / (a * a), 0.7 * l.weight));
                lobes.push((DVec3::Z, 2.0 / (a * a), 0.3 * l.weight));
            }
        }
        Ndf::Radial(r) => {
            // Its rms angle as a core width and a lobe four times wider for the tails.
            let s = r.rms_theta().max(1e-4);
            lobes.push((DVec3::Z, 4.0 / (s * s), 0.6));
            lobes.push((DVec3::Z, 0.25 / (s * s), 0.4));
        }
        Ndf::Tabulated(_) | Ndf::Harmonics(_) => {
            // Centre a broad warp on the mean normal: cheap and robust for smooth tables.
            let s = crate::grid::EqualAreaGrid::with_cells(2048);
            let mut mean = DVec3::ZERO;
            for c in 0..s.len() {
                let w = s.cell_center(c);
                mean += ndf.eval(w).max(0.0) * w;
            }
            let len = mean.length() * s.cell_solid_angle();
            if len > 1e-6 {
                // Mean resultant length R of a vMF ≈ 1 − 1/κ for large κ.
                let kappa = if len < 0.999 {
                    1.0 / (1.0 - len)
                } else {
                    1000.0
                };
                lobes.push((mean.normalize(), 4.0 * kappa.min(1e4), 1.0));
            }
        }
        Ndf::Sphere(_) | Ndf::Deltas(_) | Ndf::Cylinder(_) => {}
    }
    let uniform_share = if lobes.is_empty() { 0.6 } else { 0.05 };
    let peak_share = if hint.is_some() { 0.35 } else { 0.0 };
    let lobe_share = 1.0 - uniform_share - peak_share;
    let total_w: f64 = lobes.iter().map(|l| l.2).sum();
    let mut out = Vec::with_capacity(lobes.len() + 2);
    out.push(Warp {
        frame: Frame::IDENTITY,
        exponent: 0.0,
        share: if lobes.is_empty() && hint.is_none() {
            1.0
        } else {
            uniform_share
        },
    });
    if let Some(p) = hint {
        let share = if lobes.is_empty() { 0.4 } else { peak_share };
        out.push(Warp {
            frame: Frame::from_normal(p.axis),
            exponent: p.exponent,
            share,
        });
    }
    for (axis, exponent, w) in lobes {
        out.push(Warp {
            frame: Frame::from_normal(axis),
            exponent,
            share: lobe_share * w / total_w,
        });
    }
    let total: f64 = out.iter().map(|w| w.share).sum();
    out.iter_mut().for_each(|w| w.share /= total);
    out
}

/// `∫ n(m) g(m) dω` over the sphere, for `N` integrands at once (see the module docs).
pub fn integrate<const N: usize>(
    ndf: &Ndf,
    accuracy: Accuracy,
    hint: Option<Peak>,
    g: impl Fn(DVec3) -> [f64; N],
) -> [f64; N] {
    let mut acc = [0.0; N];
    match ndf {
        Ndf::Deltas(d) => {
            for wn in d.normals() {
                let v = g(wn.normal);
                for k in 0..N {
                    acc[k] += wn.weight * v[k];
                }
            }
        }
        Ndf::Cylinder(c) => {
            // n = δ(m·a)/(2π) on the full circle (÷π on the half circle): average g over ψ.
            let range = c.psi_range();
            let panels = 8 * accuracy.azimuth.max(4);
            let (x, w) = gl01(8);
            let h = 2.0 * range / panels as f64;
            for p in 0..panels {
                for (xk, wk) in x.iter().zip(w) {
                    let psi = -range + h * (p as f64 + xk);
                    let v = g(c.normal_at(psi));
                    for k in 0..N {
                        acc[k] += wk * h * v[k];
                    }
                }
            }
            for a in &mut acc {
                *a /= 2.0 * range;
            }
        }
        _ => {
            let ws = warps(ndf, hint);
            let (xs, wr) = gl01(accuracy.radial);
            let na = accuracy.azimuth.max(1);
            for warp in &ws {
                let inv_e = 1.0 / (0.5 * warp.exponent + 1.0);
                for (s, wsr) in xs.iter().zip(wr) {
                    let cos_a = (2.0 * s.powf(inv_e) - 1.0).clamp(-1.0, 1.0);
                    let sin_a = (1.0 - cos_a * cos_a).max(0.0).sqrt();
                    for b in 0..na {
                        let phi = 2.0 * PI * (b as f64 + 0.5) / na as f64;
                        let local = DVec3::new(sin_a * phi.cos(), sin_a * phi.sin(), cos_a);
                        let m = warp.frame.to_world(local);
                        let n = ndf.eval(m);
                        if n == 0.0 {
                            continue;
                        }
                        // Balance heuristic: this warp's share of the mixture density at m.
                        let mix: f64 = ws.iter().map(|w| w.share * w.density(m)).sum();
                        let weight = wsr / na as f64 * warp.share / mix * n;
                        let v = g(m);
                        for k in 0..N {
                            acc[k] += weight * v[k];
                        }
                    }
                }
            }
        }
    }
    acc
}

impl Ndf {
    /// `∫ n(m) g(m) dω` for any NDF: exact sums for deltas, a 1-D rule on the cylinder's circle,
    /// and [`integrate`] (lobe-adapted quadrature) otherwise. `N` values at once.
    pub fn integrate<const N: usize>(
        &self,
        accuracy: Accuracy,
        hint: Option<Peak>,
        g: impl Fn(DVec3) -> [f64; N],
    ) -> [f64; N] {
        integrate(self, accuracy, hint, g)
    }

    /// Normalisation integral, mean normal and covariance (3×3, about the mean), by quadrature.
    #[must_use]
    pub fn stats(&self) -> NdfStats {
        let acc = Accuracy::fine();
        let r = self.integrate(acc, None, |m| {
            [
                1.0,
                m.x,
                m.y,
                m.z,
                m.x * m.x,
                m.y * m.y,
                m.z * m.z,
                m.x * m.y,
                m.x * m.z,
                m.y * m.z,
            ]
        });
        let total = r[0];
        let mean = DVec3::new(r[1], r[2], r[3]) / total;
        let second = DMat3::from_cols(
            DVec3::new(r[4], r[7], r[8]),
            DVec3::new(r[7], r[5], r[9]),
            DVec3::new(r[8], r[9], r[6]),
        ) * (1.0 / total);
        let outer = DMat3::from_cols(mean * mean.x, mean * mean.y, mean * mean.z);
        NdfStats {
            integral: total,
            mean_normal: mean,
            covariance: second - outer,
        }
    }
}
