//! Time of writing a pyramid as a map file (format 4: quantised streams per band, deflated),
//! apart from the extraction: a Gaussian random surface (the map of `extract_bench`) extracted once, then
//! `Pyramid::to_bytes` three times, each with its size, wall time and CPU time
//! (docs/benchmarks.md, "Writing map files").
//!
//! ```text
//! cargo build --release -p meso-maps --example map_write
//! ./target/release/examples/map_write [N]     # N × N samples, default 512
//! ```
use meso_maps::{extract, fixtures, ExtractParams, Source};
use std::time::Instant;

/// User + system CPU seconds of this process so far (Linux `/proc/self/stat`), or 0.
fn cpu_seconds() -> f64 {
    let text = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = text.rsplit(')').next().unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |k: usize| f.get(k).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0
}

fn main() {
    let n: usize = std::env::args()
        .nth(1)
        .map_or(512, |s| s.parse().expect("a side in samples"));
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).expect("a Gaussian surface");
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .expect("the extraction");
    for _ in 0..3 {
        let (c0, t0) = (cpu_seconds(), Instant::now());
        let bytes = pyr.to_bytes();
        println!(
            "to_bytes: {} bytes, wall {:.3} s, CPU {:.2} s",
            bytes.len(),
            t0.elapsed().as_secs_f64(),
            cpu_seconds() - c0
        );
    }
}
