//! Time the editor's preview renders for every preset and object.
//!
//! `cargo run --release -p meso-serve --example preview_timing [-- SIDE [MATERIAL.toml …]]`
//! prints the median of 7 renders (after one warm-up) per preset and object at SIDE × SIDE
//! (default 384), and the evaluation path of each material; with material files, those instead
//! of the presets (e.g. a `meso fit` output). The times include compiling the material.

use meso_serve::material_json::{parse_toml, validate};
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
    let files: Vec<String> = std::env::args().skip(2).collect();
    let materials: Vec<(String, serde_json::Value)> = if files.is_empty() {
        presets()
            .into_iter()
            .map(|p| (p.id.to_string(), p.material))
            .collect()
    } else {
        files
            .iter()
            .map(|f| {
                let text = std::fs::read_to_string(f).expect("readable material file");
                (f.clone(), parse_toml(&text).expect("a valid material"))
            })
            .collect()
    };
    for (id, material) in materials {
        let m = validate(&material).expect("valid materials");
        let mut cols = Vec::new();
        let mut path = String::new();
        for object in [Object::Sphere, Object::Plane, Object::Cloth] {
            let req = RenderRequest {
                material: material.clone(),
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
            id, cols[0], cols[1], cols[2]
        );
    }
}
