//! Render a scene file with every material a Lambertian (albedo from an `albedo = [r, g, b]`
//! line of the material file when present, else 0.8) — a quick way to look at geometry and
//! lights before the real materials are plugged in:
//!
//! `cargo run --release -p meso-render --example render_toml -- SCENE.toml OUT.png [OUT.exr]`

use meso_render::{render, Lambert, RenderOptions, ResolveError, Scene, Shader};
use std::path::Path;
use std::sync::Arc;

fn lambert_from_file(p: &Path) -> Result<Arc<dyn Shader>, ResolveError> {
    let text = std::fs::read_to_string(p).map_err(|e| format!("cannot read: {e}"))?;
    let mut albedo = [0.8f32; 3];
    if let Some(line) = text.lines().find(|l| l.trim_start().starts_with("albedo")) {
        let nums: Vec<f32> = line
            .split(['=', '[', ']', ','])
            .filter_map(|s| s.trim().parse().ok())
            .collect();
        if nums.len() == 3 {
            albedo = [nums[0], nums[1], nums[2]];
        } else {
            return Err(format!("cannot parse `{}`", line.trim()).into());
        }
    }
    Ok(Arc::new(Lambert { albedo }))
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: render_toml SCENE.toml OUT.png [OUT.exr]");
        std::process::exit(2);
    }
    let scene = match Scene::from_toml_file(Path::new(&args[1]), &lambert_from_file) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::exit(1);
        }
    };
    let t = std::time::Instant::now();
    let img = render(&scene, &RenderOptions::default(), None);
    eprintln!("rendered in {:.1} ms", t.elapsed().as_secs_f64() * 1e3);
    let mut result = img.write_png(Path::new(&args[2]), 0.0);
    if let (Ok(()), Some(exr)) = (&result, args.get(3)) {
        result = img.write_exr(Path::new(exr));
    }
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
