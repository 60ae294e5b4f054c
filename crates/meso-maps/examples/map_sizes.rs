//! Map-file sizes (docs/benchmarks.md, "Map file sizes"): extract a pyramid (K ≤ 4, default
//! parameters) from a height map, a normal map or a generated 1024² height map written as a
//! 16-bit PNG, write it as a map file (format 4, the one written) and print the bytes, the ratio
//! to the input file, each stream summed over the bands, what the quantisation moved and the
//! write and read times.
//!
//! ```text
//! cargo run --release -p meso-maps --example map_sizes -- height FILE TEXEL_SIZE HEIGHT_SCALE
//! cargo run --release -p meso-maps --example map_sizes -- normal FILE        # OpenGL convention
//! cargo run --release -p meso-maps --example map_sizes -- generated OUT.png  # 1024² Gaussian
//! ```
use meso_maps::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage =
        "usage: map_sizes height FILE TEXEL_SIZE HEIGHT_SCALE | normal FILE | generated OUT.png";
    let (kind, file) = match args.as_slice() {
        [k, f, ..] => (k.as_str(), PathBuf::from(f)),
        _ => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    };
    let params = ExtractParams::default();
    let t = Instant::now();
    let pyramid = match kind {
        "height" | "generated" => {
            let (s, h) = if kind == "height" {
                let num = |i: usize| -> f64 {
                    args.get(i).and_then(|v| v.parse().ok()).unwrap_or_else(|| {
                        eprintln!("{usage}");
                        std::process::exit(2)
                    })
                };
                (num(2), num(3))
            } else {
                (0.01, write_generated(&file))
            };
            let map = HeightMap::load(&file, s, h, Border::Wrap).unwrap();
            extract(Source::Heights(&map), &params, &mut |_| {}).unwrap()
        }
        "normal" => {
            let map = NormalMap::load(&file, NormalConvention::Gl).unwrap();
            extract(Source::Normals(&map), &params, &mut |_| {}).unwrap()
        }
        _ => {
            eprintln!("{usage}");
            std::process::exit(2);
        }
    };
    let extract_s = t.elapsed().as_secs_f64();
    let input = std::fs::metadata(&file).unwrap().len();
    let t = Instant::now();
    let v4 = pyramid.to_bytes();
    let write_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let back = Pyramid::from_bytes(Path::new("<v4>"), &v4).unwrap();
    let read_s = t.elapsed().as_secs_f64();
    // What the quantisation moved (the file read back against the pyramid as extracted).
    let (mut axis, mut weight, mut eta) = (0.0f64, 0.0f64, 0.0f64);
    for (a, b) in pyramid.levels.iter().zip(&back.levels) {
        assert_eq!(a.lobe_start, b.lobe_start);
        for (x, y) in a.lobes.iter().zip(&b.lobes) {
            axis = axis.max(x.axis.angle_between(y.axis));
            weight = weight.max((x.weight - y.weight).abs());
            eta = eta.max((x.exponent - y.exponent).abs() / x.exponent.max(1e-300));
        }
    }
    let distinct: std::collections::HashSet<[u64; 3]> = pyramid.levels[0]
        .lobes
        .iter()
        .map(|l| l.axis.to_array().map(f64::to_bits))
        .collect();
    println!(
        "quantisation: axes within {axis:.2e} rad, weights {weight:.2e}, exponents {eta:.2e} \
         relative; level 0 has {} distinct lobe axes among {}",
        distinct.len(),
        pyramid.levels[0].lobes.len()
    );
    let lobes: usize = pyramid.levels.iter().map(|l| l.lobes.len()).sum();
    let texels: usize = pyramid.levels.iter().map(Level::texels).sum();
    println!(
        "{}: {}x{}, {} levels, {texels} texels, {lobes} lobes (extracted in {extract_s:.1} s)",
        file.display(),
        pyramid.width,
        pyramid.height,
        pyramid.levels.len()
    );
    println!("input file        {input:>12} bytes");
    println!(
        "format 4          {:>12} bytes  {:>6.2}x input",
        v4.len(),
        v4.len() as f64 / input as f64
    );
    println!(
        "write {write_s:.2} s, read {read_s:.2} s; round trip: {} levels",
        back.levels.len()
    );
    let names = [
        "lobe counts",
        "lobe axes",
        "lobe weights",
        "lobe exponents",
        "horizon weights",
        "horizon angles",
    ];
    // The streams of every band (docs/map-format.md), summed by stream.
    let n = if pyramid.levels[0].horizon.is_some() {
        6
    } else {
        4
    };
    let (mut sums, mut bands, mut overhead) = ([(0u64, 0u64); 6], 0, 48u64);
    let mut pos = 48;
    while pos < v4.len() {
        if &v4[pos..pos + 4] == b"LEND" {
            pos += 52;
            overhead += 52;
            continue;
        }
        bands += 1;
        pos += 20;
        overhead += 20;
        for sum in sums.iter_mut().take(n) {
            let h = &v4[pos..pos + 20];
            sum.0 += u64::from_le_bytes(h[4..12].try_into().unwrap());
            let c = u64::from_le_bytes(h[12..20].try_into().unwrap());
            sum.1 += c;
            overhead += 20;
            pos += 20 + c as usize;
        }
    }
    println!("format 4: {bands} bands, {overhead} bytes of headers and end records");
    for (name, (raw, comp)) in names.iter().zip(sums).take(n) {
        println!(
            "  stream {name:<16} raw {raw:>10}  compressed {comp:>10}  ({:.1} bytes/texel)",
            comp as f64 / texels as f64
        );
    }
}

/// Write the 1024² Gaussian random surface of `extract_bench` (correlation 4 samples) as a
/// 16-bit grey PNG at `out`; returns the height scale that gives back its heights (texel 0.01).
fn write_generated(out: &Path) -> f64 {
    let map = fixtures::gaussian(1024, 4.0, 0.1, 3, 0.01).unwrap();
    let h = map.heights();
    let lo = h.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = h.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let px: Vec<u16> = h
        .iter()
        .map(|v| ((v - lo) / (hi - lo) * 65535.0).round() as u16)
        .collect();
    let img = image::ImageBuffer::<image::Luma<u16>, _>::from_raw(1024, 1024, px).unwrap();
    img.save(out).unwrap();
    hi - lo
}
