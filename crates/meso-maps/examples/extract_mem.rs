//! Where the memory of a 1024² extraction (K ≤ 4) goes (docs/benchmarks.md, "Extraction
//! memory"): the peak resident set (`VmHWM` of /proc/self/status) after generating the map,
//! after extracting, and the bytes the pyramid itself holds, by part.
//!
//! ```text
//! cargo build --release -p meso-maps --example extract_mem
//! /usr/bin/time -v ./target/release/examples/extract_mem
//! ```
use meso_maps::*;

/// `VmHWM` and `VmRSS` of this process in MB (Linux), or zeros.
fn mem() -> (f64, f64) {
    let text = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        text.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<f64>().ok())
            .map_or(0.0, |kb| kb / 1024.0)
    };
    (field("VmHWM:"), field("VmRSS:"))
}

fn main() {
    let map = fixtures::gaussian(1024, 4.0, 0.1, 3, 0.01).unwrap();
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
    let lobe_mem = lobes * std::mem::size_of::<meso_core::ndf::PhongLobe>();
    let horizon_mem = texels * std::mem::size_of::<HorizonStats>();
    let start_mem = (texels + pyr.levels.len()) * 4;
    println!(
        "pyramid: {lobes} lobes x {} B = {:.0} MB, {texels} texels of horizon statistics x {} B = \
         {:.0} MB, lobe starts {:.0} MB: {:.0} MB in all",
        std::mem::size_of::<meso_core::ndf::PhongLobe>(),
        mb(lobe_mem),
        std::mem::size_of::<HorizonStats>(),
        mb(horizon_mem),
        mb(start_mem),
        mb(lobe_mem + horizon_mem + start_mem)
    );
    drop(map);
    let bytes = pyr.to_bytes();
    println!("its format-3 map file: {:.1} MB", mb(bytes.len()));
}
