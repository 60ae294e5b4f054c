//! The streamed extraction's memory and time (docs/benchmarks.md, "Streamed extraction"):
//! `extract_to_file` of an n² Gaussian height map (as `extract_mem` extracts it in memory),
//! the peak resident set (`VmHWM`) after generating the map and at the end. With `--png FILE`,
//! only writes the map as a 16-bit grey PNG (heights over [min, max]) for `meso extract`.
//!
//! ```text
//! cargo build --release -p meso-maps --example extract_stream
//! /usr/bin/time -v ./target/release/examples/extract_stream 4096 /tmp/g4096.map
//! ./target/release/examples/extract_stream 2048 --png /tmp/g2048.png
//! ```
use meso_maps::*;

#[path = "common/proc_status.rs"]
mod proc_status;
use proc_status::mem;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let n: usize = args
        .get(1)
        .map_or(1024, |s| s.parse().expect("a side in samples"));
    let map = fixtures::gaussian(n, 4.0, 0.1, 3, 0.01).unwrap();
    if args.get(2).map(String::as_str) == Some("--png") {
        let h = map.heights();
        let (lo, hi) = h
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
        let px: Vec<u16> = h
            .iter()
            .map(|&v| ((v - lo) / (hi - lo).max(1e-300) * 65535.0).round() as u16)
            .collect();
        let img = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(n as u32, n as u32, px)
            .expect("n² pixels");
        img.save(&args[3]).expect("writing the PNG");
        println!(
            "{}: heights {lo:.5}..{hi:.5} (height scale {:.5})",
            args[3],
            hi - lo
        );
        return;
    }
    let out = std::path::PathBuf::from(args.get(2).map_or("/tmp/extract_stream.map", |s| s));
    let (peak, rss) = mem();
    println!("after generating the map: peak {peak:.0} MB, resident {rss:.0} MB");
    let t = std::time::Instant::now();
    let levels = extract_to_file(
        Source::Heights(&map),
        &ExtractParams::default(),
        &out,
        &mut |p| {
            if p.levels_done > 0 {
                let (peak, rss) = mem();
                eprintln!(
                    "level {} done ({:.0} s): peak {peak:.0} MB, resident {rss:.0} MB",
                    p.levels_done - 1,
                    t.elapsed().as_secs_f64()
                );
            }
        },
    )
    .unwrap();
    let dt = t.elapsed().as_secs_f64();
    let (peak, rss) = mem();
    let size = std::fs::metadata(&out).map_or(0, |m| m.len());
    let est = extract_stream_bytes(n, n, 2, n * n) as f64 / 1e6;
    println!(
        "streamed extraction ({dt:.1} s): peak {peak:.0} MB, resident {rss:.0} MB; {} levels, \
         map file {:.1} MB; estimate (without the map) {est:.0} MB",
        levels.len(),
        size as f64 / 1e6
    );
}
