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
//! * `joint`: the fraction of those points that see both the light and the viewer;
//!
//! then the same four with **eight azimuths**: at 45° the light's own horizon angles along the
//! diagonal ([`meso_maps::diagonal_angles`], exact on the same surface) instead of the
//! interpolation of the +x and +y ones (at 0° and 90° the columns repeat the first four).
//!
//! ```text
//! cargo run --release -p meso-maps --example horizon_models -- HEIGHTS.jpg HEIGHT_SCALE
//! ```
//!
//! `AZ=a,b,…` sets the light's azimuths (degrees; default 0,45,90; on a diagonal the eight
//! azimuths' columns read that diagonal's angles), `ELO=e` the viewer's elevation (degrees;
//! default 59).
use glam::DVec3;
use meso_maps::{diagonal_angles, Border, Gonio, HeightMap, HorizonMap};
use rand::{RngExt, SeedableRng};
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

/// Per point, then summed per group: `[1, μ_x, E[h²]_x, μ_y, E[h²]_y, μ_o, E[h²]_o, lit,
/// seen, corners_l, corners_o, bilinear_l, bilinear_o, joint]`. `x`, `y`: the two horizon
/// directions nearest the light's azimuth; `o`: −y, the viewer's; `μ`, `E[h²]`: of the cell's
/// four corner angles; `lit` = `(m·l)⁺ (m·o)⁺/m_z` (Lambert radiance × π/E, times the seen
/// area), `seen` = `(m·o)⁺/m_z`; the rest the fractions that see the light, the viewer, both.
type Sums = [f64; 19];

/// One random point of the surface: its cell and normal group, what rays see from it, and its
/// share of its group's [`Sums`] (the same at every level, so computed once).
struct Point {
    row: usize,
    col: usize,
    group: usize,
    sees_o: bool,
    sees_l: bool,
    sums: Sums,
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

/// Mean, mean square and fraction below `e` of four corner angles.
fn corner_stats(a: &[f64; 4], e: f64) -> (f64, f64, f64) {
    let mean = a.iter().sum::<f64>() / 4.0;
    let square = a.iter().map(|v| v * v).sum::<f64>() / 4.0;
    let below = a.iter().filter(|&&v| v < e).count() as f64 / 4.0;
    (mean, square, below)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (Some(file), Some(scale)) = (args.get(1), args.get(2).and_then(|s| s.parse().ok())) else {
        eprintln!("usage: horizon_models HEIGHTS HEIGHT_SCALE (texel size 1)");
        std::process::exit(2);
    };
    let map = HeightMap::load(Path::new(file), 1.0, scale, Border::Wrap).expect("height map");
    let gonio = Gonio::new(&map).expect("tracer");
    let hz = HorizonMap::compute(&map);
    let diag = diagonal_angles(&map);
    let (w, h) = (map.width(), map.height());
    let angle = |d: usize, r: usize, c: usize| hz.angle(d, (r % h) * w + (c % w));
    let elev_l = 21f64.to_radians();
    let elev_o = std::env::var("ELO")
        .map_or(59.0, |v| v.parse::<f64>().expect("elevation"))
        .to_radians();
    let o = DVec3::new(0.0, -elev_o.cos(), elev_o.sin());
    let azs: Vec<f64> = std::env::var("AZ").map_or(vec![0.0, 45.0, 90.0], |v| {
        v.split(',').map(|x| x.parse().expect("azimuth")).collect()
    });
    for az in azs {
        let (ca, sa) = (az.to_radians().cos(), az.to_radians().sin());
        let l = DVec3::new(elev_l.cos() * ca, elev_l.cos() * sa, elev_l.sin());
        let (ix, iy) = (if ca >= 0.0 { 0 } else { 2 }, if sa >= 0.0 { 1 } else { 3 });
        let (c2, s2) = (ca * ca, sa * sa);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let points: Vec<Point> = (0..1_000_000)
            .map(|_| {
                let (x, y) = (
                    rng.random::<f64>() * w as f64,
                    rng.random::<f64>() * h as f64,
                );
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
                // The cell's corner angles: along the two directions nearest the light, the
                // light's (interpolated in azimuth) and the viewer's (−y, direction 3).
                let corners = [
                    (row, col),
                    (row, col + 1),
                    (row + 1, col),
                    (row + 1, col + 1),
                ];
                let ax = corners.map(|(r, c)| angle(ix, r, c));
                let ay = corners.map(|(r, c)| angle(iy, r, c));
                let ao = corners.map(|(r, c)| angle(3, r, c));
                let al: [f64; 4] = std::array::from_fn(|k| c2 * ax[k] + s2 * ay[k]);
                // With eight azimuths: the light's own (diagonal) angles at 45°.
                let a8 = if (az - 45.0).rem_euclid(90.0) == 0.0 {
                    let di = ((az - 45.0) / 90.0).rem_euclid(4.0) as usize;
                    corners.map(|(r, c)| {
                        f64::from(diag[di][(r % h) * w + (c % w)]) * meso_maps::ANGLE_STEP
                    })
                } else {
                    al
                };
                let (m8, q8, below8) = corner_stats(&a8, elev_l);
                let (mx, qx, _) = corner_stats(&ax, elev_l);
                let (my, qy, _) = corner_stats(&ay, elev_l);
                let (mo, qo, below_o) = corner_stats(&ao, elev_o);
                let (_, _, below_l) = corner_stats(&al, elev_l);
                let (mut bl, mut bo, mut bj, mut bl8, mut bj8) = (0.0, 0.0, 0.0, 0.0, 0.0);
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
                        let vl8 = bil(&a8) < elev_l;
                        bl8 += f64::from(u8::from(vl8)) / 16.0;
                        bj8 += f64::from(u8::from(vl8 && vo)) / 16.0;
                    }
                }
                Point {
                    row,
                    col,
                    group: group(m),
                    sees_o: gonio.sees(x, y, m, o),
                    sees_l: gonio.sees(x, y, m, l),
                    sums: [
                        1.0,
                        mx,
                        qx,
                        my,
                        qy,
                        mo,
                        qo,
                        seen * m.dot(l).max(0.0),
                        seen,
                        below_l,
                        below_o,
                        bl,
                        bo,
                        bj,
                        m8,
                        q8,
                        below8,
                        bl8,
                        bj8,
                    ],
                }
            })
            .collect();
        let (lit, seen) = points.iter().fold((0.0, 0.0), |(a, b), p| {
            let o = f64::from(u8::from(p.sees_o));
            (
                a + p.sums[7] * o * f64::from(u8::from(p.sees_l)),
                b + p.sums[8] * o,
            )
        });
        let truth = lit / seen;
        println!("light azimuth {az}°: truth {truth:.4} (radiance·π/E); models / truth by level: ramp, corners, bilinear, joint; with 8 azimuths: the same");
        for k in (0..=10usize).step_by(2) {
            let side = 1usize << k;
            let cols = w.div_ceil(side);
            let mut sums: Vec<Sums> = vec![[0.0; 19]; cols * h.div_ceil(side) * GROUPS];
            for p in &points {
                let q = &mut sums[((p.row >> k) * cols + (p.col >> k)) * GROUPS + p.group];
                for (s, a) in q.iter_mut().zip(p.sums) {
                    *s += a;
                }
            }
            // Σ lit·V_l·V_o / Σ seen·V_o per model.
            let mut num = [0.0f64; 8];
            let mut den = [0.0f64; 8];
            for q in sums.iter().filter(|q| q[0] > 0.0) {
                let n = q[0];
                let (mx, my, mo) = (q[1] / n, q[3] / n, q[5] / n);
                // As HorizonStats::visibility_along: mean and variance interpolated in azimuth.
                let ml = c2 * mx + s2 * my;
                let vl = c2 * (q[2] / n - mx * mx) + s2 * (q[4] / n - my * my);
                let pairs = [
                    (ramp(ml, vl, elev_l), ramp(mo, q[6] / n - mo * mo, elev_o)),
                    (q[9] / n, q[10] / n),
                    (q[11] / n, q[12] / n),
                    (
                        ramp(q[14] / n, q[15] / n - (q[14] / n).powi(2), elev_l),
                        ramp(mo, q[6] / n - mo * mo, elev_o),
                    ),
                    (q[16] / n, q[10] / n),
                    (q[17] / n, q[12] / n),
                ];
                for (i, (vl, vo)) in pairs.into_iter().enumerate() {
                    let i = if i < 3 { i } else { i + 1 };
                    num[i] += q[7] * vl * vo;
                    den[i] += q[8] * vo;
                }
                num[7] += q[7] * q[18] / n;
                den[7] += q[8] * q[12] / n;
                num[3] += q[7] * q[13] / n;
                den[3] += q[8] * q[12] / n;
            }
            let r: Vec<String> = (0..8)
                .map(|i| format!("{:.3}", num[i] / den[i] / truth))
                .collect();
            println!("  level {k:2} ({side:4} cells a side): {}", r.join("  "));
        }
    }
}
