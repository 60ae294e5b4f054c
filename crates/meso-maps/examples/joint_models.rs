//! How well do per-lobe statistics give the joint visibility of two directions (a light and a
//! viewer) from a steep height map? A diagnostic for
//! [`meso_maps::HorizonCdf::joint_visibility_along`] (docs/heightmaps.md, "Light and viewer
//! together per lobe").
//!
//! Random points of the tiled map take the horizon angles of their cell's corners along the
//! eight stored azimuths, interpolated bilinearly, and are grouped as a pyramid level's lobes
//! are (by texel of level `k` and by normal: flat, then 8 azimuth sectors at two slopes).
//! For every group, every pair of stored azimuths (by how far apart: 0°–180°) and elevations
//! (the list in `ELEVS`, degrees; by default off every node), the exact fraction of the
//! group's points that see both directions is compared with:
//!
//! * the product of the two fractions (the model before 2026-12-07);
//! * a stored joint: for every pair of azimuths the fraction that sees both at the grid of
//!   elevations given (indices into [`CDF_ELEVATIONS_DEG`], default `1,4,7,10,13,15`) to
//!   1/255, read between the nodes as a copula, bilinearly in the two fractions;
//! * the rule the renderer uses: the smaller fraction for azimuths 0° or 45° apart, the
//!   product otherwise.
//!
//! Printed per level and separation: mean absolute error and bias, as fractions of the exact.
//!
//! ```text
//! cargo run --release -p meso-maps --example joint_models -- HEIGHTS.jpg HEIGHT_SCALE [GRID]
//! ```
use glam::DVec3;
use meso_maps::{
    Border, HeightMap, HorizonCdfSum, HorizonDirection, HorizonJointSum, HorizonMap,
    CDF_ELEVATIONS_DEG, HORIZON_AZIMUTHS_DEG,
};
use rand::{RngExt, SeedableRng};
use std::path::Path;

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

struct P {
    row: usize,
    col: usize,
    group: usize,
    h: [f64; 8],
}

/// Slot order of HORIZON_AZIMUTHS_DEG: 0,90,180,270,45,135,225,315 → index by azimuth/45.
const SLOT_OF_OCTANT: [usize; 8] = [0, 4, 1, 5, 2, 6, 3, 7];

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let map = HeightMap::load(
        Path::new(&args[1]),
        1.0,
        args[2].parse().unwrap(),
        Border::Wrap,
    )
    .unwrap();
    let grid: Vec<usize> = args
        .get(3)
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or(vec![1, 4, 7, 10, 13, 15]);
    let hz = HorizonMap::compute(&map);
    let (w, h) = (map.width(), map.height());
    let hs = map.heights();
    let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
    let pts: Vec<P> = (0..400_000)
        .map(|_| {
            let (x, y) = (
                rng.random::<f64>() * w as f64,
                rng.random::<f64>() * h as f64,
            );
            let (col, row) = (x.floor() as usize, y.floor() as usize);
            let (s, t) = (x - x.floor(), y - y.floor());
            let idx = |r: usize, c: usize| (r % h) * w + (c % w);
            let z = |r: usize, c: usize| hs[idx(r, c)];
            let (z00, z01, z10, z11) = (
                z(row, col),
                z(row, col + 1),
                z(row + 1, col),
                z(row + 1, col + 1),
            );
            let (dx, dy) = if t <= s {
                (z01 - z00, z11 - z01)
            } else {
                (z11 - z10, z10 - z00)
            };
            let m = DVec3::new(-dx, -dy, 1.0).normalize();
            let hh = std::array::from_fn(|d| {
                let a = |r, c| hz.angle(d, idx(r, c));
                a(row, col) * (1.0 - s) * (1.0 - t)
                    + a(row, col + 1) * s * (1.0 - t)
                    + a(row + 1, col) * (1.0 - s) * t
                    + a(row + 1, col + 1) * s * t
            });
            P {
                row,
                col,
                group: group(m),
                h: hh,
            }
        })
        .collect();
    let elevs: Vec<f64> = std::env::var("ELEVS")
        .map_or(vec![7.5, 16.0, 27.0, 38.0, 51.0, 60.0], |v| {
            v.split(',').map(|x| x.parse().unwrap()).collect()
        });
    let nodes: Vec<f64> = grid.iter().map(|&i| CDF_ELEVATIONS_DEG[i]).collect();
    for k in [2usize, 4, 6, 8] {
        let cols = w.div_ceil(1 << k);
        let ngroups = cols * h.div_ceil(1 << k) * GROUPS;
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); ngroups];
        for (i, p) in pts.iter().enumerate() {
            members[((p.row >> k) * cols + (p.col >> k)) * GROUPS + p.group].push(i);
        }
        // For relative octant 0..=4 and each model: Σ|err|, Σ err; [6] Σ exact.
        let mut stat = [[[0.0f64; 2]; 5]; 5];
        let gn = nodes.len();
        for g in members.iter().filter(|g| !g.is_empty()) {
            // The library's own: each point as a set of 16 equal points, pooled.
            let (mut cs, mut js) = (HorizonCdfSum::default(), HorizonJointSum::default());
            for &i in g {
                let pts16 = pts[i].h.map(|x| [x; 16]);
                cs.add(&HorizonCdfSum::of_points(&pts16, 1.0), 1.0);
                js.add(&HorizonJointSum::of_points(&pts16, 1.0), 1.0);
            }
            let (lib_cdf, lib_joint) = (cs.finish(), js.finish());
            let dir = |slot: usize, el: f64| {
                let (az, el) = (HORIZON_AZIMUTHS_DEG[slot].to_radians(), el.to_radians());
                HorizonDirection::new(DVec3::new(
                    el.cos() * az.cos(),
                    el.cos() * az.sin(),
                    el.sin(),
                ))
            };
            let n = g.len() as f64;
            let frac = |d: usize, e: f64| g.iter().filter(|&&i| pts[i].h[d] < e).count() as f64 / n;
            let jfrac = |a: usize, ea: f64, b: usize, eb: f64| {
                g.iter()
                    .filter(|&&i| pts[i].h[a] < ea && pts[i].h[b] < eb)
                    .count() as f64
                    / n
            };
            // Node marginals per slot, and grids per ordered slot pair.
            let fnode: Vec<Vec<f64>> = (0..8)
                .map(|d| {
                    nodes
                        .iter()
                        .map(|&e| (frac(d, e.to_radians()) * 255.0).round() / 255.0)
                        .collect()
                })
                .collect();
            let mut grids = vec![vec![0.0; gn * gn]; 64];
            for a in 0..8 {
                for b in 0..8 {
                    for i in 0..gn {
                        for j in 0..gn {
                            let v = jfrac(a, nodes[i].to_radians(), b, nodes[j].to_radians());
                            grids[a * 8 + b][i * gn + j] = (v * 255.0).round() / 255.0;
                        }
                    }
                }
            }
            // The copula of pair (a, b) at (u, v), bilinear in (u, v) between nodes.
            let cop = |a: usize, b: usize, u: f64, v: f64| -> f64 {
                let us: Vec<f64> = std::iter::once(0.0)
                    .chain(fnode[a].iter().copied())
                    .chain(std::iter::once(1.0))
                    .collect();
                let vs: Vec<f64> = std::iter::once(0.0)
                    .chain(fnode[b].iter().copied())
                    .chain(std::iter::once(1.0))
                    .collect();
                let jx = |i: usize, j: usize| -> f64 {
                    if i == 0 || j == 0 {
                        0.0
                    } else if i == gn + 1 {
                        vs[j]
                    } else if j == gn + 1 {
                        us[i]
                    } else {
                        grids[a * 8 + b][(i - 1) * gn + (j - 1)]
                    }
                };
                let seg = |xs: &[f64], x: f64| -> (usize, f64) {
                    let i = xs[..xs.len() - 1]
                        .iter()
                        .rposition(|&y| y <= x)
                        .unwrap_or(0);
                    let d = xs[i + 1] - xs[i];
                    (
                        i,
                        if d > 1e-12 {
                            ((x - xs[i]) / d).clamp(0.0, 1.0)
                        } else {
                            0.0
                        },
                    )
                };
                let (ci, ti) = seg(&us, u);
                let (cj, tj) = seg(&vs, v);
                let c = jx(ci, cj) * (1.0 - ti) * (1.0 - tj)
                    + jx(ci + 1, cj) * ti * (1.0 - tj)
                    + jx(ci, cj + 1) * (1.0 - ti) * tj
                    + jx(ci + 1, cj + 1) * ti * tj;
                c.max((u + v - 1.0).max(0.0)).min(u.min(v))
            };
            for oct in 0..8usize {
                let a = SLOT_OF_OCTANT[oct];
                for rel in 0..=4usize {
                    let b = SLOT_OF_OCTANT[(oct + rel) % 8];
                    for &e1 in &elevs {
                        for &e2 in &elevs {
                            let (ua, ub) = (frac(a, e1.to_radians()), frac(b, e2.to_radians()));
                            let exact = jfrac(a, e1.to_radians(), b, e2.to_radians());
                            let prod = ua * ub;
                            let m = ua.min(ub);
                            let all = if rel == 0 { m } else { cop(a, b, ua, ub) };
                            // The rule HorizonCdf::joint_visibility_along applies.
                            let rule = if rel <= 1 { m } else { prod };
                            let lib = lib_cdf.joint_visibility_along(
                                Some(&lib_joint),
                                &dir(a, e1),
                                &dir(b, e2),
                            );
                            for (mi, v) in [prod, all, rule, lib].into_iter().enumerate() {
                                stat[rel][mi][0] += n * (v - exact).abs();
                                stat[rel][mi][1] += n * (v - exact);
                            }
                            stat[rel][4][0] += n * exact;
                        }
                    }
                }
            }
        }
        println!("level {k}: |err| bias per relative azimuth: product; every pair of azimuths as a copula on the grid; the rule (0°/45° apart: the smaller, else the product); the library (HorizonCdf with HorizonJoint)");
        for (rel, s) in stat.iter().enumerate() {
            let t = s[4][0];
            let cols: Vec<String> = (0..4)
                .map(|m| format!("{:.3} {:+.3}", s[m][0] / t, s[m][1] / t))
                .collect();
            println!("  {:3}°: {}", rel * 45, cols.join("   "));
        }
    }
}
