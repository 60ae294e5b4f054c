//! Time the NDF-mapped material with shadowing: building it from a pyramid, and rendering a
//! plane of it, with each lobe's own visibility (the default) and with one visibility per
//! texel (`NdfMapped::with_texel_visibility`, the model before):
//!
//! `cargo run --release -p meso-render --example bench_mapped -- [MAP] [SIZE] [FRAMES]`
//!
//! `MAP`: side of the generated Gaussian height map (`meso_maps::fixtures::gaussian`,
//! correlation 4 texels; default 512); `SIZE`: image side in pixels (default 256); `FRAMES`:
//! frames per case (default 5). Builds are timed without shadowing (shares only), with
//! shadowing (shares and the lobes' horizon statistics), and `meso_maps::lobe_stats` alone;
//! frames at 2, 8 and 32 texels per pixel, 1 spp, Phong η = 20 facets, one directional light at
//! 70° from the normal. Prints the best wall time and the mean process CPU time per case.

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, fixtures, lobe_stats, ExtractParams, Source};
use meso_render::*;
use std::sync::Arc;
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;
use common::plane_scene;

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_seconds;

/// Runs `f` `n` times: (best wall ms, mean CPU ms).
fn time(n: u32, mut f: impl FnMut()) -> (f64, f64) {
    let c0 = cpu_seconds();
    let mut best = f64::MAX;
    for _ in 0..n {
        let t = Instant::now();
        f();
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    (best, (cpu_seconds() - c0) * 1e3 / f64::from(n))
}

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("numbers: MAP SIZE FRAMES"))
        .collect();
    let n = args.first().copied().unwrap_or(512);
    let size = args.get(1).copied().unwrap_or(256) as u32;
    let frames = args.get(2).copied().unwrap_or(5) as u32;
    let s = 1.0 / n as f64;
    let map = fixtures::gaussian(n, 4.0, 0.7 * s, 3, s).unwrap();
    let t = Instant::now();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let lobes: usize = pyr.levels.iter().map(|l| l.lobes.len()).sum();
    println!(
        "{n}² Gaussian map: extracted in {:.1} s, {} levels, {lobes} lobes",
        t.elapsed().as_secs_f64(),
        pyr.levels.len()
    );
    let surface = Material::from_toml_str(
        "[transfer]\nkind = \"phong\"\nexponent = 20.0\nspecular = [0.6, 0.6, 0.6]\n",
    )
    .unwrap();
    let tpu = n as f64;
    for (what, shadowing) in [("without shadowing", false), ("with shadowing", true)] {
        let (wall, cpu) = time(3, || {
            std::hint::black_box(NdfMapped::new(&pyr, &surface, tpu, shadowing).unwrap());
        });
        println!("build {what}: best {wall:.0} ms wall, mean {cpu:.0} ms CPU");
    }
    for (what, horizons) in [("shares", false), ("shares + lobe horizons", true)] {
        let (wall, cpu) = time(3, || {
            std::hint::black_box(lobe_stats(&pyr, horizons));
        });
        println!("lobe_stats, {what}: best {wall:.0} ms wall, mean {cpu:.0} ms CPU");
    }
    let ndf = NdfMapped::new(&pyr, &surface, tpu, true).unwrap();
    for cells in [2.0, 8.0, 32.0] {
        let width = cells * f64::from(size) / tpu;
        for (what, shader) in [
            ("per lobe", Arc::new(ndf.clone()) as Arc<dyn Shader>),
            (
                "per texel",
                Arc::new(ndf.clone().with_texel_visibility(true)) as Arc<dyn Shader>,
            ),
        ] {
            let t = 70f64.to_radians();
            let scene = plane_scene(shader, width, size, DVec3::new(t.sin(), 0.0, t.cos()));
            let opts = RenderOptions {
                spp: Some(1),
                ..RenderOptions::default()
            };
            let (wall, cpu) = time(frames, || {
                std::hint::black_box(render(&scene, &opts, None));
            });
            println!(
                "{size}² frame, {cells} texels/px, visibility {what}: best {wall:.1} ms wall, \
                 mean {cpu:.1} ms CPU"
            );
        }
    }
}
