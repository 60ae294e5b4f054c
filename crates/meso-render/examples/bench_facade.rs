//! Time NDF-mapped frames of a steep height map with shadowing and view weighting: the facade
//! of the tests (`tests/data/facade_disp_256.png`, height 20, Lambert or glossy facets), seen
//! 45° from the normal under a light 69° from it, at 4, 16 and 64 cells per pixel and box
//! detail 0, 1 and 2 (`NdfMapped::with_box_detail`):
//!
//! `cargo run --release -p meso-render --example bench_facade -- [SIZE] [FRAMES] [MAX_LOBES] [DETAILS] [ALPHA]`
//!
//! `SIZE`: image side in pixels (default 256); `FRAMES`: frames per case (default 3), after
//! one untimed frame that builds nothing (the tables are built up front); `MAX_LOBES`: the
//! extraction's lobes per texel at most (default 4, the default of `ExtractParams`);
//! `DETAILS`: box details timed, 0 to this (default 2); `ALPHA`: glossy facets instead of
//! Lambert, GGX of this roughness with a diffuse albedo of 0.1 (the glossy facets of
//! `tests/steep.rs`; default 0: Lambert). Prints the extraction's time, then the best wall
//! time and the mean process CPU time per case.

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, Border, ExtractParams, HeightMap, Source};
use meso_render::{NdfMapped, RenderOptions, Shader};
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;

#[path = "common/cpu.rs"]
mod cpu;

fn main() {
    let nums: Vec<f64> = std::env::args()
        .skip(1)
        .map(|a| {
            a.parse()
                .expect("numbers: SIZE FRAMES MAX_LOBES DETAILS ALPHA")
        })
        .collect();
    let args: Vec<usize> = nums.iter().map(|&x| x as usize).collect();
    let alpha = nums.get(4).copied().unwrap_or(0.0);
    let size = args.first().copied().unwrap_or(256) as u32;
    let frames = args.get(1).copied().unwrap_or(3) as u32;
    let mut params = ExtractParams::default();
    params.fit.max_lobes = args.get(2).copied().unwrap_or(params.fit.max_lobes);
    let details = args.get(3).copied().unwrap_or(2);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/facade_disp_256.png");
    let map = HeightMap::load(&path, 1.0, 20.0, Border::Wrap).expect("the test facade");
    let t0 = Instant::now();
    let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).expect("extraction");
    println!(
        "extraction, at most {} lobes a texel: {:.2} s wall",
        params.fit.max_lobes,
        t0.elapsed().as_secs_f64()
    );
    let surface = if alpha > 0.0 {
        Material::from_toml_str(&format!(
            "[transfer]\nkind = \"microfacet\"\ndistribution = \"ggx\"\nalpha = {alpha}\n\
             [diffuse]\nalbedo = [0.1, 0.1, 0.1]\n"
        ))
    } else {
        Material::from_toml_str("[transfer]\nkind = \"lambert\"\n")
    }
    .expect("material");
    let tpu = map.width() as f64;
    let v = 45f64.to_radians();
    let camera = DVec3::new(0.0, -v.sin(), v.cos());
    let t = 69f64.to_radians();
    let light = DVec3::new(t.sin(), 0.0, t.cos());
    let opts = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    for cells in [4.0, 16.0, 64.0] {
        for detail in (0..=details).map(|d| d as f64) {
            let ndf: Arc<dyn Shader> = Arc::new(
                NdfMapped::new(&pyr, &surface, tpu, true)
                    .expect("material")
                    .with_box_detail(detail),
            );
            let width = cells * f64::from(size) / tpu;
            let scene = common::plane_scene_from(ndf, width, size, light, camera);
            std::hint::black_box(meso_render::render(&scene, &opts, None));
            let c0 = cpu::cpu_seconds();
            let mut best = f64::MAX;
            for _ in 0..frames {
                let t0 = Instant::now();
                std::hint::black_box(meso_render::render(&scene, &opts, None));
                best = best.min(t0.elapsed().as_secs_f64() * 1e3);
            }
            let cpu = (cpu::cpu_seconds() - c0) * 1e3 / f64::from(frames);
            println!(
                "{size}² frame, {cells} cells/px, box detail {detail}: best {best:.1} ms wall, \
                 mean {cpu:.1} ms CPU"
            );
        }
    }
}
