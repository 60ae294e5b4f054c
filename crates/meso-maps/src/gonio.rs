//! A virtual gonioreflectometer: brute-force ray tracing of the triangulated height map (tiled
//! periodically, so neighbours mask and shadow), under a directional light and an orthographic
//! view.
//!
//! For a direction pair `(i, o)`, `n × n` parallel rays along `−o` are shot through jittered
//! stratified points of one period of the tile (each ray stands for the same projected macro
//! area). The first facet hit, with normal `m`, contributes `f_μ(i, o; m)·max(0, i·m)·V` where
//! `V` is 1 unless a shadow ray towards `i` (also tiled) hits the surface; the BRDF is the
//! mean contribution divided by `cos θ_i` (radiance / (E cos θ_i)). Single bounce by default;
//! [`GonioParams::bounces`] > 1 adds light inter-reflected between facets (path tracing with a
//! shadow ray at every hit). The path continues in a cosine-weighted direction about the facet
//! normal; for rough microfacet facets (`Transfer::Microfacet`) nine draws in ten instead take
//! the facet lobe's own direction (a normal from its `D(m)(m·z)`, mirrored), weighted by the
//! mixture's density, so that glossy facets (α ≈ 0.05) converge; the estimate is unbiased
//! either way (test `lobe_continuation_agrees_with_cosine_continuation`).
//! [`GonioParams::first_bounce`] = 2 keeps only the light that has scattered before: what the
//! effective BRDF's inter-reflection adds to its single bounce (`crate::facet_ndf`).
//!
//! `f_μ` is a `meso_core::transfer::Transfer`, the very facet BRDF that
//! `meso_core::convolution::effective_brdf_with` (and so `meso brdf` and the renderer)
//! convolves with the NDF: the measurement checks that code, not a copy of it.
//!
//! Acceleration: a 2-D DDA over the grid cells with the per-cell maximum height; a ray is
//! tested against a cell's two triangles only where its height range over the cell reaches
//! below that maximum. The triangles are those of `crate::facets` (diagonal `(i,j)–(i+1,j+1)`).

use crate::error::{MapError, Result};
use crate::heightmap::{Border, HeightMap};
use glam::DVec3;
use meso_core::frame::Frame;
use meso_core::transfer::Transfer;
use rand::RngExt;
use rand::SeedableRng;
use rayon::prelude::*;

/// Parameters of a measurement.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GonioParams {
    /// Rays per side of the stratified grid (`n²` rays per direction pair; default 256).
    pub rays_per_side: usize,
    /// Trace shadow rays towards the light (default true). Masking of the view is always on.
    pub shadowing: bool,
    /// Seed of the jitter.
    pub seed: u64,
    /// Scattering events followed per ray (default 1: single bounce). With `b > 1` light
    /// inter-reflected between facets is added: from each hit, a cosine-weighted direction about
    /// the facet normal continues the path (throughput `f_μ·π`), and every hit is lit directly
    /// (shadow ray towards `i`); paths that leave the surface end (the light is directional).
    pub bounces: usize,
    /// The first scattering event whose light (lit directly at that hit) is counted, from 1
    /// (default: all). 2 keeps only the light that scattered at least once before: the part of
    /// the BRDF beyond the single bounce.
    pub first_bounce: usize,
}

impl Default for GonioParams {
    fn default() -> Self {
        GonioParams {
            rays_per_side: 256,
            shadowing: true,
            seed: 1,
            bounces: 1,
            first_bounce: 1,
        }
    }
}

/// A ray tracer over one tileable height map (cell space: unit cells, heights divided by S).
#[derive(Clone, Debug)]
pub struct Gonio {
    w: usize,
    h: usize,
    /// Heights in cell units.
    z: Vec<f64>,
    cell_max: Vec<f64>,
    zmin: f64,
    zmax: f64,
}

/// A hit: where on which triangle of the map, and its facet normal (macro frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter (cell units).
    pub t: f64,
    /// Unit facet normal.
    pub normal: DVec3,
    /// The cell hit, `[row, col]` of the map (wrapped into the tile).
    pub cell: [usize; 2],
    /// The triangle of the cell: 0 for the one holding `y ≤ x` (cell-local coordinates, the
    /// triangle `(0,0)–(1,0)–(1,1)` of `crate::facets`), 1 for the other.
    pub triangle: u8,
    /// The hit point in the cell's own coordinates, `[x, y]` ∈ [0, 1]² (x along columns).
    pub local: [f64; 2],
}

impl Gonio {
    /// The memory (bytes) a tracer of a wrapped map of `width × height` samples holds: its
    /// heights and each cell's highest corner, 8 bytes each.
    #[must_use]
    pub fn bytes(width: usize, height: usize) -> u64 {
        (width as u64)
            .saturating_mul(height as u64)
            .saturating_mul(16)
    }

    /// Prepare a wrapped height map for tracing. Clamped maps are refused (the tile would not
    /// continue, so rays near the border would see a cliff).
    pub fn new(map: &HeightMap) -> Result<Gonio> {
        if map.border() != Border::Wrap {
            return Err(MapError::InvalidParameter {
                name: "border",
                value: "clamp".into(),
                reason: "the gonioreflectometer tiles the map: it needs a wrapped map",
            });
        }
        let (w, h) = (map.width(), map.height());
        let s = map.texel_size();
        let z: Vec<f64> = map.heights().iter().map(|v| v / s).collect();
        let at = |r: usize, c: usize| z[(r % h) * w + (c % w)];
        let mut cell_max = vec![0.0; w * h];
        for r in 0..h {
            for c in 0..w {
                cell_max[r * w + c] = at(r, c)
                    .max(at(r, c + 1))
                    .max(at(r + 1, c))
                    .max(at(r + 1, c + 1));
            }
        }
        let (zmin, zmax) = z
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        Ok(Gonio {
            w,
            h,
            z,
            cell_max,
            zmin,
            zmax,
        })
    }

    #[inline]
    fn zat(&self, r: i64, c: i64) -> f64 {
        let rr = r.rem_euclid(self.h as i64) as usize;
        let cc = c.rem_euclid(self.w as i64) as usize;
        self.z[rr * self.w + cc]
    }

    /// The height (cell units) of the tiled surface above `(x, y)` (cell space: `x` along the
    /// columns, `y` along the rows, any real numbers: the map tiles), on the triangle of its
    /// cell that holds the point (`(0,0)–(1,0)–(1,1)` where `y ≤ x` in the cell, as
    /// [`Hit::triangle`] and `crate::facets`).
    #[must_use]
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        let (fx, fy) = (x.floor(), y.floor());
        let (tx, ty) = (x - fx, y - fy);
        let (c, r) = (fx as i64, fy as i64);
        let z00 = self.zat(r, c);
        let z11 = self.zat(r + 1, c + 1);
        if ty <= tx {
            z00 + tx * (self.zat(r, c + 1) - z00) + ty * (z11 - self.zat(r, c + 1))
        } else {
            let z10 = self.zat(r + 1, c);
            z00 + ty * (z10 - z00) + tx * (z11 - z10)
        }
    }

    /// Whether the surface point above `(x, y)` (cell space, as [`Gonio::height_at`]), on a
    /// facet of unit normal `m`, sees the direction `d` (macro frame, z up; need not be unit):
    /// no part of the tiled surface lies on the ray towards it, started off the facet as
    /// [`Gonio::measure`]'s shadow rays are. False for `d` at or below the macro horizon.
    #[must_use]
    pub fn sees(&self, x: f64, y: f64, m: DVec3, d: DVec3) -> bool {
        if d.z <= 0.0 {
            return false;
        }
        let p = DVec3::new(x, y, self.height_at(x, y)) + m * 1e-7;
        self.intersect(p, d.normalize(), 1e-9).is_none()
    }

    /// First intersection of the ray `o + t·d`, `t > t_min`, with the tiled surface (cell space).
    #[must_use]
    pub fn intersect(&self, o: DVec3, d: DVec3, t_min: f64) -> Option<Hit> {
        let eps = 1e-12;
        // Parameter range where the ray is inside the slab [zmin, zmax].
        let (mut t0, t1) = if d.z.abs() < 1e-15 {
            if o.z < self.zmin || o.z > self.zmax + 1e-9 {
                return None;
            }
            (t_min, t_min + 4.0 * (self.w + self.h) as f64 + 1e6)
        } else {
            let a = (self.zmin - 1e-9 - o.z) / d.z;
            let b = (self.zmax + 1e-9 - o.z) / d.z;
            (a.min(b).max(t_min), a.max(b))
        };
        if t0 > t1 {
            return None;
        }
        t0 = t0.max(t_min);
        let p = o + d * t0;
        let mut cx = p.x.floor() as i64;
        let mut cy = p.y.floor() as i64;
        let step_x: i64 = if d.x > 0.0 { 1 } else { -1 };
        let step_y: i64 = if d.y > 0.0 { 1 } else { -1 };
        let inv_x = if d.x.abs() > eps {
            1.0 / d.x.abs()
        } else {
            f64::INFINITY
        };
        let inv_y = if d.y.abs() > eps {
            1.0 / d.y.abs()
        } else {
            f64::INFINITY
        };
        let fx = p.x - cx as f64;
        let fy = p.y - cy as f64;
        let mut tmx = t0
            + if d.x > 0.0 {
                (1.0 - fx) * inv_x
            } else {
                fx * inv_x
            };
        let mut tmy = t0
            + if d.y > 0.0 {
                (1.0 - fy) * inv_y
            } else {
                fy * inv_y
            };
        let mut t_enter = t0;
        let mut guard = 0usize;
        loop {
            let t_exit = tmx.min(tmy).min(t1);
            let za = o.z + d.z * t_enter;
            let zb = o.z + d.z * t_exit;
            let cmax = self.cell_max[(cy.rem_euclid(self.h as i64) as usize) * self.w
                + cx.rem_euclid(self.w as i64) as usize];
            if za.min(zb) <= cmax + 1e-12 {
                if let Some(hit) = self.cell_hit(cx, cy, o, d, t_enter.max(t_min), t_exit) {
                    return Some(hit);
                }
            }
            if t_exit >= t1 {
                return None;
            }
            if tmx < tmy {
                cx += step_x;
                t_enter = tmx;
                tmx += inv_x;
            } else {
                cy += step_y;
                t_enter = tmy;
                tmy += inv_y;
            }
            guard += 1;
            if guard > 100_000_000 {
                return None;
            }
        }
    }

    fn cell_hit(&self, cx: i64, cy: i64, o: DVec3, d: DVec3, ta: f64, tb: f64) -> Option<Hit> {
        let h00 = self.zat(cy, cx);
        let h01 = self.zat(cy, cx + 1);
        let h10 = self.zat(cy + 1, cx);
        let h11 = self.zat(cy + 1, cx + 1);
        // Local origin relative to the cell corner.
        let lo = DVec3::new(o.x - cx as f64, o.y - cy as f64, o.z);
        let mut best: Option<Hit> = None;
        for (gx, gy, tri_a) in [(h01 - h00, h11 - h01, true), (h11 - h10, h10 - h00, false)] {
            // Plane z = h00 + gx x + gy y.
            let den = d.z - gx * d.x - gy * d.y;
            if den.abs() < 1e-300 {
                continue;
            }
            let t = (h00 + gx * lo.x + gy * lo.y - lo.z) / den;
            let tol = 1e-9 * (1.0 + t.abs());
            if t < ta - tol || t > tb + tol || t <= ta.min(tb) - 1.0 {
                continue;
            }
            let x = lo.x + d.x * t;
            let y = lo.y + d.y * t;
            let e = 1e-9;
            if x < -e || x > 1.0 + e || y < -e || y > 1.0 + e {
                continue;
            }
            if (tri_a && y > x + e) || (!tri_a && y < x - e) {
                continue;
            }
            if best.is_none_or(|b| t < b.t) {
                best = Some(Hit {
                    t,
                    normal: DVec3::new(-gx, -gy, 1.0).normalize(),
                    cell: [
                        cy.rem_euclid(self.h as i64) as usize,
                        cx.rem_euclid(self.w as i64) as usize,
                    ],
                    triangle: u8::from(!tri_a),
                    local: [x.clamp(0.0, 1.0), y.clamp(0.0, 1.0)],
                });
            }
        }
        best
    }

    /// Measure the BRDF (1/sr, RGB) for light direction `i` and view direction `o` (unit, macro
    /// frame, both with z > 0). The facet BRDF `facet` is the core's transfer function,
    /// evaluated in the facet frame `Frame::from_normal_tangent(m, DVec3::X)` exactly as
    /// `meso_core::convolution` evaluates it.
    #[must_use]
    pub fn measure(&self, facet: &Transfer, i: DVec3, o: DVec3, params: &GonioParams) -> [f64; 3] {
        self.measure_with(facet, i, o, params, LOBE_SHARE)
    }

    /// [`Gonio::measure`] with the facet-lobe share `lobe_share` of the continuation's draws
    /// for microfacet facets (0: cosine-weighted only).
    fn measure_with(
        &self,
        facet: &Transfer,
        i: DVec3,
        o: DVec3,
        params: &GonioParams,
        lobe_share: f64,
    ) -> [f64; 3] {
        if i.z <= 0.0 || o.z <= 0.0 {
            return [0.0; 3];
        }
        let n = params.rays_per_side.max(1);
        let (w, h) = (self.w as f64, self.h as f64);
        let start_z = self.zmax + 1.0;
        let sums: Vec<[f64; 3]> = (0..n)
            .into_par_iter()
            .map(|a| {
                let mut rng = rand_pcg::Pcg64::seed_from_u64(
                    params.seed ^ (a as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15),
                );
                let mut acc = [0.0; 3];
                for b in 0..n {
                    let px = (a as f64 + rng.random::<f64>()) / n as f64 * w;
                    let py = (b as f64 + rng.random::<f64>()) / n as f64 * h;
                    let origin = DVec3::new(px, py, 0.0) + o * (start_z / o.z);
                    let mut ray_o = origin;
                    let mut ray_d = -o;
                    let mut wo = o;
                    let mut through = [1.0f64; 3];
                    for bounce in 0..params.bounces.max(1) {
                        let t_min = if bounce == 0 { 0.0 } else { 1e-9 };
                        let Some(hit) = self.intersect(ray_o, ray_d, t_min) else {
                            break;
                        };
                        let m = hit.normal;
                        if wo.dot(m) <= 0.0 {
                            break;
                        }
                        let p = ray_o + ray_d * hit.t;
                        let fr = Frame::from_normal_tangent(m, DVec3::X);
                        let im = i.dot(m);
                        if bounce + 1 >= params.first_bounce
                            && im > 0.0
                            && !(params.shadowing
                                && self.intersect(p + m * 1e-7, i, 1e-9).is_some())
                        {
                            let f = facet.eval(fr.to_local(i), fr.to_local(wo));
                            for c in 0..3 {
                                acc[c] += through[c] * f[c] * im;
                            }
                        }
                        if bounce + 1 >= params.bounces {
                            break;
                        }
                        // Two numbers for a cosine-weighted draw, a third (the strategy) for
                        // microfacet facets.
                        let mut u = [rng.random(), rng.random(), 0.0];
                        if matches!(facet, Transfer::Microfacet { .. }) {
                            u[2] = rng.random();
                        }
                        let Some((local, weight)) =
                            continuation(facet, fr.to_local(wo), u, lobe_share)
                        else {
                            break;
                        };
                        let wi = fr.to_world(local);
                        for c in 0..3 {
                            through[c] *= weight[c];
                        }
                        if through.iter().all(|t| *t <= 0.0) {
                            break;
                        }
                        ray_o = p + m * 1e-7;
                        ray_d = wi;
                        wo = -wi;
                    }
                }
                acc
            })
            .collect();
        let mut tot = [0.0; 3];
        for s in sums {
            for c in 0..3 {
                tot[c] += s[c];
            }
        }
        let k = 1.0 / ((n * n) as f64 * i.z);
        tot.map(|v| v * k)
    }
}

/// Share of a microfacet facet's continuation draws taken from its lobe (the rest are
/// cosine-weighted, which bounds the weight of a draw seen from a grazing direction). The
/// relative noise (RMSE between seeds) of the light beyond the single bounce, 256² paths, on
/// half-cylinders with Beckmann α = 0.1 facets / a plain weave with α = 0.05: share 0.25:
/// 40 % / 17 %; 0.5: 3.1 % / 11.6 %; 0.75: 2.8 % / 7.8 %; 0.9: 1.8 % / 6.2 %; 1: 1.7 % / 9.1 %.
const LOBE_SHARE: f64 = 0.9;

/// The direction a path continues in after scattering at a facet (its local frame, normal +z)
/// seen from `wo` (local), and the path's throughput factor `f·cos θ / pdf` (RGB); `None` when
/// the path ends (a draw below the facet, or nothing reflected). Lambert and Phong facets:
/// cosine-weighted, factor `f·π`. Microfacet facets: with probability `lobe_share` the mirror
/// of `wo` about a normal drawn from the facet's `D(m)(m·z)` (density `D(h) h·z / (4 |wo·h|)`),
/// otherwise cosine-weighted, weighted by the mixture's density. `u ∈ [0, 1)³`, the first
/// number picking the strategy.
fn continuation(
    facet: &Transfer,
    wo: DVec3,
    u: [f64; 3],
    lobe_share: f64,
) -> Option<(DVec3, [f64; 3])> {
    use std::f64::consts::PI;
    let cosine = |u1: f64, u2: f64| {
        let r = u1.sqrt();
        let ph = 2.0 * PI * u2;
        DVec3::new(r * ph.cos(), r * ph.sin(), (1.0 - u1).sqrt())
    };
    let Transfer::Microfacet { distribution, .. } = facet else {
        let local = cosine(u[0], u[1]);
        let f = facet.eval(local, wo);
        return Some((local, f.map(|v| v * PI)));
    };
    if wo.z <= 0.0 {
        return None;
    }
    let wi = if u[0] < lobe_share {
        let m = distribution.sample([u[1], u[2]]);
        meso_core::frame::reflect(wo, m)
    } else {
        cosine(u[1], u[2])
    };
    if wi.z <= 0.0 {
        return None;
    }
    let h = (wi + wo).normalize();
    let lobe = distribution.pdf(h) / (4.0 * wo.dot(h).abs().max(1e-300));
    let pdf = lobe_share * lobe + (1.0 - lobe_share) * wi.z / PI;
    if pdf <= 0.0 || !pdf.is_finite() {
        return None;
    }
    let f = facet.eval(wi, wo);
    Some((wi, f.map(|v| v * wi.z / pdf)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A hit names the cell (wrapped into the tile), the triangle and the cell-local point of
    /// the hit point, and its normal is that triangle's.
    #[test]
    fn a_hit_names_its_cell_triangle_and_point() {
        let (w, h) = (8usize, 8usize);
        let heights: Vec<f64> = (0..w * h)
            .map(|k| 0.3 * ((k % w) as f64 * 0.9).sin() + 0.2 * ((k / w) as f64 * 1.3).cos())
            .collect();
        let map = HeightMap::from_heights(w, h, heights, 1.0, Border::Wrap).unwrap();
        let g = Gonio::new(&map).unwrap();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let mut seen = [0usize; 2];
        for _ in 0..2000 {
            let (x, y): (f64, f64) = (
                rng.random::<f64>() * 40.0 - 16.0,
                rng.random::<f64>() * 40.0 - 16.0,
            );
            let d =
                DVec3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, -1.0).normalize();
            let o = DVec3::new(x, y, 5.0);
            let hit = g
                .intersect(o, d, 0.0)
                .expect("a downward ray hits the tiled surface");
            let p = o + d * hit.t;
            let (fx, fy) = (p.x - p.x.floor(), p.y - p.y.floor());
            let [r, c] = hit.cell;
            assert_eq!(
                c,
                (p.x.floor() as i64).rem_euclid(w as i64) as usize,
                "{p:?}"
            );
            assert_eq!(
                r,
                (p.y.floor() as i64).rem_euclid(h as i64) as usize,
                "{p:?}"
            );
            assert!((hit.local[0] - fx).abs() < 1e-9 && (hit.local[1] - fy).abs() < 1e-9);
            assert_eq!(hit.triangle, u8::from(fy > fx), "{p:?}");
            // The point lies on the plane of that triangle, whose normal is the hit's.
            let z = |rr: usize, cc: usize| map.heights()[(rr % h) * w + cc % w];
            let (h00, h01, h10, h11) = (z(r, c), z(r, c + 1), z(r + 1, c), z(r + 1, c + 1));
            let (gx, gy) = if hit.triangle == 0 {
                (h01 - h00, h11 - h01)
            } else {
                (h11 - h10, h10 - h00)
            };
            assert!((h00 + gx * fx + gy * fy - p.z).abs() < 1e-9, "{p:?}");
            assert!((hit.normal - DVec3::new(-gx, -gy, 1.0).normalize()).length() < 1e-12);
            seen[usize::from(hit.triangle)] += 1;
        }
        assert!(seen[0] > 500 && seen[1] > 500, "{seen:?}");
    }

    /// `height_at` is the height of the triangle a ray hits at that point.
    #[test]
    fn height_at_lies_on_the_hit_triangles() {
        let (w, h) = (8usize, 8usize);
        let heights: Vec<f64> = (0..w * h)
            .map(|k| 0.7 * ((k % w) as f64 * 1.9).sin() + 0.5 * ((k / w) as f64 * 1.3).cos())
            .collect();
        let map = HeightMap::from_heights(w, h, heights, 0.5, Border::Wrap).unwrap();
        let g = Gonio::new(&map).unwrap();
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for _ in 0..2000 {
            let o = DVec3::new(
                rng.random::<f64>() * 40.0 - 16.0,
                rng.random::<f64>() * 40.0 - 16.0,
                9.0,
            );
            let d =
                DVec3::new(rng.random::<f64>() - 0.5, rng.random::<f64>() - 0.5, -1.0).normalize();
            let p = o + d * g.intersect(o, d, 0.0).expect("a hit").t;
            assert!((g.height_at(p.x, p.y) - p.z).abs() < 1e-9, "{p:?}");
        }
    }

    /// From a height sample, looking along a grid line, the surface point sees a direction just
    /// above its horizon angle along that line (`HorizonMap`, exact there) and not one just below
    /// it: two independent computations of the same visibility (`HorizonMap` by upper convex
    /// hulls of the line's heights, `sees` by tracing the triangles).
    #[test]
    fn sees_agrees_with_the_horizon_angles_along_grid_lines() {
        let (w, h) = (16usize, 16usize);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        let heights: Vec<f64> = (0..w * h).map(|_| rng.random::<f64>() * 3.0).collect();
        let map = HeightMap::from_heights(w, h, heights, 1.0, Border::Wrap).unwrap();
        let g = Gonio::new(&map).unwrap();
        let horizon = crate::HorizonMap::compute(&map);
        let dirs: [(f64, f64); 4] = [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)];
        let (mut hidden, mut seen) = (0, 0);
        for r in 0..h {
            for c in 0..w {
                for (k, &(dx, dy)) in dirs.iter().enumerate() {
                    let a = horizon.angle(k, r * w + c);
                    // A hair off the sample, inside the triangle whose edge is the grid line
                    // ahead (a ray exactly on a cell edge can pass between the two triangles
                    // that share it): for +x the cell's triangle (0,0)–(1,0)–(1,1) near its
                    // corner (0,0), for −x the neighbour's other triangle near its (1,1), and
                    // so on.
                    let (x, y) = (
                        c as f64 + 1e-6 * (2.0 * dx + dy),
                        r as f64 + 1e-6 * (dx + 2.0 * dy),
                    );
                    for (elev, want) in [(a + 0.01, true), (a - 0.01, false)] {
                        if elev <= 0.0 || elev >= std::f64::consts::FRAC_PI_2 {
                            continue;
                        }
                        let d = DVec3::new(dx * elev.cos(), dy * elev.cos(), elev.sin());
                        assert_eq!(
                            g.sees(x, y, DVec3::Z, d),
                            want,
                            "sample ({r}, {c}), direction {k}, horizon {a}"
                        );
                        if want {
                            seen += 1;
                        } else {
                            hidden += 1;
                        }
                    }
                }
            }
        }
        assert!(hidden > 500 && seen > 500, "{hidden} hidden, {seen} seen");
        assert!(!g.sees(3.5, 2.25, DVec3::Z, DVec3::new(1.0, 0.0, -0.1)));
    }

    /// The facet-lobe continuation changes the noise, not the answer: on V-grooves with rough
    /// conductor facets (GGX α = 0.3, where cosine-weighted draws converge too), four bounces
    /// measured with the mixture and with cosine-weighted draws alone agree within 3 % per
    /// direction pair (each about 0.5 % noisy at 384² paths), and the part beyond the single
    /// bounce (`first_bounce = 2`) is most of the total here (all of it where no wall is both
    /// lit and seen).
    #[test]
    fn lobe_continuation_agrees_with_cosine_continuation() {
        use meso_core::ndf::{Distribution, Microfacet};
        use meso_core::transfer::Fresnel;
        let map = crate::fixtures::v_grooves(32, 8, 0.25, 1.0 / 32.0).unwrap();
        let g = Gonio::new(&map).unwrap();
        let facet = Transfer::Microfacet {
            distribution: Microfacet::new(Distribution::Ggx, 0.3, 0.3).unwrap(),
            fresnel: Fresnel::None,
        };
        let params = GonioParams {
            rays_per_side: 384,
            bounces: 4,
            ..GonioParams::default()
        };
        let beyond = GonioParams {
            first_bounce: 2,
            ..params
        };
        let d = meso_core::frame::spherical_direction_deg;
        for (i, o) in [
            (d(0.0, 0.0), d(30.0, 180.0)),
            (d(40.0, 0.0), d(40.0, 180.0)),
            (d(50.0, 90.0), d(20.0, 0.0)),
        ] {
            let mixed = g.measure_with(&facet, i, o, &params, LOBE_SHARE)[0];
            let cosine = g.measure_with(&facet, i, o, &params, 0.0)[0];
            assert!(
                (mixed / cosine - 1.0).abs() < 0.03,
                "{i:?} {o:?}: lobe mixture {mixed}, cosine {cosine}"
            );
            let part = g.measure_with(&facet, i, o, &beyond, LOBE_SHARE)[0];
            assert!(part > 0.2 * mixed && part <= mixed, "{part} of {mixed}");
        }
    }
}
