//! Writes the browser check's cases as JSON (`tests/engine/lobes.test.mjs`): for every lobe set
//! of `meso_export::lobes::sample_texels` and every pair of `sample_directions`, the texels
//! (values in [0, 1]), `wi`, `wo`, `f0` and the CPU reference `f` (`lobes::eval_texel`).
//!
//! `cargo run -p meso-export --example lobe_cases -- OUT.json`

use meso_export::lobes;

fn main() {
    let out = std::env::args().nth(1).expect("usage: lobe_cases OUT.json");
    let f0s = [[0.04, 0.04, 0.04], [0.95, 0.64, 0.54]];
    let k = lobes::sample_texels()
        .iter()
        .map(Vec::len)
        .max()
        .unwrap_or(1);
    let mut cases = Vec::new();
    for (s, set) in lobes::sample_texels().iter().enumerate() {
        for (p, (wi, wo)) in lobes::sample_directions().iter().enumerate() {
            let f0 = f0s[(s + p) % 2];
            let mut texels = set.clone();
            texels.resize(k, [0.0; 4]);
            let f = lobes::eval_texel(&texels, *wi, *wo, f0);
            cases.push(serde_json::json!({
                "texels": texels,
                "wi": wi.to_array(),
                "wo": wo.to_array(),
                "f0": f0,
                "f": f,
            }));
        }
    }
    let doc = serde_json::json!({ "k": k, "cases": cases });
    std::fs::write(&out, serde_json::to_string(&doc).unwrap()).expect("write");
    eprintln!("{} cases, K = {k} -> {out}", cases.len());
}
