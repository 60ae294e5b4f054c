//! Time NDF-mapped frames of a steep height map with shadowing and view weighting: the facade
//! of the tests (`tests/data/facade_disp_256.png`, height 20, Lambert or glossy facets), seen
//! 45° from the normal under a light 69° from it, at 4, 16 and 64 cells per pixel and box
//! details 0, 1 and 2 or those asked for (`NdfMapped::with_box_detail`), and optionally the
//! bump-mapped truth of the same scenes beside them:
//!
//! `cargo run --release -p meso-render --example bench_facade -- [SIZE] [FRAMES] [MAX_LOBES] [DETAILS] [ALPHA] [BUMP_SPP] [FOV]`
//!
//! `SIZE`: image side in pixels (default 256); `FRAMES`: frames per case (default 3), after
//! one untimed frame that builds nothing (the tables are built up front); `MAX_LOBES`: the
//! extraction's lobes per texel at most (default 0: the default of `ExtractParams`, 6 on this
//! map of faces and walls);
//! `DETAILS`: box details timed, 0 to this whole number (default 2), or a comma-separated
//! list of details (e.g. `1.16,3`: a fractional detail blends two levels); `ALPHA`: glossy
//! facets instead of Lambert, GGX of this roughness with a diffuse albedo of 0.1 (the glossy
//! facets of `tests/steep.rs`; default 0: Lambert); `BUMP_SPP`: also time one frame of the
//! bump-mapped truth (`BumpMapped`, shadowed and masked by rays on the displaced mesh) at
//! this many samples per pixel (default 0: not timed); `FOV`: a pinhole camera of this
//! horizontal field of view in degrees, placed to see the same width of the plane at its
//! centre (default 0: orthographic; under a pinhole no two pixels share their viewing
//! direction, so no texel response is kept from one shading call to the next). Prints the extraction's time, then the
//! best wall time and the mean process CPU time per case.

use glam::DVec3;
use meso_core::material::Material;
use meso_maps::{extract, Border, ExtractParams, HeightMap, Source};
use meso_render::{BumpMapped, NdfMapped, RenderOptions, Shader};
use std::sync::Arc;
use std::time::Instant;

#[path = "../tests/common/mod.rs"]
mod common;

#[path = "common/cpu.rs"]
mod cpu;

fn main() {
    let words: Vec<String> = std::env::args().skip(1).collect();
    let number = |a: &str| -> f64 {
        a.parse()
            .expect("numbers: SIZE FRAMES MAX_LOBES DETAILS ALPHA BUMP_SPP FOV")
    };
    // DETAILS: a whole number N (details 0 to N) or a list.
    let details: Vec<f64> = match words.get(3) {
        Some(w) if w.contains(',') || w.contains('.') => w.split(',').map(number).collect(),
        Some(w) => (0..=number(w) as usize).map(|d| d as f64).collect(),
        None => vec![0.0, 1.0, 2.0],
    };
    // The other arguments by position (DETAILS, read above, as 0).
    let nums: Vec<f64> = words
        .iter()
        .enumerate()
        .map(|(i, w)| if i == 3 { 0.0 } else { number(w) })
        .collect();
    let args: Vec<usize> = nums.iter().map(|&x| x as usize).collect();
    let alpha = nums.get(4).copied().unwrap_or(0.0);
    let size = args.first().copied().unwrap_or(256) as u32;
    let frames = args.get(1).copied().unwrap_or(3) as u32;
    // MAX_LOBES 0 (or absent): the extraction's default (6 on the facade, a map of faces and
    // walls); a number: that many.
    let params = match args.get(2).copied() {
        Some(k) if k > 0 => ExtractParams::default().with_max_lobes(k),
        _ => ExtractParams::default(),
    };
    let path = common::facade_path();
    let map = HeightMap::load(&path, 1.0, 20.0, Border::Wrap).expect("the test facade");
    let t0 = Instant::now();
    let pyr = extract(Source::Heights(&map), &params, &mut |_| {}).expect("extraction");
    println!(
        "extraction, at most {} lobes a texel: {:.2} s wall",
        pyr.max_lobes,
        t0.elapsed().as_secs_f64()
    );
    let surface =
        Material::from_toml_str(&common::facet_toml(alpha, 0.1)).expect("the facet material");
    let tpu = map.width() as f64;
    let v = 45f64.to_radians();
    let camera = DVec3::new(0.0, -v.sin(), v.cos());
    let t = 69f64.to_radians();
    let light = DVec3::new(t.sin(), 0.0, t.cos());
    let opts = RenderOptions {
        spp: Some(1),
        ..RenderOptions::default()
    };
    let bump_spp = nums.get(5).copied().unwrap_or(0.0) as u32;
    let fov = nums.get(6).copied().unwrap_or(0.0);
    let bump: Option<Arc<dyn Shader>> = (bump_spp > 0).then(|| {
        Arc::new(BumpMapped::new(&map, &surface, tpu, true).expect("bump-mapped shader")) as _
    });
    for cells in [4.0, 16.0, 64.0] {
        let width = cells * f64::from(size) / tpu;
        if let Some(bump) = &bump {
            let scene = common::plane_scene_through(bump.clone(), width, fov, size, light, camera);
            let bump_opts = RenderOptions {
                spp: Some(bump_spp),
                ..RenderOptions::default()
            };
            let (c0, t0) = (cpu::cpu_seconds(), Instant::now());
            std::hint::black_box(meso_render::render(&scene, &bump_opts, None));
            println!(
                "{size}² frame, {cells} cells/px, bump-mapped at {bump_spp} spp: {:.1} ms wall, \
                 {:.1} ms CPU",
                t0.elapsed().as_secs_f64() * 1e3,
                (cpu::cpu_seconds() - c0) * 1e3
            );
        }
        for &detail in &details {
            let ndf: Arc<dyn Shader> = Arc::new(
                NdfMapped::new(&pyr, &surface, tpu, true)
                    .expect("material")
                    .with_box_detail(detail),
            );
            let scene = common::plane_scene_through(ndf, width, fov, size, light, camera);
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
