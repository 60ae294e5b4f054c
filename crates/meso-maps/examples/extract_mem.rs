//! Where the memory of a 1024² extraction (K ≤ 4) goes (docs/benchmarks.md, "Extraction
//! memory"): the peak resident set (`VmHWM` of /proc/self/status) after generating the map,
//! after extracting, and the bytes the pyramid itself holds, by part.
//!
//! ```text
//! cargo build --release -p meso-maps --example extract_mem
//! /usr/bin/time -v ./target/release/examples/extract_mem          # 1024²
//! /usr/bin/time -v ./target/release/examples/extract_mem 4096     # any side
//! ```
use meso_maps::*;

#[path = "common/proc_status.rs"]
mod proc_status;
use proc_status::mem;

fn main() {
    // The side (default 1024; 4096 and 8192 for docs/benchmarks.md's large maps).
    let n: usize = std::env::args()
        .nth(1)
        .map_or(1024, |s| s.parse().expect("a side in samples"));
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).unwrap();
    let (peak, rss) = mem();
    println!("after generating the map: peak {peak:.0} MB, resident {rss:.0} MB");
    let t = std::time::Instant::now();
    let pyr = extract(
        Source::Heights(&map),
        &ExtractParams::default(),
        &mut |_| {},
    )
    .unwrap();
    let dt = t.elapsed().as_secs_f64();
    let (peak, rss) = mem();
    println!("after extracting ({dt:.1} s): peak {peak:.0} MB, resident {rss:.0} MB");
    let lobes: usize = pyr.levels.iter().map(|l| l.lobes.len()).sum();
    let texels: usize = pyr.levels.iter().map(Level::texels).sum();
    let mb = |b: usize| b as f64 / 1e6;
    let lobe_mem: usize = pyr.levels.iter().map(|l| l.lobes.bytes()).sum();
    let horizon_mem: usize = pyr
        .levels
        .iter()
        .map(|l| l.horizon.as_ref().map_or(0, Horizons::bytes))
        .sum();
    let start_mem = (texels + pyr.levels.len()) * 4;
    let compact = pyr.levels.iter().filter(|l| l.lobes.is_compact()).count();
    println!(
        "pyramid: {lobes} lobes = {:.0} MB, {texels} texels of horizon statistics = {:.0} MB, \
         lobe starts {:.0} MB: {:.0} MB in all ({compact} of {} levels in f32)",
        mb(lobe_mem),
        mb(horizon_mem),
        mb(start_mem),
        mb(lobe_mem + horizon_mem + start_mem),
        pyr.levels.len()
    );
    drop(map);
    let bytes = pyr.to_bytes();
    println!("its map file (format 4): {:.1} MB", mb(bytes.len()));
}
