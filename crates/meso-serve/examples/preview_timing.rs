//! Time the editor's preview renders for every preset and object.
//!
//! `cargo run --release -p meso-serve --example preview_timing [-- SIDE]`
//! prints the median of 7 renders (after one warm-up) per preset and object at SIDE × SIDE
//! (default 384), and the evaluation path of each material.

use meso_serve::material_json::validate;
use meso_serve::presets::presets;
use meso_serve::preview::{default_lights, render_preview, Object, RenderRequest, View};

fn main() {
    let side: u32 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(384);
    println!(
        "preview {side}×{side}, 1 spp, {} rayon threads; median of 7 (ms)",
        rayon::current_num_threads()
    );
    println!(
        "{:<16} {:>8} {:>8} {:>8}  path",
        "preset", "sphere", "plane", "cloth"
    );
    for p in presets() {
        let m = validate(&p.material).expect("presets are valid");
        let mut cols = Vec::new();
        let mut path = String::new();
        for object in [Object::Sphere, Object::Plane, Object::Cloth] {
            let req = RenderRequest {
                material: p.material.clone(),
                view: View {
                    object,
                    width: side,
                    height: side,
                    ..View::default()
                },
                lights: default_lights(),
            };
            let mut times: Vec<f64> = (0..8)
                .map(|_| {
                    let r = render_preview(&req, &m.material).expect("renders");
                    path = r.path;
                    r.render_ms
                })
                .skip(1)
                .collect();
            times.sort_by(f64::total_cmp);
            cols.push(times[times.len() / 2]);
        }
        println!(
            "{:<16} {:>8.1} {:>8.1} {:>8.1}  {path}",
            p.id, cols[0], cols[1], cols[2]
        );
    }
}
