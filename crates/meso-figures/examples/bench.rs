//! Benchmarks of the figures' renderer paths (wall-clock best of N frames; CPU time too for the
//! equal-quality comparison):
//!
//! 1. the target scene — a 1024×1024 sphere, a 7-normal multiple surface (Phong
//!    facets), 4 point lights, 1 spp — through `MaterialShader`, next to the renderer's own
//!    `PhongLobes` shader on the same scene;
//! 2. the equal-quality comparison: the NDF-mapped plane at 1–16 spp against the bump map
//!    supersampled, errors against a 1024-spp bump-mapped reference, time for time (best
//!    wall time and mean CPU time per frame over ≥ 3 frames and ≥ 1 s).
//!
//! `cargo run --release -p meso-figures --example bench`

use glam::DVec3;
use meso_render::*;
use std::sync::Arc;
use std::time::Instant;

fn best_ms(frames: u32, f: &mut dyn FnMut() -> Image) -> (f64, Image) {
    let mut img = f();
    let mut best = f64::INFINITY;
    for _ in 0..frames {
        let t = Instant::now();
        img = f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (best, img)
}

/// CPU time (user + system) of this process so far, in ms, from `/proc/self/stat` (clock
/// ticks of 10 ms; `NaN` where it is not available).
fn cpu_ms() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which is in parentheses): state is field 3; utime and
    // stime are fields 14 and 15.
    let rest = s.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |k: usize| f.get(k - 3).and_then(|v| v.parse::<f64>().ok());
    match (tick(14), tick(15)) {
        (Some(u), Some(st)) => (u + st) * 10.0,
        _ => f64::NAN,
    }
}

/// Best wall time (ms) and mean CPU time per frame (ms) over at least 3 frames and at least
/// one second, after a warm-up frame.
fn timed(f: &mut dyn FnMut() -> Image) -> (f64, f64, Image) {
    let mut img = f();
    let mut best = f64::INFINITY;
    let (c0, t0) = (cpu_ms(), Instant::now());
    let mut n = 0u32;
    while n < 3 || t0.elapsed().as_secs_f64() < 1.0 {
        let t = Instant::now();
        img = f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
        n += 1;
    }
    (best, (cpu_ms() - c0) / f64::from(n), img)
}

fn sphere(shader: Arc<dyn Shader>, size: u32) -> Scene {
    let cam = Camera::new(
        Projection::Perspective { fov_deg: 40.0 },
        DVec3::new(0.0, 0.0, 3.2),
        DVec3::ZERO,
        DVec3::Y,
    )
    .expect("camera");
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: size,
            height: size,
            spp: 1,
            background: [0.0; 3],
        },
    );
    let m = b.material(shader);
    b.sphere(DVec3::ZERO, 1.0, DVec3::Y, m).expect("sphere");
    for p in [
        DVec3::new(3.0, 3.0, 4.0),
        DVec3::new(-3.0, 2.0, 4.0),
        DVec3::new(0.0, -3.0, 3.0),
        DVec3::new(2.0, 0.5, -1.0),
    ] {
        b.light(Light::Point {
            position: p,
            intensity: DVec3::splat(10.0),
        })
        .expect("light");
    }
    b.build().expect("scene")
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
    let opts = RenderOptions::default();
    // The Fig. 2d multiple surface (meso_core::catalogue): seven normals under a Phong facet.
    let seven = meso_core::catalogue::seven_normals();
    let mat = seven.material();
    let ms = MaterialShader::new(&mat);
    println!("MaterialShader path: {}", ms.path());
    let s1 = sphere(Arc::new(ms), 1024);
    let (t1, _) = best_ms(10, &mut || render(&s1, &opts, None));
    let lobes: Vec<(DVec3, f64, f64)> = match &mat.ndf {
        meso_core::ndf::Ndf::Deltas(d) => d
            .normals()
            .iter()
            .map(|n| (n.normal, n.weight, seven.exponent))
            .collect(),
        _ => unreachable!("deltas"),
    };
    // PhongLobes has no max(0, N·i)/cos θi factor: a different BRDF, the same loop size.
    let s2 = sphere(
        Arc::new(PhongLobes::new(&lobes, seven.specular.map(|c| c as f32)).expect("lobes")),
        1024,
    );
    let (t2, _) = best_ms(10, &mut || render(&s2, &opts, None));
    println!(
        "1024x1024 sphere, 7 normals, 4 point lights, 1 spp ({} threads): MaterialShader {t1:.1} ms, renderer's PhongLobes {t2:.1} ms",
        rayon::current_num_threads()
    );

    // Equal quality.
    let map = meso_figures::bump_map().expect("map");
    let pyr = meso_figures::pyramid(&map, 4).expect("pyramid");
    let surface = meso_figures::bump_surface().material().expect("surface");
    let tpu = map.cells_x() as f64;
    let bump: Arc<dyn Shader> =
        Arc::new(BumpMapped::new(&map, &surface, tpu, false).expect("bump"));
    // The NDF-mapped material at several sample counts: with a power of two ≥ 4 the renderer
    // fits each sample's footprint to its stratum of the pixel (`ShadingPoint::filter_uv`).
    let ndf_shader: Arc<dyn Shader> = Arc::new(
        NdfMapped::new(&pyr, &surface, tpu, false)
            .expect("ndf")
            .with_sharp_magnification(true),
    );
    let ndf_spp = [1u32, 2, 4, 8, 16];
    for width in [4.0, 16.0] {
        let size = 128;
        println!(
            "plane {width} tiles across {size} px ({:.0} cells/pixel):",
            width * tpu / f64::from(size)
        );
        let sb = meso_figures::plane_scene(bump.clone(), width, size, 1).expect("scene");
        let reference = render(
            &sb,
            &RenderOptions {
                spp: Some(1024),
                seed: 7,
                ..opts
            },
            None,
        );
        let sn = meso_figures::plane_scene(ndf_shader.clone(), width, size, 1).expect("scene");
        for spp in ndf_spp {
            let (t, cpu, img) = timed(&mut || {
                render(
                    &sn,
                    &RenderOptions {
                        spp: Some(spp),
                        ..opts
                    },
                    None,
                )
            });
            println!(
                "  NDF-mapped  {spp:>4} spp: error {:.4}, wall {t:.1} ms, CPU {cpu:.1} ms",
                mean_rel(&img, &reference)
            );
        }
        for spp in [1u32, 4, 16, 32, 64, 128, 256] {
            let (t, cpu, img) = timed(&mut || {
                render(
                    &sb,
                    &RenderOptions {
                        spp: Some(spp),
                        ..opts
                    },
                    None,
                )
            });
            println!(
                "  bump-mapped {spp:>4} spp: error {:.4}, wall {t:.1} ms, CPU {cpu:.1} ms",
                mean_rel(&img, &reference)
            );
        }
    }
}
