//! Time the BVH traversal: a field of `N²` small Lambert spheres on a quad (a few thousand
//! primitives, so every ray walks the tree), seen from above at an angle, under two point lights
//! (closest-hit camera rays, any-hit shadow rays), 1 spp; wall and process CPU time per frame.
//!
//! `cargo run --release -p meso-render --example bench_bvh -- [N] [SIZE] [FRAMES]` (defaults 48,
//! 512, 10).

use glam::DVec3;
use meso_render::*;
use std::sync::Arc;
use std::time::Instant;

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_seconds;

/// The scene: `n × n` spheres of radius 0.3 on a unit grid (heights varied by a hash so that
/// the tree is not a regular grid), on a quad, two point lights.
fn scene(n: usize, size: u32) -> Scene {
    let half = n as f64 / 2.0;
    let cam = Camera::new(
        Projection::Perspective { fov_deg: 50.0 },
        DVec3::new(0.0, -0.9 * half - 4.0, 0.8 * half + 3.0),
        DVec3::ZERO,
        DVec3::Z,
    )
    .expect("valid camera");
    let mut b = SceneBuilder::new(
        cam,
        ImageSettings {
            width: size,
            height: size,
            spp: 1,
            background: [0.0; 3],
        },
    );
    let m = b.material(Arc::new(Lambert {
        albedo: [0.7, 0.6, 0.5],
    }));
    b.quad(
        DVec3::new(-half - 1.0, -half - 1.0, 0.0),
        DVec3::new(n as f64 + 2.0, 0.0, 0.0),
        DVec3::new(0.0, n as f64 + 2.0, 0.0),
        m,
    )
    .expect("valid quad");
    for i in 0..n {
        for j in 0..n {
            let hash = ((i * 7919 + j * 104_729) % 97) as f64 / 97.0;
            let c = DVec3::new(
                i as f64 - half + 0.5,
                j as f64 - half + 0.5,
                0.3 + 0.6 * hash,
            );
            b.sphere(c, 0.3, DVec3::Z, m).expect("valid sphere");
        }
    }
    for p in [
        DVec3::new(-half, -half, 0.6 * half),
        DVec3::new(half, 0.2 * half, 0.3 * half),
    ] {
        b.light(Light::Point {
            position: p,
            intensity: DVec3::splat(half * half),
        })
        .expect("valid light");
    }
    b.build().expect("valid scene")
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let arg = |k: usize, d: usize| args.get(k).and_then(|a| a.parse().ok()).unwrap_or(d);
    let (n, size, frames) = (arg(1, 48), arg(2, 512) as u32, arg(3, 10) as u32);
    let scene = scene(n, size);
    let opts = RenderOptions::default();
    let first = render(&scene, &opts, None);
    let mean = first
        .pixels()
        .iter()
        .map(|p| f64::from(p[0] + p[1] + p[2]))
        .sum::<f64>()
        / first.pixels().len() as f64;
    let (c0, t0) = (cpu_seconds(), Instant::now());
    let mut best = f64::MAX;
    for _ in 0..frames {
        let t = Instant::now();
        std::hint::black_box(render(&scene, &opts, None));
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    let wall = t0.elapsed().as_secs_f64() * 1e3 / f64::from(frames);
    let cpu = (cpu_seconds() - c0) * 1e3 / f64::from(frames);
    println!(
        "{} spheres + 1 quad, {size}², 2 point lights: {wall:.1} ms wall/frame (best {best:.1}), {cpu:.1} ms CPU/frame; mean pixel {mean:.6}",
        n * n
    );
}
