//! Where the NDF-mapped material's error comes from, on the bench's plane (the zoom bump map,
//! `plane_scene`'s fixed view and light, so `wi` and `wo` are the same at every point):
//!
//! 1. per texel of every pyramid level, the exact area-weighted average of the bump-mapped
//!    shading over the texel's triangles (`truth`) against (a) the texel's fitted lobes
//!    integrated with a fine quadrature (`lobes`: the error of the lobe fit) and (b)
//!    `NdfMapped` at that texel and level (`mapped`: fit + BRDF evaluation);
//! 2. per pixel of the bench's images, the 1024-spp bump-mapped reference against the
//!    trilinear filter applied to the *true* texel averages (`filter`: the error of level
//!    selection and filter shape alone) and against `NdfMapped` at 1 spp.
//!
//! `cargo run --release -p meso-figures --example ndf_diag`

use glam::{DVec2, DVec3};
use meso_core::frame::Frame;
use meso_maps::{FacetNormals, NormalMode, Pyramid};
use meso_render::*;
use meso_testkit::lobes::phong_peaks_average;
use std::sync::Arc;

/// Phong facet of the zoom surface.
struct Surf {
    eta: f64,
    spec: f64,
    diff: [f64; 3],
}

impl Surf {
    /// Specular part of the bump-map shading of facet `m`, as a BRDF: `s (m·h)^η (m·i)⁺ / i_z`.
    fn spec(&self, m: DVec3, wi: DVec3, h: DVec3) -> f64 {
        let mi = m.dot(wi);
        if mi <= 0.0 {
            return 0.0;
        }
        self.spec * m.dot(h).max(0.0).powf(self.eta) * mi / wi.z
    }
}

fn sp_at(uv: DVec2, fp: f64) -> ShadingPoint {
    ShadingPoint {
        position: DVec3::new(uv.x, uv.y, 0.0),
        geometric_normal: DVec3::Z,
        frame: Frame::from_normal_tangent(DVec3::Z, DVec3::X),
        uv,
        dpdu: DVec3::X,
        dpdv: DVec3::Y,
        dpdx: DVec3::X * fp,
        dpdy: DVec3::Y * fp,
        duvdx: DVec2::new(fp, 0.0),
        duvdy: DVec2::new(0.0, fp),
        filter_uv: uv,
        material: MaterialId(0),
    }
}

fn mean_rel(a: &Image, b: &Image) -> f64 {
    let (mut n, mut d) = (0.0, 0.0);
    for (p, q) in a.pixels().iter().zip(b.pixels()) {
        for c in 0..3 {
            n += f64::from((p[c] - q[c]).abs());
            d += f64::from(q[c]);
        }
    }
    n / d
}

fn main() {
    // `ndf_diag K test`: the egg crate, surface and view of meso-render's materials test.
    let test_map = std::env::args().nth(2).as_deref() == Some("test");
    let max_lobes: usize = std::env::args()
        .nth(1)
        .map_or(4, |a| a.parse().expect("max lobes"));
    let (map, pyr, def, wo, wi) = if test_map {
        let tau = std::f64::consts::TAU;
        let map =
            meso_maps::HeightMap::from_fn(32, 32, 1.0 / 32.0, meso_maps::Border::Wrap, |x, y| {
                0.035 * (tau * x / 0.25).sin() * (tau * y / 0.25).sin()
            })
            .expect("map");
        let mut p = meso_maps::ExtractParams::default();
        p = p.with_max_lobes(max_lobes);
        let pyr =
            meso_maps::extract(meso_maps::Source::Heights(&map), &p, &mut |_| {}).expect("pyramid");
        let def = meso_figures::MaterialDef {
            name: "test".into(),
            lobes: vec![meso_figures::Lobe::delta(0.0, 0.0, 1.0)],
            exponent: 20.0,
            specular: [0.6; 3],
            diffuse: [0.5, 0.4, 0.3],
        };
        (
            map,
            pyr,
            def,
            DVec3::new(0.0, -0.4, 0.9).normalize(),
            DVec3::new(-0.5, 0.3, 0.8).normalize(),
        )
    } else {
        let map = meso_figures::bump_map().expect("map");
        let pyr = meso_figures::pyramid(&map, max_lobes).expect("pyramid");
        let (wi, _) = meso_figures::plane_sun();
        (
            map,
            pyr,
            meso_figures::bump_surface(),
            meso_figures::plane_view(),
            wi,
        )
    };
    let pyr: Pyramid = pyr;
    let surface = def.material().expect("surface");
    let tpu = map.cells_x() as f64;
    let s = Surf {
        eta: def.exponent,
        spec: def.specular[0],
        diff: def.diffuse,
    };
    let h = (wi + wo).normalize();
    let ndf = NdfMapped::new(&pyr, &surface, tpu, false).expect("ndf");
    let fac = FacetNormals::from_heightmap(&map, NormalMode::Triangles);
    let diff0 = s.diff[0] / std::f64::consts::PI;

    // 1. Per texel.
    println!("level  texels  lobes/texel  |lobes-truth|  (lobes-truth)  |mapped-lobes|  |mapped-truth|   (specular part, sums over texels / sum of truth)");
    let mut truths: Vec<Vec<f64>> = Vec::new();
    for (k, lev) in pyr.levels.iter().enumerate() {
        let span = lev.span;
        let mut t_all = Vec::with_capacity(lev.texels());
        let (mut e_lobe, mut e_map, mut e_eval, mut bias, mut sum_t) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for r in 0..lev.rows {
            for c in 0..lev.cols {
                let (r0, r1) = (r * span, ((r + 1) * span).min(fac.rows));
                let (c0, c1) = (c * span, ((c + 1) * span).min(fac.cols));
                let (mut num, mut n) = (0.0, 0.0);
                for (m, _) in fac.footprint(r0, r1, c0, c1) {
                    num += s.spec(m, wi, h);
                    n += 1.0;
                }
                let truth = num / n;
                let lobes = lev.texel_lobes(r, c).expect("texel");
                let lq = phong_peaks_average(&lobes, &|m| s.spec(m, wi, h), (400, 96));
                let uv = DVec2::new(
                    (c as f64 + 0.5) * span as f64 / tpu,
                    (r as f64 + 0.5) * span as f64 / tpu,
                );
                let fp = 2f64.powf(k as f64 + 0.5) / tpu;
                let sp = sp_at(uv, fp);
                assert!((ndf.lod(&sp) - k as f64).abs() < 1e-9);
                let mapped = f64::from(ndf.eval(&sp, wi, wo)[0]) - diff0;
                e_lobe += (lq - truth).abs();
                e_map += (mapped - truth).abs();
                e_eval += (mapped - lq).abs();
                bias += lq - truth;
                sum_t += truth;
                t_all.push(truth);
            }
        }
        println!(
            "{k:>5}  {:>6}  {:>11.2}  {:>13.4}  {:>13.4}  {:>13.4}  {:>13.4}",
            lev.texels(),
            lev.lobes.len() as f64 / lev.texels() as f64,
            e_lobe / sum_t,
            bias / sum_t,
            e_eval / sum_t,
            e_map / sum_t
        );
        truths.push(t_all);
    }

    if test_map {
        return;
    }
    // 2. Per pixel.
    let bump: Arc<dyn Shader> =
        Arc::new(BumpMapped::new(&map, &surface, tpu, false).expect("bump"));
    let ndf_top = pyr.levels.len() - 2;
    let ndf_s: Arc<dyn Shader> = Arc::new(
        NdfMapped::new(&pyr, &surface, tpu, false)
            .expect("ndf")
            .with_max_level(ndf_top),
    );
    let ndf_capped = NdfMapped::new(&pyr, &surface, tpu, false)
        .expect("ndf")
        .with_max_level(ndf_top);
    let mean = |img: &Image| img.pixels().iter().map(|p| f64::from(p[0])).sum::<f64>();
    for width in [4.0, 16.0] {
        let size = 128u32;
        let sb = meso_figures::plane_scene(bump.clone(), width, size, 1).expect("scene");
        let reference = render(
            &sb,
            &RenderOptions {
                spp: Some(256),
                seed: 7,
                ..RenderOptions::default()
            },
            None,
        );
        for spp in [2u32, 4, 8] {
            for scaled in [0.0, 0.25, 0.375, 0.5] {
                let sh = ndf_capped
                    .clone()
                    .with_footprint_scale(f64::from(spp).powf(-scaled))
                    .with_sharp_magnification(true);
                let sn = meso_figures::plane_scene(Arc::new(sh), width, size, 1).expect("scene");
                let img = render(
                    &sn,
                    &RenderOptions {
                        spp: Some(spp),
                        ..RenderOptions::default()
                    },
                    None,
                );
                let b = meso_figures::plane_scene(bump.clone(), width, size, 1).expect("scene");
                let bi = render(
                    &b,
                    &RenderOptions {
                        spp: Some(spp),
                        ..RenderOptions::default()
                    },
                    None,
                );
                println!(
                    "width {width} spp {spp} scaled {scaled}: mean NDF / reference {:.4}, bump / reference {:.4}; error NDF {:.4}, bump {:.4}",
                    mean(&img) / mean(&reference),
                    mean(&bi) / mean(&reference),
                    mean_rel(&img, &reference),
                    mean_rel(&bi, &reference)
                );
            }
        }
    }
    for width in [4.0, 16.0] {
        let size = 128u32;
        let sb = meso_figures::plane_scene(bump.clone(), width, size, 1).expect("scene");
        let sn = meso_figures::plane_scene(ndf_s.clone(), width, size, 1).expect("scene");
        let reference = render(
            &sb,
            &RenderOptions {
                spp: Some(1024),
                seed: 7,
                ..RenderOptions::default()
            },
            None,
        );
        let img = render(
            &sn,
            &RenderOptions {
                spp: Some(1),
                ..RenderOptions::default()
            },
            None,
        );
        let (mut e_filter, mut e_ndf, mut e_ndf_spec, mut sum, mut sum_spec) =
            (0.0, 0.0, 0.0, 0.0, 0.0);
        let mut lods = (f64::INFINITY, f64::NEG_INFINITY);
        for y in 0..size {
            for x in 0..size {
                let rd = sn
                    .camera
                    .generate_ray(f64::from(x) + 0.5, f64::from(y) + 0.5, size, size);
                let Some(sp) = sn.intersect(&rd) else {
                    continue;
                };
                let lod = ndf_capped.lod(&sp);
                lods = (lods.0.min(lod), lods.1.max(lod));
                // Trilinear taps of the true texel averages (the filter of NdfMapped).
                let l0 = lod.floor() as usize;
                let l1 = (l0 + 1).min(ndf_top);
                let t = lod - l0 as f64;
                let (u, v) = (sp.uv.x * tpu, sp.uv.y * tpu);
                let mut filt = 0.0;
                for (lev, lw) in [(l0, 1.0 - t), (l1, t)] {
                    let l = &pyr.levels[lev];
                    let tx = u / l.span as f64 - 0.5;
                    let ty = v / l.span as f64 - 0.5;
                    let (fx, fy) = (tx.floor(), ty.floor());
                    let (ax, ay) = (tx - fx, ty - fy);
                    for (dy, wy) in [(0i64, 1.0 - ay), (1, ay)] {
                        for (dx, wx) in [(0i64, 1.0 - ax), (1, ax)] {
                            let c = (fx as i64 + dx).rem_euclid(l.cols as i64) as usize;
                            let r = (fy as i64 + dy).rem_euclid(l.rows as i64) as usize;
                            filt += lw * wx * wy * truths[lev][r * l.cols + c];
                        }
                    }
                }
                let e = 2.0 * wi.z; // irradiance · cos θi
                let refv = f64::from(reference.pixels()[(y * size + x) as usize][0]);
                let ndfv = f64::from(img.pixels()[(y * size + x) as usize][0]);
                let fv = (filt + diff0) * e;
                e_filter += (fv - refv).abs();
                e_ndf += (ndfv - refv).abs();
                e_ndf_spec += (ndfv - fv).abs();
                sum += refv;
                sum_spec += refv - diff0 * e;
            }
        }
        println!(
            "plane {width} tiles across {size} px, lod {:.2}..{:.2}: red channel, relative to the reference: \
             filter(true texels) {:.4}, NDF-mapped 1 spp {:.4}, NDF-mapped vs filter(true texels) {:.4} \
             (specular share of the reference {:.2})",
            lods.0,
            lods.1,
            e_filter / sum,
            e_ndf / sum,
            e_ndf_spec / sum,
            sum_spec / sum
        );
    }
}
