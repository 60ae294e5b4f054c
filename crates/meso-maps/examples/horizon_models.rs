//! How well can horizon statistics pooled over a texel stand for the shadows of the geometry?
//! A diagnostic for the NDF-mapped material's per-lobe shadowing (docs/heightmaps.md,
//! "NDF-mapped shadows by level").
//!
//! Random points of the tiled height map are shaded by rays on the displaced surface
//! ([`Gonio::sees`], the truth: Lambert facets, light 69° from the normal at azimuths 0°, 45°
//! and 90°, viewer 31° from the normal at azimuth 270°, each facet counted by the area the
//! viewer sees, `(m·o)⁺/m_z`). The same points are then grouped as a pyramid level groups them
//! — by texel of level `k` (`2ᵏ` cells a side) and by normal (flat, and 8 azimuth sectors
//! at two slopes: about as many groups as a texel has lobes) — and each group's visibility of
//! the light and of the viewer is modelled from the horizon angles of its cells
//! ([`HorizonMap`], ±x and ±y, interpolated in azimuth with weights cos²φ, sin²φ, as
//! [`HorizonStats::visibility`] does). Printed: each model's radiance over the truth, per
//! level:
//!
//! * `ramp`: the cells' four corner angles pooled as a mean and a variance, the ramp of
//!   [`HorizonStats::visibility`], light and viewer independent (what the pyramid stores);
//! * `corners`: the exact fraction of the group's corner angles below the direction's
//!   elevation (the pooled distribution, no ramp), light and viewer independent;
//! * `bilinear`: the same of 4 × 4 points a cell with the corner angles interpolated
//!   bilinearly (the continuous surface's horizons, approximately), independent;
//! * `joint`: the fraction of those points that see both the light and the viewer.
//!
//! ```text
//! cargo run --release -p meso-maps --example horizon_models -- HEIGHTS.jpg HEIGHT_SCALE
//! ```
use glam::DVec3;
use meso_maps::{Border, Gonio, HeightMap, HorizonMap};
use std::path::Path;

/// [`meso_maps::HorizonStats::visibility`]'s ramp of half-width √3·σ, smoothstepped.
fn ramp(mu: f64, var: f64, e: f64) -> f64 {
    let half = 3f64.sqrt() * var.max(0.0).sqrt();
    if half < 1e-9 {
        return if e > mu { 1.0 } else { 0.0 };
    }
    let x = ((e - (mu - half)) / (2.0 * half)).clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// One random point of the surface: its cell, normal group and weights, and what rays see.
struct Point {
    row: usize,
    col: usize,
    group: usize,
    /// `(m·o)⁺/m_z`: the point's seen area per unit of plane area.
    seen: f64,
    /// `(m·l)⁺ (m·o)⁺/m_z`: its Lambert radiance (× π/E) times its seen area.
    lit: f64,
    sees_o: bool,
    sees_l: bool,
}

/// Normal groups: flat (slope < 0.1), then 8 azimuth sectors at slope ≤ 1 and > 1.
const GROUPS: usize = 17;

fn group(m: DVec3) -> usize {
    let slope = (1.0 - m.z * m.z).max(0.0).sqrt() / m.z;
    if slope < 0.1 {
        return 0;
    }
    let phi = m.y.atan2(m.x).rem_euclid(std::f64::consts::TAU);
    let sector = ((phi / std::f64::consts::TAU) * 8.0 + 0.5) as usize % 8;
    1 + sector + 8 * usize::from(slope > 1.0)
}

/// Per group sums: `[n, μ_x, E[h²]_x, μ_y, E[h²]_y, μ_o, E[h²]_o, lit, seen, corners_l,
/// corners_o, bilinear_l, bilinear_o, joint]` (`x`, `y`: the two horizon directions nearest
/// the light's azimuth; `o`: −y, the viewer's).
type Sums = [f64; 14];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(file), Some(scale)) = (args.get(1), args.get(2).and_then(|s| s.parse().ok())) else {
        eprintln!("usage: horizon_models HEIGHTS HEIGHT_SCALE (texel size 1)");
        std::process::exit(2);
    };
    let map = HeightMap::load(Path::new(file), 1.0, scale, Border::Wrap).expect("height map");
    let gonio = Gonio::new(&map).expect("tracer");
    let hz = HorizonMap::compute(&map);
    let (w, h) = (map.width(), map.height());
    let angle = |d: usize, r: usize, c: usize| hz.angle(d, (r % h) * w + (c % w));
    let elev_l = 21f64.to_radians();
    let elev_o = 59f64.to_radians();
    let o = DVec3::new(0.0, -elev_o.cos(), elev_o.sin());
    for az in [0.0f64, 45.0, 90.0] {
        let (ca, sa) = (az.to_radians().cos(), az.to_radians().sin());
        let l = DVec3::new(elev_l.cos() * ca, elev_l.cos() * sa, elev_l.sin());
        let (ix, iy) = (if ca >= 0.0 { 0 } else { 2 }, if sa >= 0.0 { 1 } else { 3 });
        // The angle towards the light of corner (r, c), interpolated in azimuth; towards the
        // viewer (azimuth 270°: −y, direction 3).
        let (c2, s2) = (ca * ca, sa * sa);
        let towards_l = |r: usize, c: usize| c2 * angle(ix, r, c) + s2 * angle(iy, r, c);
        let towards_o = |r: usize, c: usize| angle(3, r, c);
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        let mut uniform = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let points: Vec<Point> = (0..1_000_000)
            .map(|_| {
                let (x, y) = (uniform() * w as f64, uniform() * h as f64);
                let (col, row) = (x.floor() as usize, y.floor() as usize);
                let (tx, ty) = (x - x.floor(), y - y.floor());
                let z = |r: usize, c: usize| gonio.height_at(c as f64, r as f64);
                let (z00, z01, z10, z11) = (
                    z(row, col),
                    z(row, col + 1),
                    z(row + 1, col),
                    z(row + 1, col + 1),
                );
                // The triangle's gradient (as Gonio::height_at splits the cell).
                let (dx, dy) = if ty <= tx {
                    (z01 - z00, z11 - z01)
                } else {
                    (z11 - z10, z10 - z00)
                };
                let m = DVec3::new(-dx, -dy, 1.0).normalize();
                let seen = m.dot(o).max(0.0) / m.z;
                Point {
                    row,
                    col,
                    group: group(m),
                    seen,
                    lit: seen * m.dot(l).max(0.0),
                    sees_o: gonio.sees(x, y, m, o),
                    sees_l: gonio.sees(x, y, m, l),
                }
            })
            .collect();
        let (lit, seen) = points.iter().fold((0.0, 0.0), |(a, b), p| {
            let o = f64::from(u8::from(p.sees_o));
            (
                a + p.lit * o * f64::from(u8::from(p.sees_l)),
                b + p.seen * o,
            )
        });
        let truth = lit / seen;
        println!("light azimuth {az}°: truth {truth:.4} (radiance·π/E); models / truth by level: ramp, corners, bilinear, joint");
        for k in (0..=10usize).step_by(2) {
            let side = 1usize << k;
            let cols = w.div_ceil(side);
            let mut sums = vec![[0.0f64; 14]; cols * h.div_ceil(side) * GROUPS];
            for p in &points {
                let q: &mut Sums =
                    &mut sums[((p.row >> k) * cols + (p.col >> k)) * GROUPS + p.group];
                let corners = [
                    (p.row, p.col),
                    (p.row, p.col + 1),
                    (p.row + 1, p.col),
                    (p.row + 1, p.col + 1),
                ];
                let (al, ao) = (
                    corners.map(|(r, c)| towards_l(r, c)),
                    corners.map(|(r, c)| towards_o(r, c)),
                );
                let mean = |a: &[f64; 4]| a.iter().sum::<f64>() / 4.0;
                let square = |a: &[f64; 4]| a.iter().map(|v| v * v).sum::<f64>() / 4.0;
                let below =
                    |a: &[f64; 4], e: f64| a.iter().filter(|&&v| v < e).count() as f64 / 4.0;
                let (mut bl, mut bo, mut bj) = (0.0, 0.0, 0.0);
                for u in 0..4 {
                    for v in 0..4 {
                        let (s, t) = ((f64::from(u) + 0.5) / 4.0, (f64::from(v) + 0.5) / 4.0);
                        let bil = |a: &[f64; 4]| {
                            a[0] * (1.0 - s) * (1.0 - t)
                                + a[1] * s * (1.0 - t)
                                + a[2] * (1.0 - s) * t
                                + a[3] * s * t
                        };
                        let (vl, vo) = (bil(&al) < elev_l, bil(&ao) < elev_o);
                        bl += f64::from(u8::from(vl)) / 16.0;
                        bo += f64::from(u8::from(vo)) / 16.0;
                        bj += f64::from(u8::from(vl && vo)) / 16.0;
                    }
                }
                let add = [
                    1.0,
                    mean(&al),
                    square(&al),
                    mean(&ao),
                    square(&ao),
                    p.lit,
                    p.seen,
                    below(&al, elev_l),
                    below(&ao, elev_o),
                    bl,
                    bo,
                    bj,
                ];
                for (s, a) in q.iter_mut().zip(add) {
                    *s += a;
                }
            }
            // Σ lit·V_l·V_o / Σ seen·V_o per model.
            let mut num = [0.0f64; 4];
            let mut den = [0.0f64; 4];
            for q in sums.iter().filter(|q| q[0] > 0.0) {
                let n = q[0];
                let (ml, mo) = (q[1] / n, q[3] / n);
                let pairs = [
                    (
                        ramp(ml, q[2] / n - ml * ml, elev_l),
                        ramp(mo, q[4] / n - mo * mo, elev_o),
                    ),
                    (q[7] / n, q[8] / n),
                    (q[9] / n, q[10] / n),
                ];
                for (i, (vl, vo)) in pairs.into_iter().enumerate() {
                    num[i] += q[5] * vl * vo;
                    den[i] += q[6] * vo;
                }
                num[3] += q[5] * q[11] / n;
                den[3] += q[6] * q[10] / n;
            }
            let r: Vec<String> = (0..4)
                .map(|i| format!("{:.3}", num[i] / den[i] / truth))
                .collect();
            println!("  level {k:2} ({side:4} cells a side): {}", r.join("  "));
        }
    }
}
