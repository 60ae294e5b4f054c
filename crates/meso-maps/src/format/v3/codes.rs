//! The quantisation codes of format 3 (module docs of `v3`): a lobe's axis as two 20-bit
//! octahedral coordinates, its weight as a u16 share of the texel (the texel's codes adding to
//! exactly 65 535), its exponent as a u16 of `log2(1 + η)`, and a horizon angle in 12 bits over
//! its span.

use crate::limits::ETA_MAX;
use glam::DVec3;
use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

const Q: f64 = 65535.0;
/// Full scale of an octahedral axis coordinate (20 bits, stored in 3 bytes).
const QA: f64 = 1_048_575.0;
/// Full scale of a horizon angle (12 bits, stored in 2 bytes).
const QH: f64 = 4095.0;
/// The ranges of the horizon mean and standard deviation codes (radians): horizon angles lie in
/// [0, π/2), so their means do and their standard deviations are at most π/4.
pub(crate) const MEAN_SPAN: f64 = FRAC_PI_2;
pub(crate) const SD_SPAN: f64 = FRAC_PI_4;

/// Octahedral code of a unit vector (2 × 20 bits): the best of the four nearest codes.
pub(crate) fn oct_encode(a: DVec3) -> (u32, u32) {
    let l1 = a.x.abs() + a.y.abs() + a.z.abs();
    let (mut u, mut v) = (a.x / l1, a.y / l1);
    if a.z < 0.0 {
        (u, v) = ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum());
    }
    let (fu, fv) = ((u * 0.5 + 0.5) * QA, (v * 0.5 + 0.5) * QA);
    let mut best = (0u32, 0u32);
    let mut best_dot = f64::NEG_INFINITY;
    for qu in [fu.floor(), fu.ceil()] {
        for qv in [fv.floor(), fv.ceil()] {
            let c = (qu.clamp(0.0, QA) as u32, qv.clamp(0.0, QA) as u32);
            let d = oct_decode(c.0, c.1).dot(a);
            if d > best_dot {
                best_dot = d;
                best = c;
            }
        }
    }
    best
}

/// The unit vector of an octahedral code.
pub(crate) fn oct_decode(qu: u32, qv: u32) -> DVec3 {
    let u = f64::from(qu) / QA * 2.0 - 1.0;
    let v = f64::from(qv) / QA * 2.0 - 1.0;
    let z = 1.0 - u.abs() - v.abs();
    let (x, y) = if z < 0.0 {
        ((1.0 - v.abs()) * u.signum(), (1.0 - u.abs()) * v.signum())
    } else {
        (u, v)
    };
    DVec3::new(x, y, z).normalize()
}

/// log2(1 + ETA_MAX): the exponent code's full scale.
fn eta_scale() -> f64 {
    (1.0 + ETA_MAX).log2()
}

pub(crate) fn eta_encode(eta: f64) -> u16 {
    ((1.0 + eta.clamp(0.0, ETA_MAX)).log2() / eta_scale() * Q).round() as u16
}

pub(crate) fn eta_decode(q: u16) -> f64 {
    if q == u16::MAX {
        return ETA_MAX;
    }
    ((f64::from(q) / Q * eta_scale()).exp2() - 1.0).clamp(0.0, ETA_MAX)
}

pub(crate) fn angle_encode(x: f64, span: f64) -> u16 {
    (x / span * QH).round().clamp(0.0, QH) as u16
}

pub(crate) fn angle_decode(q: u16, span: f64) -> f64 {
    f64::from(q.min(QH as u16)) / QH * span
}

/// The weight codes of one texel's lobes: `w / Σw · Q16` rounded, then the codes farthest
/// above (below) their exact value lowered (raised) by one until they add to exactly Q16, so a
/// code is within 1 of its exact value and decoding (`q / Σq`) then encoding gives the same
/// codes back.
pub(super) fn weight_codes(w: &[f64]) -> Vec<u32> {
    let sum: f64 = w.iter().sum();
    let exact: Vec<f64> = w.iter().map(|x| x / sum * Q).collect();
    let mut q: Vec<i64> = exact.iter().map(|x| x.round() as i64).collect();
    let mut total: i64 = q.iter().sum();
    while !q.is_empty() && total != Q as i64 {
        let up = total < Q as i64;
        // The code whose rounding went most the wrong way for the correction.
        let i = (0..q.len())
            .filter(|&i| if up { q[i] < Q as i64 } else { q[i] > 0 })
            .max_by(|&a, &b| {
                let (da, db) = (exact[a] - q[a] as f64, exact[b] - q[b] as f64);
                if up {
                    da.total_cmp(&db)
                } else {
                    db.total_cmp(&da)
                }
            })
            .expect("a code can move");
        q[i] += if up { 1 } else { -1 };
        total += if up { 1 } else { -1 };
    }
    q.into_iter().map(|x| x as u32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn octahedral_codes_are_within_their_bound() {
        let mut worst: f64 = 0.0;
        let pi = std::f64::consts::PI;
        for i in 0..200 {
            for j in 0..100 {
                let th = pi * (f64::from(j) + 0.5) / 100.0;
                let ph = 2.0 * pi * f64::from(i) / 200.0;
                let a = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                let (u, v) = oct_encode(a);
                worst = worst.max(oct_decode(u, v).angle_between(a));
            }
        }
        for a in [DVec3::Z, -DVec3::Z, DVec3::X, -DVec3::Y] {
            let (u, v) = oct_encode(a);
            worst = worst.max(oct_decode(u, v).angle_between(a));
        }
        assert!(worst < 2.9e-6, "{worst}");
    }

    #[test]
    fn weight_codes_add_up_and_read_back_to_themselves() {
        for w in [
            vec![1.0],
            vec![0.5, 0.5],
            vec![1.0 / 3.0; 3],
            vec![0.1, 0.2, 0.3, 0.15, 0.25],
            vec![1e-9, 1.0 - 1e-9],
            vec![0.125; 8],
        ] {
            let q = weight_codes(&w);
            assert_eq!(q.iter().sum::<u32>(), 65535, "{w:?}");
            for (x, c) in w.iter().zip(&q) {
                assert!((f64::from(*c) / Q - x).abs() < 1.0 / Q, "{w:?} {q:?}");
            }
            let back: Vec<f64> = q.iter().map(|&c| f64::from(c) / 65535.0).collect();
            assert_eq!(weight_codes(&back), q);
        }
    }

    #[test]
    fn exponent_and_angle_codes_are_within_their_bound() {
        assert_eq!(eta_decode(eta_encode(ETA_MAX)), ETA_MAX);
        assert_eq!(eta_decode(eta_encode(0.0)), 0.0);
        let mut worst: f64 = 0.0;
        let mut eta = 1.0;
        while eta < ETA_MAX {
            let back = eta_decode(eta_encode(eta));
            worst = worst.max((back - eta).abs() / eta / (1.0 + 1.0 / eta));
            eta *= 1.013;
        }
        assert!(worst < 1.06e-4, "{worst}");
        for x in [0.0, 1e-3, 0.3, 1.2, FRAC_PI_2] {
            let back = angle_decode(angle_encode(x, MEAN_SPAN), MEAN_SPAN);
            assert!(
                (back - x).abs() <= 0.5 * MEAN_SPAN / QH + 1e-15,
                "{x} {back}"
            );
        }
    }
}
