//! Time the benchmark scene (1024² sphere, 7-lobe multiple surface, 4 point lights, 1 spp)
//! in wall-clock and process CPU time, which stays meaningful on a loaded machine:
//!
//! `cargo run --release -p meso-render --example bench_sphere -- [SIZE] [FRAMES] [OUT.png] [--per-hit] [--material FILE.toml]`
//!
//! `--per-hit` forces the per-hit shading path instead of the stream path (for comparison);
//! `--material` shades the sphere with a material file (through `MaterialShader`) instead of the
//! seven Phong lobes (e.g. one Beckmann lobe, the common material).
//! Also prints the best single frame's wall time.

#[path = "../benches/common/mod.rs"]
mod common;

use meso_render::{render, RenderOptions};
use std::time::Instant;

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_seconds;

fn main() {
    let per_hit = std::env::args().any(|a| a == "--per-hit");
    let all: Vec<String> = std::env::args().collect();
    let material = all
        .iter()
        .position(|a| a == "--material")
        .and_then(|k| all.get(k + 1).cloned());
    let args: Vec<String> = all
        .iter()
        .enumerate()
        .filter(|(k, a)| {
            *a != "--per-hit" && *a != "--material" && !(*k > 0 && all[k - 1] == "--material")
        })
        .map(|(_, a)| a.clone())
        .collect();
    let size: u32 = args.get(1).and_then(|a| a.parse().ok()).unwrap_or(1024);
    let frames: u32 = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(20);
    let scene = match &material {
        None => common::scene(size),
        Some(path) => {
            let text = std::fs::read_to_string(path).unwrap_or_else(|e| {
                eprintln!("{path}: {e}");
                std::process::exit(1)
            });
            let m = meso_core::material::Material::from_toml_str(&text).unwrap_or_else(|e| {
                eprintln!("{path}: {e}");
                std::process::exit(1)
            });
            let shader = meso_render::MaterialShader::new(&m);
            println!("material {path}: {}", shader.path());
            common::scene_with(size, std::sync::Arc::new(shader))
        }
    };
    let opts = RenderOptions {
        per_hit,
        ..RenderOptions::default()
    };
    let _ = render(&scene, &opts, None); // warm-up
    let (c0, t0) = (cpu_seconds(), Instant::now());
    let mut img = None;
    let mut best = f64::INFINITY;
    for _ in 0..frames {
        let t = Instant::now();
        img = Some(render(&scene, &opts, None));
        best = best.min(t.elapsed().as_secs_f64());
    }
    let wall = t0.elapsed().as_secs_f64() / f64::from(frames);
    let cpu = (cpu_seconds() - c0) / f64::from(frames);
    let threads = rayon::current_num_threads();
    println!(
        "{size}x{size}{}: wall {:.1} ms/frame (best {:.1} ms), CPU {:.1} ms/frame ({threads} threads; CPU/threads = {:.1} ms)",
        if per_hit { " per-hit" } else { "" },
        wall * 1e3,
        best * 1e3,
        cpu * 1e3,
        cpu * 1e3 / threads as f64
    );
    if let (Some(out), Some(img)) = (args.get(3), img) {
        if let Err(e) = img.write_png(std::path::Path::new(out), 0.0) {
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
