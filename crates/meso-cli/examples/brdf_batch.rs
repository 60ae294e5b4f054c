//! `cargo run --release -p meso-cli --example brdf_batch [N]` — evaluate a material's BRDF at N
//! random direction pairs (default 10⁶) across cores, as the Python package's `Material.brdf`
//! does (rayon over chunks of 1024 rows), and print the wall time: the Rust side of the
//! Python-overhead benchmark in docs/benchmarks.md (`crates/meso-py/benches/brdf_batch.py` is the
//! Python side, on the same material).

use glam::DVec3;
use meso_core::material::Material;
use meso_core::shading::{FastBrdf, Policy};
use rayon::prelude::*;

/// The benchmark's material: one GGX lobe, Schlick Fresnel, a diffuse base.
const MATERIAL: &str = "form = \"microfacet\"\n[ndf]\nkind = \"ggx\"\nalpha = 0.1\n\
[transfer]\nkind = \"mirror\"\nfresnel = \"schlick\"\nf0 = [0.04, 0.04, 0.04]\n\
[diffuse]\nalbedo = [0.5, 0.4, 0.3]\n";

/// SplitMix64: a reproducible uniform number in [0, 1).
fn uniform(state: &mut u64) -> f64 {
    *state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    (z ^ (z >> 31)) as f64 / 18_446_744_073_709_551_616.0
}

fn hemisphere(u: f64, v: f64) -> DVec3 {
    let z = u;
    let s = (1.0 - z * z).max(0.0).sqrt();
    let phi = std::f64::consts::TAU * v;
    DVec3::new(s * phi.cos(), s * phi.sin(), z)
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1_000_000);
    let m = Material::from_toml_str(MATERIAL).expect("material");
    // The plan `meso brdf` and Python's `Material.brdf` evaluate.
    let m = FastBrdf::with_policy(&m, Policy::Accurate);
    let mut s = 1u64;
    let pairs: Vec<(DVec3, DVec3)> = (0..n)
        .map(|_| {
            let (a, b, c, d) = (
                uniform(&mut s),
                uniform(&mut s),
                uniform(&mut s),
                uniform(&mut s),
            );
            (hemisphere(a, b), hemisphere(c, d))
        })
        .collect();
    let mut best = f64::INFINITY;
    let mut checksum = 0.0;
    for _ in 0..5 {
        let t = std::time::Instant::now();
        let mut out = vec![[0.0f64; 3]; n];
        out.par_chunks_mut(1024).enumerate().for_each(|(c, chunk)| {
            for (k, slot) in chunk.iter_mut().enumerate() {
                let (i, o) = pairs[c * 1024 + k];
                *slot = m.eval(i, o);
            }
        });
        best = best.min(t.elapsed().as_secs_f64());
        checksum = out.iter().map(|v| v[1]).sum::<f64>();
    }
    println!(
        "rust: {n} pairs, best of 5: {:.3} s ({:.1} ns/pair); checksum {checksum:.6e}",
        best,
        best / n as f64 * 1e9
    );
}
